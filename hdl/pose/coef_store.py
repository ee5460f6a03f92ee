"""The pose solver's coefficient store: a (slot, row) in, the nine coefficients of that
segment's design row out, :attr:`PoseSolverParams.coef_latency` clocks later.

Two layouts, chosen by ``PoseSolverParams.coef_poly_fmts``:

* a table of every row (``slots × rows`` entries per coefficient; any lens): the
  coefficients are read one clock after the address;
* polynomials in the row (``slots × terms`` entries, :mod:`hdl.pose.row_polynomials`):
  the terms are read, then Horner's scheme runs one multiply-add per clock (one DSP48
  per coefficient and step) and the sum is rounded half-even into the coefficient format.
  For a rectified pinhole rig the terms replace 480 rows by 2, which is what lets a
  large rig's store fit in block RAM (issue 17).

Either way the contents are the initial values given at build time and can be rewritten
at run time through ``write`` (entry ``slot · entries_per_slot + row`` or ``+ term``).
The forecast keeps copies of the same memories and arithmetic that evaluate only the
two coefficients of one design term per clock
(:class:`hdl.pose.coef_term_store.TermStore`).
"""

import numpy as np
from amaranth.hdl import Module, Signal, signed
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.fixed import UQ, Overflow, Rounding, hdl_add, hdl_mul, hdl_resize

__all__ = ["CoefficientStore", "coef_write_signature", "checked_contents", "delayed_rows",
           "horner"]


def coef_write_signature(params):
    """Run-time write of one stored entry (driven by the register file).

    Members
    -------
    addr : Out(entry_bits)
        Entry ``slot · entries_per_slot + row`` (table) or ``+ term`` (polynomials).
    index : Out(4)
        Coefficient 0–8: a_T x y z, a_C x y z, a_R x y z.
    data : Out(signed(coef_store_width))
        Raw value in that entry's format (the low bits of a narrower format).
    en : Out(1)
    """
    return wiring.Signature({"addr": Out(params.entry_bits), "index": Out(4),
                             "data": Out(signed(params.coef_store_width)), "en": Out(1)})


def checked_contents(params, contents, name):
    """``contents`` (zeros if None) as an int array (slots, entries_per_slot, 9) whose
    every value fits its format; a ValueError naming ``name`` otherwise."""
    shape = (params.slots, params.entries_per_slot, 9)
    if contents is None:
        contents = np.zeros(shape, dtype=np.int64)
    contents = np.asarray(contents)
    if contents.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, not {contents.shape}")
    for k in range(9):
        for t in range(params.coef_terms) if params.coef_terms else (None,):
            fmt = params.coef_fmt(k, t)
            values = contents[..., k] if t is None else contents[:, t, k]
            try:
                fmt.raw(values)
            except (OverflowError, TypeError) as exc:
                where = f"coefficient {k}" if t is None else f"coefficient {k} term {t}"
                raise ValueError(f"{name} {where} does not fit {fmt}: {exc}") from None
    return contents


class CoefficientStore(wiring.Component):
    """Coefficient store of :class:`hdl.pose_solver.PoseSolver`.

    Parameters
    ----------
    params : PoseSolverParams
    contents : ndarray (slots, entries_per_slot, 9) of int, optional
        Initial raw contents: rows of coefficients, or polynomial terms (zeros if
        omitted); a value that does not fit its format raises.
    name : str
        The contents' name in error messages.

    Members
    -------
    slot, row : In
        The segment and camera row whose coefficients are wanted (sampled every clock).
    data : Out(ArrayLayout(signed(coef_width), 9))
        Its coefficients, raw in ``coef_t/c/r_fmt``, ``params.coef_latency`` clocks later.
    write : In(coef_write_signature(params))
    """

    #: Has the run-time write port (a subclass's copy may not).
    writable = True

    def __init__(self, params, contents=None, *, name="coefficients"):
        self.params = params
        self.contents = checked_contents(params, contents, name)
        super().__init__({
            "slot": In(params.slot_bits),
            "row": In(params.row_bits),
            "data": Out(data.ArrayLayout(signed(params.coef_width), 9)),
            "write": In(coef_write_signature(params)),
        })

    def _ports(self):
        """The read ports' (slot, row, data …)."""
        return [(self.slot, self.row, self.data)]

    def _memory(self, m, name, shape, index, term=None):
        """One stored lane (coefficient ``index``, polynomial ``term``): each read port's
        data (:meth:`_ports`' slot and row); run-time writes reach it when
        ``write.index`` and the entry's term match."""
        p = self.params
        values = self.contents[..., index] if term is None else self.contents[:, term, index]
        store = Memory(shape=shape, depth=values.size,
                       init=[int(v) for v in values.reshape(-1)])
        m.submodules[name] = store
        datas = []
        for slot, row, *_ in self._ports():
            read = store.read_port()
            m.d.comb += read.addr.eq(slot if term is not None else slot * p.rows + row)
            datas.append(read.data)
        if self.writable:
            write = store.write_port()
            hit = self.write.en & (self.write.index == index)
            if term is None:
                m.d.comb += write.addr.eq(self.write.addr)
            else:
                hit &= self.write.addr % p.coef_terms == term
                m.d.comb += write.addr.eq(self.write.addr // p.coef_terms)
            m.d.comb += [write.data.eq(self.write.data), write.en.eq(hit)]
        return datas

    def elaborate(self, platform):
        p = self.params
        m = Module()
        ports = self._ports()
        if not p.coef_terms:
            for k in range(9):
                datas = self._memory(m, f"coefficients{k}", signed(p.coef_width), k)
                m.d.comb += [out[k].eq(d) for (_, _, out), d in zip(ports, datas)]
            return m
        rows = [delayed_rows(m, p, row, f"_{n}" * n) for n, (_, row, _) in enumerate(ports)]
        for k in range(9):
            terms = [self._memory(m, f"coefficients{k}_{t}",
                                  signed(p.coef_fmt(k, t).width), k, t)
                     for t in range(p.coef_terms)]
            for n, (_, _, out) in enumerate(ports):
                acc, fmt = horner(m, p, [datas[n] for datas in terms],
                                  [p.coef_fmt(k, t) for t in range(p.coef_terms)], rows[n],
                                  f"{k}" + f"_{n}" * n)
                m.d.sync += out[k].eq(hdl_resize(acc, fmt, p.coef_fmt(k), Rounding.HALF_EVEN,
                                                 Overflow.SATURATE))
        return m


def delayed_rows(m, params, row, suffix):
    """``row`` registered once per polynomial term: entry ``step`` is the row a Horner
    step ``step`` multiplies by (the row delayed alongside the terms)."""
    delayed = [Signal(params.row_bits, name=f"row{t}{suffix}")
               for t in range(params.coef_terms)]
    m.d.sync += delayed[0].eq(row)
    m.d.sync += [delayed[t].eq(delayed[t - 1]) for t in range(1, params.coef_terms)]
    return delayed


def horner(m, params, terms, fmts, rows, name):
    """Horner's scheme on the raw ``terms`` (lowest power first, formats ``fmts``; the
    memories' data, one clock after the address) at the row ``rows[step]`` of each
    step, one exact multiply-add per clock; returns the registered sum and its format
    (``coef_terms − 1`` clocks after the data; the caller rounds it)."""
    row_fmt = UQ(params.row_bits, 0)
    top = len(terms) - 1
    acc, fmt = terms[top], fmts[top]
    for step, t in enumerate(range(top - 1, -1, -1)):
        product, product_fmt = hdl_mul(acc, fmt, rows[step], row_fmt)
        # the lower term's read is delayed to meet the product
        lower = terms[t]
        for d in range(step):
            held = Signal.like(lower, name=f"c{name}_{t}_d{d}")
            m.d.sync += held.eq(lower)
            lower = held
        total, fmt = hdl_add(product, product_fmt, lower, fmts[t])
        acc = Signal(fmt.shape(), name=f"horner{name}_{t}")
        m.d.sync += acc.eq(total)
    return acc, fmt

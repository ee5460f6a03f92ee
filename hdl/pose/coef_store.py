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
The forecast (:class:`hdl.pose.forecast_predictor.RowPredictor`) keeps copies without
the write port and with a second read port (both ports of each block RAM read: the
forecast's own rows and :class:`hdl.pose.measured_shift.MeasuredShift`'s measurements);
with polynomials each read port has its own Horner datapath.
"""

import numpy as np
from amaranth.hdl import Module, Signal, signed
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.fixed import UQ, Overflow, Rounding, hdl_add, hdl_mul, hdl_resize

__all__ = ["CoefficientStore", "coef_write_signature", "coef_read_signature"]


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


def coef_read_signature(params):
    """A read port of the store, from the reader's side: the ``slot`` and camera ``row``
    out (sampled every clock), their nine coefficients (raw ``coef_t/c/r_fmt``) in,
    ``params.coef_latency`` clocks later."""
    return wiring.Signature({"slot": Out(params.slot_bits), "row": Out(params.row_bits),
                             "data": In(data.ArrayLayout(signed(params.coef_width), 9))})


class CoefficientStore(wiring.Component):
    """Coefficient store of :class:`hdl.pose_solver.PoseSolver` (and the forecast's).

    Parameters
    ----------
    params : PoseSolverParams
    contents : ndarray (slots, entries_per_slot, 9) of int, optional
        Initial raw contents: rows of coefficients, or polynomial terms (zeros if
        omitted); a value that does not fit its format raises.
    name : str
        The contents' name in error messages.
    second_read : bool
        Add the read port ``second``.
    writable : bool
        Add the run-time write port ``write`` (without it the contents are fixed).

    Members
    -------
    slot, row : In
        The segment and camera row whose coefficients are wanted (sampled every clock).
    data : Out(ArrayLayout(signed(coef_width), 9))
        Its coefficients, raw in ``coef_t/c/r_fmt``, ``params.coef_latency`` clocks later.
    second : In(coef_read_signature(params)), with ``second_read``
        Another (slot, row) read at the same time, with the same latency.
    write : In(coef_write_signature(params)), with ``writable``
    """

    def __init__(self, params, contents=None, *, name="coefficients", second_read=False,
                 writable=True):
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
        self.params = params
        self.contents = contents
        self.second_read, self.writable = second_read, writable
        super().__init__({
            "slot": In(params.slot_bits),
            "row": In(params.row_bits),
            "data": Out(data.ArrayLayout(signed(params.coef_width), 9)),
            **({"second": In(coef_read_signature(params))} if second_read else {}),
            **({"write": In(coef_write_signature(params))} if writable else {}),
        })

    def _ports(self):
        """The read ports' (slot, row, data)."""
        ports = [(self.slot, self.row, self.data)]
        if self.second_read:
            ports.append((self.second.slot, self.second.row, self.second.data))
        return ports

    def _memory(self, m, name, shape, index, term=None):
        """One stored lane (coefficient ``index``, polynomial ``term``): each read port's
        data; run-time writes reach it when ``write.index`` and the entry's term match."""
        p = self.params
        values = self.contents[..., index] if term is None else self.contents[:, term, index]
        store = Memory(shape=shape, depth=values.size,
                       init=[int(v) for v in values.reshape(-1)])
        m.submodules[name] = store
        datas = []
        for slot, row, _ in self._ports():
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
        # per port the row, delayed alongside so each Horner step multiplies by the same y
        rows = []
        for n, (_, row, _) in enumerate(ports):
            delayed = [Signal(p.row_bits, name=f"row{t}" + f"_{n}" * n)
                       for t in range(p.coef_terms)]
            m.d.sync += delayed[0].eq(row)
            m.d.sync += [delayed[t].eq(delayed[t - 1]) for t in range(1, p.coef_terms)]
            rows.append(delayed)
        for k in range(9):
            terms = [self._memory(m, f"coefficients{k}_{t}",
                                  signed(p.coef_fmt(k, t).width), k, t)
                     for t in range(p.coef_terms)]
            for n, (_, _, out) in enumerate(ports):
                self._horner(m, k, [datas[n] for datas in terms], rows[n], out[k],
                             f"_{n}" * n)
        return m

    def _horner(self, m, k, terms, rows, out, suffix):
        """Coefficient ``k`` of one read port: ``terms`` (the memories' data, one clock
        after the address) evaluated at the port's row (``rows[step]`` at each step),
        one multiply-add per clock, rounded half-even into ``out``."""
        p = self.params
        row_fmt = UQ(p.row_bits, 0)
        top = p.coef_terms - 1
        acc, fmt = terms[top], p.coef_fmt(k, top)
        for step, t in enumerate(range(top - 1, -1, -1)):
            product, product_fmt = hdl_mul(acc, fmt, rows[step], row_fmt)
            # the lower term's read is delayed to meet the product
            lower = terms[t]
            for d in range(step):
                held = Signal.like(lower, name=f"c{k}_{t}_d{d}{suffix}")
                m.d.sync += held.eq(lower)
                lower = held
            total, fmt = hdl_add(product, product_fmt, lower, p.coef_fmt(k, t))
            acc = Signal(fmt.shape(), name=f"horner{k}_{t}{suffix}")
            m.d.sync += acc.eq(total)
        m.d.sync += out.eq(hdl_resize(acc, fmt, p.coef_fmt(k), Rounding.HALF_EVEN,
                                      Overflow.SATURATE))

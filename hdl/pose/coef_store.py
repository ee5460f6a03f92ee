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
"""

import numpy as np
from amaranth.hdl import Module, Signal, signed
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.fixed import UQ, Overflow, Rounding, hdl_add, hdl_mul, hdl_resize

__all__ = ["CoefficientStore", "coef_write_signature"]


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


class CoefficientStore(wiring.Component):
    """Coefficient store of :class:`hdl.pose_solver.PoseSolver`.

    Parameters
    ----------
    params : PoseSolverParams
    contents : ndarray (slots, entries_per_slot, 9) of int, optional
        Initial raw contents: rows of coefficients, or polynomial terms (zeros if
        omitted); a value that does not fit its format raises.

    Members
    -------
    slot, row : In
        The segment and camera row whose coefficients are wanted (sampled every clock).
    data : Out(ArrayLayout(signed(coef_width), 9))
        Its coefficients, raw in ``coef_t/c/r_fmt``, ``params.coef_latency`` clocks later.
    write : In(coef_write_signature(params))
    """

    def __init__(self, params, contents=None):
        shape = (params.slots, params.entries_per_slot, 9)
        if contents is None:
            contents = np.zeros(shape, dtype=np.int64)
        contents = np.asarray(contents)
        if contents.shape != shape:
            raise ValueError(f"coefficients must have shape {shape}, not {contents.shape}")
        for k in range(9):          # raises if a value does not fit its format
            if params.coef_terms:
                for t in range(params.coef_terms):
                    params.coef_fmt(k, t).raw(contents[:, t, k])
            else:
                params.coef_fmt(k).raw(contents[..., k])
        self.params = params
        self.contents = contents
        super().__init__({
            "slot": In(params.slot_bits),
            "row": In(params.row_bits),
            "data": Out(data.ArrayLayout(signed(params.coef_width), 9)),
            "write": In(coef_write_signature(params)),
        })

    def _memory(self, m, name, shape, index, term=None):
        """One stored lane (coefficient ``index``, polynomial ``term``): its read port's
        data; run-time writes reach it when ``write.index`` and the entry's term match."""
        p = self.params
        values = self.contents[..., index] if term is None else self.contents[:, term, index]
        store = Memory(shape=shape, depth=values.size,
                       init=[int(v) for v in values.reshape(-1)])
        m.submodules[name] = store
        read, write = store.read_port(), store.write_port()
        hit = self.write.en & (self.write.index == index)
        if term is None:
            m.d.comb += [read.addr.eq(self.slot * p.rows + self.row),
                         write.addr.eq(self.write.addr)]
        else:
            m.d.comb += read.addr.eq(self.slot)
            hit &= self.write.addr % p.coef_terms == term
            m.d.comb += write.addr.eq(self.write.addr // p.coef_terms)
        m.d.comb += [write.data.eq(self.write.data), write.en.eq(hit)]
        return read.data

    def elaborate(self, platform):
        p = self.params
        m = Module()
        if not p.coef_terms:
            for k in range(9):
                m.d.comb += self.data[k].eq(self._memory(m, f"coefficients{k}",
                                                         signed(p.coef_width), k))
            return m

        # Horner: the row is delayed alongside so each step multiplies by the same y
        row_fmt = UQ(p.row_bits, 0)
        rows = [Signal(p.row_bits, name=f"row{t}") for t in range(p.coef_terms)]
        m.d.sync += rows[0].eq(self.row)
        m.d.sync += [rows[t].eq(rows[t - 1]) for t in range(1, p.coef_terms)]
        top = p.coef_terms - 1
        for k in range(9):
            terms = [self._memory(m, f"coefficients{k}_{t}",
                                  signed(p.coef_fmt(k, t).width), k, t)
                     for t in range(p.coef_terms)]
            acc, fmt = terms[top], p.coef_fmt(k, top)
            for step, t in enumerate(range(top - 1, -1, -1)):
                product, product_fmt = hdl_mul(acc, fmt, rows[step], row_fmt)
                # the lower term's read is delayed to meet the product
                lower = terms[t]
                for d in range(step):
                    held = Signal.like(lower, name=f"c{k}_{t}_d{d}")
                    m.d.sync += held.eq(lower)
                    lower = held
                total, fmt = hdl_add(product, product_fmt, lower, p.coef_fmt(k, t))
                acc = Signal(fmt.shape(), name=f"horner{k}_{t}")
                m.d.sync += acc.eq(total)
            m.d.sync += self.data[k].eq(hdl_resize(acc, fmt, p.coef_fmt(k), Rounding.HALF_EVEN,
                                                   Overflow.SATURATE))
        return m

"""The row-descriptor FIR (:mod:`hdl.row_descriptor`): each row convolved with the
quantized second derivative of a Gaussian, one sign bit per column."""

from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import UQ, hdl_add, hdl_mul_constant
from hdl.descriptor.layouts import descriptor_layout, framed_layout
from hdl.descriptor.params import check_lane_params

__all__ = ["DescriptorFIR"]


class DescriptorFIR(wiring.Component):
    """Second-derivative-of-Gaussian FIR and sign of one camera's rows, one column per
    clock.

    The window holds the last ``2R + 1`` pixels of the row; the symmetric kernel is
    applied as ``R + 1`` pre-added pairs times constant coefficients (raw
    ``coeff_fmt``), summed exactly (no narrowing anywhere) in a registered adder tree.
    The bit of column ``pos − R`` is ``response > 0`` and the column is strong where
    ``|response| ≥ strong_raw``; both are 0 while ``pos < 2R`` (the window is not yet
    inside the row: golden's border convention).

    Members
    -------
    i : In(stream.Signature(framed_layout(params, 1)))
    o : Out(stream.Signature(descriptor_layout(params, 1)))

    Latency :attr:`latency` clocks; one column per clock; backpressure stalls the whole
    pipeline (``i.ready`` low while ``o`` holds an untaken item). Reset clears the
    pipeline's valid bits (the window needs no reset: its first ``2R`` columns are
    masked).
    """

    def __init__(self, params):
        self.params = check_lane_params(params)
        self._terms = sum(1 for q in self._pair_coeffs() if q != 0)
        super().__init__({
            "i": In(stream.Signature(framed_layout(params, 1))),
            "o": Out(stream.Signature(descriptor_layout(params, 1))),
        })

    def _pair_coeffs(self):
        """Coefficient of the centre tap, then of each symmetric pair ``±1 … ±R``."""
        k = self.params.kernel_raw()
        return k[self.params.radius:]

    @property
    def tree_levels(self):
        return max(self._terms - 1, 0).bit_length()

    @property
    def latency(self):
        """Window, pre-add, product, then one clock per adder-tree level (the last level
        registers the sign bit)."""
        return 3 + self.tree_levels

    def elaborate(self, platform):
        p = self.params
        m = Module()
        r = p.radius
        stall = self.o.valid & ~self.o.ready
        advance = ~stall
        m.d.comb += self.i.ready.eq(advance)

        # control that rides along: one record per stage, valid bit separate
        ctrl_layout = descriptor_layout(p, 1)
        stages = self.tree_levels + 2                 # window, pre-add, product, tree…
        valid = [Signal(name=f"valid{k}") for k in range(stages + 1)]
        ctrl = [Signal(ctrl_layout, name=f"ctrl{k}") for k in range(stages + 1)]
        item = self.i.payload
        with m.If(advance):
            m.d.sync += [valid[0].eq(self.i.valid), ctrl[0].pos.eq(item.pos),
                         ctrl[0].first.eq(item.first), ctrl[0].last.eq(item.last),
                         ctrl[0].meta.eq(item.meta)]
            for k in range(1, stages + 1):
                m.d.sync += [valid[k].eq(valid[k - 1]), ctrl[k].eq(ctrl[k - 1])]

        pixel_fmt = p.pixel_fmt
        coeffs = self._pair_coeffs()
        tau = p.strong_raw()
        window = [Signal(p.pixel_bits, name=f"w{t}") for t in range(2 * r + 1)]
        with m.If(advance & self.i.valid):
            m.d.sync += window[0].eq(item.pixels[0])
            m.d.sync += [window[t].eq(window[t - 1]) for t in range(1, 2 * r + 1)]
        # pre-add the symmetric pairs (registered)
        pair_fmt = UQ(pixel_fmt.int_bits + 1, 0)
        pairs = []
        for d, q in enumerate(coeffs):
            if q == 0:
                continue
            s = Signal(pair_fmt.shape(), name=f"pair{d}")
            value = window[r] if d == 0 else hdl_add(window[r - d], pixel_fmt,
                                                      window[r + d], pixel_fmt)[0]
            with m.If(advance):
                m.d.sync += s.eq(value)
            pairs.append((s, q))
        # constant products (registered)
        terms = []
        for s, q in pairs:
            value, fmt = hdl_mul_constant(s, pair_fmt, q, p.coeff_fmt)
            prod = Signal(fmt.shape(), name=f"prod{len(terms)}")
            with m.If(advance):
                m.d.sync += prod.eq(value)
            terms.append((prod, fmt))
        # adder tree, one registered level per clock; the last level keeps the sign
        for level in range(self.tree_levels):
            nxt = []
            for t in range(0, len(terms), 2):
                if t + 1 < len(terms):
                    value, fmt = hdl_add(*terms[t], *terms[t + 1])
                else:
                    value, fmt = terms[t]
                nxt.append((value, fmt))
            if level == self.tree_levels - 1:
                bit, strong = Signal(name="bit"), Signal(name="strong")
                interior = ctrl[stages - 1].pos >= 2 * r
                total = nxt[0][0]
                with m.If(advance):
                    m.d.sync += [bit.eq((total > 0) & interior),
                                 strong.eq(((total >= tau) | (total <= -tau)) & interior)]
            else:
                regs = []
                for value, fmt in nxt:
                    reg = Signal(fmt.shape(), name=f"sum{level}_{len(regs)}")
                    with m.If(advance):
                        m.d.sync += reg.eq(value)
                    regs.append((reg, fmt))
                terms = regs

        last = ctrl[stages]
        m.d.comb += [
            self.o.valid.eq(valid[stages]),
            self.o.payload.pos.eq(last.pos), self.o.payload.first.eq(last.first),
            self.o.payload.last.eq(last.last), self.o.payload.meta.eq(last.meta),
        ]
        m.d.comb += [self.o.payload.bits[0].eq(bit), self.o.payload.strong[0].eq(strong)]
        return m

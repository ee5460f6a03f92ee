"""Streaming domain-transform recursive filter (one RF round), one pixel per clock.

The filter smooths an 8- or 16-bit image (``value``) along the edges of an 8-bit guide
(Gastal & Oliveira's RF with ``sigma_H = sigma_s``, :func:`golden.dt.recursive_filter`
with ``iterations=1``). Pixels arrive in raster order; four passes follow each other:

1. horizontal causal: ``J = K + w_h (J_left - K)``, a one-clock recursion;
2. horizontal anti-causal over a row buffer read backwards one row later;
3. vertical causal with one line of state;
4. vertical anti-causal over a window of ``L`` lines: a chain of ``L - 1`` line buffers
   feeds ``L - 1`` pipelined recursion steps, so row ``y`` starts its backward recursion
   at row ``y + L - 1`` (:func:`golden.dt.rf_anticausal_window`); the error against the
   exact frame-buffered pass decays like ``a**L``.

A last row buffer turns the backwards rows into raster order again, so the latency is the
same for every pixel: ``(L + 1)`` rows plus a few clocks (:attr:`DomainTransformFilter.latency`).

Weights: ``w = a**d = exp(-sqrt(2)/sigma_s - sqrt(2) |dI| / sigma_r)
= 2**-(k_s + k_r |dI|)`` with ``k = sqrt(2) / ln(2) / sigma``. Two free-running
dividers turn the run-time registers ``sigma_s`` and ``sigma_r`` into ``k_s``, ``k_r``;
each weight is ``2**-n`` times two lookup-table factors ``2**-f`` (the high and low 10
bits of the fraction ``f``, floored to 20 bits) in fixed point
(:class:`hdl.dt.units.WeightUnit`). The first pixel of every row and every pixel of a
frame's first row get weight 0, which starts the recursions; it also keeps frames and
the filler rows used for flushing apart.

The fixed-point formats and every narrowing come from :mod:`hdl.fixed`; the bit-exact
numpy model of all of this is :mod:`emulator.dt.filter`, which imports the same
constants (:mod:`hdl.dt.params`). Several rounds with the golden schedule:
:class:`hdl.dt.rounds.DomainTransformRounds`.
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out


from hdl.dt.params import COEF_FMT, GUIDE_BITS, SIGMA_FMT, SIGMA_MIN_RAW, DtFilterParams
from hdl.dt.units import Reciprocal, WeightUnit, hdl_rf_step, read_enable
from hdl.fixed import Overflow, Rounding, hdl_resize

__all__ = ["DomainTransformFilter", "filter_signature"]


def filter_signature(params):
    """Ports of a DT filter built with ``params`` (one round or several): pixels in and
    out, the two sigma registers, and the clamp flags."""
    return wiring.Signature({
        "i": In(stream.Signature(params.input_layout())),
        "o": Out(stream.Signature(params.output_layout())),
        "sigma_s": In(SIGMA_FMT.shape()),
        "sigma_r": In(SIGMA_FMT.shape()),
        "clamped": Out(2),
    })

def _abs_diff(a, b):
    return Mux(a > b, a - b, b - a)[:GUIDE_BITS]


def _delays(m, first, count, en, name):
    """``[first, first delayed by 1, ..., by count]`` advances (registers enabled by ``en``)."""
    chain = [first]
    for n in range(count):
        reg = Signal(first.shape(), name=f"{name}{n + 1}")
        with m.If(en):
            m.d.sync += reg.eq(chain[-1])
        chain.append(reg)
    return chain


class DomainTransformFilter(wiring.Component):
    """Streaming domain-transform recursive filter (one round), one pixel per clock.

    Parameters
    ----------
    params : DtFilterParams

    Members
    -------
    i : In(stream.Signature(StructLayout(guide: 8, value: value_bits, last: 1)))
        Pixels in raster order, ``width`` per row: the guide (``UQ(8, 0)``), the value to
        filter (``UQ(value_bits, 0)``) and ``last``, which marks the final row of a frame
        (sampled on the row's last pixel).
    o : Out(stream.Signature(StructLayout(value: value_bits, last: 1)))
        The filtered values (``UQ(value_bits, 0)``, rounded half up) in raster order;
        ``last`` on the final pixel of each frame.
    sigma_s : In(SIGMA_FMT)
        Spatial standard deviation in pixels (``UQ(10, 6)``, at least 1.0).
    sigma_r : In(SIGMA_FMT)
        Range standard deviation in guide LSBs (``UQ(10, 6)``, at least 1.0).
    clamped : Out(2)
        Bit 0 (``sigma_s``) and bit 1 (``sigma_r``): the register is below 1.0 and the
        block is filtering with 1.0 instead; a status flag, so that a bad register value
        is seen, not silently replaced (the emulator rejects such values).

    Both sigmas are run-time registers: they are turned into coefficients continuously
    and each frame uses the values latched at its first pixel, once they have been
    stable for :attr:`coefficient_settle_clocks`.

    Latency: :attr:`latency` clocks from an input pixel's transfer to the same pixel's
    output when nothing stalls (``window + 1`` rows plus a few clocks), the same for every
    pixel. Throughput: one pixel per clock, across rows and frames. Backpressure: the
    whole pipeline advances in lock step and holds while ``o`` has an untaken pixel or
    ``i`` has none; no pixel is dropped. Flushing: the last ``window + 1`` rows of a frame
    leave as the next frame's rows arrive, or, if ``i`` is idle at a row start, while the
    block runs :attr:`flush_rows` filler rows (``i.ready`` low for those rows). Reset:
    clears control state and the output; line buffers keep stale data, which weight-0
    rows keep out of every result.
    """

    #: Register stages from the input to the horizontal causal pass (input, weights).
    _CAUSAL_STAGE = 1 + WeightUnit.latency
    #: Advances from a pixel entering the vertical stages to its window output, per step.
    _VERTICAL_CAUSAL_STAGE = _CAUSAL_STAGE + 2

    def __init__(self, params=DtFilterParams()):
        if not isinstance(params, DtFilterParams):
            raise TypeError(f"params must be a DtFilterParams, not {params!r}")
        self.params = params
        super().__init__(filter_signature(params))


    @classmethod
    def _output_stage(cls, params):
        return cls._VERTICAL_CAUSAL_STAGE + params.window

    @property
    def output_stage(self):
        """Advance (after the input's) at which a pixel's output register is loaded."""
        return self._output_stage(self.params)

    @property
    def latency(self):
        """Clocks from an input transfer to the same pixel on ``o`` (no stalls)."""
        return self.latency_of(self.params)

    @classmethod
    def latency_of(cls, params):
        """:attr:`latency` of a build, without making one."""
        return (params.window + 1) * params.width + cls._output_stage(params) + 1

    @property
    def flush_rows(self):
        """Filler rows that push a frame's tail out when no further input comes."""
        return self.params.window + 2

    #: Clocks after a sigma register change before a new frame is sure to use it.
    coefficient_settle_clocks = 2 * Reciprocal.cycles

    def elaborate(self, platform):
        p = self.params
        width, window, vf = p.width, p.window, p.value_fmt
        m = Module()
        tag_layout = data.StructLayout({"k": range(width), "dir": 1, "real": 1, "first": 1,
                                        "last": 1})

        # --- run-time coefficients --------------------------------------------------------
        m.submodules.recip_s = recip_s = Reciprocal()
        m.submodules.recip_r = recip_r = Reciprocal()
        m.d.comb += [recip_s.sigma.eq(self.sigma_s), recip_r.sigma.eq(self.sigma_r),
                     self.clamped.eq(Cat(self.sigma_s < SIGMA_MIN_RAW,
                                         self.sigma_r < SIGMA_MIN_RAW))]

        # --- input control: real rows, filler rows, the advance -----------------------------
        k_in = Signal(range(width))
        dir_in = Signal()
        in_filler = Signal()
        frame_first = Signal(init=1)
        pending = Signal(range(self.flush_rows + 1))
        filler = Signal()
        advance = Signal()
        out_stall = Signal()
        m.d.comb += [
            out_stall.eq(self.o.valid & ~self.o.ready),
            filler.eq(in_filler | ((k_in == 0) & frame_first & ~self.i.valid & (pending != 0))),
            advance.eq((filler | self.i.valid) & ~out_stall),
            self.i.ready.eq(~out_stall & ~filler),
        ]
        with m.If(advance):
            with m.If(k_in == width - 1):
                m.d.sync += [k_in.eq(0), dir_in.eq(~dir_in), in_filler.eq(0)]
                with m.If(filler):
                    m.d.sync += pending.eq(pending - 1)
                with m.Elif(self.i.p.last):
                    m.d.sync += [pending.eq(self.flush_rows), frame_first.eq(1)]
                with m.Else():
                    m.d.sync += [pending.eq(Mux(pending != 0, pending - 1, 0)),
                                 frame_first.eq(0)]
            with m.Else():
                m.d.sync += [k_in.eq(k_in + 1), in_filler.eq(filler)]

        # Stage 0: the pixel (zeros for filler rows) and its tag.
        tag0 = Signal(tag_layout)
        guide0 = Signal(GUIDE_BITS)
        value0 = Signal(p.value_bits)
        with m.If(advance):
            m.d.sync += [
                tag0.k.eq(k_in), tag0.dir.eq(dir_in), tag0.real.eq(~filler),
                tag0.first.eq(frame_first | filler), tag0.last.eq(~filler & self.i.p.last),
                guide0.eq(Mux(filler, 0, self.i.p.guide)),
                value0.eq(Mux(filler, 0, self.i.p.value)),
            ]
        tags = _delays(m, tag0, self.output_stage - 1, advance, "tag")
        values = _delays(m, value0, WeightUnit.latency, advance, "value")

        # Stage 1..4: weights from the guide's change to the left and upward.
        m.submodules.guide_line = guide_line = Memory(shape=GUIDE_BITS, depth=width, init=[])
        gl_rd, gl_wr = guide_line.read_port(), guide_line.write_port()
        m.d.comb += [gl_rd.addr.eq(k_in), gl_rd.en.eq(read_enable(advance)), gl_wr.addr.eq(k_in),
                     gl_wr.data.eq(Mux(filler, 0, self.i.p.guide)), gl_wr.en.eq(advance)]
        guide_left = Signal(GUIDE_BITS)
        with m.If(advance):
            m.d.sync += guide_left.eq(guide0)
        m.submodules.weights = weights = WeightUnit(p, lanes=2)
        k_s, k_r = Signal(COEF_FMT.shape()), Signal(COEF_FMT.shape())
        frame_start = tags[0].real & tags[0].first & (tags[0].k == 0)
        m.d.comb += [
            weights.en.eq(advance),
            weights.k_s.eq(Mux(frame_start, recip_s.k, k_s)),
            weights.k_r.eq(Mux(frame_start, recip_r.k, k_r)),
            weights.g[0].eq(_abs_diff(guide0, guide_left)),
            weights.g[1].eq(_abs_diff(guide0, gl_rd.data)),
        ]
        with m.If(advance):
            m.d.sync += [k_s.eq(weights.k_s), k_r.eq(weights.k_r)]

        # Stage 5: horizontal causal pass, into the row buffer.
        t4 = tags[self._CAUSAL_STAGE - 1]
        w_h = Mux(t4.k == 0, 0, weights.w[0])
        w_v = Mux(t4.first, 0, weights.w[1])
        causal = Signal(vf.shape())
        causal_next = hdl_rf_step(values[-1] << p.frac_bits, causal, w_h, p)
        row_entry = data.StructLayout({"j": vf.shape(), "wh": p.weight_fmt.width,
                                       "wv": p.weight_fmt.width})
        m.submodules.row_buffer = row_buffer = Memory(shape=row_entry, depth=width, init=[])
        rb_rd, rb_wr = row_buffer.read_port(), row_buffer.write_port()
        rb_addr = Mux(t4.dir, width - 1 - t4.k, t4.k)
        m.d.comb += [rb_rd.addr.eq(rb_addr), rb_rd.en.eq(read_enable(advance)), rb_wr.addr.eq(rb_addr),
                     rb_wr.en.eq(advance), rb_wr.data.j.eq(causal_next),
                     rb_wr.data.wh.eq(w_h), rb_wr.data.wv.eq(w_v)]
        with m.If(advance):
            m.d.sync += causal.eq(causal_next)

        # Stage 6: horizontal anti-causal pass over the previous row, read backwards.
        t5 = tags[self._CAUSAL_STAGE]
        anti = Signal(vf.shape())
        wh_right = Signal(p.weight_fmt.width)
        wv6 = Signal(p.weight_fmt.width)
        with m.If(advance):
            m.d.sync += [
                anti.eq(hdl_rf_step(rb_rd.data.j, anti, Mux(t5.k == 0, 0, wh_right), p)),
                wh_right.eq(rb_rd.data.wh),
                wv6.eq(rb_rd.data.wv),
            ]

        # Stage 7: vertical causal pass with one line of state.
        m.submodules.column_state = column_state = Memory(shape=vf.shape(), depth=width, init=[])
        cs_rd, cs_wr = column_state.read_port(), column_state.write_port()
        t6 = tags[self._CAUSAL_STAGE + 1]
        vertical = Signal(vf.shape())
        vertical_next = hdl_rf_step(anti, cs_rd.data, wv6, p)
        m.d.comb += [cs_rd.addr.eq(t5.k), cs_rd.en.eq(read_enable(advance)), cs_wr.addr.eq(t6.k),
                     cs_wr.en.eq(advance), cs_wr.data.eq(vertical_next)]
        with m.If(advance):
            m.d.sync += vertical.eq(vertical_next)

        # Stages 8..6+L: vertical anti-causal pass over a window of L lines. Line buffer i
        # holds row r-i; step i folds that row into the recursion started at row r.
        line_entry = data.StructLayout({"j": vf.shape(), "w": p.weight_fmt.width})
        incoming = Signal(line_entry)
        m.d.comb += [incoming.j.eq(vertical_next), incoming.w.eq(wv6)]
        acc, acc_w = vertical, Signal(p.weight_fmt.width)
        with m.If(advance):
            m.d.sync += acc_w.eq(wv6)
        for step in range(1, window):
            line = Memory(shape=line_entry, depth=width, init=[])
            m.submodules[f"line{step}"] = line
            rd, wr = line.read_port(), line.write_port()
            addr = tags[self._VERTICAL_CAUSAL_STAGE + step - 2].k
            m.d.comb += [rd.addr.eq(addr), rd.en.eq(read_enable(advance)), wr.addr.eq(addr),
                         wr.en.eq(advance), wr.data.eq(incoming)]
            nxt, nxt_w = Signal(vf.shape(), name=f"acc{step}"), Signal(p.weight_fmt.width,
                                                                        name=f"acc{step}_w")
            with m.If(advance):
                m.d.sync += [nxt.eq(hdl_rf_step(rd.data.j, acc, acc_w, p)), nxt_w.eq(rd.data.w)]
            incoming, acc, acc_w = rd.data, nxt, nxt_w

        # Output: back to raster order through one more row buffer.
        t_last = tags[self.output_stage - 1]
        flags = data.StructLayout({"real": 1, "last": 1})
        history = [Signal(flags, name=f"row_flags{n}") for n in range(window + 1)]
        m.submodules.out_buffer = out_buffer = Memory(shape=p.value_bits, depth=width, init=[])
        ob_rd, ob_wr = out_buffer.read_port(), out_buffer.write_port()
        ob_addr = Mux(t_last.dir, width - 1 - t_last.k, t_last.k)
        m.d.comb += [
            ob_rd.addr.eq(ob_addr), ob_rd.en.eq(read_enable(advance)), ob_wr.addr.eq(ob_addr),
            ob_wr.en.eq(advance),
            ob_wr.data.eq(hdl_resize(acc, vf, p.output_fmt, Rounding.HALF_UP, Overflow.ERROR)),
            self.o.p.value.eq(ob_rd.data),
        ]
        with m.If(advance):
            m.d.sync += [self.o.valid.eq(history[window].real),
                         self.o.p.last.eq(history[window].last & (t_last.k == width - 1))]
            with m.If(t_last.k == width - 1):
                m.d.sync += history[0].eq(Cat(t_last.real, t_last.last))
                m.d.sync += [history[n].eq(history[n - 1]) for n in range(1, window + 1)]
        with m.Elif(self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        return m

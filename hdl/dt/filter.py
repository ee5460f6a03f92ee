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
bits of the fraction ``f``, floored to 20 bits) in fixed point (:class:`WeightUnit`). The first pixel of every row and every pixel of a
frame's first row get weight 0, which starts the recursions; it also keeps frames and
the filler rows used for flushing apart.

The fixed-point formats and every narrowing come from :mod:`hdl.fixed`; the bit-exact
numpy model of all of this is :mod:`emulator.dt.filter`, which imports the constants
below.
"""

import functools
import math
from dataclasses import dataclass, replace

from amaranth.hdl import Cat, Module, Mux, ResetSignal, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.checks import check_int

from hdl.fixed import (Overflow, Rounding, SQ, UQ, add_format, hdl_add, hdl_mul, hdl_resize,
                       mul_format)

__all__ = ["SIGMA_FMT", "COEF_FMT", "GUIDE_BITS", "COEF_NUMERATOR", "TABLE_ADDR_BITS",
           "SCHEDULE_FMT", "schedule_scales", "DtFilterParams", "Reciprocal", "WeightUnit",
           "DomainTransformFilter", "DomainTransformRounds"]

#: Run-time registers ``sigma_s`` (pixels) and ``sigma_r`` (guide LSBs); values below 1.0
#: are clamped to 1.0 by the hardware and reported on ``DomainTransformFilter.clamped``.
SIGMA_FMT = UQ(10, 6)
#: ``k = sqrt(2) / ln(2) / sigma``, the weight exponent per unit of distance (log2 units).
COEF_FMT = UQ(2, 28)
#: Bits of the guide pixels.
GUIDE_BITS = 8

#: ``sqrt(2) / ln(2)`` quantized once, scaled so that ``k_raw = COEF_NUMERATOR // sigma_raw``.
COEF_NUMERATOR = int(UQ(2, COEF_FMT.frac_bits + SIGMA_FMT.frac_bits).quantize(
    math.sqrt(2.0) / math.log(2.0)))
#: Clamp of the sigma registers (raw 1.0); keeps every ``k`` inside ``COEF_FMT``.
SIGMA_MIN_RAW = 1 << SIGMA_FMT.frac_bits
#: Per-round scale ``sigma_H,i / sigma_s`` of the RF schedule (at most 1.0).
SCHEDULE_FMT = UQ(1, 16)


@functools.cache
def schedule_scales(rounds):
    """Raw ``SCHEDULE_FMT`` scales of :func:`golden.dt.sigma_schedule`, quantized once
    (half up): round ``i`` of ``rounds`` filters with ``sigma_H,i = scale_i sigma_s``."""
    from golden.dt import sigma_schedule
    return tuple(int(SCHEDULE_FMT.quantize(v, Rounding.HALF_UP))
                 for v in sigma_schedule(1.0, rounds))


#: The exponent's fraction, floored to ``2 * TABLE_ADDR_BITS`` bits, is looked up in two
#: tables, one for each half of its bits.
TABLE_ADDR_BITS = 10
#: Extra fraction bits kept when the two table entries' product is rounded.
PRODUCT_GUARD_BITS = 2


@functools.cache
def weight_tables(table_fmt):
    """``2**-(i / 2**10)`` and ``2**-(i / 2**20)``, i = 0..1023, as raw ``table_fmt`` lists."""
    size = 1 << TABLE_ADDR_BITS
    high = table_fmt.quantize([2.0 ** -(i / size) for i in range(size)])
    low = table_fmt.quantize([2.0 ** -(i / size ** 2) for i in range(size)])
    return [int(v) for v in high], [int(v) for v in low]


@dataclass(frozen=True, kw_only=True)
class DtFilterParams:
    """Build parameters of :class:`DomainTransformFilter` (plain data: the model uses it too).

    Parameters
    ----------
    width : int
        Pixels per row; sizes every line buffer. At least ``window + 8`` (and 16).
    value_bits : {8, 16}
        Bits of the filtered image.
    window : int
        Lines ``L`` seen by the vertical anti-causal pass (1: no such pass).
    frac_bits : int
        Fraction bits carried by the recursions (internal format
        ``UQ(value_bits, frac_bits)``).
    """
    width: int = 640
    value_bits: int = 8
    window: int = 8
    frac_bits: int = 8

    def __post_init__(self):
        check_int("value_bits", self.value_bits)
        if self.value_bits not in (8, 16):
            raise ValueError(f"value_bits must be one of 8, 16, not {self.value_bits}")
        check_int("window", self.window, 1, 64)
        check_int("frac_bits", self.frac_bits, 0, 16)
        check_int("width", self.width, max(16, self.window + 8), 1 << 16)

    replace = replace

    @property
    def value_fmt(self):
        """Internal format of the recursions' values."""
        return UQ(self.value_bits, self.frac_bits)

    @property
    def diff_fmt(self):
        """Difference of two internal values (exact)."""
        return SQ(self.value_bits + 1, self.frac_bits)

    @property
    def output_fmt(self):
        return UQ(self.value_bits, 0)

    @property
    def weight_fmt(self):
        """Feedback weights ``a**d`` in [0, 1): 8 fraction bits more than the values have
        integer bits, so that ``1 - a**d`` stays accurate when ``sigma_s`` is large."""
        return UQ(0, self.value_bits + 8)

    @property
    def table_fmt(self):
        """Entries of the ``2**-f`` tables (1.0 at address 0)."""
        return UQ(1, self.weight_fmt.frac_bits)

    @property
    def product_fmt(self):
        """The two table entries' product, rounded (half up) to this."""
        return UQ(1, self.weight_fmt.frac_bits + PRODUCT_GUARD_BITS)

    @property
    def shifted_fmt(self):
        """:attr:`product_fmt` times ``2**-n``, ``n <= weight frac bits`` (exact)."""
        return UQ(1, self.product_fmt.frac_bits + self.weight_fmt.frac_bits)

    @property
    def zero_exponent(self):
        """From this integer part of the exponent on, the weight rounds to 0."""
        return self.weight_fmt.frac_bits + 1

    def input_layout(self):
        return data.StructLayout({"guide": GUIDE_BITS, "value": self.value_bits, "last": 1})

    def output_layout(self):
        return data.StructLayout({"value": self.value_bits, "last": 1})


# --- gateware pieces ----------------------------------------------------------------------

def hdl_rf_step(k, p, w, params):
    """``k + round_half_up(w (p - k))``: one recursion step (model: ``emulator.dt.filter.rf_step``).

    ``k``, ``p`` are raw ``value_fmt``, ``w`` raw ``weight_fmt``. The result is a convex
    combination of ``k`` and ``p`` and so fits ``value_fmt``.
    """
    vf, df = params.value_fmt, params.diff_fmt
    prod, prod_fmt = hdl_mul(p - k, df, w, params.weight_fmt)
    delta = hdl_resize(prod, prod_fmt, df, Rounding.HALF_UP, Overflow.ERROR)
    total, total_fmt = hdl_add(k, vf, delta, df)
    return hdl_resize(total, total_fmt, vf, Rounding.FLOOR, Overflow.ERROR)


def exponent_fmt():
    """Format of ``k_s + k_r g`` (exact)."""
    return add_format(COEF_FMT, mul_format(COEF_FMT, UQ(GUIDE_BITS, 0)))


def lookup_fmt():
    """The exponent with the fraction bits the tables resolve (floored to it)."""
    return UQ(exponent_fmt().int_bits, 2 * TABLE_ADDR_BITS)


def _read_enable(advance):
    """Read-port enable: on every advance, and during reset too, so that the ports' data
    registers hold initialized memory contents (not X in simulation) from the start."""
    return advance | ResetSignal()


class Reciprocal(wiring.Component):
    """``k = COEF_NUMERATOR // max(sigma, 1.0)`` by restoring division, over and over.

    Members
    -------
    sigma : In(SIGMA_FMT)
        The register, sampled when a division starts.
    k : Out(COEF_FMT)
        The last finished quotient; it follows a change of ``sigma`` within
        ``2 * cycles`` clocks.
    """

    #: Numerator bits; one quotient bit per clock, plus one clock to load.
    NUMERATOR_BITS = COEF_NUMERATOR.bit_length()
    cycles = NUMERATOR_BITS + 1

    sigma: In(SIGMA_FMT.shape())
    k: Out(COEF_FMT.shape())

    def elaborate(self, platform):
        m = Module()
        nb = self.NUMERATOR_BITS
        divisor = Signal(SIGMA_FMT.width)
        numerator = Signal(nb)
        remainder = Signal(SIGMA_FMT.width)
        quotient = Signal(nb)
        step = Signal(range(nb + 1))
        trial = Signal(SIGMA_FMT.width + 1)
        fits = Signal()
        m.d.comb += [trial.eq((remainder << 1) | numerator[-1]), fits.eq(trial >= divisor)]
        with m.If(step == 0):
            m.d.sync += [
                divisor.eq(Mux(self.sigma < SIGMA_MIN_RAW, SIGMA_MIN_RAW, self.sigma)),
                numerator.eq(COEF_NUMERATOR), remainder.eq(0), quotient.eq(0), step.eq(1),
            ]
        with m.Else():
            m.d.sync += [
                remainder.eq(Mux(fits, trial - divisor, trial)),
                quotient.eq((quotient << 1) | fits),
                numerator.eq(numerator << 1),
                step.eq(Mux(step == nb, 0, step + 1)),
            ]
            with m.If(step == nb):
                m.d.sync += self.k.eq((quotient << 1) | fits)
        return m


class WeightUnit(wiring.Component):
    """Feedback weights ``2**-(k_s + k_r g)`` for ``lanes`` guide differences per clock.

    The exponent ``e = n + f`` (integer ``n``, fraction ``f`` floored to 20 bits) gives
    ``2**-f = T_high[f_high] * T_low[f_low]`` from two tables addressed by the high and
    low halves of ``f``'s bits; the product is rounded, shifted right by ``n`` and
    rounded to ``weight_fmt``.

    Parameters
    ----------
    params : DtFilterParams
        Gives ``weight_fmt`` and the tables' format.
    lanes : int
        Weights per clock; the tables get one read port per lane.

    Members
    -------
    en : In(1)
        Advances the pipeline (all stages at once).
    k_s, k_r : In(COEF_FMT)
        Exponent coefficients, sampled with ``g``.
    g : In(ArrayLayout(8, lanes))
        Absolute guide differences (``UQ(8, 0)``).
    w : Out(ArrayLayout(weight_fmt, lanes))
        The weights of the ``g`` sampled :attr:`latency` advances earlier (counting the
        advance that samples them).
    """

    #: Exponent, table read, table product, rounding and shift.
    latency = 4

    def __init__(self, params, lanes):
        self.params = params
        self.lanes = lanes
        super().__init__({
            "en": In(1),
            "k_s": In(COEF_FMT.shape()),
            "k_r": In(COEF_FMT.shape()),
            "g": In(data.ArrayLayout(GUIDE_BITS, lanes)),
            "w": Out(data.ArrayLayout(params.weight_fmt.width, lanes)),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        ef, lf, tf = exponent_fmt(), lookup_fmt(), p.table_fmt
        frac = lf.frac_bits
        table_high, table_low = weight_tables(tf)
        m.submodules.table_high = high = Memory(shape=tf.shape(), depth=len(table_high),
                                                init=table_high)
        m.submodules.table_low = low = Memory(shape=tf.shape(), depth=len(table_low),
                                              init=table_low)
        for lane in range(self.lanes):
            exponent = Signal(lf.shape(), name=f"exponent{lane}")
            whole = Signal(range(p.zero_exponent + 1), name=f"whole{lane}")
            whole_d = Signal.like(whole, name=f"whole{lane}_d")
            product = Signal(mul_format(tf, tf).shape(), name=f"product{lane}")
            rd_high, rd_low = high.read_port(), low.read_port()
            scaled, scaled_fmt = hdl_mul(self.k_r, COEF_FMT, self.g[lane], UQ(GUIDE_BITS, 0))
            rounded = hdl_resize(product, mul_format(tf, tf), p.product_fmt,
                                 Rounding.HALF_UP, Overflow.ERROR)
            shifted = (rounded << p.weight_fmt.frac_bits) >> whole_d
            m.d.comb += [
                rd_high.en.eq(_read_enable(self.en)), rd_low.en.eq(_read_enable(self.en)),
                rd_high.addr.eq(exponent[frac - TABLE_ADDR_BITS:frac]),
                rd_low.addr.eq(exponent[frac - 2 * TABLE_ADDR_BITS:frac - TABLE_ADDR_BITS]),
            ]
            with m.If(self.en):
                m.d.sync += [
                    exponent.eq(hdl_resize(hdl_add(self.k_s, COEF_FMT, scaled, scaled_fmt)[0],
                                           ef, lf, Rounding.FLOOR, Overflow.ERROR)),
                    whole.eq(Mux(exponent[frac:] >= p.zero_exponent, p.zero_exponent,
                                 exponent[frac:])),
                    product.eq(rd_high.data * rd_low.data),
                    whole_d.eq(whole),
                    self.w[lane].eq(Mux(whole_d == p.zero_exponent, 0, hdl_resize(
                        shifted, p.shifted_fmt, p.weight_fmt, Rounding.HALF_UP,
                        Overflow.SATURATE))),
                ]
        return m


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
        super().__init__({
            "i": In(stream.Signature(params.input_layout())),
            "o": Out(stream.Signature(params.output_layout())),
            "sigma_s": In(SIGMA_FMT.shape()),
            "sigma_r": In(SIGMA_FMT.shape()),
            "clamped": Out(2),
        })


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
        m.d.comb += [gl_rd.addr.eq(k_in), gl_rd.en.eq(_read_enable(advance)), gl_wr.addr.eq(k_in),
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
        m.d.comb += [rb_rd.addr.eq(rb_addr), rb_rd.en.eq(_read_enable(advance)), rb_wr.addr.eq(rb_addr),
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
        m.d.comb += [cs_rd.addr.eq(t5.k), cs_rd.en.eq(_read_enable(advance)), cs_wr.addr.eq(t6.k),
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
            m.d.comb += [rd.addr.eq(addr), rd.en.eq(_read_enable(advance)), wr.addr.eq(addr),
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
            ob_rd.addr.eq(ob_addr), ob_rd.en.eq(_read_enable(advance)), ob_wr.addr.eq(ob_addr),
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


class DomainTransformRounds(wiring.Component):
    """``rounds`` RF rounds with the golden schedule, one pixel per clock.

    :func:`golden.dt.recursive_filter` runs ``N`` rounds with ``sigma_H,i = scale_i
    sigma_s`` (:func:`golden.dt.sigma_schedule`). Since a round's weights are
    ``exp(-sqrt(2) / sigma_H,i (1 + sigma_s / sigma_r |dI|))``, round ``i`` is a
    :class:`DomainTransformFilter` whose registers are ``scale_i sigma_s`` and
    ``scale_i sigma_r`` (``scale_i`` in ``SCHEDULE_FMT``, the products rounded half up to
    ``SIGMA_FMT``). The stages are chained value to value; the guide follows each pixel
    through a FIFO deep enough for a stage's pixels in flight, so it meets its pixel at
    the next stage.

    Parameters
    ----------
    params : DtFilterParams
        Every stage's build.
    rounds : int
        Number of rounds, 1 to 8 (1 is one :class:`DomainTransformFilter`).

    Members
    -------
    i, o, sigma_s, sigma_r, clamped
        As :class:`DomainTransformFilter`; ``clamped`` is any stage's flag.

    Latency: :attr:`latency` = ``rounds`` times a stage's, when nothing stalls.
    Throughput: one pixel per clock. Backpressure: as a stage; a full guide FIFO cannot
    happen (its depth exceeds a stage's pixels in flight). The registers must hold while
    any pixel of a frame is inside (each stage latches them at its own first pixel).
    """

    def __init__(self, params=DtFilterParams(), rounds=3):
        if not isinstance(params, DtFilterParams):
            raise TypeError(f"params must be a DtFilterParams, not {params!r}")
        check_int("rounds", rounds, 1, 8)
        self.params, self.rounds = params, rounds
        super().__init__({
            "i": In(stream.Signature(params.input_layout())),
            "o": Out(stream.Signature(params.output_layout())),
            "sigma_s": In(SIGMA_FMT.shape()),
            "sigma_r": In(SIGMA_FMT.shape()),
            "clamped": Out(2),
        })

    @property
    def latency(self):
        return self.rounds * DomainTransformFilter.latency_of(self.params)

    @property
    def fifo_depth(self):
        """Guide FIFO entries between stages: a stage's latency plus its output register."""
        return DomainTransformFilter.latency_of(self.params) + 2

    coefficient_settle_clocks = DomainTransformFilter.coefficient_settle_clocks

    def elaborate(self, platform):
        p = self.params
        m = Module()
        stages = [DomainTransformFilter(p) for _ in range(self.rounds)]
        flags = []
        for n, (stage, scale) in enumerate(zip(stages, schedule_scales(self.rounds))):
            m.submodules[f"round{n}"] = stage
            for port, register in ((stage.sigma_s, self.sigma_s), (stage.sigma_r, self.sigma_r)):
                product, fmt = hdl_mul(register, SIGMA_FMT, scale, SCHEDULE_FMT)
                m.d.comb += port.eq(hdl_resize(product, fmt, SIGMA_FMT, Rounding.HALF_UP,
                                               Overflow.ERROR))
            flags.append(stage.clamped)
        m.d.comb += self.clamped.eq(functools.reduce(lambda a, b: a | b, flags))

        # the first stage takes the input; the guide of every pixel it takes goes on
        fifos = [SyncFIFOBuffered(width=GUIDE_BITS, depth=self.fifo_depth)
                 for _ in range(self.rounds - 1)]
        for n, fifo in enumerate(fifos):
            m.submodules[f"guide{n}"] = fifo
        first = stages[0]
        room = fifos[0].w_rdy if fifos else 1
        m.d.comb += [first.i.p.eq(self.i.p), first.i.valid.eq(self.i.valid & room),
                     self.i.ready.eq(first.i.ready & room)]
        if fifos:
            m.d.comb += [fifos[0].w_data.eq(self.i.p.guide),
                         fifos[0].w_en.eq(self.i.valid & self.i.ready)]
        # stage n takes stage n-1's output with the guide from FIFO n-1 and passes it on
        for n in range(1, self.rounds):
            prev, stage, fifo = stages[n - 1], stages[n], fifos[n - 1]
            room = fifos[n].w_rdy if n < len(fifos) else 1
            ok = fifo.r_rdy & room
            m.d.comb += [stage.i.p.guide.eq(fifo.r_data), stage.i.p.value.eq(prev.o.p.value),
                         stage.i.p.last.eq(prev.o.p.last),
                         stage.i.valid.eq(prev.o.valid & ok),
                         prev.o.ready.eq(stage.i.ready & ok),
                         fifo.r_en.eq(prev.o.valid & stage.i.ready & ok)]
            if n < len(fifos):
                m.d.comb += [fifos[n].w_data.eq(fifo.r_data),
                             fifos[n].w_en.eq(prev.o.valid & stage.i.ready & ok)]
        wiring.connect(m, stages[-1].o, wiring.flipped(self.o))
        return m

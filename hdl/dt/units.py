"""Arithmetic pieces of the domain-transform filter (:mod:`hdl.dt.filter`): the
recursion step, the divider that turns a sigma register into a weight exponent, and the
weight unit (``2**-n`` times two table factors)."""

from amaranth.hdl import Module, Mux, ResetSignal, Signal
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out


from hdl.dt.params import (COEF_FMT, COEF_NUMERATOR, GUIDE_BITS, SIGMA_FMT, SIGMA_MIN_RAW,
                           TABLE_ADDR_BITS, exponent_fmt, lookup_fmt, weight_tables)
from hdl.fixed import Overflow, Rounding, UQ, hdl_add, hdl_mul, hdl_resize, mul_format

__all__ = ["hdl_rf_step", "read_enable", "Reciprocal", "WeightUnit"]


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


def read_enable(advance):
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
                rd_high.en.eq(read_enable(self.en)), rd_low.en.eq(read_enable(self.en)),
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



"""Parameters and fixed-point constants of the domain-transform filter
(:mod:`hdl.dt.filter`), without gateware: the bit-exact model (:mod:`emulator.dt.filter`)
imports the same constants and formats.
"""

import functools
import math
from dataclasses import dataclass, replace

from golden.checks import check_int

from hdl.fixed import SQ, UQ, Rounding, add_format, mul_format

__all__ = ["SIGMA_FMT", "COEF_FMT", "GUIDE_BITS", "COEF_NUMERATOR", "SIGMA_MIN_RAW",
           "SCHEDULE_FMT", "schedule_scales", "TABLE_ADDR_BITS", "PRODUCT_GUARD_BITS",
           "weight_tables", "DtFilterParams", "exponent_fmt", "lookup_fmt"]

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
    """Build parameters of :class:`hdl.dt.filter.DomainTransformFilter`.

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
        from amaranth.lib import data
        return data.StructLayout({"guide": GUIDE_BITS, "value": self.value_bits, "last": 1})

    def output_layout(self):
        from amaranth.lib import data
        return data.StructLayout({"value": self.value_bits, "last": 1})


def exponent_fmt():
    """Format of ``k_s + k_r g`` (exact)."""
    return add_format(COEF_FMT, mul_format(COEF_FMT, UQ(GUIDE_BITS, 0)))


def lookup_fmt():
    """The exponent with the fraction bits the tables resolve (floored to it)."""
    return UQ(exponent_fmt().int_bits, 2 * TABLE_ADDR_BITS)

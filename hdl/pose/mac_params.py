"""Parameters of the multiply-accumulate block (:mod:`hdl.pose.mac`), without gateware:
its model (:mod:`emulator.pose.mac`) reads the same object."""

from dataclasses import dataclass, replace

from hdl.fixed import SQ, Overflow, QFormat, Rounding, check_format, mul_format

__all__ = ["MacParams"]


@dataclass(frozen=True, kw_only=True)
class MacParams:
    """Formats of :class:`hdl.pose.mac.MultiplyAccumulate`.

    Parameters
    ----------
    a_fmt, b_fmt : QFormat
        Operand formats.
    acc_fmt : QFormat
        Accumulator format; its fraction bits must equal the product's, and it must be
        signed if either operand is. Accumulation wraps in ``acc_fmt`` (choose it wide
        enough for the longest vector: ``log2(length)`` guard bits).
    out_fmt : QFormat
        Output format.
    rounding : Rounding
        Rounding of the accumulator to ``out_fmt``.
    overflow : Overflow
        Overflow of the accumulator to ``out_fmt``.
    """
    a_fmt: QFormat = SQ(2, 16)
    b_fmt: QFormat = SQ(2, 16)
    acc_fmt: QFormat = SQ(12, 32)
    out_fmt: QFormat = SQ(8, 16)
    rounding: Rounding = Rounding.HALF_EVEN
    overflow: Overflow = Overflow.SATURATE

    def __post_init__(self):
        for name in ("a_fmt", "b_fmt", "acc_fmt", "out_fmt"):
            check_format(name, getattr(self, name))
        if not isinstance(self.rounding, Rounding):
            raise TypeError(f"rounding must be a Rounding, not {self.rounding!r}")
        if not isinstance(self.overflow, Overflow):
            raise TypeError(f"overflow must be an Overflow, not {self.overflow!r}")
        product = mul_format(self.a_fmt, self.b_fmt)
        if self.acc_fmt.frac_bits != product.frac_bits:
            raise ValueError(f"acc_fmt must have the product's {product.frac_bits} fraction "
                             f"bits, not {self.acc_fmt.frac_bits}")
        if product.signed and not self.acc_fmt.signed:
            raise ValueError("acc_fmt must be signed when an operand is signed")

    replace = replace

    @property
    def product_fmt(self):
        return mul_format(self.a_fmt, self.b_fmt)

    def input_layout(self):
        from amaranth.lib import data
        return data.StructLayout({"a": self.a_fmt.shape(), "b": self.b_fmt.shape(),
                                  "last": 1})

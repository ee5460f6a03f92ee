"""The one definition of rowtrack's fixed-point formats.

A :class:`QFormat` describes a two's-complement (``SQ``) or unsigned (``UQ``) number
with ``int_bits`` integer bits and ``frac_bits`` fraction bits. The same object gives

* the Amaranth shape of the raw integer (:meth:`QFormat.shape`) and the gateware for
  every narrowing (:func:`hdl_resize`), and
* the numpy model of the same arithmetic on raw integers (:meth:`QFormat.quantize`,
  :func:`resize`, :func:`add`, :func:`mul`), used by the bit-accurate emulator.

There is no second copy: the emulator and the HDL both call into this module, and the
property tests in ``sim_tests/common/test_fixed.py`` check that the two agree bit for bit.

Conventions
-----------
``SQ(i, f)``: signed, ``i`` integer bits *including* the sign bit, width ``i + f``,
range ``[-2**(i-1), 2**(i-1) - 2**-f]``.
``UQ(i, f)``: unsigned, width ``i + f``, range ``[0, 2**i - 2**-f]``.
A raw value ``r`` stands for ``r * 2**-f``.

Exact operations (:func:`add`, :func:`mul`) return a format wide enough that they can
never overflow. Every narrowing goes through :func:`resize` / :func:`hdl_resize`, which
names its rounding (:class:`Rounding`) and its overflow behaviour (:class:`Overflow`).

Model arrays are ``int64`` while the format is at most 62 bits wide and Python-int
object arrays beyond, so wide accumulators are modelled exactly too.
"""

import enum
from dataclasses import dataclass

import numpy as np

from golden.checks import check_int

__all__ = ["Rounding", "Overflow", "QFormat", "SQ", "UQ", "check_format",
           "resize", "add", "mul", "hdl_resize", "hdl_add", "hdl_mul", "hdl_mul_constant"]

_INT64_SAFE_WIDTH = 62


class Rounding(enum.Enum):
    """How a narrowing drops fraction bits."""
    #: Round toward minus infinity (drop the bits; free in hardware).
    FLOOR = "floor"
    #: Round to nearest, ties toward plus infinity (add half an LSB, then floor).
    HALF_UP = "half_up"
    #: Round to nearest, ties to even (convergent rounding; no bias on average).
    HALF_EVEN = "half_even"


class Overflow(enum.Enum):
    """What a narrowing does with a value outside the destination range."""
    #: Keep the low bits (two's-complement wrap-around).
    WRAP = "wrap"
    #: Clamp to the nearest representable value.
    SATURATE = "saturate"
    #: The format was chosen so this cannot happen: the model raises
    #: :class:`OverflowError` if it does; the hardware keeps the low bits (no logic).
    ERROR = "error"


@dataclass(frozen=True)
class QFormat:
    """A fixed-point format. Use :func:`SQ` and :func:`UQ` to build one.

    Parameters
    ----------
    signed : bool
        Two's complement if true.
    int_bits : int
        Integer bits, including the sign bit of a signed format.
    frac_bits : int
        Fraction bits.

    Raises
    ------
    TypeError
        If a bit count is not an integer.
    ValueError
        If a bit count is negative, the width is zero, or a signed format has no sign bit.
    """
    signed: bool
    int_bits: int
    frac_bits: int

    def __post_init__(self):
        for name in ("int_bits", "frac_bits"):
            check_int(name, getattr(self, name), 0)
        if self.signed and self.int_bits < 1:
            raise ValueError(f"int_bits of a signed format must be at least 1 (the sign bit), "
                             f"not {self.int_bits}")
        if self.width < 1:
            raise ValueError("a format must be at least one bit wide")

    def __str__(self):
        return f"{'SQ' if self.signed else 'UQ'}({self.int_bits}, {self.frac_bits})"

    @property
    def width(self):
        """Bits in the raw integer."""
        return self.int_bits + self.frac_bits

    @property
    def min_raw(self):
        return -(1 << (self.width - 1)) if self.signed else 0

    @property
    def max_raw(self):
        return (1 << (self.width - 1 if self.signed else self.width)) - 1

    @property
    def lsb(self):
        """The value of one raw step, ``2**-frac_bits``."""
        return 2.0 ** -self.frac_bits

    @property
    def min_value(self):
        return self.min_raw * self.lsb

    @property
    def max_value(self):
        return self.max_raw * self.lsb

    def shape(self):
        """The Amaranth shape of the raw integer."""
        from amaranth.hdl import signed, unsigned
        return signed(self.width) if self.signed else unsigned(self.width)

    def dtype(self):
        """The numpy dtype that holds this format's raw values exactly."""
        return np.int64 if self.width <= _INT64_SAFE_WIDTH else object

    def raw(self, values):
        """Check that integer ``values`` are raw values of this format; return an array."""
        arr = np.asarray(values)
        if arr.dtype.kind not in "iuO":
            raise TypeError(f"raw values of {self} must be integers, not {arr.dtype}")
        arr = arr.astype(self.dtype())
        self._check_range(arr, what="raw value")
        return arr

    def quantize(self, values, rounding=Rounding.HALF_EVEN, overflow=Overflow.ERROR):
        """Real numbers to raw integers of this format.

        Constants are quantized once, here; by default a value that does not fit raises
        :class:`OverflowError` (ask for ``Overflow.SATURATE`` to clamp).
        """
        x = np.asarray(values, dtype=np.float64) * (2.0 ** self.frac_bits)
        if not np.all(np.isfinite(x)):
            raise ValueError(f"cannot quantize non-finite values to {self}")
        if rounding is Rounding.FLOOR:
            q = np.floor(x)
        elif rounding is Rounding.HALF_UP:
            q = np.floor(x + 0.5)
        elif rounding is Rounding.HALF_EVEN:
            q = np.round(x)  # numpy rounds ties to even
        else:
            raise TypeError(f"rounding must be a Rounding, not {rounding!r}")
        if self.width <= _INT64_SAFE_WIDTH:
            q = np.clip(q, -2.0 ** 63, 2.0 ** 63 - 1024).astype(np.int64)
        else:
            q = np.vectorize(int, otypes=[object])(q)
        return _apply_overflow(q, self, overflow, what="quantized value")

    def to_float(self, raw):
        """Raw integers to float64 (exact while the width is at most 53 bits)."""
        return np.asarray(raw).astype(np.float64) * self.lsb

    def _check_range(self, arr, what):
        if arr.size and (np.any(arr < self.min_raw) or np.any(arr > self.max_raw)):
            bad = arr[(arr < self.min_raw) | (arr > self.max_raw)].flat[0]
            raise OverflowError(f"{what} {bad} does not fit {self} "
                                f"(raw range [{self.min_raw}, {self.max_raw}])")


def SQ(int_bits, frac_bits):
    """Signed format: ``int_bits`` including the sign bit, ``frac_bits`` fraction bits."""
    return QFormat(True, int_bits, frac_bits)


def UQ(int_bits, frac_bits):
    """Unsigned format with ``int_bits`` integer and ``frac_bits`` fraction bits."""
    return QFormat(False, int_bits, frac_bits)


def check_format(name, value, *, signed=None):
    """Raise ``TypeError`` unless ``value`` is a :class:`QFormat`, and ``ValueError``
    unless it is signed (``signed=True``) or unsigned (``signed=False``) as asked; the
    message names the parameter, as :mod:`golden.checks` does for numbers."""
    if not isinstance(value, QFormat):
        raise TypeError(f"{name} must be a QFormat, not {value!r}")
    if signed is not None and value.signed != signed:
        raise ValueError(f"{name} must be {'signed' if signed else 'unsigned'}, not {value}")


# --- exact operations -------------------------------------------------------------------

def add_format(a, b):
    """The narrowest format that holds every ``a + b`` exactly."""
    signed = a.signed or b.signed
    ia = a.int_bits + (1 if signed and not a.signed else 0)
    ib = b.int_bits + (1 if signed and not b.signed else 0)
    return QFormat(signed, max(ia, ib) + 1, max(a.frac_bits, b.frac_bits))


def mul_format(a, b):
    """The narrowest format that holds every ``a * b`` exactly."""
    return QFormat(a.signed or b.signed, a.int_bits + b.int_bits, a.frac_bits + b.frac_bits)


def _widen(raw, fmt):
    return np.asarray(raw).astype(fmt.dtype())


def add(a_raw, a_fmt, b_raw, b_fmt):
    """Exact sum; returns ``(raw, format)``."""
    fmt = add_format(a_fmt, b_fmt)
    a = _widen(a_fmt.raw(a_raw), fmt) << (fmt.frac_bits - a_fmt.frac_bits)
    b = _widen(b_fmt.raw(b_raw), fmt) << (fmt.frac_bits - b_fmt.frac_bits)
    return a + b, fmt


def mul(a_raw, a_fmt, b_raw, b_fmt):
    """Exact product; returns ``(raw, format)``."""
    fmt = mul_format(a_fmt, b_fmt)
    return _widen(a_fmt.raw(a_raw), fmt) * _widen(b_fmt.raw(b_raw), fmt), fmt


# --- narrowing ------------------------------------------------------------------------

def _apply_overflow(raw, dst, overflow, what):
    if overflow is Overflow.ERROR:
        dst._check_range(raw, what)
        return raw
    if overflow is Overflow.SATURATE:
        return np.clip(raw, dst.min_raw, dst.max_raw).astype(dst.dtype())
    if overflow is Overflow.WRAP:
        low = raw & ((1 << dst.width) - 1)
        if dst.signed:
            low = np.where(low >= (1 << (dst.width - 1)), low - (1 << dst.width), low)
        return np.asarray(low).astype(dst.dtype())
    raise TypeError(f"overflow must be an Overflow, not {overflow!r}")


def _round_shift(raw, shift, rounding):
    """Arithmetic right shift of raw integers by ``shift`` > 0 bits with rounding."""
    if rounding is Rounding.FLOOR:
        return raw >> shift
    if rounding is Rounding.HALF_UP:
        return (raw + (1 << (shift - 1))) >> shift
    if rounding is Rounding.HALF_EVEN:
        q = raw >> shift
        rem = raw & ((1 << shift) - 1)
        half = 1 << (shift - 1)
        up = (rem > half) | ((rem == half) & ((q & 1) == 1))
        return q + up.astype(q.dtype)
    raise TypeError(f"rounding must be a Rounding, not {rounding!r}")


def resize(raw, src, dst, rounding, overflow):
    """Convert raw values of format ``src`` to format ``dst`` (the model of :func:`hdl_resize`).

    Fraction bits are dropped with ``rounding``; out-of-range results follow ``overflow``.
    """
    wide = QFormat(True, max(src.int_bits, dst.int_bits) + 2, max(src.frac_bits, dst.frac_bits))
    arr = _widen(src.raw(raw), wide)
    shift = src.frac_bits - dst.frac_bits
    if shift > 0:
        arr = _round_shift(arr, shift, rounding)
    elif shift < 0:
        arr = arr << -shift
    return _apply_overflow(arr, dst, overflow, what=f"{src}->{dst} result")


# --- gateware -------------------------------------------------------------------------

def _as(value, fmt):
    """Reinterpret an Amaranth value as the raw integer of ``fmt`` (width and sign)."""
    from amaranth.hdl import Value
    v = Value.cast(value)
    if v.shape().width != fmt.width:
        v = v.as_signed() if v.shape().signed else v.as_unsigned()
        v = v[:fmt.width] if v.shape().width > fmt.width else v
    return v.as_signed() if fmt.signed else v.as_unsigned()


def _extend(value, src, width):
    """Sign- or zero-extend ``value`` (format ``src``) to ``width`` bits, as signed."""
    from amaranth.hdl import Cat, Value
    v = _as(value, src)
    pad = width - src.width
    fill = v[-1] if src.signed else Value.cast(0)
    return Cat(v, fill.replicate(pad)).as_signed() if pad > 0 else v.as_signed()


def hdl_add(a, a_fmt, b, b_fmt):
    """Exact sum of two raw Amaranth values; returns ``(value, format)``."""
    fmt = add_format(a_fmt, b_fmt)
    wa = _extend(a, a_fmt, fmt.width + 1) << (fmt.frac_bits - a_fmt.frac_bits)
    wb = _extend(b, b_fmt, fmt.width + 1) << (fmt.frac_bits - b_fmt.frac_bits)
    return _as(wa + wb, fmt), fmt


def hdl_mul(a, a_fmt, b, b_fmt):
    """Exact product of two raw Amaranth values; returns ``(value, format)``."""
    fmt = mul_format(a_fmt, b_fmt)
    return _as(_as(a, a_fmt) * _as(b, b_fmt), fmt), fmt


def hdl_mul_constant(a, a_fmt, q, q_fmt):
    """Exact product of a raw Amaranth value and the constant raw ``q`` of ``q_fmt``;
    ``(value, format)`` as :func:`hdl_mul`. A constant ``±2**k`` is a shift (and a
    negation), not a multiplier: synthesis maps every ``*`` it sees to a DSP48."""
    from amaranth.hdl import Const
    q = int(q)
    if q == 0 or abs(q) & (abs(q) - 1):
        return hdl_mul(a, a_fmt, Const(q, q_fmt.shape()), q_fmt)
    fmt = mul_format(a_fmt, q_fmt)
    shifted = _extend(a, a_fmt, fmt.width + 1) << (abs(q).bit_length() - 1)
    return _as(-shifted if q < 0 else shifted, fmt), fmt


def hdl_resize(value, src, dst, rounding, overflow):
    """Gateware that narrows or widens a raw value of ``src`` to ``dst``.

    Combinational; bit-exact with :func:`resize`. ``Overflow.ERROR`` generates no check
    (the low bits are kept), so use it only where the formats make overflow impossible.
    """
    from amaranth.hdl import Mux
    wide_w = max(src.int_bits, dst.int_bits) + 2 + max(src.frac_bits, dst.frac_bits)
    v = _extend(value, src, wide_w)
    shift = src.frac_bits - dst.frac_bits
    if shift > 0:
        if rounding is Rounding.FLOOR:
            v = v >> shift
        elif rounding is Rounding.HALF_UP:
            v = (v + (1 << (shift - 1))) >> shift
        elif rounding is Rounding.HALF_EVEN:
            q = v >> shift
            rem = v.as_unsigned()[:shift]
            half = 1 << (shift - 1)
            up = (rem > half) | ((rem == half) & q[0])
            v = q + up
        else:
            raise TypeError(f"rounding must be a Rounding, not {rounding!r}")
    elif shift < 0:
        v = v << -shift
    if overflow is Overflow.SATURATE:
        v = Mux(v > dst.max_raw, dst.max_raw, Mux(v < dst.min_raw, dst.min_raw, v))
    elif overflow not in (Overflow.WRAP, Overflow.ERROR):
        raise TypeError(f"overflow must be an Overflow, not {overflow!r}")
    return _as(v, dst)

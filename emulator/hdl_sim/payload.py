"""Packing ``lib.data`` layouts to and from the flat integers seen on Verilog ports.

Amaranth flattens a stream payload into one ``<port>__payload`` vector; these helpers
let cocotb benches (and models) speak in field dictionaries instead.
"""

from amaranth.hdl import Shape
from amaranth.lib import data

__all__ = ["pack", "unpack", "width"]


def width(layout):
    return Shape.cast(layout).width


def _to_signed(value, bits):
    return value - (1 << bits) if value >> (bits - 1) & 1 else value


def pack(layout, value):
    """A field dict (nested for nested layouts; a list for an array layout) or an int to
    the flat unsigned integer."""
    if not isinstance(layout, data.Layout):
        shape = Shape.cast(layout)
        if not isinstance(value, int):
            raise TypeError(f"expected an integer for a {shape} field, not {value!r}")
        lo = -(1 << (shape.width - 1)) if shape.signed else 0
        hi = (1 << (shape.width - (1 if shape.signed else 0))) - 1
        if not lo <= value <= hi:
            raise ValueError(f"value {value} does not fit {shape}")
        return value & ((1 << shape.width) - 1)
    if isinstance(layout, data.ArrayLayout) and isinstance(value, (list, tuple)):
        value = dict(enumerate(value))          # an array's elements, in order
    missing = {name for name, _ in layout} - set(value)
    extra = set(value) - {name for name, _ in layout}
    if missing or extra:
        raise ValueError(f"payload fields differ from the layout: missing {sorted(missing)}, "
                         f"unknown {sorted(extra)}")
    flat = 0
    for name, field in layout:
        flat |= pack(field.shape, value[name]) << field.offset
    return flat


def unpack(layout, flat):
    """The flat unsigned integer to a field dict (signed fields sign-extended)."""
    flat = int(flat)
    if not isinstance(layout, data.Layout):
        shape = Shape.cast(layout)
        bits = flat & ((1 << shape.width) - 1)
        return _to_signed(bits, shape.width) if shape.signed else bits
    return {name: unpack(field.shape, flat >> field.offset) for name, field in layout}

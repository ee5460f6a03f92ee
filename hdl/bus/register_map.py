"""Register maps declared as data: the model behind the register file, its documentation
and the register tests.

A :class:`RegisterMap` is a list of :class:`RegisterGroup` (one per block, at a fixed
offset) of :class:`Register` (a name, a shape — an integer width or an Amaranth layout,
usually the block's own ``config_layout()``/``status_layout()`` — an access kind, and a
count for per-camera arrays). From it come

* the AXI4-Lite decoder (:class:`hdl.bus.register_file.RegisterFile`: one port per register),
* the documentation table (:meth:`RegisterMap.markdown`, ``docs/register_map.md``), and
* the register tests (they walk :meth:`RegisterMap.words`).

A block adds a register by adding a line to its group (rowtrack's map is declared in
:mod:`hdl.bus.regmap`); no decoder changes.

Fields are packed into 32-bit words without straddling a word boundary (see
:meth:`Register.pieces`); reading word 0 of a read-only element of several words
samples the whole element and its other words answer from that sample (read word 0
first for a consistent value), and a write-only value is delivered when its highest
word is written. Array elements follow each other.
"""

import enum
import keyword
import zlib
from dataclasses import dataclass, field, replace

from amaranth.hdl import Shape
from amaranth.lib import data

from golden.checks import check_int

__all__ = ["Access", "Register", "RegisterGroup", "RegisterMap", "Word", "WORD_BYTES",
           "WORD_BITS"]

WORD_BYTES = 4
WORD_BITS = 32


class Access(enum.Enum):
    """Who writes a register."""
    #: Control: written (and read back) by the PS, drives the block.
    RW = "rw"
    #: Status: driven by the block, read by the PS; writes are errors.
    RO = "ro"
    #: Command: a write delivers the value with a one-clock strobe; reads are errors.
    WO = "wo"
    #: Constant known at build time (identification); writes are errors.
    CONST = "const"


def _check_name(what, name):
    if not isinstance(name, str):
        raise TypeError(f"{what} must be a string, not {name!r}")
    if not name.isidentifier() or keyword.iskeyword(name) or name.startswith("_") \
            or "__" in name:
        raise ValueError(f"{what} must be an identifier without leading or double "
                         f"underscores, not {name!r}")


def _flat_fields(shape, prefix=""):
    """``(name, offset, width)`` of every leaf field of ``shape`` (nested names dotted)."""
    if isinstance(shape, data.ArrayLayout):
        step = Shape.cast(shape.elem_shape).width
        return [(sub, k * step + offset, width)
                for k in range(shape.length)
                for sub, offset, width in _flat_fields(shape.elem_shape,
                                                       f"{prefix[:-1]}[{k}].")]
    if isinstance(shape, data.Layout):
        return [(sub, fld.offset + offset, width)
                for name, fld in shape
                for sub, offset, width in _flat_fields(fld.shape, f"{prefix}{name}.")]
    return [(prefix[:-1] or "value", 0, Shape.cast(shape).width)]


@dataclass(frozen=True)
class Piece:
    """Bits ``[src, src + width)`` of an element (field ``name``, ``part`` of it when
    the field spans words) at bits ``[dst, dst + width)`` of its word ``word``."""
    name: str
    src: int
    width: int
    word: int
    dst: int
    part: tuple = None


@dataclass(frozen=True)
class Register:
    """One register (or an array of ``count`` identical ones).

    Parameters
    ----------
    name : str
    shape : int or amaranth.lib.data.Layout
        Width in bits, or a layout whose fields are documented bit by bit.
    access : Access
    doc : str
    count : int
        Elements (e.g. one per camera); the port is an ``ArrayLayout`` when above 1.
    reset : int or dict
        Value after reset of an ``RW`` register (a dict for a layout's fields).
    value : int
        The value of a ``CONST`` register.
    """
    name: str
    shape: object
    access: Access
    doc: str
    count: int = 1
    reset: object = 0
    value: int = 0

    def __post_init__(self):
        _check_name("name", self.name)
        if isinstance(self.shape, bool) or not isinstance(self.shape, (int, data.Layout)):
            raise TypeError(f"shape of {self.name} must be a width or a Layout, "
                            f"not {self.shape!r}")
        if self.width < 1:
            raise ValueError(f"shape of {self.name} must be at least one bit wide")
        if not isinstance(self.access, Access):
            raise TypeError(f"access of {self.name} must be an Access, not {self.access!r}")
        check_int(f"count of {self.name}", self.count, 1)
        if self.reset and self.access is not Access.RW:
            raise ValueError(f"reset of {self.name} applies to RW registers only")
        if self.value and self.access is not Access.CONST:
            raise ValueError(f"value of {self.name} applies to CONST registers only")
        if self.access is Access.CONST and not 0 <= self.value < (1 << self.width):
            raise ValueError(f"value of {self.name} must fit {self.width} bits, "
                             f"not {self.value}")
        if not 0 <= self.reset_raw < (1 << self.width):
            raise ValueError(f"reset of {self.name} must fit {self.width} bits")

    @property
    def width(self):
        """Bits of one element."""
        return self.shape if isinstance(self.shape, int) else Shape.cast(self.shape).width

    @property
    def words(self):
        """32-bit words of one element."""
        return max(piece.word for piece in self.pieces()) + 1

    @property
    def reset_raw(self):
        """The reset value as an integer."""
        if isinstance(self.reset, dict):
            if not isinstance(self.shape, data.Layout):
                raise TypeError(f"reset of {self.name} is a dict but its shape has no fields")
            return self.shape.const(self.reset).as_value().value & ((1 << self.width) - 1)
        if not isinstance(self.reset, int) or isinstance(self.reset, bool):
            raise TypeError(f"reset of {self.name} must be an integer or a dict, "
                            f"not {self.reset!r}")
        return self.reset

    def port_shape(self):
        """The Amaranth shape of this register's port (an array when ``count > 1``)."""
        return self.shape if self.count == 1 else data.ArrayLayout(self.shape, self.count)

    def fields(self):
        """``(name, offset, width)`` of the fields of one element."""
        if isinstance(self.shape, int):
            return [("value", 0, self.shape)]
        return _flat_fields(self.shape)

    def pieces(self):
        """Where the bits of one element sit in its words, as :class:`Piece` objects.

        Fields are packed in order, never across a word boundary: a field that does not
        fit the rest of the current word starts the next one, and a field wider than a
        word starts a word of its own and continues in the following ones. Software
        then reads any field of up to 32 bits with one access.
        """
        out, word, used = [], 0, 0
        for name, offset, width in self.fields():
            for lo in range(0, width, WORD_BITS):
                chunk = min(WORD_BITS, width - lo)
                if used + chunk > WORD_BITS or (lo == 0 and width > WORD_BITS and used):
                    word, used = word + 1, 0
                part = (lo, lo + chunk) if width > WORD_BITS else None
                out.append(Piece(name, offset + lo, chunk, word, used, part))
                used += chunk
        return out


@dataclass(frozen=True)
class RegisterGroup:
    """The registers of one block, placed from byte offset ``offset`` in order."""
    name: str
    offset: int
    doc: str
    registers: tuple = field(default_factory=tuple)

    def __post_init__(self):
        _check_name("group name", self.name)
        if not isinstance(self.offset, int) or self.offset < 0 or self.offset % WORD_BYTES:
            raise ValueError(f"offset of group {self.name} must be a non-negative multiple "
                             f"of {WORD_BYTES}, not {self.offset!r}")
        object.__setattr__(self, "registers", tuple(self.registers))
        for reg in self.registers:
            if not isinstance(reg, Register):
                raise TypeError(f"group {self.name} must hold Registers, not {reg!r}")
        names = [r.name for r in self.registers]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"group {self.name} declares {sorted(dup)[0]!r} twice")

    @property
    def size(self):
        """Bytes the group occupies."""
        return WORD_BYTES * sum(r.words * r.count for r in self.registers)


@dataclass(frozen=True)
class Word:
    """One mapped 32-bit word: word ``word`` of element ``index`` of a register."""
    offset: int
    group: RegisterGroup
    register: Register
    index: int
    word: int

    def pieces(self):
        """The element's bits in this word."""
        return [p for p in self.register.pieces() if p.word == self.word]

    @property
    def last(self):
        """The highest word of its element (a write-only value is delivered here)."""
        return self.word == self.register.words - 1


@dataclass(frozen=True)
class RegisterMap:
    """Groups of registers in an address window on the AXI bus.

    Parameters
    ----------
    groups : tuple of RegisterGroup
    base : int
        Bus address of offset 0 (a multiple of ``size``).
    size : int
        Bytes in the window (a power of two); every other address answers SLVERR.
    """
    groups: tuple
    base: int = 0x4000_0000
    size: int = 0x1000

    def __post_init__(self):
        object.__setattr__(self, "groups", tuple(self.groups))
        if not isinstance(self.size, int) or self.size < WORD_BYTES or self.size & (self.size - 1):
            raise ValueError(f"size must be a power of two of at least {WORD_BYTES} bytes, "
                             f"not {self.size!r}")
        if not isinstance(self.base, int) or self.base < 0 or self.base % self.size:
            raise ValueError(f"base must be a non-negative multiple of size ({self.size:#x}), "
                             f"not {self.base!r}")
        names = [g.name for g in self.groups]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"group {sorted(dup)[0]!r} is declared twice")
        spans = sorted((g.offset, g.offset + g.size, g.name) for g in self.groups)
        for (a_lo, a_hi, a), (b_lo, _, b) in zip(spans, spans[1:]):
            if b_lo < a_hi:
                raise ValueError(f"group {b} at {b_lo:#x} overlaps group {a} "
                                 f"({a_lo:#x}..{a_hi - 1:#x})")
        for lo, hi, name in spans:
            if hi > self.size:
                raise ValueError(f"group {name} ends at {hi:#x}, beyond the window of "
                                 f"{self.size:#x} bytes")

    replace = replace

    @property
    def addr_bits(self):
        """Bits of a byte offset inside the window."""
        return self.size.bit_length() - 1

    def group(self, name):
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(f"no register group {name!r}")

    def words(self):
        """Every mapped word, in address order."""
        out = []
        for g in self.groups:
            offset = g.offset
            for reg in g.registers:
                for index in range(reg.count):
                    for word in range(reg.words):
                        out.append(Word(offset, g, reg, index, word))
                        offset += WORD_BYTES
        return sorted(out, key=lambda w: w.offset)

    def find(self, group, name):
        """The first word of register ``group.name`` (its address is ``base + offset``)."""
        for w in self.words():
            if w.group.name == group and w.register.name == name:
                return w
        raise KeyError(f"no register {group}.{name}")

    def layout_crc(self):
        """CRC-32 of the map's shape (offsets, names, widths, access, fields), not of
        constant values: software compares it with the ``ident.map_crc`` register."""
        text = "\n".join(
            f"{w.offset}:{w.group.name}.{w.register.name}[{w.index}].{w.word}:"
            f"{w.register.access.value}:{w.pieces()}" for w in self.words())
        return zlib.crc32(text.encode())

    def with_value(self, group, name, value):
        """A copy with CONST register ``group.name`` set to ``value``."""
        groups = []
        for g in self.groups:
            if g.name == group:
                regs = tuple(replace(r, value=value) if r.name == name else r
                             for r in g.registers)
                g = replace(g, registers=regs)
            groups.append(g)
        return replace(self, groups=tuple(groups))

    def markdown(self, title="Register map"):
        """The documentation page: one table per group, one row per field."""
        lines = [f"# {title}", "",
                 f"AXI4-Lite, 32-bit words, window `{self.base:#010x}`–"
                 f"`{self.base + self.size - 1:#010x}` on the PS7 M_AXI_GP0 port. Any other "
                 "address, a misaligned address, a write to an `ro`/`const` register, a "
                 "read of a `wo` register or a partial (byte-strobed) write to a `wo` "
                 "register answers **SLVERR**; the bus never hangs.",
                 "",
                 "Access: `rw` control (reads back), `ro` status, `wo` command (the write "
                 "is delivered to the block with a one-clock strobe when the element's "
                 "highest word is written), `const` build-time constant. Fields never "
                 "straddle words: a field that does not fit the rest of a word starts the "
                 "next; a field wider than 32 bits takes whole words, low bits first. "
                 "Reading word 0 of an `ro` register (or array element) of several words "
                 "samples the whole element; its other words answer from that sample, so "
                 "read word 0 first and then the others for one consistent value. `rw` "
                 "words are read as stored. "
                 "Unlisted bits read as 0. Counters wrap.",
                 "", f"Map CRC-32 (`ident.map_crc`): `{self.layout_crc():#010x}`.", ""]
        for g in self.groups:
            lines += [f"## `{g.name}` (offset `{g.offset:#05x}`)", "", g.doc, "",
                      "| address | register | access | bits | field | reset/value | description |",
                      "|---|---|---|---|---|---|---|"]
            for w in (w for w in self.words() if w.group is g):
                reg = w.register
                label = reg.name + (f"[{w.index}]" if reg.count > 1 else "") + (
                    f" (word {w.word})" if reg.words > 1 else "")
                known = reg.reset_raw if reg.access is Access.RW else (
                    reg.value if reg.access is Access.CONST else None)
                for k, piece in enumerate(w.pieces()):
                    hi = piece.dst + piece.width - 1
                    bits = f"{hi}:{piece.dst}" if piece.width > 1 else f"{piece.dst}"
                    value = "" if known is None else \
                        f"`{(known >> piece.src) & ((1 << piece.width) - 1):#x}`"
                    part = f" (bits {piece.part[1] - 1}:{piece.part[0]})" if piece.part else ""
                    first = k == 0
                    lines.append(f"| `{self.base + w.offset:#010x}` | {label if first else ''} | "
                                 f"{reg.access.value if first else ''} | {bits} | "
                                 f"{piece.name}{part} | {value} | "
                                 f"{reg.doc if first and w.word == 0 else ''} |")
            lines.append("")
        return "\n".join(lines)

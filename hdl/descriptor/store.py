"""Reference store: the previous frame's descriptor row for every row of a camera.

Descriptor bits of columns ``0 … width − R − 1`` of every row in 36-bit words of a
``lib.memory`` (18 words per 640-pixel row, 8,640 words = 311,040 bits for 640×480:
the width of a block RAM with its parity bits, so the frame fits nine RAMB36),
plus a tag per row (valid, frame number). Each word is read one column before the row
reaches it and written back, with the new row's bits, after its last column: the
read of the previous frame's word always comes first, so reading the reference and
writing the new row never collide, whatever the window and centre, without a second
frame buffer. The matcher lines the bits up with its own delay lines.
"""

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.descriptor.layouts import descriptor_layout, pair_layout
from hdl.descriptor.params import RowDescriptorParams

__all__ = ["ReferenceStore"]

#: Bits per memory word (a block RAM's data and parity bits).
WORD_BITS = 36


def _times_constant(value, constant):
    """``value * constant`` as shifted adds (a few LUTs, no DSP for a row address)."""
    terms = [value << k for k in range(constant.bit_length()) if constant >> k & 1]
    total = Const(0)
    for term in terms:
        total = total + term
    return total


class ReferenceStore(wiring.Component):
    """Swap a streaming descriptor row with the stored row of the previous frame.

    Column ``j = pos − R ≥ 0`` of row ``meta.row`` comes out as ``ref`` with the bit the
    previous write of that row left there, and the current bit replaces it. The row's
    tag is read with every column and written with its last one: ``valid = not
    meta.bad`` (the row's final verdict), ``frame = meta.frame``. ``no_reference`` is
    set unless the tag is valid and from frame ``meta.frame − 1`` (modulo
    ``2**frame_bits``). Rows at or beyond ``height`` are not written and read as zeros.

    Members
    -------
    i : In(stream.Signature(descriptor_layout(params, 1)))
    o : Out(stream.Signature(pair_layout(params)))

    Latency 2 (bit select, output register with the tag check); one column per clock;
    backpressure stalls both stages. Reset clears the valid bits, not the memories
    (which start all zero: no valid reference until a frame has been stored).
    """

    latency = 2

    def __init__(self, params):
        if not isinstance(params, RowDescriptorParams):
            raise TypeError(f"params must be a RowDescriptorParams, not {params!r}")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(descriptor_layout(params, 1))),
            "o": Out(stream.Signature(pair_layout(params))),
        })

    @property
    def words_per_row(self):
        return -(-(self.params.width - self.params.radius) // WORD_BITS)

    def elaborate(self, platform):
        p = self.params
        m = Module()
        stall = self.o.valid & ~self.o.ready
        advance = ~stall
        m.d.comb += self.i.ready.eq(advance)
        item = self.i.payload
        accept = self.i.valid & advance
        stored = p.width - p.radius            # columns 0 … stored − 1 are kept

        tag_layout = data.StructLayout({"valid": 1, "frame": p.frame_bits})
        m.submodules.words = words = Memory(shape=WORD_BITS,
                                            depth=p.height * self.words_per_row, init=[])
        m.submodules.tags = tags = Memory(shape=tag_layout, depth=p.height, init=[])
        words_rd, words_wr = words.read_port(), words.write_port()
        tags_rd, tags_wr = tags.read_port(), tags.write_port()

        # the row's first word, registered with its first item (R ≥ 2, so the first
        # read, at column −1 = pos R − 1, comes after it)
        row_base = Signal(range(p.height * self.words_per_row + 1))
        in_frame = item.meta.row < p.height
        with m.If(accept & item.first):
            m.d.sync += row_base.eq(_times_constant(item.meta.row, self.words_per_row))
        # word and bit of this item's column j = pos − R, counted from the row's first
        # item (column −R: bit WORD_BITS − R of word −1)
        next_bit = Signal(range(WORD_BITS))
        next_word = Signal(range(-1, self.words_per_row + 1))
        bit = Mux(item.first, WORD_BITS - p.radius, next_bit)
        word = Mux(item.first, -1, next_word)
        word_end = bit == WORD_BITS - 1
        column = item.pos - p.radius
        with m.If(accept):
            m.d.sync += [next_bit.eq(Mux(word_end, 0, bit + 1)), next_word.eq(word + word_end)]

        # read the next word while passing the last column of this one
        m.d.comb += [
            words_rd.addr.eq(row_base + word + 1),
            words_rd.en.eq(accept & word_end & (column + 1 < stored)),
        ]
        # the stored word, shifted out one bit per column (no wide bit-select mux)
        old_bits = Signal(WORD_BITS - 1)
        ref_bit = Mux(bit == 0, words_rd.data[0], old_bits[0])
        with m.If(accept):
            m.d.sync += old_bits.eq(Mux(bit == 0, words_rd.data[1:], old_bits >> 1))

        # collect the new word; write it with its last column (or the row's last)
        new_word = Signal(WORD_BITS)
        merged = Cat(Mux(bit == k, item.bits[0], new_word[k]) for k in range(WORD_BITS))
        with m.If(accept):
            m.d.sync += new_word.eq(merged)
        m.d.comb += [
            words_wr.addr.eq(row_base + word), words_wr.data.eq(merged),
            words_wr.en.eq(accept & (column >= 0) & in_frame &
                           (word_end | (column == stored - 1))),
            tags_rd.addr.eq(item.meta.row), tags_rd.en.eq(advance),
            tags_wr.addr.eq(item.meta.row),
            tags_wr.data.valid.eq(~item.meta.bad), tags_wr.data.frame.eq(item.meta.frame),
            tags_wr.en.eq(accept & item.last & in_frame),
        ]

        s1_valid = Signal()
        s1 = Signal(pair_layout(p))
        with m.If(advance):
            m.d.sync += [s1_valid.eq(self.i.valid), s1.cur.eq(item.bits[0]),
                         s1.ref.eq(ref_bit), s1.strong.eq(item.strong[0]),
                         s1.pos.eq(item.pos), s1.first.eq(item.first), s1.last.eq(item.last),
                         s1.meta.eq(item.meta)]
            tag = tags_rd.data
            previous = (s1.meta.frame - 1)[:p.frame_bits]
            s1_in_frame = s1.meta.row < p.height
            out = self.o.payload
            m.d.sync += [
                self.o.valid.eq(s1_valid), out.eq(s1),
                out.ref.eq(s1.ref & s1_in_frame),
                out.no_reference.eq(~tag.valid | (tag.frame != previous) | ~s1_in_frame),
            ]
        return m

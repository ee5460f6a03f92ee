"""Reference store: the previous frame's descriptor row that a camera row is matched
against.

Descriptor bits of columns ``0 … width − R − 1`` of every row in 36-bit words of a
``lib.memory`` (18 words per 640-pixel row: the width of a block RAM with its parity
bits), plus a tag per stored row. Each word is read one column before the row reaches
it and written back, with the new row's bits, after its last column: the read of a
word always comes first, so a row may overwrite the very slot it reads, whatever the
window and centre. The matcher lines the bits up with its own delay lines.

Two kinds, one parameter (``follow``):

* same row (``follow=False``, the top's lanes today): one slot per row index, row ``y``
  reads what row ``y`` of the previous frame left (8,640 words for 640×480: nine RAMB36);
* followed rows (``follow=True``, issue 16): a ring of ``height + D + 1`` slots
  (``params.ring_rows``, D = ``params.row_displacement``); row ``y`` of a frame is
  written to slot ``(base + y) mod ring_rows`` and reads, for each segment ``k``, row
  ``source[k]`` (the row's ``meta.source``, the forecast's row addresses) of the
  previous frame from ``(previous base + source[k]) mod ring_rows``; ``base`` moves on
  by ``height`` whenever the frame number changes. Word ``q`` is read from the row of
  segment ``params.word_segments(centre)[q]`` (the segment of current column
  ``36q + 18 + centre``: each segment's window reads its own row around its centre
  shift), so a row switches rows at word boundaries, one read per word as before. The
  previous frame's row ``s`` is overwritten by row ``s + D + 1``, which reads it first,
  so every ``0 ≤ source < height`` with ``row − source ≤ D + 1`` is served; a segment
  outside that range reads zeros, the row has no reference and is counted. At 640×480
  and the default D = 31 the ring is 512 rows = 9,216 words, the same nine RAMB36.
"""

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.descriptor.layouts import descriptor_layout, pair_layout
from hdl.descriptor.params import REFERENCE_WORD_BITS, check_lane_params
from hdl.logic import same

__all__ = ["ReferenceStore", "COUNT_BITS"]

#: Bits per memory word (a block RAM's data and parity bits).
WORD_BITS = REFERENCE_WORD_BITS

#: Width of the saturating count of out-of-range requests.
COUNT_BITS = 32


def _times_constant(value, constant):
    """``value * constant`` as shifted adds (a few LUTs, no DSP for a row address)."""
    terms = [value << k for k in range(constant.bit_length()) if constant >> k & 1]
    total = Const(0)
    for term in terms:
        total = total + term
    return total


def _wrap(value, size):
    """``value mod size`` for ``0 ≤ value < 2·size`` (one compare and subtract)."""
    return Mux(value >= size, value - size, value)


class ReferenceStore(wiring.Component):
    """Swap a streaming descriptor row with a stored row of the previous frame.

    Column ``j = pos − R ≥ 0`` of the row comes out as ``ref`` with the bit of the
    stored row it reads (the same row index, or with ``follow`` the ring slot of row
    ``meta.source[k]`` of the previous frame, ``k`` its word's segment), and the current
    bit replaces the bit of the row's own slot. The row's tag is written with its last
    column: ``valid = not meta.bad`` (the row's final verdict), ``frame = meta.frame``
    (and ``row = meta.row`` with ``follow``). ``no_reference`` is set unless the tag
    read is valid and from frame ``meta.frame − 1`` (modulo ``2**frame_bits``); with
    ``follow``, every column ``j ≥ 0`` checks the tag of its word's slot (of row
    ``meta.source[k]``, the request in range) and ``no_reference`` stays set from the
    first that fails to the row's end. Rows at or beyond ``height`` are not written and
    read as zeros, like out-of-range requests.

    Parameters
    ----------
    params : RowDescriptorParams
    follow : bool
        Ring of followed rows instead of the same-row store; needs ``radius ≥ 3``
        (the row's slot addresses take two columns to compute, before the first read
        at column −1).

    Members
    -------
    i : In(stream.Signature(descriptor_layout(params, 1)))
    o : Out(stream.Signature(pair_layout(params)))
    out_of_range : Out(COUNT_BITS), with ``follow`` only
        Rows (index below ``height``) whose request was outside the served range,
        counted with their last column; saturates at all ones.

    Latency 2 (bit select, output register with the tag check); one column per clock;
    backpressure stalls both stages. With ``follow``, ``no_reference`` is set before
    column 0 and final with the row's last column, where the matcher takes it. Reset
    restarts the ring's frame tracking and the count, not the memories (which start all
    zero: no valid reference until a frame has been stored).
    """

    latency = 2

    def __init__(self, params, follow=False):
        self.params = check_lane_params(params)
        if not isinstance(follow, bool):
            raise TypeError(f"follow must be a bool, not {follow!r}")
        if follow and params.radius < 3:
            raise ValueError(f"a followed reference store needs a descriptor radius of at "
                             f"least 3 (sigma > 2/3) to compute its ring address, not "
                             f"{params.radius}")
        self.follow = follow
        members = {"i": In(stream.Signature(descriptor_layout(params, 1))),
                   "o": Out(stream.Signature(pair_layout(params)))}
        if follow:
            members["out_of_range"] = Out(COUNT_BITS)
        super().__init__(members)

    @property
    def words_per_row(self):
        return -(-(self.params.width - self.params.radius) // WORD_BITS)

    @property
    def slots(self):
        """Stored rows: ``height``, or the ring's ``height + D + 1``."""
        return self.params.ring_rows if self.follow else self.params.height

    def _same_row(self, m, item, first):
        """Slot = the row index: word base registered with the row's first item (R ≥ 2,
        so the first read, at column −1 = pos R − 1, comes after it)."""
        p = self.params
        row_base = Signal(range(p.height * self.words_per_row + 1))
        with m.If(first):
            m.d.sync += row_base.eq(_times_constant(item.meta.row, self.words_per_row))
        return {"read_base": row_base, "write_base": row_base,
                "read_slot": item.meta.row, "write_slot": item.meta.row, "ok": Const(1)}

    def _ring(self, m, item, first, accept, read):
        """Ring slots, one read slot per segment: sums with the row's first item,
        wrapped and turned into word addresses with its second (both final from pos 2 ≤
        R − 1 on); then, word by word, the slot of the segment each word goes with
        (``params.word_segments``), and whether a segment the row reads is out of range
        (counted once per row)."""
        p = self.params
        size, height, w, k = p.ring_rows, p.height, self.words_per_row, p.segments
        base, previous = Signal(range(size)), Signal(range(size))
        frame = Signal(p.frame_bits)
        # (base + height) mod size, one clock behind base (rows are ≥ 8 items apart)
        following = Signal(range(size), init=height)
        m.d.sync += following.eq(_wrap(base + height, size))
        changed = item.meta.frame != frame
        now = Mux(changed, following, base)
        before = Mux(changed, base, previous)
        sum_shape = range(size + (1 << p.row_bits))
        write_sum = Signal(sum_shape)
        read_sums = [Signal(sum_shape, name=f"read_sum{s}") for s in range(k)]
        outside = Array(Signal(name=f"outside{s}") for s in range(k))
        row = item.meta.row
        with m.If(first):
            m.d.sync += [base.eq(now), previous.eq(before), frame.eq(item.meta.frame),
                         write_sum.eq(now + row)]
            for s in range(k):
                source = item.meta.source[s]
                m.d.sync += [read_sums[s].eq(before + source),
                             outside[s].eq((source >= height) |
                                           (row > source + (p.row_displacement + 1)))]
        read_slots = Array(Signal(range(size), name=f"read_slot{s}") for s in range(k))
        read_bases = Array(Signal(range(size * w + 1), name=f"read_base{s}")
                           for s in range(k))
        write_slot, write_base = Signal(range(size)), Signal(range(size * w + 1))
        write_wrapped = Mux(row < height, _wrap(write_sum, size), 0)
        with m.If(accept & ~item.first):
            for s in range(k):
                wrapped = Mux(outside[s], 0, _wrap(read_sums[s], size))
                m.d.sync += [read_slots[s].eq(wrapped),
                             read_bases[s].eq(_times_constant(wrapped, w))]
            m.d.sync += [write_slot.eq(write_wrapped),
                         write_base.eq(_times_constant(write_wrapped, w))]

        # the word read next: its middle column plus the centre, hence its segment
        half, starts = REFERENCE_WORD_BITS // 2, p.segment_starts
        reach = REFERENCE_WORD_BITS * w + half + p.centre_range
        middle = Signal(range(-p.centre_range - 1, reach + 1))
        with m.If(first):
            m.d.sync += middle.eq(half + item.meta.centre)
        with m.Elif(read):
            m.d.sync += middle.eq(middle + REFERENCE_WORD_BITS)
        upcoming = Signal(range(k))
        m.d.comb += upcoming.eq(sum((middle >= start).as_unsigned() for start in starts))
        current = Signal(range(k))          # the segment of the word being passed
        any_outside = Signal()              # a word the row read was out of range
        with m.If(first):
            m.d.sync += any_outside.eq(0)
        with m.Elif(read):
            m.d.sync += [current.eq(upcoming), any_outside.eq(any_outside | outside[upcoming])]

        count = Signal(COUNT_BITS)
        with m.If(accept & item.last & (row < height) & any_outside & ~count.all()):
            m.d.sync += count.eq(count + 1)
        m.d.comb += self.out_of_range.eq(count)
        return {"read_base": read_bases[upcoming], "write_base": write_base,
                "read_slot": read_slots[current], "write_slot": write_slot,
                "expected_row": item.meta.source[current],
                "ok": ~outside[current] & (item.pos >= p.radius)}

    def elaborate(self, platform):
        p = self.params
        m = Module()
        stall = self.o.valid & ~self.o.ready
        advance = ~stall
        m.d.comb += self.i.ready.eq(advance)
        item = self.i.payload
        accept = self.i.valid & advance
        first = accept & item.first
        stored = p.width - p.radius            # columns 0 … stored − 1 are kept
        w = self.words_per_row

        # word and bit of this item's column j = pos − R, counted from the row's first
        # item (column −R: bit WORD_BITS − R of word −1)
        next_bit = Signal(range(WORD_BITS))
        next_word = Signal(range(-1, w + 1))
        bit = Mux(item.first, WORD_BITS - p.radius, next_bit)
        word = Mux(item.first, -1, next_word)
        word_end = bit == WORD_BITS - 1
        column = item.pos - p.radius
        with m.If(accept):
            m.d.sync += [next_bit.eq(Mux(word_end, 0, bit + 1)), next_word.eq(word + word_end)]
        # read the next word while passing the last column of this one
        read = accept & word_end & (column + 1 < stored)

        tag_fields = {"valid": 1, "frame": p.frame_bits}
        if self.follow:
            tag_fields["row"] = p.row_bits
        m.submodules.words = words = Memory(shape=WORD_BITS, depth=self.slots * w, init=[])
        m.submodules.tags = tags = Memory(shape=data.StructLayout(tag_fields),
                                          depth=self.slots, init=[])
        words_rd, words_wr = words.read_port(), words.write_port()
        tags_rd, tags_wr = tags.read_port(), tags.write_port()
        at = self._ring(m, item, first, accept, read) if self.follow else \
            self._same_row(m, item, first)
        in_frame = item.meta.row < p.height

        m.d.comb += [
            words_rd.addr.eq(at["read_base"] + word + 1),
            words_rd.en.eq(read),
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
            words_wr.addr.eq(at["write_base"] + word), words_wr.data.eq(merged),
            words_wr.en.eq(accept & (column >= 0) & in_frame &
                           (word_end | (column == stored - 1))),
            tags_rd.addr.eq(at["read_slot"]), tags_rd.en.eq(advance),
            tags_wr.addr.eq(at["write_slot"]),
            tags_wr.data.valid.eq(~item.meta.bad), tags_wr.data.frame.eq(item.meta.frame),
            tags_wr.en.eq(accept & item.last & in_frame),
        ]
        if self.follow:
            m.d.comb += tags_wr.data.row.eq(item.meta.row)

        # what the tag check needs of the item is worked out on entry to s1, so that
        # after the tag read only the two compares and the flags remain (issue 17: the
        # frame's subtraction and the bounds took the path to 12 LUT levels in the top)
        s1_valid, s1_served, s1_checked = Signal(), Signal(), Signal()
        s1 = Signal(pair_layout(p))
        s1_previous = Signal(p.frame_bits)
        s1_expected = Signal(p.row_bits)
        missing = Signal()          # followed: a checked column of this row had no reference
        with m.If(advance):
            m.d.sync += [s1_valid.eq(self.i.valid), s1.cur.eq(item.bits[0]),
                         s1.ref.eq(ref_bit), s1.strong.eq(item.strong[0]),
                         s1.pos.eq(item.pos), s1.first.eq(item.first), s1.last.eq(item.last),
                         s1.meta.eq(item.meta), s1_served.eq(at["ok"] & in_frame),
                         s1_checked.eq(item.pos >= p.radius),
                         s1_previous.eq(item.meta.frame - 1)]
            tag = tags_rd.data
            stale = ~tag.valid | ~same(tag.frame, s1_previous)
            out = self.o.payload
            m.d.sync += [self.o.valid.eq(s1_valid), out.eq(s1),
                         out.ref.eq(s1.ref & s1_served)]
            if self.follow:
                # each column checks the slot of its own word's segment; the row has a
                # reference when every checked column had one (final with the last)
                lacking = missing | (s1_checked & (stale | ~same(tag.row, s1_expected) |
                                                   ~s1_served))
                m.d.sync += [s1_expected.eq(at["expected_row"]),
                             out.no_reference.eq(~s1_checked | lacking)]
                with m.If(s1_valid):
                    m.d.sync += missing.eq(Mux(s1.last, 0, lacking))
            else:
                m.d.sync += out.no_reference.eq(stale | ~s1_served)
        return m

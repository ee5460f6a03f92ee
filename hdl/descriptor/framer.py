"""Framing of the row-descriptor lanes (:mod:`hdl.row_descriptor`): rows of exactly
``width`` pixels out of a camera beat stream (:class:`RowFramer`), and the descriptor
bits of a stereo pair's two rows joined column by column (:class:`StereoJoin`)."""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.descriptor.layouts import descriptor_layout, framed_layout
from hdl.descriptor.params import check_lane_params
from hdl.logic import same

__all__ = ["RowFramer", "StereoJoin", "saturate_centre", "saturate_half_width"]


def saturate_centre(params, value):
    """A run-time window centre (``centre_fmt``) saturated to ``±centre_range``
    (``params.clamp_centre`` in gateware), as the lanes sample it."""
    cr = params.centre_range
    return Mux(value > cr, cr, Mux(value < -cr, -cr, value))


def saturate_half_width(params, value):
    """``(w in force, out of range)`` of a run-time half-width ``value`` (an unsigned
    ``half_width_fmt`` value): ``params.saturate_half_width`` in gateware, the one
    definition the lanes and the engine's status bit share."""
    ok = (value >= params.min_half_width) & (value <= params.max_half_width)
    return Mux(ok, value, params.max_half_width), ~ok


class RowFramer(wiring.Component):
    """Rows of exactly ``width`` pixels out of a camera beat stream.

    A ``first`` beat opens a row; if the previous row is still incomplete its end is
    padded first (zero pixels, while ``i`` waits). A ``last`` before column
    ``width − 1`` makes the row short: it is padded to the width. A row whose column
    ``width − 1`` lacks ``last`` is long: it ends there and the rest is dropped, like any
    beat outside an open row. Such rows, rows with reason bits (``flags``) and rows
    indexed at or beyond ``height`` are bad; ``meta.bad`` is sticky along the row, so its
    last item carries the final verdict.

    Parameters
    ----------
    params : RowDescriptorParams
    follow : bool
        The beats carry their row's centre and its segments' source rows
        (``hdl.streams.followed_pixel_layout``) instead of a ``centre`` port; without,
        every segment's ``meta.source`` is the row itself.
    paired : bool
        The beats carry ``paired`` (``params.input_layout(follow, paired=True)``), kept
        in ``meta.paired``; without, ``meta.paired`` is 0.

    Members
    -------
    i : In(stream.Signature(params.input_layout(follow, paired)))
        Camera beats (``hdl.streams.camera_pixel_layout``).
    centre : In(params.centre_fmt.shape()), without ``follow`` only
        Shift-window centre, integer pixels, sampled with each row's first beat and
        saturated to ``±centre_range`` (with ``follow``: the beat's ``centre``).
    half_width : In(params.half_width_fmt.shape())
        Run-time half-width ``w`` of the shift window (``[−w, w]`` around the centre,
        within the built window), sampled with each row's first beat; a value outside
        ``min_half_width … max_half_width`` (0 included) is taken as the built maximum
        (``saturate_half_width``; the engine flags it).
    o : Out(stream.Signature(framed_layout(params, 1)))

    Latency 1 (output register); one beat per clock, except one clock per pad pixel.
    Backpressure: ``i`` waits while ``o`` holds an untaken column.
    """

    latency = 1

    def __init__(self, params, follow=False, paired=False):
        self.params = check_lane_params(params)
        self.follow, self.paired = follow, paired
        members = {"i": In(stream.Signature(params.input_layout(follow, paired))),
                   "o": Out(stream.Signature(framed_layout(params, 1))),
                   "half_width": In(params.half_width_fmt.shape())}
        if not follow:
            members["centre"] = In(params.centre_fmt.shape())
        super().__init__(members)

    def elaborate(self, platform):
        p = self.params
        m = Module()
        beat = self.i.payload
        width = p.width
        asked, source = (beat.centre, beat.source) if self.follow else \
            (self.centre, Cat(*[beat.row] * p.segments))

        col = Signal(range(width + 1), init=width)   # width: no incomplete row
        incomplete = Signal()                         # col != width, registered
        col_last = Signal()                           # col == width − 1, registered
        pad_mode = Signal()                           # padding a short row
        meta = Signal.like(self.o.payload.meta)

        cuts_short = beat.first & incomplete          # the beat would open a row early
        pad_now = pad_mode | (self.i.valid & cuts_short)
        take = ~pad_now & self.i.valid & (beat.first | incomplete)
        opens = take & beat.first
        pos = Mux(opens, 0, col)
        at_end = ~opens & col_last                    # a row is wider than one pixel
        short = take & beat.last & ~at_end
        long_row = take & at_end & ~beat.last

        item = Signal.like(self.o.payload)
        with m.If(opens):
            m.d.comb += [
                item.meta.camera.eq(beat.camera), item.meta.frame.eq(beat.frame),
                item.meta.row.eq(beat.row), item.meta.t_first.eq(beat.t_first),
                item.meta.centre.eq(saturate_centre(p, asked)), item.meta.source.eq(source),
                item.meta.half_width.eq(saturate_half_width(p, self.half_width)[0]),
                item.meta.paired.eq(beat.paired if self.paired else 0),
            ]
        with m.Else():
            m.d.comb += item.meta.eq(meta)
        row_bad = Mux(opens, beat.row >= p.height, meta.bad)
        m.d.comb += [
            item.meta.bad.eq(row_bad | pad_now | (take & beat.flags.any()) | short | long_row),
            item.pixels[0].eq(Mux(pad_now, 0, beat.data)),
            item.pos.eq(pos), item.first.eq(opens), item.last.eq(at_end),
        ]

        # output register; beats outside a row are taken and dropped
        advance = ~self.o.valid | self.o.ready
        # ``ready`` without ``i.valid`` (it only matters with a beat): the producer's
        # valid logic stays off this ready path (issue 17)
        m.d.comb += self.i.ready.eq(advance & ~pad_mode & ~cuts_short)
        with m.If(advance):
            m.d.sync += [self.o.valid.eq(pad_now | take), self.o.payload.eq(item)]
            with m.If(pad_now | take):
                m.d.sync += [
                    meta.eq(item.meta),
                    col.eq(Mux(at_end, width, pos + 1)),
                    incomplete.eq(~at_end), col_last.eq(pos == width - 2),
                    pad_mode.eq(~at_end & (pad_mode | short)),
                ]
        return m


class StereoJoin(wiring.Component):
    """Pair the descriptor bits of a stereo pair's rows column by column.

    At a row boundary the two head rows are compared: same (frame, row) → their columns
    go out together (``bits[0]``/``strong[0]`` from ``a``, ``bits[1]``/``strong[1]`` from
    ``b``); otherwise the older row (frame order modulo ``2**frame_bits``, then row
    index) is dropped whole, so one lost row does not misalign the pair for good.

    The output's metadata is the stereo lane's own: ``camera``, ``frame``, ``row``,
    ``t_first`` from ``a``, ``bad`` from either, the centre and the built maximum
    half-width (the stereo lane searches its whole window). The centre is, with
    ``centre_port``, the ``centre`` port sampled with the first column pair of each row
    (saturated to ``±centre_range``): the rows are a temporal lane's, whose centre is the
    forecast's, and the port is a pair's register. Without, it is the one ``a``'s rows
    carry (their framer sampled the lane's centre with the row's first beat, however
    late ``b``'s row comes). The half-width and source row the inputs carry are not used.

    Members
    -------
    a, b : In(stream.Signature(descriptor_layout(params, 1)))
    centre : In(params.centre_fmt.shape()), with ``centre_port`` only
    o : Out(stream.Signature(descriptor_layout(params, 2)))

    Latency 1 (output register); one column pair per clock; two different head rows
    wait one clock before the older starts to drop.
    """

    latency = 1

    def __init__(self, params, centre_port=True):
        self.params = check_lane_params(params)
        self.centre_port = centre_port
        members = {
            "a": In(stream.Signature(descriptor_layout(params, 1))),
            "b": In(stream.Signature(descriptor_layout(params, 1))),
            "o": Out(stream.Signature(descriptor_layout(params, 2))),
        }
        if centre_port:
            members["centre"] = In(params.centre_fmt.shape())
        super().__init__(members)

    def elaborate(self, platform):
        p = self.params
        m = Module()
        a, b = self.a.payload, self.b.payload
        mode = Signal(2)          # 0: at a boundary, 1: pairing, 2: dropping a, 3: dropping b
        both = self.a.valid & self.b.valid
        # "no bit differs" maps to a LUT tree where ``==`` gave a chain (issue 17: the
        # stereo slices into ``mode`` were 11 LUT levels in the top)
        same_frame = same(a.meta.frame, b.meta.frame)
        same_row = same_frame & same(a.meta.row, b.meta.row)
        frame_gap = (a.meta.frame - b.meta.frame)[:p.frame_bits]
        # same_frame, not frame_gap == 0: the same test without the subtraction's carry
        # in front of it; and which row is older is registered, off the ready path
        # (issue 17): two different heads wait a clock (neither moves), then the older
        # is dropped
        a_older = Signal()              # of the heads of the clock before
        settled = Signal()              # the heads differed a clock ago: a_older is theirs
        m.d.sync += a_older.eq(frame_gap[-1] | (same_frame & (a.meta.row < b.meta.row)))
        differ = (mode == 0) & both & ~same_row
        m.d.sync += settled.eq(differ & ~settled)
        pairing = (mode == 1) | ((mode == 0) & same_row)
        drop_a = (mode == 2) | (differ & settled & a_older)
        drop_b = (mode == 3) | (differ & settled & ~a_older)
        advance = ~self.o.valid | self.o.ready
        paired = both & pairing & advance
        m.d.comb += [
            self.a.ready.eq((pairing & self.b.valid & advance) | drop_a),
            self.b.ready.eq((pairing & self.a.valid & advance) | drop_b),
        ]
        if self.centre_port:
            centre = Signal.like(self.o.payload.meta.centre)     # of the row being paired
            sampled = saturate_centre(p, self.centre)
            with m.If(paired & a.first):
                m.d.sync += centre.eq(sampled)
            row_centre = Mux(a.first, sampled, centre)
        else:
            row_centre = a.meta.centre
        out = self.o.payload
        with m.If(advance):
            m.d.sync += [
                self.o.valid.eq(both & pairing),
                out.bits[0].eq(a.bits[0]), out.bits[1].eq(b.bits[0]),
                out.strong[0].eq(a.strong[0]), out.strong[1].eq(b.strong[0]),
                out.pos.eq(a.pos), out.first.eq(a.first), out.last.eq(a.last),
                out.meta.camera.eq(a.meta.camera), out.meta.frame.eq(a.meta.frame),
                out.meta.row.eq(a.meta.row), out.meta.t_first.eq(a.meta.t_first),
                out.meta.bad.eq(a.meta.bad | b.meta.bad),
                out.meta.centre.eq(row_centre),
                out.meta.half_width.eq(p.max_half_width),
            ]
        with m.If(paired):
            m.d.sync += mode.eq(Mux(a.last, 0, 1))
        with m.Elif(self.a.valid & drop_a):
            m.d.sync += mode.eq(Mux(a.last, 0, 2))
        with m.Elif(self.b.valid & drop_b):
            m.d.sync += mode.eq(Mux(b.last, 0, 3))
        return m

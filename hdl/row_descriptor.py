"""Per-camera measurement engine: pixels in, (shift, confidence) per row segment out.

A temporal lane (:class:`RowDescriptor`) chains four blocks, one pixel per clock:

1. :class:`hdl.descriptor.framer.RowFramer` cuts the camera stream into rows of exactly ``width`` pixels
   (pads short rows, drops stray beats, flags such rows bad) and samples the run-time
   shift-window centre with each row's first pixel;
2. :class:`hdl.descriptor.fir.DescriptorFIR` convolves each row with the quantized second derivative of a
   Gaussian (``RowDescriptorParams.kernel_raw``) and keeps the sign: one bit per column;
3. :class:`hdl.descriptor.store.ReferenceStore` swaps the row's bits with the bits
   of the same row of the previous frame, or (``follow=True``) of the previous frame's
   row the input names per row, from a ring of ``height + D + 1`` rows (on-chip memory);
4. :class:`hdl.descriptor.matcher.ShiftMatcher` accumulates Hamming costs for every shift of the
   window while the row streams and, per segment, finds the best shift, its sub-pixel
   refinement and the peak-ratio confidence.

:class:`StereoRowDescriptor` matches the two cameras of a stereo pair against each
other instead: the two rows' descriptor bits, joined column by column
(:class:`hdl.descriptor.framer.StereoJoin`), into the matcher. In the measurement engine
the bits are the pair's temporal lanes' (``RowDescriptor(paired=True)`` hands its FIR's
bits on, ``StereoRowDescriptor(shared=True)`` takes them: the same filter is not built
twice); alone, the stereo lane has a framer and a FIR per camera.
Conventions are ``golden.descriptor``'s; the bit-accurate model is
``emulator/row_descriptor.py``; the formats are listed in ``docs/descriptor/row_descriptor.md``.
"""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.descriptor.layouts import descriptor_layout, pair_layout
from hdl.descriptor.matcher import ShiftMatcher
from hdl.descriptor.params import STEREO_640X480, RowDescriptorParams, check_lane_params
from hdl.descriptor.store import COUNT_BITS, ReferenceStore
from hdl.descriptor.fir import DescriptorFIR
from hdl.descriptor.framer import RowFramer, StereoJoin
from hdl.stream_fork import StreamFork

__all__ = ["RowDescriptor", "StereoRowDescriptor", "connect_shared_bits"]


def connect_shared_bits(m, src, dst):
    """A temporal lane's ``bits`` (``RowDescriptor(paired=True)``) into an input of its
    pair's ``StereoRowDescriptor(shared=True)``: the bits and what the stereo lane
    reads of the row's metadata (its key, ``t_first`` and ``bad``; the centre and
    half-width are the stereo lane's own, :class:`hdl.descriptor.framer.StereoJoin`).
    The two lanes' parameters differ in ``match``, hence in the metadata's widths."""
    item, to = src.payload, dst.payload
    m.d.comb += [dst.valid.eq(src.valid), src.ready.eq(dst.ready),
                 to.bits.eq(item.bits), to.strong.eq(item.strong), to.pos.eq(item.pos),
                 to.first.eq(item.first), to.last.eq(item.last)]
    m.d.comb += [to.meta[name].eq(item.meta[name])
                 for name in ("camera", "frame", "row", "t_first", "bad")]


def _lane_output(params, own_matcher):
    """A lane's output member: its matcher's measurements, or the matcher's input."""
    if own_matcher:
        return {"o": Out(stream.Signature(params.measurement_layout()))}
    return {"columns": Out(stream.Signature(pair_layout(params)))}


def _end_lane(m, lane, columns):
    """The lane's columns into its own matcher and out on ``o``, or out on ``columns``."""
    if lane.matcher is None:
        wiring.connect(m, columns, wiring.flipped(lane.columns))
        return
    m.submodules.matcher = lane.matcher
    wiring.connect(m, columns, lane.matcher.i)
    wiring.connect(m, lane.matcher.o, wiring.flipped(lane.o))


def _connect_pair(m, src, dst):
    """The joined bits as the matcher's current (camera a) and reference (camera b)
    bits."""
    m.d.comb += [
        dst.valid.eq(src.valid), src.ready.eq(dst.ready),
        dst.payload.cur.eq(src.payload.bits[0]), dst.payload.ref.eq(src.payload.bits[1]),
        dst.payload.strong.eq(src.payload.strong[0]), dst.payload.no_reference.eq(0),
        dst.payload.pos.eq(src.payload.pos), dst.payload.first.eq(src.payload.first),
        dst.payload.last.eq(src.payload.last), dst.payload.meta.eq(src.payload.meta),
    ]


class RowDescriptor(wiring.Component):
    """Temporal lane of one camera: framer → FIR → reference store → matcher.

    Each row is matched against the same row of the previous frame, or with
    ``follow=True`` against the previous frame's row its beats name (the forecast's row
    address, from a ring store: :class:`hdl.descriptor.store.ReferenceStore`); K
    measurements per row (``params.segments``). Model:
    ``emulator.row_descriptor.TemporalLaneModel(params, follow)``.

    Parameters
    ----------
    params : RowDescriptorParams
    follow : bool
        Follow rows: centre and source row come with each row's first beat.
    paired : bool
        The lane also hands its FIR's bits on (``bits``) to its pair's stereo lane, for
        the rows whose first beat carries ``paired`` (both cameras of the pair are in
        the row set); a :class:`hdl.stream_fork.StreamFork` gives every column to the
        reference store and, of those rows, to ``bits``.
    own_matcher : bool
        The lane ends in its own :class:`hdl.descriptor.matcher.ShiftMatcher` (``o``);
        without, it hands the store's columns on (``columns``) to a matcher that serves
        several lanes (``ShiftMatcher(ports=P)``, the measurement engine's way).

    Members
    -------
    i : In(stream.Signature(params.input_layout(follow, paired)))
        Camera beats, one pixel per transfer (``hdl.streams.camera_pixel_layout``, with
        ``follow`` ``hdl.streams.followed_pixel_layout``, with ``paired`` a ``paired``
        bit).
    centre : In(params.centre_fmt.shape()), without ``follow`` only
        Window centre in pixels (e.g. the shift predicted from the motion), sampled
        with each row's first pixel, saturated to ``±centre_range``.
    half_width : In(params.half_width_fmt.shape())
        Run-time half-width ``w`` of the shift window: shifts ``centre ± w`` within the
        built window, sampled with each row's first pixel; outside ``min_half_width …
        max_half_width`` (0 included) the built maximum (the engine flags it).
    o : Out(stream.Signature(params.measurement_layout())), with ``own_matcher`` only
        Measurements (formats in ``hdl.descriptor.params.row_measurement_layout``).
    columns : Out(stream.Signature(pair_layout(params))), without ``own_matcher`` only
        The matcher's input: each column's current and reference bits,
        :attr:`columns_latency` clocks after its pixel.
    out_of_range : Out(hdl.descriptor.store.COUNT_BITS), with ``follow`` only
        Rows whose source row was outside the range the ring serves (saturating).
    bits : Out(stream.Signature(descriptor_layout(params, 1))), with ``paired`` only
        The FIR's columns of the paired rows (``connect_shared_bits``), :attr:`bits_latency`
        clocks after their pixels.

    Latency :attr:`latency` clocks from a row's last pixel to its segment-0
    measurement (segment k follows k clocks later); one pixel per clock with no
    bubbles between rows. Backpressure on ``o`` (and on ``bits`` for a paired row) stalls
    the pipeline back to ``i``. Reset empties the pipeline; the reference store keeps
    its contents but every reference is invalid until a full frame has passed (tags
    start invalid).
    """

    def __init__(self, params=RowDescriptorParams(), follow=False, paired=False,
                 own_matcher=True):
        self.params = check_lane_params(params)
        self.store = ReferenceStore(params, follow)
        self.follow, self.paired = follow, paired
        self.framer = RowFramer(params, follow, paired)
        self.fir = DescriptorFIR(params)
        self.tap = StreamFork(descriptor_layout(params, 1), 2) if paired else None
        self.matcher = ShiftMatcher(params) if own_matcher else None
        members = {"i": In(stream.Signature(params.input_layout(follow, paired))),
                   "half_width": In(params.half_width_fmt.shape()),
                   **_lane_output(params, own_matcher)}
        if follow:
            members["out_of_range"] = Out(COUNT_BITS)
        else:
            members["centre"] = In(params.centre_fmt.shape())
        if paired:
            members["bits"] = Out(stream.Signature(descriptor_layout(params, 1)))
        super().__init__(members)

    @property
    def bits_latency(self):
        """Clocks from a pixel to its column on ``bits`` (the fork adds none)."""
        return self.framer.latency + self.fir.latency

    @property
    def columns_latency(self):
        """Clocks from a pixel to its column at the matcher's input."""
        return self.bits_latency + self.store.latency

    @property
    def latency(self):
        """Clocks from a row's last pixel to its segment-0 measurement (own matcher)."""
        return self.columns_latency + self.matcher.latency

    def elaborate(self, platform):
        m = Module()
        m.submodules.framer = self.framer
        m.submodules.fir = self.fir
        m.submodules.store = self.store
        wiring.connect(m, wiring.flipped(self.i), self.framer.i)
        m.d.comb += self.framer.half_width.eq(self.half_width)
        if self.follow:
            m.d.comb += self.out_of_range.eq(self.store.out_of_range)
        else:
            m.d.comb += self.framer.centre.eq(self.centre)
        wiring.connect(m, self.framer.o, self.fir.i)
        if self.paired:
            m.submodules.tap = tap = self.tap
            wiring.connect(m, self.fir.o, tap.i)
            wiring.connect(m, tap.o[0], self.store.i)
            # the stereo lane sees only paired rows; the others' columns pass it by
            shared = tap.o[1]
            paired = shared.payload.meta.paired
            m.d.comb += [self.bits.payload.eq(shared.payload),
                         self.bits.valid.eq(shared.valid & paired),
                         shared.ready.eq(self.bits.ready | ~paired)]
        else:
            wiring.connect(m, self.fir.o, self.store.i)
        _end_lane(m, self, self.store.o)
        return m


class StereoRowDescriptor(wiring.Component):
    """Stereo lane of a camera pair: disparity of camera ``a``'s row against camera
    ``b``'s row of the same time (``cur[x] ≈ ref[x − d]``: ``a`` is the left camera of a
    rectified pair). Default window ``[10, 70]`` px (``STEREO_640X480``).

    Parameters
    ----------
    params : RowDescriptorParams
    shared : bool
        Take the two rows' descriptor bits from the pair's temporal lanes
        (``RowDescriptor(paired=True).bits`` through ``connect_shared_bits``, the
        measurement engine's way: their parameters' descriptor must be these) instead
        of framing and filtering camera beats in the lane (a framer and a FIR per
        camera).
    own_matcher : bool
        As :class:`RowDescriptor`'s: without, the joined columns go out on ``columns``
        to a matcher several stereo lanes share.

    Members
    -------
    a, b : In(stream.Signature(params.input_layout())), or with ``shared``
           In(stream.Signature(descriptor_layout(params, 1)))
        Beats, or descriptor bits, of the two cameras.
    centre : In(params.centre_fmt.shape())
        Window centre, sampled with each row's first beat of ``a`` (by ``a``'s framer);
        with ``shared``, with the first column of each row of ``a`` the lane pairs with
        ``b``'s (:class:`hdl.descriptor.framer.StereoJoin`: the bits carry the temporal
        lane's centre, and the port is the pair's register).
    o : Out(stream.Signature(params.measurement_layout())), with ``own_matcher`` only
        Measurements with ``a``'s row key and ``t_first``; ``bad`` if either row was
        bad; ``no_reference`` is always 0.
    columns : Out(stream.Signature(pair_layout(params))), without ``own_matcher`` only
        The joined columns as the matcher's input (``a``'s bits current, ``b``'s
        reference).

    The stereo lane searches its whole built window (no run-time half-width).

    Latency :attr:`latency` from the later of the pair's last pixels (with ``shared``:
    last descriptor columns) to segment 0. No memory: the reference is the partner row
    itself.
    """

    def __init__(self, params=STEREO_640X480, shared=False, own_matcher=True):
        self.params = check_lane_params(params)
        self.shared = shared
        self.fronts = [] if shared else [(RowFramer(params), DescriptorFIR(params))
                                         for _ in "ab"]
        self.join = StereoJoin(params, centre_port=shared)
        self.matcher = ShiftMatcher(params) if own_matcher else None
        beat = descriptor_layout(params, 1) if shared else params.input_layout()
        super().__init__({
            "a": In(stream.Signature(beat)),
            "b": In(stream.Signature(beat)),
            "centre": In(params.centre_fmt.shape()),
            **_lane_output(params, own_matcher),
        })

    @property
    def columns_latency(self):
        """Clocks from the later of a column pair's pixels (with ``shared``: descriptor
        columns) to the joined column at the matcher's input."""
        front = sum(block.latency for block in self.fronts[0]) if self.fronts else 0
        return front + self.join.latency

    @property
    def latency(self):
        return self.columns_latency + self.matcher.latency

    def elaborate(self, platform):
        m = Module()
        m.submodules.join = join = self.join
        if self.shared:
            wiring.connect(m, wiring.flipped(self.a), join.a)
            wiring.connect(m, wiring.flipped(self.b), join.b)
        for name, (framer, fir), port, to in zip("ab", self.fronts, (self.a, self.b),
                                                 (join.a, join.b)):
            m.submodules[f"framer_{name}"] = framer
            m.submodules[f"fir_{name}"] = fir
            wiring.connect(m, wiring.flipped(port), framer.i)
            wiring.connect(m, framer.o, fir.i)
            wiring.connect(m, fir.o, to)
            # a's framer samples the centre with the row's first beat, and the rows carry
            # it to the join; the stereo window has no run-time width
            m.d.comb += [framer.centre.eq(self.centre if name == "a" else 0),
                         framer.half_width.eq(0)]
        if self.shared:
            m.d.comb += join.centre.eq(self.centre)
        joined = stream.Signature(pair_layout(self.params)).create()
        _connect_pair(m, join.o, joined)
        _end_lane(m, self, joined)
        return m

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
other instead (two framers, :class:`hdl.descriptor.framer.StereoJoin`, a two-channel
FIR, the matcher).
Conventions are ``golden.descriptor``'s; the bit-accurate model is
``emulator/row_descriptor.py``; the formats are listed in ``docs/descriptor/row_descriptor.md``.
"""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.descriptor.matcher import ShiftMatcher
from hdl.descriptor.params import STEREO_640X480, RowDescriptorParams, check_lane_params
from hdl.descriptor.store import COUNT_BITS, ReferenceStore
from hdl.descriptor.fir import DescriptorFIR
from hdl.descriptor.framer import RowFramer, StereoJoin

__all__ = ["RowDescriptor", "StereoRowDescriptor"]


def _connect_pair(m, fir, matcher):
    """A two-channel FIR's bits as the matcher's current (camera a) and reference
    (camera b) bits."""
    src, dst = fir.o, matcher.i
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

    Members
    -------
    i : In(stream.Signature(params.input_layout(follow)))
        Camera beats, one pixel per transfer (``hdl.streams.camera_pixel_layout``, with
        ``follow`` ``hdl.streams.followed_pixel_layout``).
    centre : In(params.centre_fmt.shape()), without ``follow`` only
        Window centre in pixels (e.g. the shift predicted from the motion), sampled
        with each row's first pixel, saturated to ``±centre_range``.
    half_width : In(params.half_width_fmt.shape())
        Run-time half-width ``w`` of the shift window: shifts ``centre ± w`` within the
        built window, sampled with each row's first pixel; outside ``min_half_width …
        max_half_width`` (0 included) the built maximum (the engine flags it).
    o : Out(stream.Signature(params.measurement_layout()))
        Measurements (formats in ``hdl.descriptor.params.row_measurement_layout``).
    out_of_range : Out(hdl.descriptor.store.COUNT_BITS), with ``follow`` only
        Rows whose source row was outside the range the ring serves (saturating).

    Latency :attr:`latency` clocks from a row's last pixel to its segment-0
    measurement (segment k follows k clocks later); one pixel per clock with no
    bubbles between rows. Backpressure on ``o`` stalls the pipeline back to ``i``.
    Reset empties the pipeline; the reference store keeps its contents but every
    reference is invalid until a full frame has passed (tags start invalid).
    """

    def __init__(self, params=RowDescriptorParams(), follow=False):
        self.params = check_lane_params(params)
        self.store = ReferenceStore(params, follow)
        self.follow = follow
        self.framer = RowFramer(params, follow)
        self.fir = DescriptorFIR(params)
        self.matcher = ShiftMatcher(params)
        members = {"i": In(stream.Signature(params.input_layout(follow))),
                   "half_width": In(params.half_width_fmt.shape()),
                   "o": Out(stream.Signature(params.measurement_layout()))}
        if follow:
            members["out_of_range"] = Out(COUNT_BITS)
        else:
            members["centre"] = In(params.centre_fmt.shape())
        super().__init__(members)

    @property
    def latency(self):
        return self.framer.latency + self.fir.latency + self.store.latency + \
            self.matcher.latency

    def elaborate(self, platform):
        m = Module()
        m.submodules.framer = self.framer
        m.submodules.fir = self.fir
        m.submodules.store = self.store
        m.submodules.matcher = self.matcher
        wiring.connect(m, wiring.flipped(self.i), self.framer.i)
        m.d.comb += self.framer.half_width.eq(self.half_width)
        if self.follow:
            m.d.comb += self.out_of_range.eq(self.store.out_of_range)
        else:
            m.d.comb += self.framer.centre.eq(self.centre)
        wiring.connect(m, self.framer.o, self.fir.i)
        wiring.connect(m, self.fir.o, self.store.i)
        wiring.connect(m, self.store.o, self.matcher.i)
        wiring.connect(m, self.matcher.o, wiring.flipped(self.o))
        return m


class StereoRowDescriptor(wiring.Component):
    """Stereo lane of a camera pair: disparity of camera ``a``'s row against camera
    ``b``'s row of the same time (``cur[x] ≈ ref[x − d]``: ``a`` is the left camera of a
    rectified pair). Default window ``[10, 70]`` px (``STEREO_640X480``).

    Members
    -------
    a, b : In(stream.Signature(params.input_layout()))
        Beats of the two cameras.
    centre : In(params.centre_fmt.shape())
        Window centre, sampled with the first pixel of each row of ``a``.
    o : Out(stream.Signature(params.measurement_layout()))
        Measurements with ``a``'s metadata; ``bad`` if either row was bad;
        ``no_reference`` is always 0.

    The stereo lane searches its whole built window (no run-time half-width).

    Latency :attr:`latency` from the later of the pair's last pixels to segment 0.
    No memory: the reference is the partner row itself.
    """

    def __init__(self, params=STEREO_640X480):
        self.params = check_lane_params(params)
        self.framer_a = RowFramer(params)
        self.framer_b = RowFramer(params)
        self.join = StereoJoin(params)
        self.fir = DescriptorFIR(params, channels=2)
        self.matcher = ShiftMatcher(params)
        super().__init__({
            "a": In(stream.Signature(params.input_layout())),
            "b": In(stream.Signature(params.input_layout())),
            "centre": In(params.centre_fmt.shape()),
            "o": Out(stream.Signature(params.measurement_layout())),
        })

    @property
    def latency(self):
        return self.framer_a.latency + self.join.latency + self.fir.latency + \
            self.matcher.latency

    def elaborate(self, platform):
        m = Module()
        for name in ("framer_a", "framer_b", "join", "fir", "matcher"):
            m.submodules[name] = getattr(self, name)
        wiring.connect(m, wiring.flipped(self.a), self.framer_a.i)
        wiring.connect(m, wiring.flipped(self.b), self.framer_b.i)
        m.d.comb += [self.framer_a.centre.eq(self.centre), self.framer_b.centre.eq(0),
                     self.framer_a.half_width.eq(self.params.max_half_width)]
        wiring.connect(m, self.framer_a.o, self.join.a)
        wiring.connect(m, self.framer_b.o, self.join.b)
        wiring.connect(m, self.join.o, self.fir.i)
        _connect_pair(m, self.fir, self.matcher)
        wiring.connect(m, self.matcher.o, wiring.flipped(self.o))
        return m

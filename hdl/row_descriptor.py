"""Per-camera measurement engine: pixels in, (shift, confidence) per row segment out.

A temporal lane (:class:`RowDescriptor`) chains four blocks, one pixel per clock:

1. :class:`RowFramer` cuts the camera stream into rows of exactly ``width`` pixels
   (pads short rows, drops stray beats, flags such rows bad) and samples the run-time
   shift-window centre with each row's first pixel;
2. :class:`DescriptorFIR` convolves each row with the quantized second derivative of a
   Gaussian (``RowDescriptorParams.kernel_raw``) and keeps the sign: one bit per column;
3. :class:`hdl.descriptor.store.ReferenceStore` swaps the row's bits with the bits
   of the same row of the previous frame (on-chip memory);
4. :class:`hdl.descriptor.matcher.ShiftMatcher` accumulates Hamming costs for every shift of the
   window while the row streams and, per segment, finds the best shift, its sub-pixel
   refinement and the peak-ratio confidence.

:class:`StereoRowDescriptor` matches the two cameras of a stereo pair against each
other instead (two framers, :class:`StereoJoin`, a two-channel FIR, the matcher).
Conventions are ``golden.descriptor``'s; the bit-accurate model is
``emulator/row_descriptor.py``; the formats are listed in ``docs/descriptor/row_descriptor.md``.
"""

from amaranth.hdl import Const, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import UQ, hdl_add, hdl_mul
from hdl.descriptor.matcher import ShiftMatcher
from hdl.descriptor.layouts import descriptor_layout, framed_layout
from hdl.descriptor.params import STEREO_640X480, RowDescriptorParams
from hdl.descriptor.store import ReferenceStore

__all__ = ["RowFramer", "DescriptorFIR", "StereoJoin", "RowDescriptor",
           "StereoRowDescriptor"]


def _check_params(params):
    if not isinstance(params, RowDescriptorParams):
        raise TypeError(f"params must be a RowDescriptorParams, not {params!r}")
    return params


class RowFramer(wiring.Component):
    """Rows of exactly ``width`` pixels out of a camera beat stream.

    A ``first`` beat opens a row; if the previous row is still incomplete its end is
    padded first (zero pixels, while ``i`` waits). A ``last`` before column
    ``width − 1`` makes the row short: it is padded to the width. A row whose column
    ``width − 1`` lacks ``last`` is long: it ends there and the rest is dropped, like any
    beat outside an open row. Such rows, rows with reason bits (``flags``) and rows
    indexed at or beyond ``height`` are bad; ``meta.bad`` is sticky along the row, so its
    last item carries the final verdict.

    Members
    -------
    i : In(stream.Signature(params.input_layout()))
        Camera beats (``hdl.streams.camera_pixel_layout``).
    centre : In(params.centre_fmt.shape())
        Shift-window centre, integer pixels, sampled with each row's first beat and
        saturated to ``±centre_range``.
    o : Out(stream.Signature(framed_layout(params, 1)))

    Latency 1 (output register); one beat per clock, except one clock per pad pixel.
    Backpressure: ``i`` waits while ``o`` holds an untaken column.
    """

    latency = 1

    def __init__(self, params):
        self.params = _check_params(params)
        super().__init__({
            "i": In(stream.Signature(params.input_layout())),
            "centre": In(params.centre_fmt.shape()),
            "o": Out(stream.Signature(framed_layout(params, 1))),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        beat = self.i.payload
        width = p.width

        col = Signal(range(width + 1), init=width)   # width: no incomplete row
        incomplete = Signal()                         # col != width, registered
        col_last = Signal()                           # col == width − 1, registered
        pad_mode = Signal()                           # padding a short row
        meta = Signal.like(self.o.payload.meta)

        pad_now = pad_mode | (self.i.valid & beat.first & incomplete)
        take = ~pad_now & self.i.valid & (beat.first | incomplete)
        opens = take & beat.first
        pos = Mux(opens, 0, col)
        at_end = ~opens & col_last                    # a row is wider than one pixel
        short = take & beat.last & ~at_end
        long_row = take & at_end & ~beat.last

        cr = p.centre_range
        centre = Mux(self.centre > cr, cr, Mux(self.centre < -cr, -cr, self.centre))
        item = Signal.like(self.o.payload)
        with m.If(opens):
            m.d.comb += [
                item.meta.camera.eq(beat.camera), item.meta.frame.eq(beat.frame),
                item.meta.row.eq(beat.row), item.meta.t_first.eq(beat.t_first),
                item.meta.centre.eq(centre),
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
        m.d.comb += self.i.ready.eq(advance & ~pad_now)
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


class DescriptorFIR(wiring.Component):
    """Second-derivative-of-Gaussian FIR and sign, one column per clock per channel.

    The window holds the last ``2R + 1`` pixels of the row; the symmetric kernel is
    applied as ``R + 1`` pre-added pairs times constant coefficients (raw
    ``coeff_fmt``), summed exactly (no narrowing anywhere) in a registered adder tree.
    The bit of column ``pos − R`` is ``response > 0`` and the column is strong where
    ``|response| ≥ strong_raw``; both are 0 while ``pos < 2R`` (the window is not yet
    inside the row: golden's border convention).

    Members
    -------
    i : In(stream.Signature(framed_layout(params, channels)))
    o : Out(stream.Signature(descriptor_layout(params, channels)))

    Latency :attr:`latency` clocks; one column per clock; backpressure stalls the whole
    pipeline (``i.ready`` low while ``o`` holds an untaken item). Reset clears the
    pipeline's valid bits (the window needs no reset: its first ``2R`` columns are
    masked).
    """

    def __init__(self, params, channels=1):
        self.params = _check_params(params)
        if channels not in (1, 2):
            raise ValueError(f"channels must be 1 or 2, not {channels!r}")
        self.channels = channels
        self._terms = sum(1 for q in self._pair_coeffs() if q != 0)
        super().__init__({
            "i": In(stream.Signature(framed_layout(params, channels))),
            "o": Out(stream.Signature(descriptor_layout(params, channels))),
        })

    def _pair_coeffs(self):
        """Coefficient of the centre tap, then of each symmetric pair ``±1 … ±R``."""
        k = self.params.kernel_raw()
        return k[self.params.radius:]

    @property
    def tree_levels(self):
        return max(self._terms - 1, 0).bit_length()

    @property
    def latency(self):
        """Window, pre-add, product, then one clock per adder-tree level (the last level
        registers the sign bit)."""
        return 3 + self.tree_levels

    def elaborate(self, platform):
        p = self.params
        m = Module()
        r = p.radius
        stall = self.o.valid & ~self.o.ready
        advance = ~stall
        m.d.comb += self.i.ready.eq(advance)

        # control that rides along: one record per stage, valid bit separate
        ctrl_layout = descriptor_layout(p, self.channels)
        stages = self.tree_levels + 2                 # window, pre-add, product, tree…
        valid = [Signal(name=f"valid{k}") for k in range(stages + 1)]
        ctrl = [Signal(ctrl_layout, name=f"ctrl{k}") for k in range(stages + 1)]
        item = self.i.payload
        with m.If(advance):
            m.d.sync += [valid[0].eq(self.i.valid), ctrl[0].pos.eq(item.pos),
                         ctrl[0].first.eq(item.first), ctrl[0].last.eq(item.last),
                         ctrl[0].meta.eq(item.meta)]
            for k in range(1, stages + 1):
                m.d.sync += [valid[k].eq(valid[k - 1]), ctrl[k].eq(ctrl[k - 1])]

        pixel_fmt = p.pixel_fmt
        coeffs = self._pair_coeffs()
        out_bits, out_strong = [], []
        tau = p.strong_raw()
        for ch in range(self.channels):
            window = [Signal(p.pixel_bits, name=f"w{ch}_{t}") for t in range(2 * r + 1)]
            with m.If(advance & self.i.valid):
                m.d.sync += window[0].eq(item.pixels[ch])
                m.d.sync += [window[t].eq(window[t - 1]) for t in range(1, 2 * r + 1)]
            # pre-add the symmetric pairs (registered)
            pair_fmt = UQ(pixel_fmt.int_bits + 1, 0)
            pairs = []
            for d, q in enumerate(coeffs):
                if q == 0:
                    continue
                s = Signal(pair_fmt.shape(), name=f"pair{ch}_{d}")
                value = window[r] if d == 0 else hdl_add(window[r - d], pixel_fmt,
                                                          window[r + d], pixel_fmt)[0]
                with m.If(advance):
                    m.d.sync += s.eq(value)
                pairs.append((s, q))
            # constant products (registered)
            terms = []
            for s, q in pairs:
                value, fmt = hdl_mul(s, pair_fmt, Const(q, p.coeff_fmt.shape()), p.coeff_fmt)
                prod = Signal(fmt.shape(), name=f"prod{ch}_{len(terms)}")
                with m.If(advance):
                    m.d.sync += prod.eq(value)
                terms.append((prod, fmt))
            # adder tree, one registered level per clock; the last level keeps the sign
            for level in range(self.tree_levels):
                nxt = []
                for t in range(0, len(terms), 2):
                    if t + 1 < len(terms):
                        value, fmt = hdl_add(*terms[t], *terms[t + 1])
                    else:
                        value, fmt = terms[t]
                    nxt.append((value, fmt))
                if level == self.tree_levels - 1:
                    bit, strong = Signal(name=f"bit{ch}"), Signal(name=f"strong{ch}")
                    interior = ctrl[stages - 1].pos >= 2 * r
                    total = nxt[0][0]
                    with m.If(advance):
                        m.d.sync += [bit.eq((total > 0) & interior),
                                     strong.eq(((total >= tau) | (total <= -tau)) & interior)]
                    out_bits.append(bit)
                    out_strong.append(strong)
                else:
                    regs = []
                    for value, fmt in nxt:
                        reg = Signal(fmt.shape(), name=f"sum{ch}_{level}_{len(regs)}")
                        with m.If(advance):
                            m.d.sync += reg.eq(value)
                        regs.append((reg, fmt))
                    terms = regs

        last = ctrl[stages]
        m.d.comb += [
            self.o.valid.eq(valid[stages]),
            self.o.payload.pos.eq(last.pos), self.o.payload.first.eq(last.first),
            self.o.payload.last.eq(last.last), self.o.payload.meta.eq(last.meta),
        ]
        for ch, (bit, strong) in enumerate(zip(out_bits, out_strong)):
            m.d.comb += [self.o.payload.bits[ch].eq(bit), self.o.payload.strong[ch].eq(strong)]
        return m


class StereoJoin(wiring.Component):
    """Pair the framed rows of a stereo pair column by column.

    At a row boundary the two head rows are compared: same (frame, row) → their columns
    go out together (``pixels[0]`` from ``a``, ``pixels[1]`` from ``b``; metadata from
    ``a``, ``bad`` from either); otherwise the older row (frame order modulo
    ``2**frame_bits``, then row index) is dropped whole, so one lost row does not
    misalign the pair for good.

    Members
    -------
    a, b : In(stream.Signature(framed_layout(params, 1)))
    o : Out(stream.Signature(framed_layout(params, 2)))

    Latency 1 (output register); one column pair per clock.
    """

    latency = 1

    def __init__(self, params):
        self.params = _check_params(params)
        super().__init__({
            "a": In(stream.Signature(framed_layout(params, 1))),
            "b": In(stream.Signature(framed_layout(params, 1))),
            "o": Out(stream.Signature(framed_layout(params, 2))),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        a, b = self.a.payload, self.b.payload
        mode = Signal(2)          # 0: at a boundary, 1: pairing, 2: dropping a, 3: dropping b
        both = self.a.valid & self.b.valid
        same = (a.meta.frame == b.meta.frame) & (a.meta.row == b.meta.row)
        frame_gap = (a.meta.frame - b.meta.frame)[:p.frame_bits]
        a_older = frame_gap[-1] | ((frame_gap == 0) & (a.meta.row < b.meta.row))
        pairing = (mode == 1) | ((mode == 0) & same)
        drop_a = (mode == 2) | ((mode == 0) & both & ~same & a_older)
        drop_b = (mode == 3) | ((mode == 0) & both & ~same & ~a_older)
        advance = ~self.o.valid | self.o.ready
        paired = both & pairing & advance
        m.d.comb += [
            self.a.ready.eq((pairing & self.b.valid & advance) | drop_a),
            self.b.ready.eq((pairing & self.a.valid & advance) | drop_b),
        ]
        out = self.o.payload
        with m.If(advance):
            m.d.sync += [
                self.o.valid.eq(both & pairing),
                out.pixels[0].eq(a.pixels[0]), out.pixels[1].eq(b.pixels[0]),
                out.pos.eq(a.pos), out.first.eq(a.first), out.last.eq(a.last),
                out.meta.eq(a.meta), out.meta.bad.eq(a.meta.bad | b.meta.bad),
            ]
        with m.If(paired):
            m.d.sync += mode.eq(Mux(a.last, 0, 1))
        with m.Elif(self.a.valid & drop_a):
            m.d.sync += mode.eq(Mux(a.last, 0, 2))
        with m.Elif(self.b.valid & drop_b):
            m.d.sync += mode.eq(Mux(b.last, 0, 3))
        return m


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

    Each row is matched against the same row of the previous frame; K measurements
    per row (``params.segments``).

    Parameters
    ----------
    params : RowDescriptorParams

    Members
    -------
    i : In(stream.Signature(params.input_layout()))
        Camera beats, one pixel per transfer (``hdl.streams.camera_pixel_layout``).
    centre : In(params.centre_fmt.shape())
        Window centre in pixels (e.g. the shift predicted from the motion), sampled
        with each row's first pixel, saturated to ``±centre_range``.
    o : Out(stream.Signature(params.measurement_layout()))
        Measurements (formats in ``hdl.descriptor.params.row_measurement_layout``).

    Latency :attr:`latency` clocks from a row's last pixel to its segment-0
    measurement (segment k follows k clocks later); one pixel per clock with no
    bubbles between rows. Backpressure on ``o`` stalls the pipeline back to ``i``.
    Reset empties the pipeline; the reference store keeps its contents but every
    reference is invalid until a full frame has passed (tags start invalid).
    """

    def __init__(self, params=RowDescriptorParams()):
        self.params = _check_params(params)
        self.framer = RowFramer(params)
        self.fir = DescriptorFIR(params)
        self.store = ReferenceStore(params)
        self.matcher = ShiftMatcher(params)
        super().__init__({
            "i": In(stream.Signature(params.input_layout())),
            "centre": In(params.centre_fmt.shape()),
            "o": Out(stream.Signature(params.measurement_layout())),
        })

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

    Latency :attr:`latency` from the later of the pair's last pixels to segment 0.
    No memory: the reference is the partner row itself.
    """

    def __init__(self, params=STEREO_640X480):
        self.params = _check_params(params)
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
        m.d.comb += [self.framer_a.centre.eq(self.centre), self.framer_b.centre.eq(0)]
        wiring.connect(m, self.framer_a.o, self.join.a)
        wiring.connect(m, self.framer_b.o, self.join.b)
        wiring.connect(m, self.join.o, self.fir.i)
        _connect_pair(m, self.fir, self.matcher)
        wiring.connect(m, self.matcher.o, wiring.flipped(self.o))
        return m

"""Parameters, fixed-point formats and stream layouts of the row-descriptor lane.

No Amaranth at import time: the emulator (``emulator/row_descriptor.py``), the golden
comparison and the benches read the same object as the gateware (``hdl/row_descriptor.py``,
``hdl/descriptor/store.py``, ``hdl/descriptor/matcher.py``). The conventions are those of
:mod:`golden.descriptor`; this module adds what the hardware needs on top of them: the
quantized kernel (made here, once), the formats of every result, the run-time centre
range, and the matcher's schedule.
"""

from dataclasses import dataclass, replace

from golden.checks import check_int
from golden.descriptor import STEREO_MATCH, DescriptorParams, MatchParams, dog2_kernel

from hdl.fixed import SQ, UQ, QFormat, Rounding, check_format

__all__ = ["RowDescriptorParams", "DEFAULT_SEGMENTS", "TEMPORAL_640X480", "STEREO_640X480",
           "check_lane_params", "REFERENCE_WORD_BITS"]

#: Temporal segments per row (K) of a lane, the engine and the top unless told otherwise:
#: the solver has one slot per camera and segment.
DEFAULT_SEGMENTS = 4


def _signed_bits(lo, hi):
    """Bits of the narrowest two's-complement integer holding ``lo..hi``."""
    bits = 1
    while not (-(1 << (bits - 1)) <= lo and hi <= (1 << (bits - 1)) - 1):
        bits += 1
    return bits


#: Bits per word of the reference store (a block RAM's data and parity bits): a followed
#: store switches the row it reads between segments at these words' boundaries.
REFERENCE_WORD_BITS = 36

#: D of a followed reference store (see ``max_row_displacement``).
DEFAULT_MAX_ROW_DISPLACEMENT = 31


@dataclass(frozen=True, kw_only=True)
class RowDescriptorParams:
    """One camera lane (temporal) or camera pair (stereo) of the measurement engine.

    Parameters
    ----------
    width, height : int
        Row width in pixels and rows per frame (the reference store holds
        ``height × width`` descriptor bits).
    descriptor : golden.descriptor.DescriptorParams
        σ of the second-derivative-of-Gaussian kernel.
    match : golden.descriptor.MatchParams
        Shift window (relative to the run-time centre), segments K, peak-ratio cap and
        the textureless threshold.
    coeff_frac_bits : int
        Fraction bits of the kernel coefficients, format ``SQ(2, coeff_frac_bits)``.
    subpixel_frac_bits : int
        Fraction bits of the sub-pixel shift, format ``SQ(1, subpixel_frac_bits)``.
    confidence_fmt : QFormat
        Unsigned format of the peak-ratio confidence; must hold ``peak_ratio_cap``.
    centre_range : int
        The run-time centre is saturated to ``[-centre_range, centre_range]``.
    max_row_displacement : int
        D, the largest upward row displacement ``d = y − source`` (content moving down
        the image) a followed reference store serves: its ring holds ``height + D + 1``
        rows (:attr:`ring_rows`) and serves, for row ``y``, the previous frame's rows
        ``max(0, y − D − 1) … height − 1``. Default 31: the measured row displacement of
        the papers' motion on stereo20 is at most 11 rows per frame (docs/descriptor/
        row_descriptor.md), and at 640×480 a ring of 512 rows fills the nine block RAMs
        the same-row store already uses. ``None`` (the default) means 31, or
        ``2**row_bits`` for frames too short to index that far (a short co-simulated
        window); :attr:`row_displacement` is the value in force.
    scan_lanes : int
        Costs the matcher examines per clock after a segment ends.
    pixel_bits, camera_bits, frame_bits, row_bits, timestamp_bits : int
        Widths of the camera pixel stream (``hdl.streams.camera_pixel_layout``).

    Raises
    ------
    TypeError, ValueError
        Naming the parameter; also when a row is too short for the window at some
        allowed centre, or a segment too short for the matcher to finish one segment
        before the next ends (which would cost bubbles).
    """
    width: int = 640
    height: int = 480
    descriptor: DescriptorParams = DescriptorParams()
    match: MatchParams = MatchParams(segments=DEFAULT_SEGMENTS)
    coeff_frac_bits: int = 16
    subpixel_frac_bits: int = 6
    confidence_fmt: QFormat = UQ(2, 6)
    centre_range: int = 32
    max_row_displacement: int = None
    scan_lanes: int = 4
    pixel_bits: int = 8
    camera_bits: int = 3
    frame_bits: int = 16
    row_bits: int = 10
    timestamp_bits: int = 32

    def __post_init__(self):
        check_int("width", self.width, 8)
        check_int("height", self.height, 1)
        if not isinstance(self.descriptor, DescriptorParams):
            raise TypeError(f"descriptor must be a DescriptorParams, not {self.descriptor!r}")
        if not isinstance(self.match, MatchParams):
            raise TypeError(f"match must be a MatchParams, not {self.match!r}")
        check_int("coeff_frac_bits", self.coeff_frac_bits, 2, 20)
        check_int("subpixel_frac_bits", self.subpixel_frac_bits, 1, 12)
        check_format("confidence_fmt", self.confidence_fmt, signed=False)
        if self.match.peak_ratio_cap > self.confidence_fmt.max_value:
            raise ValueError(f"confidence_fmt {self.confidence_fmt} cannot hold "
                             f"peak_ratio_cap {self.match.peak_ratio_cap}")
        check_int("centre_range", self.centre_range, 0)
        check_int("scan_lanes", self.scan_lanes, 1, 16)
        check_int("pixel_bits", self.pixel_bits, 1, 16)
        check_int("camera_bits", self.camera_bits, 1, 8)
        check_int("frame_bits", self.frame_bits, 1, 32)
        check_int("row_bits", self.row_bits, 1, 16)
        check_int("timestamp_bits", self.timestamp_bits, 1, 64)
        if self.max_row_displacement is not None:
            check_int("max_row_displacement", self.max_row_displacement, 0, 1 << self.row_bits)
        if self.height > 1 << self.row_bits:
            raise ValueError(f"row_bits {self.row_bits} cannot index {self.height} rows")
        if self.n_shifts < 4:
            raise ValueError(f"the shift window must hold at least 4 shifts (so a second "
                             f"minimum exists), not {self.n_shifts}")
        for centre in (-self.centre_range, self.centre_range):
            lo, hi = self.compare_range(centre)
            if hi - lo < 2 * self.segments:
                raise ValueError(f"width {self.width} leaves {max(hi - lo, 0)} columns to "
                                 f"compare at centre {centre}, too few for "
                                 f"{self.segments} segment(s)")
            if (hi - lo) // self.segments < self.engine_period:
                raise ValueError(f"width {self.width}: segments of {(hi - lo) // self.segments} "
                                 f"columns at centre {centre} are shorter than the "
                                 f"{self.engine_period} clocks the matcher needs per "
                                 f"segment; use fewer segments, more scan_lanes or a "
                                 f"smaller centre_range")

    replace = replace

    # --- geometry (golden.descriptor conventions, centre saturated) ---------------------

    @property
    def radius(self):
        return self.descriptor.radius

    @property
    def n_shifts(self):
        return self.match.n_shifts

    @property
    def segments(self):
        return self.match.segments

    @property
    def row_displacement(self):
        """D in force: ``max_row_displacement``, or its default for this frame."""
        if self.max_row_displacement is not None:
            return self.max_row_displacement
        return min(DEFAULT_MAX_ROW_DISPLACEMENT, 1 << self.row_bits)

    @property
    def ring_rows(self):
        """Rows of a followed reference store's ring: ``height + D + 1``."""
        return self.height + self.row_displacement + 1

    def source_in_range(self, row, source):
        """Whether a followed store serves row ``source`` of the previous frame to row
        ``row``: ``0 ≤ source < height`` and ``row − source ≤ D + 1`` (the ring slot of
        ``source`` is rewritten by row ``source + D + 1``, which reads it first)."""
        return 0 <= source < self.height and row - source <= self.row_displacement + 1

    @property
    def reference_words(self):
        """Words of a stored reference row: columns ``0 … width − R − 1``, each word
        ``REFERENCE_WORD_BITS`` columns."""
        return -(-(self.width - self.radius) // REFERENCE_WORD_BITS)

    @property
    def segment_starts(self):
        """Current-row columns where segments ``1 … K − 1`` begin at centre 0 (the
        bounds of ``golden.descriptor.segment_bounds``), the followed store's switches."""
        lo, hi = self.compare_range(0)
        return tuple(lo + (hi - lo) * i // self.segments for i in range(1, self.segments))

    def word_segments(self, centre):
        """The segment whose row a followed reference store reads each stored word from
        (tuple, one per word of :attr:`reference_words`): word ``q`` (columns ``36q …
        36q + 35``) is the reference that current column ``36q + 18 + centre`` (its
        middle, at the window's centre shift) is compared with, and goes with that
        column's segment by :attr:`segment_starts`. ``centre`` is the saturated centre."""
        half = REFERENCE_WORD_BITS // 2
        return tuple(sum(REFERENCE_WORD_BITS * q + half + centre >= start
                         for start in self.segment_starts)
                     for q in range(self.reference_words))

    def column_segments(self, centre):
        """:meth:`word_segments` per column ``0 … width − 1`` (tuple): each column the
        segment of its word; the border columns after the last stored word take the
        last word's."""
        words = self.word_segments(centre)
        return tuple(words[min(x // REFERENCE_WORD_BITS, len(words) - 1)]
                     for x in range(self.width))

    def clamp_centre(self, centre):
        """The centre the hardware uses: saturated to ``±centre_range``."""
        return int(max(-self.centre_range, min(self.centre_range, int(centre))))

    def compare_range(self, centre):
        """Compared columns ``[lo, hi)`` at ``centre`` (as ``golden.descriptor``)."""
        a = self.clamp_centre(centre) + self.match.shift_min
        return (self.radius + max(a + self.n_shifts - 1, 0),
                self.width - self.radius + min(a, 0))

    # --- run-time search-window half-width -------------------------------------------------

    @property
    def max_half_width(self):
        """The built maximum of the run-time half-width ``w``: the window ``[−w, w]``
        around the centre covers the built window ``[shift_min, shift_max]``."""
        return max(-self.match.shift_min, self.match.shift_max, 0)

    @property
    def min_half_width(self):
        """The smallest run-time half-width whose window ``[−w, w] ∩ [shift_min,
        shift_max]`` holds 4 shifts (as the built window must, so that a second minimum
        at distance ≥ 2 exists wherever the first lies)."""
        w = 1
        while self._window_size(w) < 4:
            w += 1
        return w

    def _window_size(self, w):
        first, last = self.window_indices(w)
        return last - first + 1

    @property
    def half_width_fmt(self):
        """The run-time half-width port: an unsigned integer wide enough for
        :attr:`max_half_width` (larger values it can hold are out of range)."""
        return UQ(self.max_half_width.bit_length(), 0)

    def saturate_half_width(self, w):
        """``(w in force, out of range)``: ``w`` if ``min_half_width ≤ w ≤
        max_half_width``, else the built maximum (and ``True``: counted, never silent)."""
        w = int(w)
        if self.min_half_width <= w <= self.max_half_width:
            return w, False
        return self.max_half_width, True

    def window_indices(self, w):
        """Cost indices ``(first, last)`` (0 … n_shifts − 1, shift ``shift_min + i``)
        of the run-time window ``[−w, w] ∩ [shift_min, shift_max]`` around the centre;
        ``(0, n_shifts − 1)`` at :attr:`max_half_width`."""
        m = self.match
        return max(0, -w - m.shift_min), min(self.n_shifts - 1, w - m.shift_min)

    def delays(self, centre):
        """``(current, reference)`` delays in columns that line up ``cur[x]`` with
        ``ref[x − centre − shift_min]``; one of them is zero."""
        a = self.clamp_centre(centre) + self.match.shift_min
        return max(0, -a), max(0, a)

    @property
    def max_delays(self):
        """The largest ``(current, reference)`` delays over the centre range."""
        return self.delays(-self.centre_range)[0], self.delays(self.centre_range)[1]

    # --- formats ------------------------------------------------------------------------

    @property
    def pixel_fmt(self):
        return UQ(self.pixel_bits, 0)

    @property
    def coeff_fmt(self):
        """Kernel coefficients: SQ(2, f), room for the zero-sum correction of the centre
        tap (its float value is −1)."""
        return SQ(2, self.coeff_frac_bits)

    def kernel_raw(self):
        """The quantized kernel, raw ``coeff_fmt`` integers (``2R + 1`` taps).

        The one place the coefficients are made: ``golden.descriptor.dog2_kernel``
        rounded half-even, then the rounding residue moved onto the centre tap so the
        taps sum to exactly zero (a flat row gives a zero response, hence bit 0,
        as in the float model). Symmetric, like the float kernel.
        """
        raw = self.coeff_fmt.quantize(dog2_kernel(self.descriptor), Rounding.HALF_EVEN)
        raw[self.radius] -= raw.sum()
        self.coeff_fmt.raw(raw)  # the corrected centre tap must still fit
        return tuple(int(v) for v in raw)

    @property
    def strong_fmt(self):
        """Response magnitude threshold (``descriptor.strong_response``) in the raw scale
        of the quantized kernel's response."""
        return UQ(self.pixel_bits + 4, self.coeff_frac_bits)

    def strong_raw(self):
        """``strong_response`` as a raw ``strong_fmt`` integer (quantized once)."""
        return int(self.strong_fmt.quantize(self.descriptor.strong_response, Rounding.HALF_EVEN))

    @property
    def max_segment_cost(self):
        """The largest Hamming cost of one shift over one segment: the longest segment
        at any centre the hardware uses (``⌈(hi − lo) / K⌉`` columns of
        :meth:`compare_range`; the bounds ``lo + (hi − lo)·k // K`` differ by at most
        that)."""
        k, r = self.segments, self.centre_range
        return max(-(-(hi - lo) // k)
                   for lo, hi in map(self.compare_range, range(-r, r + 1)))

    @property
    def cost_fmt(self):
        """Hamming cost of one shift over one segment, wide enough that its all-ones
        value (the matcher's ``top``, read for shifts outside the run-time window) is
        above :attr:`max_segment_cost`."""
        return UQ((self.max_segment_cost + 1).bit_length(), 0)

    @property
    def centre_fmt(self):
        """The run-time centre port: an integer wide enough for ``±centre_range``."""
        return SQ(_signed_bits(-self.centre_range, self.centre_range), 0)

    @property
    def shift_fmt(self):
        """Integer shift ``d*`` (pixels) over every centre and window position."""
        return SQ(_signed_bits(self.match.shift_min - self.centre_range,
                               self.match.shift_max + self.centre_range), 0)

    @property
    def subpixel_fmt(self):
        """Sub-pixel refinement δ ∈ [−0.5, 0.5]."""
        return SQ(1, self.subpixel_frac_bits)

    @property
    def transition_bits(self):
        """Width of the saturating per-segment bit-change counter."""
        return max(self.match.min_transitions, 1).bit_length()

    @property
    def strong_bits(self):
        """Width of the saturating per-segment strong-column counter."""
        return max(self.match.min_strong, 1).bit_length()

    @property
    def segment_bits(self):
        return max(self.segments - 1, 1).bit_length()

    def cap_raw(self):
        """``peak_ratio_cap`` as a raw ``confidence_fmt`` integer (quantized once)."""
        return int(self.confidence_fmt.quantize(self.match.peak_ratio_cap, Rounding.HALF_EVEN))

    # --- matcher schedule (hdl/descriptor/matcher.py builds it from these numbers) -----------------

    @property
    def scan_groups(self):
        """Clocks per pass over the costs, ``scan_lanes`` costs per clock."""
        return -(-self.n_shifts // self.scan_lanes)

    @property
    def ratio_quotient_bits(self):
        """Quotient bits of c₂/c₁ before rounding: the confidence format plus one."""
        return self.confidence_fmt.int_bits + self.confidence_fmt.frac_bits + 1

    @property
    def subpixel_quotient_bits(self):
        """Quotient bits of |δ| ≤ ½ with one fraction bit more than the output."""
        return self.subpixel_frac_bits + 1

    @property
    def engine_result_step(self):
        """Clocks from a segment's last column entering the cost counters to its result
        being stored. With G = :attr:`scan_groups` and Q the longer quotient: pass 1
        reads groups at steps 1 … G, takes each group's minimum one step later and
        folds it the step after; pass 2 reads at G + 2 … 2G + 1 (once the first minimum
        is final), then marks, reduces and folds in three more steps; the dividers load
        at 2G + 5 and run Q steps; one step rounds, one stores."""
        quotient = max(self.ratio_quotient_bits, self.subpixel_quotient_bits)
        return 2 * self.scan_groups + 7 + quotient

    @property
    def engine_period(self):
        """Clocks the matcher is busy per segment; shorter segments would stall input."""
        return self.engine_result_step + 1

    # --- stream layouts (Amaranth imported only when asked for) -------------------------

    def input_layout(self, follow=False, paired=False):
        """The camera pixel stream this lane consumes (one pixel per transfer); with
        ``follow`` each beat also carries its row's window centre and its segments'
        source rows (``hdl.streams.followed_pixel_layout``); with ``paired`` a ``paired``
        bit, sampled with the row's first beat: the row also goes to the pair's stereo
        lane (``hdl.row_descriptor.RowDescriptor``)."""
        from amaranth.lib import data

        from hdl.streams import camera_pixel_layout, followed_pixel_layout
        camera = {"pixel_bits": self.pixel_bits, "camera_bits": self.camera_bits,
                  "frame_bits": self.frame_bits, "row_bits": self.row_bits,
                  "timestamp_bits": self.timestamp_bits}
        if follow:
            layout = followed_pixel_layout(centre_fmt=self.centre_fmt,
                                           segments=self.segments, **camera)
        else:
            layout = camera_pixel_layout(**camera)
        return data.StructLayout({**layout.members, "paired": 1}) if paired else layout

    def measurement_layout(self):
        """The measurement stream (one transfer per segment per row)."""
        from hdl.streams import row_measurement_layout
        return row_measurement_layout(
            camera_bits=self.camera_bits, frame_bits=self.frame_bits,
            row_bits=self.row_bits, timestamp_bits=self.timestamp_bits,
            segment_bits=self.segment_bits, shift_fmt=self.shift_fmt,
            subpixel_fmt=self.subpixel_fmt, confidence_fmt=self.confidence_fmt)


#: One 640×480 camera, temporal matching over [−20, 20] around the centre, 4 segments.
TEMPORAL_640X480 = RowDescriptorParams()

#: A 640×480 stereo pair, disparity [10, 70] px around the centre, one segment.
STEREO_640X480 = RowDescriptorParams(match=STEREO_MATCH)


def check_lane_params(params):
    """``params`` if it is a :class:`RowDescriptorParams` (every lane block takes one),
    else ``TypeError`` naming it."""
    if not isinstance(params, RowDescriptorParams):
        raise TypeError(f"params must be a RowDescriptorParams, not {params!r}")
    return params

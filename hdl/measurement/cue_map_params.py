"""The depth cue of each temporal segment: where its columns are, in the stereo lane's.

Plain Python, no Amaranth: the one definition of the cue map's constants and formats,
read by the model (:mod:`emulator.measurement.cue_map`) and the gateware
(:mod:`hdl.measurement.cue_map`).

Why. The stereo lane compares camera A's columns from its own first comparable column
on (its window reaches further: on stereo20 the stereo segments start at column 76, the
temporal ones at 26), and camera B sees every point ``d`` columns further left than A.
Taking stereo segment ``k·K_s // K``'s disparity for temporal segment ``k`` of both
cameras therefore gives each segment the depth of other columns, a bias of 7e-5 rad in
θx on the papers' motion (docs/e2e_gap.md section 9). The map instead interpolates the
pair's stereo cues linearly at the segment's **centre column** (centre 0), as camera A
sees it: camera A's own centre, and camera B's centre moved right by the cue there
(a fixed point, reached in :data:`B_PASSES` passes).

Arithmetic (raw integers of the formats below, bit-exact in model and gateware):

1. Position ``X`` (:attr:`CueMap.position_fmt`, twice the column, the cue's fraction
   bits): ``(T_k << f) + 2·shift`` with ``T_k`` twice segment ``k``'s centre
   (``lo + hi − 1``) and ``shift`` 0 for camera A, camera A's mapped cue for camera B.
2. Clamped into ``[S_0, S_last]`` (twice the stereo segments' centres, ``<< f``): no
   extrapolation beyond the end centres.
3. Interval ``j`` = the number of inner centres ``S_1 … S_{K_s−2}`` at or left of ``X``;
   distance ``d = X − S_j`` (:attr:`CueMap.distance_fmt`, ``0 ≤ d ≤ S_{j+1} − S_j``).
4. Weight ``w = d · R_j`` floored into :data:`WEIGHT_FMT` (``0 ≤ w ≤ 1``), ``R_j`` the
   interval's reciprocal ``1 / (S_{j+1} − S_j)`` floored into
   :attr:`CueMap.reciprocal_fmt` (segments are equal parts of the row up to a column,
   so the pitches differ by one and each interval has its constant).
5. Both cues usable: ``c_j + w·(c_{j+1} − c_j)`` exact, rounded half-even into
   ``cue_fmt``; the convex combination cannot overflow (the model raises if it did).
   One usable: that one. None: no cue (the segment gets no weight). With one stereo
   segment every temporal segment takes it.
6. **Coverage.** A segment whose final position ``X`` (step 1 before the clamp: camera
   A's centre, camera B's after its last pass) lies outside ``[F, L]``, twice the stereo
   lane's first and last compared columns (:attr:`CueMap.first`, :attr:`CueMap.last`,
   ``<< f``), has no cue, whatever the clamped interpolation gave: the stereo lane
   measures no depth there (on stereo20 camera A's temporal segment 0, columns 26–98,
   lies two thirds left of column 76), and the end segment's cue, measured 50–100
   columns away, biased the floor pair's Ty by a pattern repeated every frame
   (docs/e2e_gap.md section 12). Golden (b) takes no measurement there either (too few
   pixels with depth). Camera B's passes still move by the clamped cues; only the final
   cue is dropped.
"""

from dataclasses import dataclass

from golden.descriptor import segment_bounds

from hdl.fixed import Rounding, QFormat, SQ, UQ, check_format
from hdl.descriptor.params import RowDescriptorParams

__all__ = ["CueMap", "WEIGHT_FMT", "B_PASSES"]

#: Camera B's passes: it sees the point at A's column ``u_A = u_B + d(u_A)``; pass 1
#: moves its centre by camera A's cue there (``d`` at ``u_B``, off by ``d``'s change
#: over ``d`` columns), pass 2 by pass 1's cue (off by the change over that error).
B_PASSES = 2

#: The interpolation weight: 16 fraction bits, an error of at most 2**-16 of the two
#: cues' difference (below the 1/1024-pixel cue step for differences under 64 px).
WEIGHT_FMT = UQ(1, 16)
#: Fraction bits of the reciprocals beyond the weight's and the pitch's: the floored
#: reciprocal's error moves ``w`` by less than 2**-(16 + GUARD_BITS).
GUARD_BITS = 4


def _doubled_centres(lane):
    return tuple(lo + hi - 1 for lo, hi in segment_bounds(lane.width, lane.descriptor,
                                                          lane.match))


@dataclass(frozen=True, kw_only=True)
class CueMap:
    """Constants and formats of the cue map of one (temporal, stereo) lane pair.

    Build with :meth:`for_lanes`. Attributes: ``temporal`` (``T_k``, twice the temporal
    segments' centre columns at centre 0), ``stereo`` (``S_j``, the stereo segments'),
    ``first`` and ``last`` (``F``, ``L``: twice the stereo lane's first and last compared
    columns),
    ``reciprocal`` (raw ``R_j`` in ``reciprocal_fmt``, one per interval), and the
    formats ``cue_fmt``, ``position_fmt``, ``distance_fmt``, ``reciprocal_fmt``,
    ``difference_fmt`` (``c_{j+1} − c_j``).
    """
    temporal: tuple
    stereo: tuple
    first: int
    last: int
    reciprocal: tuple
    cue_fmt: QFormat
    position_fmt: QFormat
    distance_fmt: QFormat
    reciprocal_fmt: QFormat
    difference_fmt: QFormat

    @classmethod
    def for_lanes(cls, temporal, stereo, cue_fmt):
        """The map of temporal lane parameters ``temporal`` and stereo ones ``stereo``
        (:class:`~hdl.descriptor.params.RowDescriptorParams`) for cues in ``cue_fmt``
        (unsigned)."""
        for name, lane in (("temporal", temporal), ("stereo", stereo)):
            if not isinstance(lane, RowDescriptorParams):
                raise TypeError(f"{name} must be a RowDescriptorParams, not {lane!r}")
        check_format("cue_fmt", cue_fmt, signed=False)
        t, s = _doubled_centres(temporal), _doubled_centres(stereo)
        compared = segment_bounds(stereo.width, stereo.descriptor, stereo.match)
        f = cue_fmt.frac_bits
        pitches = [b - a for a, b in zip(s, s[1:])]
        widest = max(pitches, default=1)
        top = max(t) + 2 * (1 << cue_fmt.int_bits)
        reciprocal_fmt = UQ(0, WEIGHT_FMT.frac_bits + widest.bit_length() + GUARD_BITS)
        return cls(
            temporal=t, stereo=s, first=2 * compared[0][0], last=2 * (compared[-1][1] - 1),
            reciprocal=tuple(int(reciprocal_fmt.quantize(1 / p, Rounding.FLOOR))
                             for p in pitches),
            cue_fmt=cue_fmt, position_fmt=UQ(top.bit_length(), f),
            distance_fmt=UQ(widest.bit_length(), f), reciprocal_fmt=reciprocal_fmt,
            difference_fmt=SQ(cue_fmt.int_bits + 1, f))

    def covered(self, position):
        """Whether raw position ``position`` (``position_fmt``) is within the stereo
        lane's compared columns (step 6): a plain int, or an Amaranth value."""
        f = self.cue_fmt.frac_bits
        return (position >= self.first << f) & (position <= self.last << f)

    @property
    def segments(self):
        """K, the temporal segments."""
        return len(self.temporal)

    @property
    def stereo_segments(self):
        """K_s, the stereo segments."""
        return len(self.stereo)

"""Parameters of the measurement router (row-descriptor lanes → pose solver).

Plain Python, no Amaranth: :mod:`emulator.measurement.router` (the bit-accurate model)
and :mod:`hdl.measurement.router` (the gateware) build from the same object.
"""

import math
from dataclasses import dataclass, field, replace

from golden.checks import check_int, check_number
from golden.depth import DEFAULT_RANGE, DepthRange
from golden.descriptor import STEREO_MATCH

from hdl.pose.params import PoseSolverParams
from hdl.descriptor.params import RowDescriptorParams
from hdl.measurement.cue_map_params import CueMap

__all__ = ["RouterParams", "StereoWindow"]


@dataclass(frozen=True)
class StereoWindow:
    """The stereo lanes' disparity search window and which of its results give a depth.

    A stereo measurement gives a cue only when its integer disparity lies in
    :attr:`accepted` (the window less ``guard`` pixels at each end: a best cost in a
    guard band or on the edge means the surface may lie outside the depth range, issue
    18), its peak ratio is at least ``min_ratio`` (and not 0: textureless) and its
    refined disparity is positive. The default is the fixed [10, 70] window of
    :data:`golden.descriptor.STEREO_MATCH` with no guard and no ratio bound (a top built
    without a rig); :meth:`for_pairs` derives one from a rig's pairs as the golden
    tracker's :class:`golden.depth.StereoDepth` does, without the golden's peak-ratio
    bound by default (docs/measurement/measurement_router.md, "Stereo window": on the
    hardware's wider segments it removed more good cues than bad ones).

    Parameters
    ----------
    shift_min, shift_max : int
        Disparity search window (pixels, centre 0).
    guard : int
        Pixels at each end of the window whose best cost gives no depth.
    min_ratio : float
        Smallest peak ratio (the stereo lane's confidence) that gives a depth.
    """
    shift_min: int = STEREO_MATCH.shift_min
    shift_max: int = STEREO_MATCH.shift_max
    guard: int = 0
    min_ratio: float = 0.0

    def __post_init__(self):
        check_int("shift_min", self.shift_min)
        check_int("shift_max", self.shift_max, self.shift_min + 3)
        check_int("guard", self.guard, 0)
        low, high = self.accepted
        if high < low:
            raise ValueError(f"guard {self.guard} leaves no disparity of the window "
                             f"[{self.shift_min}, {self.shift_max}] accepted")
        check_number("min_ratio", self.min_ratio, 0)

    replace = replace

    @classmethod
    def for_pairs(cls, focal_baselines, depth_range=DEFAULT_RANGE, min_ratio=0.0):
        """The window of pairs with these ``f·b`` (pixels): the union of
        ``depth_range``'s per-pair windows (the lanes share one), its guard, and
        ``min_ratio`` (the golden's is :data:`golden.depth.MIN_PEAK_RATIO`).
        ``ValueError`` without a pair."""
        if not isinstance(depth_range, DepthRange):
            raise TypeError(f"depth_range must be a DepthRange, not {depth_range!r}")
        windows = [depth_range.window(fb) for fb in focal_baselines]
        if not windows:
            raise ValueError("focal_baselines must name at least one stereo pair")
        return cls(shift_min=min(lo for lo, _ in windows),
                   shift_max=max(hi for _, hi in windows), guard=depth_range.guard,
                   min_ratio=min_ratio)

    @property
    def accepted(self):
        """Integer disparities ``(low, high)`` that give a depth."""
        return self.shift_min + self.guard, self.shift_max - self.guard

    def match(self, segments):
        """The stereo lanes' matcher parameters with ``segments`` segments."""
        return replace(STEREO_MATCH, shift_min=self.shift_min, shift_max=self.shift_max,
                       segments=segments)

    def min_confidence_raw(self, confidence_fmt):
        """The smallest raw ``confidence_fmt`` confidence that gives a depth: at least
        ``min_ratio`` and never 0 (textureless). ``ValueError`` if the format cannot
        reach ``min_ratio``."""
        raw = math.ceil(self.min_ratio * (1 << confidence_fmt.frac_bits))
        if raw > confidence_fmt.max_raw:
            raise ValueError(f"min_ratio {self.min_ratio} is beyond the stereo lanes' "
                             f"confidence_fmt {confidence_fmt}")
        return max(raw, 1)


@dataclass(frozen=True, kw_only=True)
class RouterParams:
    """What the router needs: the two blocks' parameters and the stereo pairing.

    Parameters
    ----------
    cameras : int
        Number of cameras (temporal lanes); slots are ``cameras × segments``.
    pairs : tuple of (int, int)
        Stereo pairs ``(A, B)`` in stereo-lane order (A: the camera whose row is the
        lane's current row). Every camera belongs to exactly one pair.
    temporal, stereo : RowDescriptorParams
        The temporal and the stereo lanes' parameters (segments, shift and sub-pixel
        formats).
    solver : PoseSolverParams
        The solver's parameters (``slots``, input formats, ``time_bits``).
    cue_fallback : bool
        A stereo segment whose match fails lends its pair's last usable cue of the same
        row (the closed loop's, issue 16 item 4): a store of ``pairs × K_s × height``
        cues. Default off (no store).
    stereo_window : StereoWindow
        Which stereo measurements give a depth; its window must be ``stereo.match``'s.

    Attributes
    ----------
    pair_of : dict
        Each camera's pair, by its camera A.
    cue_map : hdl.measurement.cue_map_params.CueMap
        How each temporal segment's cue comes from its pair's stereo cues.

    Raises
    ------
    TypeError, ValueError
        Naming the parameter.
    """
    cameras: int
    pairs: tuple
    temporal: RowDescriptorParams
    stereo: RowDescriptorParams
    solver: PoseSolverParams
    cue_fallback: bool = False
    stereo_window: StereoWindow = StereoWindow()
    pair_of: dict = field(init=False, repr=False, compare=False)
    cue_map: CueMap = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        check_int("cameras", self.cameras, 1)
        for name in ("temporal", "stereo"):
            if not isinstance(getattr(self, name), RowDescriptorParams):
                raise TypeError(f"{name} must be a RowDescriptorParams, not "
                                f"{getattr(self, name)!r}")
        if not isinstance(self.solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {self.solver!r}")
        if not isinstance(self.cue_fallback, bool):
            raise TypeError(f"cue_fallback must be a bool, not {self.cue_fallback!r}")
        self._check_stereo_window()
        for name in ("frame_bits", "row_bits"):
            if getattr(self.stereo, name) != getattr(self.temporal, name):
                raise ValueError(f"stereo.{name} must equal temporal.{name} = "
                                 f"{getattr(self.temporal, name)}, not "
                                 f"{getattr(self.stereo, name)}")
        if self.solver.row_bits < self.temporal.row_bits:
            raise ValueError(f"solver.row_bits must be at least temporal.row_bits = "
                             f"{self.temporal.row_bits}, not {self.solver.row_bits}")
        slots = self.cameras * self.temporal.segments
        if self.solver.slots != slots:
            raise ValueError(f"solver.slots must be cameras × segments = {slots}, not "
                             f"{self.solver.slots}")
        pair_of = {}
        for index, pair in enumerate(self.pairs):
            if len(pair) != 2 or pair[0] == pair[1]:
                raise ValueError(f"pairs[{index}] must be two different cameras, not {pair!r}")
            for camera in pair:
                if not 0 <= camera < self.cameras:
                    raise ValueError(f"pairs[{index}] names camera {camera}, outside "
                                     f"0 … {self.cameras - 1}")
                if camera in pair_of:
                    raise ValueError(f"pairs: camera {camera} is in more than one pair")
                pair_of[camera] = pair[0]
        missing = sorted(set(range(self.cameras)) - set(pair_of))
        if missing:
            raise ValueError(f"pairs must give every camera a stereo pair; cameras "
                             f"{missing} have none")
        object.__setattr__(self, "pair_of", pair_of)
        object.__setattr__(self, "cue_map", CueMap.for_lanes(self.temporal, self.stereo,
                                                             self.solver.cue_fmt))

    def _check_stereo_window(self):
        window, match = self.stereo_window, self.stereo.match
        if not isinstance(window, StereoWindow):
            raise TypeError(f"stereo_window must be a StereoWindow, not {window!r}")
        if (window.shift_min, window.shift_max) != (match.shift_min, match.shift_max):
            raise ValueError(f"stereo_window [{window.shift_min}, {window.shift_max}] must "
                             f"be the stereo lanes' window [{match.shift_min}, "
                             f"{match.shift_max}]")
        self.depth_limits()                                         # raises if unreachable

    def depth_limits(self):
        """``(least confidence raw, lowest, highest integer disparity)`` of a stereo
        measurement that gives a depth (``stereo_window`` on the stereo lanes'
        ``confidence_fmt``): the model's and the gateware's one rule."""
        window = self.stereo_window
        return (window.min_confidence_raw(self.stereo.confidence_fmt), *window.accepted)

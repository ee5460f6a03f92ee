"""Parameters and result of the golden tracker (:mod:`golden.tracker`)."""

from dataclasses import dataclass, replace

import numpy as np

from .checks import check_int, check_number
from .descriptor import DescriptorParams, MatchParams
from .temporal_filter import SCALE_CEILING

__all__ = ["REFERENCES", "DEPTHS", "SOLVERS", "MOTION_GAINS", "DEFAULT_MOTION_GAIN", "POSE_ALPHA",
           "DISPARITY_SIGMA", "SHIFT_SIGMA", "BOUNDARIES", "TrackerParams", "TrackResult"]

REFERENCES = ("homography", "previous")
DEPTHS = ("auto", "stereo", "overlap", "oracle")
SOLVERS = ("linear", "nonlinear")
MOTION_GAINS = ("information", "scalar")
#: The gain law of the golden tracker and of the hardware's forecast unless told otherwise:
#: with the scalar gain 8-camera rigs such as the board rig diverge (docs/board_rig.md).
DEFAULT_MOTION_GAIN = "information"
#: The pose track's pull towards each measured pose (``TrackerParams.pose_alpha``; the
#: hardware's motion track takes the same default).
POSE_ALPHA = 0.02
#: The depth-sensitivity weight's disparity error and matching error, pixels
#: (``TrackerParams.disparity_sigma``, ``.shift_sigma``; the hardware's consistency stage
#: takes their ratio).
DISPARITY_SIGMA, SHIFT_SIGMA = 1.0, 0.3
BOUNDARIES = ("partial", "none")


@dataclass(frozen=True, kw_only=True)
class TrackerParams:
    """Parameters of the golden tracker (defaults: ``docs/tracker.md`` gives the reasons).

    Parameters
    ----------
    reference : str
        ``"homography"`` (a: rotation-compensated previous frame, the papers') or
        ``"previous"`` (b: the previous frame's stored descriptor rows).
    reselect_angle : float
        (a) Rotation (rad) since the reference rotation that forces a new one.
    parallax : bool
        (a) Also compensate the translation's parallax when reading the reference, with
        the current depth (off: the papers' rotation-only compensation).
    follow_rows : bool
        (b) Read the stored row the content is predicted to come from instead of the
        same row index.
    follow_segments : bool
        (b, with ``follow_rows``) One row address per segment: each segment's points are
        compared in the row they are predicted to have moved to, its own mean vertical
        displacement (a rotation about the optical axis or the row direction tilts the
        displacement along the row by several rows; compared in one row, the segments
        far from the row's mean see texture from the wrong rows and under-read their
        shifts). The reference row is put together from the segments' rows: column
        ``j`` from the row of the segment that column ``j + centre`` of the current row
        belongs to. Off: one address per camera row, the mean over the row.
    sigma : float
        Descriptor σ (pixels).
    strong_test : bool
        Also call a segment textureless when it has too few strong columns (the matcher's
        optional flat-row test; off: bit transitions only).
    window : int
        Half-width of the temporal shift window (pixels), centred on the prediction.
    segments : int
        Segments (equations) per camera row.
    depth : str
        ``"stereo"`` (pair disparity), ``"overlap"`` (depth maps bootstrapped from
        neighbouring cameras), ``"oracle"`` (the simulator's true depth — ablations
        only) or ``"auto"`` (stereo if the rig has rectified pairs, else overlap).
    disparity_blocks : int
        Disparity segments per row (stereo).
    min_depth_fraction : float
        Share of a segment's pixels that need a depth for the segment to count.
    alpha, beta : float
        Holt–Winters level and trend smoothing of the per-slot motion.
    motion_gain : str
        Gain of the motion filter's level update: ``"information"`` (the matrix gain of
        :func:`golden.temporal_filter.information_gain`) or ``"scalar"`` (plain α, the
        hardware forecast's simplification).
    loop_delay_rows : int
        Loop delay (row periods): a slot's forecast (window centres, followed rows, the
        linearisation and the outlier test) only includes the steps of slots solved at
        least this long before the slot starts, as with a hardware solver whose step
        arrives after later rows have started (0: every earlier slot's step).
    pose_alpha : float
        How far a typical slot's pose moves from the pose carried on from the previous
        slot (at the forecast rate) towards the pose its measurements give.
    huber_k : float
        Huber threshold (robust scales).
    scale_initial, scale_floor : float
        Robust scale of the shift innovations at the start and its floor (pixels).
    scale_smoothing : float
        λ of the robust scale recursion.
    scale_ceiling : float
        Largest robust scale (pixels): a persistent bias raises the scale until it is
        accepted; capped, it stays an outlier.
    disparity_sigma : float
        Disparity error (pixels) assumed for measured depth: the inverse-depth error of a
        camera is ``disparity_sigma / (f · baseline)`` (baseline to its nearest camera;
        0 for the oracle).
    shift_sigma : float
        Typical matching error (pixels) against which a segment's depth sensitivity
        (how far that inverse-depth error moves its predicted shift at the forecast
        translation) is weighed: weight ``1 / (1 + (σ_depth / shift_sigma)²)``.
    consistency_k : float
        A camera group (a stereo pair; a camera on rigs without pairs) whose average
        misfit against the solution of the other groups exceeds ``consistency_k ·
        shift_sigma`` pixels is dropped from the slot (the group with the largest, once
        per slot; :class:`golden.tracker_robust.GroupConsistency`); 0 disables the test.
    consistency_share : float
        A group is judged only if the other groups keep this share of every unknown's
        information: at 0.1 the leave-one-out solution of three stereo pairs predicted
        the fourth so poorly that the issue's 4-pair rig, whose pairs each carry most of
        some direction, had sound pairs dropped in 21 % of its slots (oracle depth).
    consistency_always : bool
        Apply the test while tracking too; off: only while re-acquiring after a loss
        (whose reference frames, carried through the loss, are off differently for each
        pair). While tracking, on the issue's rig with the oracle depth, it dropped sound
        pairs in 8–45 % of the slots and one of three runs diverged (docs/tracker.md).
    consistency_smoothing : float
        Weight of a new slot in that average.
    min_confidence : float
        A slot needs one measurement at least this confident to step.
    min_cameras : int
        ... and measurements from at least this many cameras (fewer cameras leave
        directions weakly determined; such a slot carries on from the latest pose).
    max_condition : float
        Largest condition number of the weighted design matrix, both column-scaled and
        scaled by the typical slot's information (an unknown the slot barely measures).
    boundary : str
        What a slot does whose system exceeds ``max_condition`` (frame boundaries, where
        few cameras contribute): ``"partial"`` steps in the directions the system
        determines (eigen-directions within ``max_condition``) and keeps the forecast in
        the others; ``"none"`` takes no step.
    status_window : float
        Window of the tracking status (:mod:`golden.tracking_status`), in frames.
    lost_update_fraction, lost_outlier_fraction : float
        Lost below this share of stepped slots or above this share of outlier
        innovations over the window.
    degraded_update_fraction, degraded_outlier_fraction : float
        Degraded below / above these.
    degraded_condition : float
        Degraded when the window's median condition number exceeds this.
    degraded_measurements : float
        Degraded with fewer confident measurements per stepped slot (window mean).
    recovery_window : int
        Half-width of the shift window (pixels, centred on zero motion) while re-acquiring
        after a loss.
    block_rows : int
        Slots whose window centres and reference rows are predicted together.
    geometry_stride : int
        Every n-th pixel of a segment enters its averaged equation (the averages of
        smooth per-pixel coefficients; 1 uses every pixel).
    solver : str
        ``"linear"`` (one weighted least-squares solve) or ``"nonlinear"`` (refined on
        the exact projection model, for comparison).
    """
    reference: str = "homography"
    reselect_angle: float = 0.06
    parallax: bool = True
    follow_rows: bool = True
    follow_segments: bool = True
    sigma: float = 2.0
    strong_test: bool = False
    window: int = 20
    segments: int = 8
    depth: str = "auto"
    disparity_blocks: int = 16
    min_depth_fraction: float = 0.5
    alpha: float = 0.1
    beta: float = 0.01
    motion_gain: str = DEFAULT_MOTION_GAIN
    loop_delay_rows: int = 0
    pose_alpha: float = POSE_ALPHA
    huber_k: float = 2.0
    scale_initial: float = 0.5
    scale_floor: float = 0.1
    scale_smoothing: float = 0.1
    scale_ceiling: float = SCALE_CEILING
    disparity_sigma: float = DISPARITY_SIGMA
    shift_sigma: float = SHIFT_SIGMA
    consistency_k: float = 4.0
    consistency_share: float = 0.5
    consistency_always: bool = False
    consistency_smoothing: float = 0.05
    min_confidence: float = 1.0
    min_cameras: int = 3
    max_condition: float = 100.0
    boundary: str = "partial"
    status_window: float = 0.25
    lost_update_fraction: float = 0.2
    lost_outlier_fraction: float = 0.5
    degraded_update_fraction: float = 0.7
    degraded_outlier_fraction: float = 0.25
    degraded_condition: float = 50.0
    degraded_measurements: float = 6.0
    recovery_window: int = 40
    block_rows: int = 48
    geometry_stride: int = 4
    solver: str = "linear"

    def __post_init__(self):
        for name, options in (("reference", REFERENCES), ("depth", DEPTHS),
                              ("solver", SOLVERS), ("motion_gain", MOTION_GAINS),
                              ("boundary", BOUNDARIES)):
            if getattr(self, name) not in options:
                raise ValueError(f"{name} must be one of {', '.join(options)}, "
                                 f"not {getattr(self, name)!r}")
        for name in ("parallax", "follow_rows", "follow_segments", "strong_test",
                     "consistency_always"):
            if not isinstance(getattr(self, name), bool):
                raise TypeError(f"{name} must be a bool, not {getattr(self, name)!r}")
        check_number("reselect_angle", self.reselect_angle, 0, low_open=True)
        check_int("window", self.window, 1)
        check_int("segments", self.segments, 1)
        check_int("disparity_blocks", self.disparity_blocks, 1)
        check_int("block_rows", self.block_rows, 1)
        check_int("loop_delay_rows", self.loop_delay_rows, 0)
        check_int("geometry_stride", self.geometry_stride, 1)
        check_int("recovery_window", self.recovery_window, 1)
        check_number("consistency_share", self.consistency_share, 0, 1, high_open=True)
        check_number("min_depth_fraction", self.min_depth_fraction, 0, 1,
               low_open=True)
        check_number("alpha", self.alpha, 0, 1, low_open=True)
        check_number("pose_alpha", self.pose_alpha, 0, 1, low_open=True)
        check_number("beta", self.beta, 0, 1)
        for name in ("huber_k", "scale_initial", "scale_floor", "scale_smoothing",
                     "scale_ceiling", "shift_sigma", "max_condition", "status_window",
                     "degraded_condition"):
            check_number(name, getattr(self, name), 0, low_open=True)
        check_number("min_confidence", self.min_confidence, 0)
        for name in ("disparity_sigma", "consistency_k", "degraded_measurements"):
            check_number(name, getattr(self, name), 0)
        check_number("consistency_smoothing", self.consistency_smoothing, 0, 1, low_open=True)
        for name in ("lost_update_fraction", "lost_outlier_fraction",
                     "degraded_update_fraction", "degraded_outlier_fraction"):
            check_number(name, getattr(self, name), 0, 1)
        if self.scale_ceiling < self.scale_floor:
            raise ValueError(f"scale_ceiling must be at least scale_floor "
                             f"({self.scale_floor}), not {self.scale_ceiling}")
        check_int("min_cameras", self.min_cameras, 1)
        DescriptorParams(sigma=self.sigma)

    replace = replace

    @property
    def descriptor(self):
        return DescriptorParams(sigma=self.sigma)

    @property
    def matcher(self):
        return MatchParams(shift_min=-self.window, shift_max=self.window,
                           segments=self.segments)

    @property
    def recovery_matcher(self):
        """The widened search of a re-acquisition after a loss."""
        return MatchParams(shift_min=-self.recovery_window, shift_max=self.recovery_window,
                           segments=self.segments)


@dataclass
class TrackResult:
    """The tracker's output, one entry per occupied row slot.

    Members
    -------
    times : (S,) slot times (s)
    rotations, positions : (S, 3, 3), (S, 3) estimated world-from-rig poses
    tracked : (S,) bool, false for the initialisation slots (poses given)
    updated : (S,) bool, the slot made a measurement step
    condition : (S,) condition number of the weighted system, the larger of its column-scaled
        one and the one scaled by the typical slot's information (NaN: none)
    equations : (S,) measurements with non-zero confidence
    camera_confidence : (S, N) best segment confidence of each camera (NaN: no row)
    motion : (S, 6) the smoothed one-frame motion Y of each slot
    forecast : (S, 6) the forecast Ŷ of each slot (with the loop delay)
    measured : (S, 6) the value ``Ŷ + δ`` the motion filter took (NaN where no step)
    linear_step, refined_step : (S, 6) with ``solver="nonlinear"``: the linear and the
        refined δ (NaN where no step)
    status : (S,) uint8 :class:`golden.tracking_status.TrackingStatus` code of each slot
    drifted : (S,) bool, the slot comes after a loss (absolute pose drifted)
    judged, outliers : (S,) innovations judged and those beyond the Huber threshold
    dropped_group : (S,) camera group the consistency test dropped (-1: none)
    partial : (S,) bool, the slot stepped only in its determined directions
    determinable : (S,) bool, the slot could have stepped had every usable segment
        matched (the status' update fraction counts only these)
    period : frame period (s) over which Y is defined
    params : dict of the TrackerParams used, plus ``depth_source``
    """
    times: np.ndarray
    rotations: np.ndarray
    positions: np.ndarray
    tracked: np.ndarray
    updated: np.ndarray
    condition: np.ndarray
    equations: np.ndarray
    camera_confidence: np.ndarray
    motion: np.ndarray
    forecast: np.ndarray
    measured: np.ndarray
    linear_step: np.ndarray
    refined_step: np.ndarray
    status: np.ndarray
    drifted: np.ndarray
    judged: np.ndarray
    outliers: np.ndarray
    dropped_group: np.ndarray
    partial: np.ndarray
    determinable: np.ndarray
    period: float
    params: dict

"""Parameters and number formats of the robust consistency stage between the measurement
router and the pose solver (issue 16 item 3; no Amaranth here: the emulator's model
:mod:`emulator.measurement.consistency` and the gateware
:mod:`hdl.measurement.consistency` read them).

First, per camera, the reference-time correction: the lane compared the row with the
previous frame's row ``source`` (the forecast's row address), exposed ``source − row``
row periods later than the same row, so its shifts show the motion over
``P − (source − row)`` row periods (``P`` row periods per frame); each shift is scaled by
``P / (P − (source − row))`` to the one-frame motion ``Y`` the solver estimates (the
golden tracker predicts from the reference row's own pose instead).

Then, per channel (camera × segment = the solver's slot) the stage judges each measured shift
against the forecast's predicted shift, as :class:`golden.temporal_filter.RobustScale`
does in float: the innovation ``r = shift − predicted``, the robust scale ``σ`` of the
channel (its only state), the Huber weight ``min(1, kσ/|r|)`` that multiplies the peak
ratio into the confidence, an outlier (``|r| > kσ``) replaced by the prediction, and
the τ²-scale recursion ``σ'² = σ²(1 − λ + λ c_k ρ(r/σ))`` with the biweight ``ρ``,
between a floor and a ceiling (the golden's ``scale_ceiling``: without it a persistent
bias raises the scale until it is accepted).
Before the Huber weight, each measurement's confidence is multiplied by its *depth
weight* (issue 18, :func:`golden.tracker_robust.depth_weights`): a stereo disparity
error ``σ_d`` moves the predicted shift by ``|p_T| σ_d / d`` pixels, where ``p_T`` is
the translation part of the predicted shift (the forecast's ``a_T·T̂``) and ``d`` the
measurement's depth cue (a disparity); against the matching error ``s`` that is the
ratio ``ρ = (σ_d/s) |p_T| / d`` and the weight ``1/(1 + ρ²) = d² / (d² + ((σ_d/s) p_T)²)``.
Segments whose shift is mostly translation of a near surface, whose depth error
therefore becomes shift error, count less.
Per row it applies the golden tracker's gates (some confidence ≥ ``min_confidence``,
at least ``min_cameras`` cameras with a confidence); the solver's own pivot check stands
for the golden's condition-number gate.
"""

import math
from dataclasses import dataclass, replace

from golden.checks import check_int, check_number
from golden.temporal_filter import BIWEIGHT_CK, HUBER_K, SCALE_CEILING
from golden.tracker_params import DISPARITY_SIGMA, SHIFT_SIGMA

from hdl.fixed import SQ, UQ, Overflow, QFormat, Rounding, check_format
from hdl.pose.params import PoseSolverParams

__all__ = ["ConsistencyParams"]


@dataclass(frozen=True, kw_only=True)
class ConsistencyParams:
    """Sizes, run-time settings and formats of the consistency stage.

    Parameters
    ----------
    solver : PoseSolverParams
        The solver the stage feeds: ``slots`` channels, ``shift_fmt`` of the shifts in and
        out, ``conf_fmt`` of the confidences.
    segments : int
        Segments K per camera (a channel's camera is ``slot // K``).
    frame_rows : float
        Row periods per frame period ``P`` (blanking included; register,
        ``frame_rows_fmt``), at least the solver's rows.
    max_row_offset : int
        Largest ``|source − row|`` whose shifts are used (register); a camera compared
        further off gets zero confidence (counted): its reference is nearly as new as the
        row, the factor ``P/(P − Δ)`` large.
    predicted_fmt : QFormat
        Signed format of the forecast's predicted shift (the forecast's
        ``displacement_fmt``).
    huber_k : float
        Huber threshold in scales (register, ``k_fmt``).
    scale_initial, scale_floor : float
        Starting scale of every channel and its lower bound, pixels (registers,
        ``scale_fmt``).
    scale_ceiling : float
        Upper bound of the scale, pixels (register, ``scale_fmt``; default the golden
        tracker's, :data:`golden.temporal_filter.SCALE_CEILING`): an innovation beyond
        ``huber_k · scale_ceiling`` always stays an outlier. At least ``scale_floor``;
        the starting scale is ``min(max(scale_initial, scale_floor), scale_ceiling)``.
    smoothing : float
        λ of the scale recursion, in (0, 1] (register: ``1 − λ`` and ``λ·c_k`` in
        ``gain_fmt``).
    biweight_ck : float
        The biweight's normalisation ``c_k`` (golden: 2.52 for k = 2).
    min_confidence : float
        A row needs one confidence at least this (register, the solver's ``conf_fmt``).
    min_cameras : int
        ... and confidences from at least this many cameras (register).
    depth_ratio : float
        ``σ_d / s`` of the depth weight, the disparity error over the matching error
        (register, ``depth_ratio_fmt``; default the golden tracker's ``disparity_sigma /
        shift_sigma``); 0 turns the weight off (oracle depth).
    depth_frac_bits : int
        Fraction bits of the depth weight's operands ``d`` and ``(σ_d/s) p_T`` (half-even;
        :attr:`depth_term_fmt`): 4 puts them on a 1/16-px grid, far finer than the
        disparity error they weigh.
    innovation_fmt : QFormat
        Signed format of ``r`` (pixels; saturated, counted: a saturated innovation is far
        beyond any ``kσ`` the scale format allows, so the verdict is the same).
    scale_fmt : QFormat
        Unsigned format of ``σ`` (pixels; the state, one word per channel; an update that
        would leave it saturates, counted).
    frame_rows_fmt, time_fmt : QFormat
        Unsigned formats of ``P`` and of the per-camera factor ``P/(P − Δ)`` (one
        division per camera and row, rounded half-even).
    k_fmt, ratio_fmt, gain_fmt : QFormat
        Unsigned formats of ``k``, of the divider's quotients ``min(|r|, kσ)/max(|r|, kσ)``
        and of the depth weight (floor) and of the recursion's gains and factor.
    depth_ratio_fmt : QFormat
        Unsigned format of ``depth_ratio``.
    """
    solver: PoseSolverParams
    segments: int
    frame_rows: float
    max_row_offset: int = 16
    predicted_fmt: QFormat = SQ(10, 8)
    huber_k: float = HUBER_K
    scale_initial: float = 0.5
    scale_floor: float = 0.1
    scale_ceiling: float = SCALE_CEILING
    smoothing: float = 0.1
    biweight_ck: float = BIWEIGHT_CK
    min_confidence: float = 1.0
    min_cameras: int = 3
    depth_ratio: float = DISPARITY_SIGMA / SHIFT_SIGMA
    depth_frac_bits: int = 4
    innovation_fmt: QFormat = SQ(7, 10)
    scale_fmt: QFormat = UQ(5, 11)
    frame_rows_fmt: QFormat = UQ(13, 4)
    time_fmt: QFormat = UQ(2, 16)
    k_fmt: QFormat = UQ(3, 8)
    ratio_fmt: QFormat = UQ(1, 15)
    gain_fmt: QFormat = UQ(2, 16)
    depth_ratio_fmt: QFormat = UQ(4, 8)

    def __post_init__(self):
        if not isinstance(self.solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {self.solver!r}")
        check_int("segments", self.segments, 1)
        if self.solver.slots % self.segments:
            raise ValueError(f"segments {self.segments} must divide the solver's "
                             f"{self.solver.slots} slots")
        for name in ("predicted_fmt", "innovation_fmt"):
            check_format(name, getattr(self, name), signed=True)
        for name in ("scale_fmt", "k_fmt", "ratio_fmt", "gain_fmt", "frame_rows_fmt",
                     "time_fmt", "depth_ratio_fmt"):
            check_format(name, getattr(self, name), signed=False)
        if self.ratio_fmt.int_bits < 1:
            raise ValueError(f"ratio_fmt must hold 1, not {self.ratio_fmt}")
        for name in ("huber_k", "scale_initial", "scale_floor"):
            check_number(name, getattr(self, name), 0, low_open=True)
        check_number("scale_ceiling", self.scale_ceiling, self.scale_floor)
        check_number("smoothing", self.smoothing, 0, 1, low_open=True)
        rows = self.solver.rows
        check_number("frame_rows", self.frame_rows, rows, self.frame_rows_fmt.max_value)
        check_int("max_row_offset", self.max_row_offset, 0, rows - 1)
        largest = self.frame_rows_raw / (self.frame_rows_raw - (
            self.max_row_offset << self.frame_rows_fmt.frac_bits))
        if largest > self.time_fmt.max_value:
            raise ValueError(f"time_fmt {self.time_fmt} cannot hold the largest "
                             f"reference-time factor {largest:.3f} (frame_rows "
                             f"{self.frame_rows}, max_row_offset {self.max_row_offset})")
        check_number("biweight_ck", self.biweight_ck, 0, low_open=True)
        check_number("min_confidence", self.min_confidence, 0)
        check_int("min_cameras", self.min_cameras, 1, self.cameras)
        check_number("depth_ratio", self.depth_ratio, 0, self.depth_ratio_fmt.max_value)
        check_int("depth_frac_bits", self.depth_frac_bits, 0, 16)
        for name, value, fmt in (("huber_k", self.huber_k, self.k_fmt),
                                 ("scale_initial", self.scale_initial, self.scale_fmt),
                                 ("scale_floor", self.scale_floor, self.scale_fmt),
                                 ("scale_ceiling", self.scale_ceiling, self.scale_fmt),
                                 ("min_confidence", self.min_confidence,
                                  self.solver.conf_fmt)):
            if value > fmt.max_value:
                raise ValueError(f"{name} must be at most {fmt.max_value} ({fmt}), "
                                 f"not {value}")
            if name != "min_confidence" and self._raw(value, fmt) == 0:
                raise ValueError(f"{name} {value} rounds to 0 in {fmt}")
        if self.lam_ck_raw == 0:
            raise ValueError(f"smoothing·biweight_ck {self.smoothing * self.biweight_ck} "
                             f"rounds to 0 in gain_fmt {self.gain_fmt}")

    replace = replace

    @staticmethod
    def _raw(value, fmt):
        return int(fmt.quantize(value, Rounding.HALF_EVEN, Overflow.ERROR))

    @property
    def cameras(self):
        return self.solver.slots // self.segments

    @property
    def channels(self):
        return self.solver.slots

    # --- the run-time registers, raw -----------------------------------------------------

    @property
    def frame_rows_raw(self):
        return self._raw(self.frame_rows, self.frame_rows_fmt)

    @property
    def k_raw(self):
        return self._raw(self.huber_k, self.k_fmt)

    @property
    def initial_raw(self):
        return self._raw(min(max(self.scale_initial, self.scale_floor), self.scale_ceiling),
                         self.scale_fmt)

    @property
    def floor_raw(self):
        return self._raw(self.scale_floor, self.scale_fmt)

    @property
    def ceiling_raw(self):
        return self._raw(self.scale_ceiling, self.scale_fmt)

    @property
    def keep_raw(self):
        """``1 − λ`` in ``gain_fmt``."""
        return self._raw(1 - self.smoothing, self.gain_fmt)

    @property
    def lam_ck_raw(self):
        """``λ·c_k`` in ``gain_fmt``."""
        return self._raw(self.smoothing * self.biweight_ck, self.gain_fmt)

    @property
    def depth_ratio_raw(self):
        return self._raw(self.depth_ratio, self.depth_ratio_fmt)

    @property
    def depth_term_fmt(self):
        """Signed format of the depth weight's operands ``d`` (the cue) and ``(σ_d/s)
        p_T``, each rounded half-even to ``depth_frac_bits``: wide enough for both at
        their formats' extremes (no saturation; the weight is ``d² / (d² + ((σ_d/s)
        p_T)²)`` of their squares)."""
        cue, pred, ratio = self.solver.cue_fmt, self.predicted_fmt, self.depth_ratio_fmt
        largest = max(cue.max_value, -pred.min_value * ratio.max_value)
        return SQ(math.floor(math.log2(largest)) + 3, self.depth_frac_bits)

    @property
    def min_confidence_raw(self):
        return self._raw(self.min_confidence, self.solver.conf_fmt)

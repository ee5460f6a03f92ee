"""Parameters and number formats of the motion forecast after the pose solver (no
Amaranth here: the emulator's model and the gateware, hdl/pose/forecast.py, read them).

The forecast closes the measurement loop (issue 16): a Holt–Winters filter with scalar
gains on the solver's one-frame motion ``Y`` gives, for every camera row about to be read,
the predicted shift of each temporal segment (the lane's run-time window centre) and the
predicted displacement across rows (which stored row of the previous frame the lane
reads). Both come from coefficient stores like the solver's: the solver's own store for
the shift along the row, a second one of the same layout for the displacement across rows
(:func:`golden.pose_lsq.shift_coefficients` with ``axis=1``).
"""

from dataclasses import dataclass, replace

from golden.checks import check_int, check_number
from golden.tracker_params import DEFAULT_MOTION_GAIN, MOTION_GAINS, POSE_ALPHA
from golden.tracker_solve import TYPICAL_SMOOTHING

from hdl.fixed import SQ, UQ, Overflow, QFormat, Rounding
from hdl.pose.params import PoseSolverParams

__all__ = ["ForecastParams", "MOTION_GAINS"]



@dataclass(frozen=True, kw_only=True)
class ForecastParams:
    """Sizes, gains and formats of the motion forecast.

    Parameters
    ----------
    solver : PoseSolverParams
        The solver whose step records the forecast takes (``step_fmt``) and whose
        coefficient store and design-row arithmetic (``coef_*_fmt``, ``cue_fmt``,
        ``a_fmt``) give the shift along the row.
    row_coef_t_fmt, row_coef_c_fmt, row_coef_r_fmt : QFormat
        Formats of the across-rows coefficient store (same layout as the solver's).
    row_coef_poly_fmts : tuple
        The across-rows store's polynomial terms (``PoseSolverParams.coef_poly_fmts``
        of :attr:`row_store`; empty: a store of every row). Its displacement across rows
        is quadratic in the row for a pinhole camera (the ``1 + y²`` of a rotation), so
        it needs one term more than the solver's.
    segments : int
        Temporal segments K per camera row (``solver.slots`` = cameras × K).
    height : int
        Rows per frame (a predicted row address is saturated to ``[0, height − 1]``).
    centre_range : int
        A window centre is saturated to ``[−centre_range, centre_range]`` (the lanes').
    alpha, beta : float
        Level and trend gains; quantized to ``gain_fmt`` (half-even), neither may round
        to 0 (alpha) or leave ``[0, 1]``.
    gain_fmt : QFormat
        Unsigned format of the gains.
    motion_fmt : QFormat
        Level, trend and forecast of ``Y`` (metres, radians); one format, so a forecast
        ``k`` rows ahead is ``level + k·trend`` on raw integers.
    displacement_fmt : QFormat
        Predicted shift or displacement of a segment (pixels; rounded half-even,
        saturated with a flag).
    loop_delay_rows : int
        Row periods between a row's solve and the first row whose forecast includes it
        (``golden.tracker``'s parameter of the same name).
    motion_gain : str
        ``"scalar"``: the level moves by ``alpha`` of the innovation; ``"information"``:
        by ``(N + Λ)⁻¹ N`` of it, with ``Λ = (1 − α)/α · N_typical``
        (``golden.tracker``'s parameter of the same name and default; the emulator's
        model, :mod:`emulator.pose.information_gain`; the gateware,
        :mod:`hdl.pose.prior_store` and the engine's gain program).
    typical_smoothing : float
        Weight of each solved row's normal matrix in the running typical information
        (``motion_gain="information"``); quantized to ``gain_fmt``.
    prior_fmt : QFormat
        Unsigned format of the prior's weight ``(1 − α)/α`` (half-even).
    track_alpha : float
        The motion track's pull towards the filter's level after each solved row
        (golden's ``pose_alpha``, :mod:`emulator.pose.motion_track`); quantized to
        ``gain_fmt``.
    reciprocal_fmt : QFormat
        Unsigned format of ``1 / frame_rows``, the motion track's rate per row period
        (half-even).
    """
    solver: PoseSolverParams
    row_coef_t_fmt: QFormat
    row_coef_c_fmt: QFormat
    row_coef_r_fmt: QFormat
    row_coef_poly_fmts: tuple = ()
    segments: int
    height: int
    centre_range: int = 32
    alpha: float = 0.1
    beta: float = 0.01
    gain_fmt: QFormat = UQ(1, 17)
    motion_fmt: QFormat = SQ(1, 39)
    displacement_fmt: QFormat = SQ(10, 8)
    loop_delay_rows: int = 1
    motion_gain: str = DEFAULT_MOTION_GAIN
    typical_smoothing: float = TYPICAL_SMOOTHING
    prior_fmt: QFormat = UQ(8, 16)
    track_alpha: float = POSE_ALPHA
    reciprocal_fmt: QFormat = UQ(1, 31)

    def __post_init__(self):
        if not isinstance(self.solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {self.solver!r}")
        for name in ("row_coef_t_fmt", "row_coef_c_fmt", "row_coef_r_fmt", "motion_fmt",
                     "displacement_fmt", "gain_fmt"):
            if not isinstance(getattr(self, name), QFormat):
                raise TypeError(f"{name} must be a QFormat, not {getattr(self, name)!r}")
        for name in ("motion_fmt", "displacement_fmt"):
            if not getattr(self, name).signed:
                raise ValueError(f"{name} must be signed, not {getattr(self, name)}")
        if self.gain_fmt.signed:
            raise ValueError(f"gain_fmt must be unsigned, not {self.gain_fmt}")
        check_int("segments", self.segments, 1)
        if self.solver.slots % self.segments:
            raise ValueError(f"segments {self.segments} must divide the solver's "
                             f"{self.solver.slots} slots")
        check_int("height", self.height, 1, self.solver.rows)
        check_int("centre_range", self.centre_range, 0)
        check_number("alpha", self.alpha, 0, 1, low_open=True)
        check_number("beta", self.beta, 0, 1)
        if self.alpha_raw == 0:
            raise ValueError(f"alpha {self.alpha} rounds to 0 in gain_fmt {self.gain_fmt}")
        check_int("loop_delay_rows", self.loop_delay_rows, 0)
        if self.motion_gain not in MOTION_GAINS:
            raise ValueError(f"motion_gain must be one of {MOTION_GAINS}, not "
                             f"{self.motion_gain!r}")
        check_number("typical_smoothing", self.typical_smoothing, 0, 1, low_open=True)
        if self.smoothing_raw == 0:
            raise ValueError(f"typical_smoothing {self.typical_smoothing} rounds to 0 in "
                             f"gain_fmt {self.gain_fmt}")
        if not isinstance(self.prior_fmt, QFormat) or self.prior_fmt.signed:
            raise ValueError(f"prior_fmt must be an unsigned QFormat, not {self.prior_fmt!r}")
        prior = (1 - self.alpha) / self.alpha
        if prior > self.prior_fmt.max_value:
            raise ValueError(f"alpha {self.alpha} gives a prior weight (1 - alpha)/alpha = "
                             f"{prior:.4g} beyond prior_fmt {self.prior_fmt}")
        check_number("track_alpha", self.track_alpha, 0, 1, low_open=True)
        if self.track_alpha_raw == 0:
            raise ValueError(f"track_alpha {self.track_alpha} rounds to 0 in gain_fmt "
                             f"{self.gain_fmt}")
        if not isinstance(self.reciprocal_fmt, QFormat) or self.reciprocal_fmt.signed \
                or self.reciprocal_fmt.max_value < 1:
            raise ValueError(f"reciprocal_fmt must be an unsigned QFormat holding 1, not "
                             f"{self.reciprocal_fmt!r}")
        self.row_store   # the across-rows store must be a valid store of the solver's kind

    replace = replace

    @property
    def cameras(self):
        return self.solver.slots // self.segments

    @property
    def row_store(self):
        """The solver's parameters with the across-rows store's formats: the same design
        row arithmetic and store layout for the displacement across rows."""
        return self.solver.replace(coef_t_fmt=self.row_coef_t_fmt,
                                   coef_c_fmt=self.row_coef_c_fmt,
                                   coef_r_fmt=self.row_coef_r_fmt,
                                   coef_poly_fmts=self.row_coef_poly_fmts)

    def _gain_raw(self, value):
        return int(self.gain_fmt.quantize(value, Rounding.HALF_EVEN, Overflow.ERROR))

    @property
    def alpha_raw(self):
        return self._gain_raw(self.alpha)

    @property
    def beta_raw(self):
        return self._gain_raw(self.beta)

    @property
    def smoothing_raw(self):
        return self._gain_raw(self.typical_smoothing)

    @property
    def track_alpha_raw(self):
        return self._gain_raw(self.track_alpha)

    def reciprocal_raw(self, frame_rows):
        """``1 / frame_rows`` raw in ``reciprocal_fmt``, rounded to nearest: ``⌊(⌊2^(F+1) /
        P⌋ + 1) / 2⌋``, what the gateware's divider computes (``2^F / P`` is never a tie
        for ``P`` below ``2^(F+1)``)."""
        check_int("frame_rows", frame_rows, 1)
        return (2 ** (self.reciprocal_fmt.frac_bits + 1) // frame_rows + 1) // 2

    @property
    def prior_raw(self):
        """``(1 − α)/α`` raw in ``prior_fmt``: the prior information's weight, so that a
        typical row's information gain is ``α``."""
        return int(self.prior_fmt.quantize((1 - self.alpha) / self.alpha, Rounding.HALF_EVEN,
                                           Overflow.ERROR))

    @property
    def information_fmt(self):
        """The prior information ``Λ`` and ``N + Λ``: the solver's ``normal_fmt`` with
        room for the prior's weight and the sum."""
        normal = self.solver.normal_fmt
        return SQ(normal.int_bits + self.prior_fmt.int_bits + 1, normal.frac_bits)

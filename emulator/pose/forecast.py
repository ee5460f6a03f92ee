"""Bit-accurate model of the motion forecast after the pose solver (issue 16): the
specification of the gateware :class:`hdl.pose.forecast.Forecast` (bit-exact with it,
``sim_tests/pose/test_forecast_hdl.py`` and the cocotb bench ``sim_tests/pose/forecast/``).

Integers only, with the formats of :class:`hdl.pose.forecast_params.ForecastParams` and
the arithmetic of :mod:`hdl.fixed`:

1. :class:`MotionFilter`: Holt–Winters on the one-frame motion ``Y`` with scalar gains
   (the golden tracker's ``motion_gain="scalar"``): ``p = L + B``,
   ``L' = p + α (y − p)``, ``B' = B + β (L' − p)``, each product rounded half-even; a
   row without a solved step keeps ``L' = p``, ``B' = B``. ``p``, ``L'`` and ``B'`` are
   saturated into ``motion_fmt`` and the update counted (:attr:`MotionFilter.saturated`):
   a diverging loop stops at the format's bound (±1 m or rad per frame) and says so,
   instead of wrapping to the opposite sign.
2. The loop delay: a row's forecast is made from the filter's state after the newest row
   solved ``loop_delay_rows`` row periods before it starts,
   ``Ŷ = L_j + k·B_j`` on raw integers (:class:`golden.temporal_filter.DelayedForecast`
   does the bookkeeping, the same code as the golden tracker's), saturated into
   ``motion_fmt`` and counted (:attr:`ForecastModel.saturated`).
3. :meth:`ForecastModel.predict`: for a camera row ``y`` with the depth cue of each
   segment, the design rows of the solver's store (:func:`emulator.pose_solver.design_row`,
   the solver's own rounding) give each segment's predicted shift ``a·Ŷ`` and, from the
   across-rows store, its predicted displacement across rows, rounded half-even into
   ``displacement_fmt`` (saturated, flagged). Per camera, the window centre is the mean
   shift of its K segments and the row address ``y −`` their mean displacement, each
   rounded half-up to an integer and saturated (to ``±centre_range`` and
   ``[0, height − 1]``) with a flag, never silently.
"""

import numpy as np

from golden.temporal_filter import DelayedForecast
from hdl.fixed import SQ, Overflow, Rounding, mul, resize
from emulator.pose.program import Value, dot
from emulator.pose_solver import PoseRows, design_row

__all__ = ["MotionFilter", "ForecastModel", "output_transfers", "clamp", "sum_format"]


class MotionFilter:
    """Holt–Winters with scalar gains on raw ``motion_fmt`` integers (6,).

    Parameters
    ----------
    params : ForecastParams
    level : array_like of int (6,)
        Initial level, raw ``motion_fmt``; the trend starts at 0.
    """

    def __init__(self, params, level):
        self.params = params
        #: Updates in which some value was saturated into ``motion_fmt``.
        self.saturated = 0
        self.restart(level)

    def restart(self, level):
        """Level ``level`` (raw ``motion_fmt``), trend 0; :attr:`saturated` goes on
        counting (the gateware's counter clears only on reset)."""
        self.level = self.params.motion_fmt.raw(np.asarray(level, dtype=np.int64))
        self.trend = np.zeros_like(self.level)

    def _gained(self, gain_raw, raw):
        """``gain · raw`` (``raw`` a difference of two ``motion_fmt`` values, |raw| < 2)
        rounded half-even, one integer bit wider than ``motion_fmt``."""
        p = self.params
        product, product_fmt = mul(gain_raw, p.gain_fmt, raw, sum_format(p.motion_fmt, 2))
        return resize(product, product_fmt, sum_format(p.motion_fmt, 1), Rounding.HALF_EVEN,
                      Overflow.ERROR)

    def predicted(self):
        """``p = L + B`` saturated into ``motion_fmt`` (raw (6,)): the level a row's
        update starts from, and the information gain's prediction."""
        return clamp(self.params.motion_fmt, self.level + self.trend, [])

    def update(self, value=None, gain=None):
        """Take a solved step (raw ``solver.step_fmt``, (6,)) or none; returns the new
        level. ``gain``: the level's move ``d`` already solved by the information gain
        (raw ``solver.step_fmt``, :func:`emulator.pose.information_gain.gain_step`);
        None: the scalar ``α``. (The argument keeps the interface of
        :class:`golden.temporal_filter.HoltWinters`, whose ``gain`` is the matrix.)"""
        p = self.params
        if gain is not None and (p.motion_gain != "information" or np.shape(gain) != (6,)):
            raise ValueError(f"gain must be None, or the information gain's move (6 raw "
                             f"step_fmt values) with motion_gain 'information', not {gain!r} "
                             f"with motion_gain {p.motion_gain!r}")
        clamps = []
        predicted = clamp(p.motion_fmt, self.level + self.trend, clamps)
        level = predicted
        step_fmt = p.solver.step_fmt
        if value is not None and gain is not None:
            d = resize(step_fmt.raw(np.asarray(gain, dtype=np.int64)), step_fmt,
                       p.motion_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
            level = clamp(p.motion_fmt, predicted + d, clamps)
        elif value is not None:
            y = resize(step_fmt.raw(np.asarray(value, dtype=np.int64)), step_fmt,
                       p.motion_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
            level = clamp(p.motion_fmt, predicted + self._gained(p.alpha_raw, y - predicted),
                          clamps)
        self.trend = clamp(p.motion_fmt,
                           self.trend + self._gained(p.beta_raw, level - predicted), clamps)
        self.level = level
        self.saturated += any(clamps)
        return level


def sum_format(fmt, extra):
    """``fmt`` with ``extra`` more integer bits: where sums of its values are formed."""
    return SQ(fmt.int_bits + extra, fmt.frac_bits)


def clamp(fmt, raw, clamps):
    """Raw sums of ``fmt`` values (same fraction bits) saturated into ``fmt``
    (``Overflow.SATURATE``); appends to ``clamps`` whether any was out of range."""
    raw = np.asarray(raw, dtype=np.int64)
    out = np.clip(raw, fmt.min_raw, fmt.max_raw)
    clamps.append(bool(np.any(out != raw)))
    return out


class ForecastModel:
    """The forecast of one pipeline: step records in, window centres and row addresses of
    the rows about to be read out.

    Parameters
    ----------
    params : ForecastParams
    coef_raw, row_coef_raw : ndarray (slots, rows, 9)
        The solver's coefficient store and the across-rows store
        (``PipelineConfig.coef_raw`` and ``.row_coef_raw``).
    initial : array_like of int (6,)
        The motion before the first row, raw ``motion_fmt``.
    """

    def __init__(self, params, coef_raw, row_coef_raw, initial):
        self.params = params
        self.coef_raw, self.row_coef_raw = coef_raw, row_coef_raw
        self.filter = MotionFilter(params, initial)
        self.loop = DelayedForecast(self.filter, params.loop_delay_rows)
        self._saturated_queries = 0

    def restart(self, initial):
        """The filter and the loop delay's states as constructed at ``initial`` (raw
        ``motion_fmt``, (6,)); :attr:`saturated` goes on counting, as the gateware's
        ``loop.forecast_counters.motion``, which only a reset clears."""
        self.filter.restart(initial)
        self.loop = DelayedForecast(self.filter, self.params.loop_delay_rows)

    def take(self, slot, step=None, gain=None):
        """The solver's step of row slot ``slot`` (raw ``step_fmt``; ``None`` if the row
        was flagged) and the information gain's move (:meth:`MotionFilter.update`): the
        filter's update."""
        return self.loop.update(slot, step, gain)

    def motion(self, slot):
        """Forecast ``Ŷ`` (raw ``motion_fmt``, saturated) for row slot ``slot``, whose
        step will be the next the filter takes."""
        clamps = []
        motion = clamp(self.params.motion_fmt, self.loop.forecast(slot), clamps)
        self._saturated_queries += clamps[0]
        return motion

    @property
    def saturated(self):
        """Filter updates and forecasts in which a value was saturated into
        ``motion_fmt`` (the gateware's ``loop.forecast_counters.motion``)."""
        return self.filter.saturated + self._saturated_queries

    def _terms(self, store, coef_raw, row, cue, motion):
        """The six terms ``(1, a_i, Ŷ_i)`` of every slot's ``a·Ŷ`` (the first three the
        translation part ``a_T·T̂``), for :func:`emulator.pose.program.dot`."""
        slots = self.params.solver.slots
        zeros = np.zeros((1, slots), dtype=np.int64)
        rows = PoseRows(slot=np.arange(slots)[None], shift=zeros, cue=np.asarray(cue)[None],
                        conf=zeros, present=np.ones((1, slots), dtype=bool),
                        row=np.array([row]), time=np.array([0]))
        a = design_row(store, coef_raw, rows)
        y = [Value(np.full((1, slots), int(v), dtype=np.int64), self.params.motion_fmt)
             for v in motion]
        return [(1, a[i], y[i]) for i in range(6)]

    def _sum(self, terms):
        """The terms summed and rounded once into ``displacement_fmt`` (raw per slot,
        saturated) and whether each saturated."""
        value, saturated = dot(self.params.displacement_fmt, terms=terms)
        return np.array([int(v) for v in value.raw[0]], dtype=np.int64), saturated[0]

    def _displacements(self, store, coef_raw, row, cue, motion):
        """Every slot's ``a·Ŷ`` (raw ``displacement_fmt``, saturated) and whether it
        saturated."""
        return self._sum(self._terms(store, coef_raw, row, cue, motion))

    def _camera_means(self, raw):
        """Per camera: the mean of its K segments' raw displacements, rounded half-up to
        an integer number of pixels."""
        p = self.params
        total = raw.reshape(p.cameras, p.segments).sum(axis=1)
        unit = p.segments << p.displacement_fmt.frac_bits
        return (2 * total + unit) // (2 * unit)

    def _segment_rows(self, row, across):
        """Per camera and segment (cameras, K): the previous frame's row the segment's
        content is predicted to come from, ``row`` minus its displacement across rows
        rounded half-up, and whether it was saturated to the frame."""
        p = self.params
        unit = 1 << p.displacement_fmt.frac_bits
        source = row - (2 * across + unit) // (2 * unit)
        source = source.reshape(p.cameras, p.segments)
        return np.clip(source, 0, p.height - 1), (source < 0) | (source >= p.height)

    def predict(self, slot, row, cue):
        """The forecast for camera row ``row`` read in row slot ``slot``, with the depth
        cue of every segment ``cue`` (raw ``solver.cue_fmt``, (slots,)).

        Returns a dict: ``motion`` (6,) raw ``motion_fmt``; ``shift``, its translation
        part ``translation`` (the three translation terms, rounded once, saturated) and
        ``across`` (slots,) raw ``displacement_fmt`` with ``shift_saturated`` and
        ``across_saturated``;
        per camera ``centre`` and ``source_row`` (the camera mean's row: integers,
        saturated) with ``centre_saturated``/``row_saturated``; per camera and segment
        ``segment_rows`` (cameras, K), the rows the lanes read, with
        ``segment_rows_saturated``.
        """
        p = self.params
        motion = self.motion(slot)
        terms = self._terms(p.solver, self.coef_raw, row, cue, motion)
        shift, shift_sat = self._sum(terms)
        translation, _ = self._sum(terms[:3])
        across, across_sat = self._displacements(p.row_store, self.row_coef_raw, row, cue,
                                                 motion)
        centre = self._camera_means(shift)
        source = row - self._camera_means(across)
        segment_rows, segment_saturated = self._segment_rows(row, across)
        return {"motion": motion, "shift": shift, "shift_saturated": shift_sat,
                "translation": translation,
                "segment_rows": segment_rows, "segment_rows_saturated": segment_saturated,
                "across": across, "across_saturated": across_sat,
                "centre": np.clip(centre, -p.centre_range, p.centre_range),
                "centre_saturated": np.abs(centre) > p.centre_range,
                "source_row": np.clip(source, 0, p.height - 1),
                "row_saturated": (source < 0) | (source >= p.height)}


def output_transfers(params, prediction, row):
    """The gateware's output transfers of one row's :meth:`ForecastModel.predict`
    (``hdl.pose.forecast_predictor.output_layout``): one dict per camera, camera 0
    first; the saturation flags of a camera's K segments as bits, its ``segment_rows`` a
    dict by segment (as :func:`emulator.hdl_sim.payload.unpack` gives an array)."""
    k = params.segments

    def bits(flags):
        return sum(int(bool(f)) << n for n, f in enumerate(flags))

    p = prediction
    return [{"camera": c, "row": int(row), "centre": int(p["centre"][c]),
             "source_row": int(p["source_row"][c]),
             "centre_saturated": int(p["centre_saturated"][c]),
             "row_saturated": int(p["row_saturated"][c]),
             "shift_saturated": bits(p["shift_saturated"][c * k:(c + 1) * k]),
             "across_saturated": bits(p["across_saturated"][c * k:(c + 1) * k]),
             "segment_rows": dict(enumerate(int(r) for r in p["segment_rows"][c])),
             "segment_rows_saturated": bits(p["segment_rows_saturated"][c]),
             "last": int(c == params.cameras - 1)} for c in range(params.cameras)]

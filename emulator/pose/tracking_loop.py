"""Bit-accurate model of the back half of the closed measurement loop (issue 16): the
specification of the gateware :class:`hdl.pose.tracking_loop.TrackingLoop` (bit-exact
with it, ``sim_tests/pose/tracking_loop/``), and the loop :func:`emulator.pipeline.run`
closes.

From the measurement engine's transfers of a row back to the forecast of the rows about
to be read, composed of the blocks' own models:

1. :meth:`TrackingLoopModel.request`: the forecast of camera row ``row`` read in row
   slot ``slot`` (:meth:`ForecastModel.predict`) with the depth cue each segment had in
   the same row of the previous frame (the cue store, ``slots × height``, 0 until a row
   wrote it);
2. :meth:`TrackingLoopModel.close`: with a consistency stage, the row's transfers are
   judged (:meth:`ConsistencyModel.apply`) against the predicted shift of each
   measurement, ``a·Ŷ`` with the measurement's own cue and the row's forecast ``Ŷ``
   (and weighed by its translation part ``a_T·T̂``, the depth weight), and
   each camera's row offset ``source − row`` of the row's forecast; the cue store keeps
   every non-zero cue; the solver's step of the judged row (none if flagged: a gated
   row has all confidences 0, so EMPTY) updates the forecast's filter;
3. :meth:`TrackingLoopModel.restart`: between a frame's last row and the next frame's
   first, the filter starts again at ``initial`` (as constructed) and the row slots at
   0; the cue store and the consistency stage's scales are kept (they hold the previous
   frame's cues and the measurements' statistics, which a restart does not change). The
   gateware's ``restart`` takes effect at such a point: the first frame boundary of its
   requests after the strobe, once every row forecast before it has its record.
"""

import numpy as np

from emulator.measurement.consistency import ConsistencyModel
from emulator.measurement.router import pose_rows
from emulator.pose.forecast import ForecastModel
from emulator.pose.tracking_status import row_counts
from emulator.pose.information_gain import PriorInformation, gain_step
from emulator.pose_solver import accumulate, solve_system

__all__ = ["TrackingLoopModel"]


class TrackingLoopModel:
    """The loop's state: the forecast's filter, the cue store, the consistency stage's
    scales.

    Parameters
    ----------
    params : ForecastParams
    coef_raw, row_coef_raw : ndarray (slots, rows, 9)
        The solver's coefficient store and the across-rows store.
    initial : array_like of int (6,)
        The motion before the first row, raw ``params.motion_fmt``.
    consistency : ConsistencyParams or None
        The consistency stage in front of the solver (none: transfers go on unjudged).
    """

    def __init__(self, params, coef_raw, row_coef_raw, initial, consistency=None):
        self.params, self.coef_raw, self.row_coef_raw = params, coef_raw, row_coef_raw
        self.forecast = ForecastModel(params, coef_raw, row_coef_raw, initial)
        self.consistency = None if consistency is None else ConsistencyModel(consistency)
        information = params.motion_gain == "information"
        self.prior = PriorInformation(params) if information else None
        self._counts = {"gain_flagged": 0} if information else {}
        self.cues = np.zeros((params.solver.slots, params.height), dtype=np.int64)
        self.prediction = None
        #: The last judged row's ``(judged, outliers, confident)``, the tracking-status
        #: unit's row counts (:func:`emulator.pose.tracking_status.row_counts`); None
        #: without a consistency stage or for a row without transfers.
        self.row_counts = None
        #: The last closed row's solved step (raw ``solver.step_fmt``; None if flagged).
        self.step = None

    @property
    def counts(self):
        """The consistency stage's counters (empty without one) and, with the
        information gain, its ``gain_flagged`` rows."""
        stage = {} if self.consistency is None else dict(self.consistency.counts)
        return {**stage, **self._counts}

    def restart(self, initial):
        """The filter as constructed at ``initial`` (raw ``motion_fmt``, (6,)), before
        the first row of a frame; the next row's slot is 0. The cue store, the
        consistency stage and the forecast's saturation count keep their state."""
        self.forecast.restart(initial)
        self.prediction = None

    def request(self, slot, row):
        """The forecast of camera row ``row`` read in row slot ``slot`` (the dict of
        :meth:`ForecastModel.predict`), from the previous frame's cues of the row; it
        stays the row's forecast for :meth:`close`."""
        self.prediction = self.forecast.predict(slot, row, self.cues[:, row])
        return self.prediction

    def close(self, transfers, slot, row):
        """The row's transfers (router dicts in stream order, possibly none) after the
        row's :meth:`request`: returns ``(judged transfers, level)``, the transfers the
        solver takes and the filter's level after the row's step (raw ``motion_fmt``;
        a flagged row, or one without transfers, gives the filter no step)."""
        step, self.row_counts = None, None
        if self.consistency is not None and transfers:
            cue = np.zeros(self.params.solver.slots, dtype=np.int64)
            cue[[t["slot"] for t in transfers]] = [t["cue"] for t in transfers]
            predicted = self.forecast.predict(slot, row, cue)
            delta = self.prediction["segment_rows"].ravel() - row
            transfers, verdict = self.consistency.apply(transfers, predicted["shift"], delta,
                                                        predicted["translation"])
            self.row_counts = row_counts(verdict["conf_in"], verdict,
                                         self.params.solver.slots)
        for t in transfers:
            if t["cue"]:                          # 0: no stereo cue for that segment
                self.cues[t["slot"], row] = t["cue"]
        gain = None
        if transfers:
            solver = self.params.solver
            rows = pose_rows(self.params, transfers)
            normal, rhs = accumulate(solver, self.coef_raw, rows)
            result = solve_system(solver, normal, rhs, rows.counts > solver.slots)
            if result.flags[0] == 0:
                step = result.step[0]
                if self.prior is not None:
                    gain = self._gain(normal, rhs)
        self.step = step
        return transfers, self.forecast.take(slot, step, gain)

    def _gain(self, normal, rhs):
        """The information gain's move of a solved row (None: its solve was flagged,
        counted in ``gain_flagged``; the filter moves by ``α``); the row's normal matrix
        joins the prior information."""
        prior = self.prior.updated([int(v.raw[0]) for v in normal])
        d, flags = gain_step(self.params, normal, rhs, prior[None],
                             self.forecast.filter.predicted()[None])
        self.prior.keep(prior)
        if flags[0]:
            self._counts["gain_flagged"] += 1
            return None
        return d[0]

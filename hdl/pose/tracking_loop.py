"""The back half of the closed measurement loop (issue 16): from the measurement engine's
transfers back to the forecast of the rows about to be read. Bit-accurate model:
:class:`emulator.pose.tracking_loop.TrackingLoopModel`; ``docs/pose/tracking_loop.md``.

Only wiring of blocks with their own modules and tests::

    i ──► context join ──► MeasuredShift ──► ConsistencyStage ──► PoseSolver ──┐
            ▲   (cue store write)                     gated ───────►          │ records
            │                                                                  ▼
      row contexts ◄── o ◄── Forecast (filter, predictor) ◄── RequestGenerator (cue store)
                                   │ updates
                                   ▼
                              MotionTrack ──► track (Y of every row)

* :class:`hdl.pose.loop_requests.RequestGenerator`: one request per row slot with the
  previous frame's cues of the row;
* :class:`hdl.pose.forecast.Forecast`: per request one transfer per camera on ``o``
  (with its ``row``); the solver's records update its filter, whose every update goes
  on to :class:`hdl.pose.motion_track.MotionTrack`: ``Y`` of every row, the loop's
  estimate of the one-frame motion (``docs/pose/motion_track.md``);
* the *row contexts*, a FIFO of ``loop_delay_rows + 1`` entries written at a row's last
  forecast transfer: its row, ``Ŷ`` and each camera's ``source − row``. A request can
  only be taken once the record of the row ``loop_delay_rows + 1`` before it is in, so no
  more rows are forecast and not yet measured (``o`` waits if the FIFO is full);
* the measurements of a row are joined with the oldest context (a measurement waits for
  it; the context goes with the row's ``last``; a measurement of another row than the
  context's is counted ``mismatched``, never a hang);
* :class:`hdl.pose.measured_shift.MeasuredShift`: each measurement's predicted shift
  with its own cue (the forecast's second store port);
* :class:`hdl.measurement.consistency.ConsistencyStage`, then
  :class:`hdl.pose_solver.PoseSolver` with the stage's ``gated`` verdict.

The loop delay is ``loop_delay_rows`` (ForecastParams): a request of slot ``s`` waits for
the record of slot ``s − 1 − loop_delay_rows``. Assumed: every row forecast gets at least
one measurement (the engine emits every slot of every row), else its record never comes
and the requests stop. ``restart`` waits for a clean point, the next frame boundary of
the requests with every forecast row's record in (:mod:`hdl.pose.loop_requests`), so no
stale context is ever joined.
"""

from amaranth.hdl import Module, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFO
from amaranth.lib.wiring import In, Out, connect, flipped

from hdl.measurement.consistency import (ConsistencyStage, counts_layout, settings_init,
                                         settings_layout)
from hdl.measurement.consistency_params import ConsistencyParams
from hdl.pose.forecast import Forecast
from hdl.pose.forecast_filter import DEFAULT_SLOT_BITS
from hdl.pose.forecast_params import ForecastParams
from hdl.pose.forecast_predictor import output_layout
from hdl.pose.loop_requests import RequestGenerator
from hdl.pose.measured_shift import MeasuredShift
from hdl.pose.motion_track import MotionTrack
from hdl.pose.row_counter import verdict_layout
from hdl.pose_solver import PoseSolver, measurement_layout, record_layout
from hdl.stream_fork import StreamFork

__all__ = ["TrackingLoop", "loop_counters_layout", "information_settings"]


def loop_counters_layout(params):
    """The loop's own counters (wrapping, ``solver.counter_bits``): measurements whose row
    was not the forecast row's, predicted shifts saturated, rows of the motion track in
    which a value saturated, with the information gain solved rows whose gain was
    flagged (the filter moved by α; the model's ``counts["gain_flagged"]``); and its
    status bits ``restart_pending`` (a ``restart`` waits for its frame boundary) and
    ``track_overrange`` (the track's ring is shorter than ``frame_rows``, or it is 0: the
    track runs with the ring's length)."""
    bits = params.solver.counter_bits
    gain = {"gain_flagged": bits} if params.motion_gain == "information" else {}
    return data.StructLayout({"mismatched": bits, "predicted_saturated": bits,
                              "track_saturated": bits, "restart_pending": 1,
                              "track_overrange": 1, **gain})


def information_settings(loop, settings):
    """The assignments of the information gain's registers (``settings.prior_weight``,
    ``.typical_smoothing``, :mod:`hdl.bus.regmap`) to ``loop``: none for a scalar-gain
    build."""
    if loop.params.motion_gain != "information":
        return []
    return [loop.prior_weight.eq(settings.prior_weight),
            loop.smoothing.eq(settings.typical_smoothing)]


class TrackingLoop(wiring.Component):
    """Measurements in, the forecast of the next rows out.

    Parameters
    ----------
    params : ForecastParams
    stage : ConsistencyParams
        Its ``solver`` and ``segments`` are the forecast's; its ``frame_rows`` (a whole
        number) is the request generator's frame period.
    coefficients, row_coefficients : ndarray (slots, entries_per_slot, 9)
        The forecast's stores in their layouts (``PipelineConfig.coef_store``,
        ``.row_coef_store``: polynomial terms, or every row); the first is a copy of the
        solver's store (see ``docs/pose/tracking_loop.md``).
    solver_store : ndarray
        The solver's store contents (``PipelineConfig.coef_store``: rows, or their
        polynomials).
    bits_per_clock : int
        Of the consistency stage's iterative units.
    track_stream : bool
        Offer every row's ``Y`` on a ``track`` stream (the benches take it); False: only
        ``track_y`` (a top's register).

    Members
    -------
    i : In(stream.Signature(measurement_layout(solver)))
        The engine's measurements, a row's slots distinct, ``last`` on its final one.
    o : Out(stream.Signature(output_layout(params)))
        The forecast: per row ``cameras`` transfers with the ``row`` they are for.
    track : Out(stream.Signature(ArrayLayout(motion_fmt, 6))), with ``track_stream``
        ``Y`` after each row (raw ``motion_fmt``), the model's
        :class:`~emulator.pose.motion_track.MotionTrackModel`; restarted with the filter
        at ``initial``, its frame the built ``stage.frame_rows`` (the ring's length) or
        the run-time ``frame_rows`` read then. A stalled ``track`` stalls the filter's
        next record, hence the loop. Without ``track_stream`` the loop takes every ``Y``
        itself (``track_y`` only).
    track_y : Out(ArrayLayout(motion_fmt, 6))
        The last ``Y`` taken on ``track``, held (0 after reset).
    track_alpha : In(unsigned(gain_fmt.width)), reset ``params.track_alpha_raw``
        The track's pull (:class:`~hdl.pose.motion_track.MotionTrack`).
    records : Out(stream.Signature(record_layout(solver)))
        Every pose record (the forecast takes each too; a record leaves the solver once
        both have: a stalled ``records`` stalls the loop).
    verdicts : Out(stream.Signature(verdict_layout()))
        Each judged measurement's verdict bits, offered as the solver is offered the
        measurement (a stalled ``verdicts`` stalls the solver's input): the tracking
        status' row counts (:func:`hdl.pose.row_counter.verdict_layout`; ``confident``
        is before the row's gates).
    coef_write : In(coef_write_signature(solver))
        The solver's coefficient store load (:class:`hdl.pose_solver.PoseSolver`).
    pivot_log2 : In, pivot_log2_error : Out
        The solver's conditioning gate (:class:`hdl.pose_solver.PoseSolver`).
    alpha, beta, initial : In
        The forecast's gains and start (:class:`hdl.pose.forecast.Forecast`).
    prior_weight, smoothing : In, with ``motion_gain="information"``
        The information gain's prior weight and smoothing (:class:`hdl.pose_solver.PoseSolver`).
    restart : In(1)
        Strobe: restart the filter at ``initial`` (read then) and the requests at row 0,
        slot 0, at the next frame boundary of the requests once every row forecast
        before it has its record (:mod:`hdl.pose.loop_requests`): the rows forecast
        before the boundary are measured, joined and solved as before, so nothing is
        dropped and nothing mismatched; the model's
        :meth:`~emulator.pose.tracking_loop.TrackingLoopModel.restart` before that
        frame. Meanwhile row 0 is not forecast (in a top the engine's row set waits)
        and ``counters.restart_pending`` is set.
    settings : In(settings_layout(stage)), reset to the stage's parameters
    frame_rows : In(unsigned(slot_bits)), reset ``stage.frame_rows``
    counts, forecast_counters, solver_counters, counters : Out
        The stage's, the forecast's, the solver's and :func:`loop_counters_layout`.
    """

    def __init__(self, params, stage, coefficients, row_coefficients, solver_store, *,
                 bits_per_clock=2, slot_bits=DEFAULT_SLOT_BITS, track_stream=False):
        if not isinstance(params, ForecastParams):
            raise TypeError(f"params must be a ForecastParams, not {params!r}")
        if not isinstance(stage, ConsistencyParams):
            raise TypeError(f"stage must be a ConsistencyParams, not {stage!r}")
        if stage.solver != params.solver or stage.segments != params.segments:
            raise ValueError("stage must have the forecast's solver and segments")
        if stage.frame_rows != int(stage.frame_rows):
            raise ValueError(f"the stage's frame_rows must be a whole number of row periods "
                             f"(the requests' slots), not {stage.frame_rows}")
        self.params, self.stage = params, stage
        self._requests = RequestGenerator(params, int(stage.frame_rows), slot_bits=slot_bits)
        self._forecast = Forecast(params, coefficients, row_coefficients, slot_bits=slot_bits,
                                  shared_port=True, track=True)
        self._track = MotionTrack(params, int(stage.frame_rows), slot_bits=slot_bits)
        self._shift = MeasuredShift(params, stage)
        self._stage = ConsistencyStage(stage, bits_per_clock=bits_per_clock)
        information = params.motion_gain == "information"
        self._solver = PoseSolver(params.solver, solver_store,
                                  gain=params if information else None)
        s = params.solver
        f = self._forecast.signature.members
        solver = self._solver.signature.members
        super().__init__({
            **({"prior_weight": solver["prior_weight"], "smoothing": solver["smoothing"]}
               if information else {}),
            "i": In(stream.Signature(measurement_layout(s))),
            "o": Out(stream.Signature(output_layout(params))),
            **({"track": self._track.signature.members["o"]} if track_stream else {}),
            "track_y": Out(data.ArrayLayout(params.motion_fmt.shape(), 6)),
            "track_alpha": self._track.signature.members["alpha"],
            "records": Out(stream.Signature(record_layout(s))),
            "verdicts": Out(stream.Signature(verdict_layout())),
            "coef_write": self._solver.signature.members["coef_write"],
            "pivot_log2": self._solver.signature.members["pivot_log2"],
            "pivot_log2_error": self._solver.signature.members["pivot_log2_error"],
            "alpha": f["alpha"], "beta": f["beta"], "initial": f["initial"],
            "restart": f["restart"],
            "settings": In(settings_layout(stage), init=settings_init(stage)),
            "frame_rows": self._requests.signature.members["frame_rows"],
            "counts": Out(counts_layout()),
            "forecast_counters": f["counters"],
            "solver_counters": self._solver.signature.members["counters"],
            "counters": Out(loop_counters_layout(params)),
        })

    def context_layout(self):
        """A forecast row's context: its row, ``Ŷ`` and each segment's ``source − row``
        (by solver slot: camera · K + segment)."""
        p, s = self.params, self.params.solver
        return data.StructLayout({
            "row": s.row_bits, "motion": data.ArrayLayout(p.motion_fmt.shape(), 6),
            "delta": data.ArrayLayout(signed(s.row_bits + 1), s.slots)})

    def elaborate(self, platform):
        p = self.params
        m = Module()
        m.submodules.requests = requests = self._requests
        m.submodules.forecast = forecast = self._forecast
        m.submodules.shift = shift = self._shift
        m.submodules.stage = stage = self._stage
        m.submodules.solver = solver = self._solver
        m.submodules.track = track = self._track
        layout = self.context_layout()
        m.submodules.contexts = contexts = SyncFIFO(width=layout.size,
                                                    depth=p.loop_delay_rows + 1)

        # --- requests → forecast → o, each row's context kept
        connect(m, requests.o, forecast.requests)
        m.d.comb += [requests.frame_rows.eq(self.frame_rows),
                     requests.restart.eq(self.restart), requests.drained.eq(forecast.idle),
                     forecast.alpha.eq(self.alpha), forecast.beta.eq(self.beta),
                     forecast.initial.eq(self.initial),
                     forecast.restart.eq(requests.restarting),
                     self.counters.restart_pending.eq(requests.restart_pending),
                     self.forecast_counters.eq(forecast.counters),
                     self.o.payload.eq(forecast.o.payload),
                     self.o.valid.eq(forecast.o.valid & contexts.w_rdy),
                     forecast.o.ready.eq(self.o.ready & contexts.w_rdy)]
        out = forecast.o.payload
        deltas = Signal(layout.members["delta"])
        k = p.segments
        offsets = [(out.segment_rows[n] - out.row).as_signed() for n in range(k)]
        written = Signal(layout)
        m.d.comb += [written.row.eq(out.row), written.motion.eq(forecast.motion),
                     written.delta.eq(deltas),
                     *[written.delta[out.camera * k + n].eq(offsets[n]) for n in range(k)],
                     contexts.w_data.eq(written.as_value()),
                     contexts.w_en.eq(self.o.valid & self.o.ready & out.last)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += [deltas[out.camera * k + n].eq(offsets[n]) for n in range(k)]

        # --- the filter's updates → the motion track → Y, restarted with the filter
        connect(m, forecast.track, track.i)
        m.d.comb += [track.frame_rows.eq(self.frame_rows), track.alpha.eq(self.track_alpha),
                     track.initial.eq(self.initial), track.restart.eq(requests.restarting),
                     self.counters.track_saturated.eq(track.saturated),
                     self.counters.track_overrange.eq(track.overrange)]
        if "track" in self.signature.members:
            connect(m, track.o, flipped(self.track))
        else:
            m.d.comb += track.o.ready.eq(1)
        with m.If(track.o.valid & track.o.ready):
            m.d.sync += self.track_y.eq(track.o.payload)

        # --- i joined with the oldest context → predicted shift, cue store
        context = data.View(layout, contexts.r_data)
        i, q = self.i, shift.i.payload
        take = Signal()
        camera = i.payload.slot >> (p.segments - 1).bit_length()
        m.d.comb += [shift.i.valid.eq(i.valid & contexts.r_rdy),
                     i.ready.eq(shift.i.ready & contexts.r_rdy),
                     take.eq(i.valid & i.ready),
                     contexts.r_en.eq(take & i.payload.last),
                     q.motion.eq(context.motion), q.delta.eq(context.delta[i.payload.slot]),
                     *[getattr(q, name).eq(getattr(i.payload, name))
                       for name in i.payload.shape().members],
                     requests.write_en.eq(take & (i.payload.cue != 0)),
                     requests.write_slot.eq(i.payload.slot),
                     requests.write_row.eq(i.payload.row),
                     requests.write_cue.eq(i.payload.cue)]
        connect(m, shift.coef, forecast.coef)
        counters = self.counters
        with m.If(take & (i.payload.row != context.row)):
            m.d.sync += counters.mismatched.eq(counters.mismatched + 1)
        with m.If(shift.o.valid & shift.o.ready & shift.saturated):
            m.d.sync += counters.predicted_saturated.eq(counters.predicted_saturated + 1)

        # --- judged → solver (with the row's verdict) → records → forecast
        connect(m, shift.o, stage.i)
        # the judged measurements to the solver and, as verdicts, to the status' counts
        judged = data.StructLayout({"measurement": stage.o.payload.shape(), "judged": 1,
                                    "outlier": 1, "determinable": 1})
        m.submodules.judged_fork = judged_fork = StreamFork(judged, 2)
        to_solver, to_status = judged_fork.o
        m.d.comb += [judged_fork.i.valid.eq(stage.o.valid), stage.o.ready.eq(judged_fork.i.ready),
                     judged_fork.i.payload.measurement.eq(stage.o.payload),
                     judged_fork.i.payload.judged.eq(stage.judged),
                     judged_fork.i.payload.outlier.eq(stage.outlier),
                     judged_fork.i.payload.determinable.eq(stage.determinable),
                     solver.i.valid.eq(to_solver.valid), to_solver.ready.eq(solver.i.ready),
                     solver.i.payload.eq(to_solver.payload.measurement),
                     self.verdicts.valid.eq(to_status.valid),
                     to_status.ready.eq(self.verdicts.ready),
                     self.verdicts.payload.judged.eq(to_status.payload.judged),
                     self.verdicts.payload.outliers.eq(to_status.payload.outlier),
                     self.verdicts.payload.confident.eq(
                         to_status.payload.measurement.conf != 0),
                     self.verdicts.payload.last.eq(to_status.payload.measurement.last),
                     self.verdicts.payload.determinable.eq(to_status.payload.determinable)]
        # every record to the forecast and out
        m.submodules.record_fork = record_fork = StreamFork(solver.o.payload.shape(), 2)
        connect(m, solver.o, record_fork.i)
        connect(m, record_fork.o[0], forecast.records)
        if p.motion_gain == "information":
            # the moves go straight to the filter, which takes them with the record; the
            # solver starts its next row only once they are taken, so the filter's
            # prediction is settled (update_clocks) before the row's program reads it
            # (cycle 54 of the program)
            assert forecast.record_clocks < 54
            connect(m, solver.gains, forecast.gains)
            taken = record_fork.o[0]
            with m.If(taken.valid & taken.ready & (taken.payload.flags == 0)
                      & ~forecast.gains.payload.ok):
                m.d.sync += self.counters.gain_flagged.eq(self.counters.gain_flagged + 1)
            m.d.comb += [solver.predicted.eq(forecast.predicted),
                         solver.prior_weight.eq(self.prior_weight),
                         solver.smoothing.eq(self.smoothing)]
        connect(m, record_fork.o[1], flipped(self.records))
        m.d.comb += [solver.gated.eq(stage.gated), stage.settings.eq(self.settings),
                     self.counts.eq(stage.counts), self.solver_counters.eq(solver.counters),
                     solver.pivot_log2.eq(self.pivot_log2),
                     self.pivot_log2_error.eq(solver.pivot_log2_error)]
        connect(m, flipped(self.coef_write), solver.coef_write)
        return m

"""The motion forecast after the pose solver (issue 16): the solver's pose records in,
for every camera row about to be read each camera's window centre and the previous
frame's row to compare against out. Bit-accurate model:
:class:`emulator.pose.forecast.ForecastModel`; formats and parameters:
:class:`hdl.pose.forecast_params.ForecastParams`; ``docs/pose/forecast.md``.

Two blocks: :class:`hdl.pose.forecast_filter.MotionFilter` (Holt–Winters on the steps,
the loop delay) and :class:`hdl.pose.forecast_predictor.RowPredictor` (the two
coefficient stores and the per-camera means). This component only joins them: a request
is taken when the predictor is idle and the filter may answer its slot.
"""

from amaranth.hdl import Module
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out, connect, flipped

from hdl.pose.forecast_filter import DEFAULT_SLOT_BITS, MotionFilter
from hdl.pose.forecast_predictor import RowPredictor, output_layout

__all__ = ["Forecast", "request_layout", "output_layout", "default_forecast"]


def request_layout(params, slot_bits=DEFAULT_SLOT_BITS):
    """A camera row about to be read.

    Fields
    ------
    slot : unsigned(slot_bits)
        Its row slot: the count of row periods (``ForecastModel``'s ``slot``), modulo
        ``2**slot_bits``; one request per row slot, in increasing order.
    row : unsigned(row_bits)
        The camera row (addresses the coefficient stores).
    cue : ArrayLayout(cue_fmt, slots)
        The depth cue of every segment (camera-major), raw ``solver.cue_fmt``.
    """
    s = params.solver
    return data.StructLayout({"slot": slot_bits, "row": s.row_bits,
                              "cue": data.ArrayLayout(s.cue_fmt.shape(), s.slots)})


class Forecast(wiring.Component):
    """The motion forecast of one pipeline.

    Parameters
    ----------
    params : ForecastParams
    coefficients, row_coefficients : ndarray (slots, entries_per_slot, 9)
        The contents of the solver's coefficient store and of the across-rows store in
        their layouts (raw; ``PipelineConfig.coef_store`` and ``.row_coef_store``:
        polynomial terms, evaluated by Horner to ``.coef_raw`` and ``.row_coef_raw``,
        which the model reads; or every row).
    slot_bits : int
        Width of the row slot (see :class:`MotionFilter`).
    shared_port : bool
        Expose a second read port of the solver's store: ``coef`` (see
        :class:`RowPredictor`).
    track : bool
        Hand the filter's updates to a motion track: ``track`` (see :class:`MotionFilter`).

    Members
    -------
    requests : In(stream.Signature(request_layout(params, slot_bits)))
    records : In(stream.Signature(PoseSource.layout()))
        One pose record per requested row slot, in order, after that slot's request
        (a row without measurements: any record with a flag). The record of slot ``j``
        must come for a request of a slot ``> j + loop_delay_rows`` to be taken.
    o : Out(stream.Signature(output_layout(params)))
        Per request, one transfer per camera.
    motion : Out(ArrayLayout(motion_fmt, 6))
        The forecast ``Ŷ`` of the row in progress (from its first output until the
        next request's).
    counters : Out(counters_layout(params))
        Saturations counted (:func:`hdl.pose.forecast_predictor.counters_layout`).
    alpha, beta, initial, restart : In
        The filter's run-time gains and restart (see :class:`MotionFilter`).
    gains : In, predicted : Out
        With ``motion_gain="information"``: the filter's (see :class:`MotionFilter`).
    track : Out, with ``track=True``
        The filter's updates (see :class:`MotionFilter`).
    idle : Out(1)
        No request in progress and every request's record taken (and handed to the
        track): a ``restart`` now drops nothing (:class:`hdl.pose.tracking_loop.TrackingLoop` restarts only then).

    Latency: :attr:`latency` clocks from a request's transfer to its first output
    when idle; the row's last output :attr:`row_clocks` clocks after the request when
    outputs are taken at once. Records take :attr:`record_clocks` clocks each.
    """

    def __init__(self, params, coefficients, row_coefficients, *, slot_bits=DEFAULT_SLOT_BITS,
                 shared_port=False, track=False):
        self._filter = MotionFilter(params, slot_bits=slot_bits, track=track)
        self._predictor = RowPredictor(params, coefficients, row_coefficients,
                                       shared_port=shared_port)
        self.params, self.slot_bits = params, slot_bits
        f = self._filter.signature.members
        shared = {"coef": self._predictor.signature.members["coef"]} if shared_port else {}
        information = {"gains": f["gains"], "predicted": f["predicted"]} \
            if params.motion_gain == "information" else {}
        tracked = {"track": f["track"]} if track else {}
        super().__init__({
            **shared, **information, **tracked,
            "requests": In(stream.Signature(request_layout(params, slot_bits))),
            "records": f["records"],
            "o": Out(stream.Signature(output_layout(params))),
            "motion": Out(f["motion"].shape),
            "counters": self._predictor.signature.members["counters"],
            "alpha": f["alpha"], "beta": f["beta"], "initial": f["initial"],
            "restart": f["restart"],
            "idle": Out(1),
        })

    @property
    def latency(self):
        return (self._filter.query_latency + 1 + 6 * self.params.segments - 1
                + self._predictor.drain)

    @property
    def row_clocks(self):
        return self.latency + (self.params.cameras - 1) * self._predictor.camera_clocks

    @property
    def record_clocks(self):
        return self._filter.update_clocks

    def elaborate(self, platform):
        m = Module()
        m.submodules.filter = motion = self._filter
        m.submodules.predictor = predictor = self._predictor
        request = self.requests
        m.d.comb += [
            motion.query.valid.eq(request.valid & predictor.idle),
            motion.query.payload.eq(request.payload.slot),
            request.ready.eq(motion.query.ready & predictor.idle),
            predictor.start.eq(request.valid & request.ready),
            predictor.row.eq(request.payload.row), predictor.cue.eq(request.payload.cue),
            predictor.motion.eq(motion.motion), predictor.motion_valid.eq(motion.motion_valid),
            predictor.motion_saturated.eq(motion.saturated),
            self.motion.eq(motion.motion), self.counters.eq(predictor.counters),
            motion.alpha.eq(self.alpha), motion.beta.eq(self.beta),
            motion.initial.eq(self.initial), motion.restart.eq(self.restart),
            self.idle.eq(predictor.idle & motion.drained),
        ]
        connect(m, flipped(self.records), motion.records)
        if self.params.motion_gain == "information":
            connect(m, flipped(self.gains), motion.gains)
            m.d.comb += self.predicted.eq(motion.predicted)
        if "track" in self.signature.members:
            connect(m, motion.track, flipped(self.track))
        connect(m, predictor.o, flipped(self.o))
        if "coef" in self.signature.members:
            connect(m, flipped(self.coef), predictor.coef)
        return m


def default_forecast():
    """The forecast of a default-sized top (:class:`hdl.top_params.TopParams`: four
    cameras of K = 4 segments, 480 rows): the first two pairs of the ``stereo8-board``
    rig, with that rig's polynomial stores (``PipelineConfig.coef_store`` and
    ``.row_coef_store``, real contents, so Yosys keeps them): the catalog's build, for
    Verilog and synthesis."""
    from golden.rig import Rig, preset
    from hdl.pipeline_config import PipelineConfig
    from hdl.top_params import DEFAULT_CAMERAS
    board = preset("stereo8-board")
    rig = Rig(name="stereo8-board front pairs", cameras=board.cameras[:DEFAULT_CAMERAS],
              row_points=board.row_points, allow_unobservable=True)
    config = PipelineConfig.for_rig(rig)
    return Forecast(config.forecast(), *config.forecast_stores)

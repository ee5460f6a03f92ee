"""The measurement engine: aligned row sets in, the pose solver's measurements out.

Between the camera front end (:class:`hdl.front_end.camera_sync.CameraFrontEnd`, whose row aligner
delivers row ``y`` of every camera as one stream) and the pose solver
(:class:`hdl.pose_solver.PoseSolver`) sit

* :class:`hdl.measurement.row_set_fork.RowSetFork`: each camera's beats to its temporal
  lane, marked ``paired`` when the camera's pair is complete in the set, one ticket per
  row set; it registers ``rows`` (its ``ready`` is the AND of every lane's, which would
  otherwise run on into the row aligner and the camera inputs, issue 17);
* :class:`hdl.register_slice.RegisterSlice` on every lane input: the fork's ``valid``
  follows its forecast join, and a lane's ``ready`` comes through its framer and FIR;
  registered, neither runs on into the other's logic. Likewise on each stereo lane's
  two inputs: the stereo join's ``ready`` waits for both cameras' columns and would
  otherwise chain the pair's two FIRs and framers;
* one temporal lane per camera (:class:`hdl.row_descriptor.RowDescriptor`: the row
  against the same row of the previous frame, K segment measurements), which also
  hands its FIR's bits of the paired rows on (``paired=True``);
* one stereo lane per rectified pair (:class:`hdl.row_descriptor.StereoRowDescriptor`:
  camera A's row against camera B's) on the bits of its pair's two temporal lanes
  (``shared=True``: the descriptor filter is built once per camera), fed only the rows
  of sets in which both cameras are;
* the lanes' shift matchers (:class:`hdl.descriptor.matcher.ShiftMatcher`), one per
  lane or, with ``EngineParams.matcher_ports`` P > 1, one per P lanes of consecutive
  cameras (temporal) or pairs (stereo), each lane's measurements on their own output
  (issue 17 item 3);
* the measurement router (:class:`hdl.measurement.router.MeasurementRouter`): each
  ticket's measurements to the solver's slots, with the pair's disparity as depth cue.

In the closed loop (``EngineParams.follow``, issue 16) the temporal lanes follow rows
(``RowDescriptor(follow=True)``: the previous frame's row the forecast names, at the
forecast's window centre), a ``forecast`` input takes the forecast's rows
(:class:`hdl.measurement.forecast_rows.ForecastRows` gathers each), and the fork joins
one with each row set, checking their row keys (mismatches counted and resynchronized,
:mod:`hdl.measurement.row_set_fork`). The stereo lanes stay at the ``cfg`` centre and
their built window: they take the temporal lanes' bits, not their rows' metadata.

The bit-accurate model is :mod:`emulator.measurement.engine`; ``docs/measurement/measurement_engine.md``
has the figures.
"""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.descriptor.framer import saturate_half_width
from hdl.descriptor.layouts import descriptor_layout
from hdl.descriptor.matcher import ShiftMatcher
from hdl.front_end.params import CameraParams
from hdl.measurement.engine_params import (EngineParams, engine_config_layout,
                                           engine_status_layout)
from hdl.measurement.forecast_rows import ForecastRows
from hdl.measurement.router import MeasurementRouter
from hdl.pose.params import PoseSolverParams
from hdl.pose_solver import measurement_layout
from hdl.row_descriptor import RowDescriptor, StereoRowDescriptor, connect_shared_bits
from hdl.measurement.row_set_fork import RowSetFork
from hdl.register_slice import RegisterSlice

__all__ = ["EngineParams", "MeasurementEngine", "default_engine_params", "engine_config_layout",
           "engine_status_layout", "default_follow_engine"]


def default_engine_params():
    """Four 640×480 cameras in two pairs (0, 1) and (2, 3), four temporal segments."""
    camera = CameraParams(n_cameras=4)
    solver = PoseSolverParams(slots=16, rows=camera.max_height)
    return EngineParams.for_cameras(camera, solver, ((0, 1), (2, 3)))


def default_follow_engine():
    """The closed-loop engine of one 640×480 stereo pair: K = 4 temporal segments, K_s =
    4 stereo segments, following lanes, the router's cue fallback (the catalog's
    ``follow_engine``, a small build for its resources)."""
    camera = CameraParams(n_cameras=2)
    solver = PoseSolverParams(slots=8, rows=camera.max_height)
    return MeasurementEngine(EngineParams.for_cameras(
        camera, solver, ((0, 1),), stereo_segments=4, follow=True, cue_fallback=True))


class MeasurementEngine(wiring.Component):
    """Row-descriptor lanes of a camera cluster with their fork and router.

    Parameters
    ----------
    params : EngineParams
        Default :func:`default_engine_params`.

    Members
    -------
    rows : In(stream.Signature(params.aligned_layout()))
        Row sets from ``CameraFrontEnd.o`` (``CameraParams.aligned_layout()``).
    forecast : In(stream.Signature(params.forecast_layout())), with ``follow`` only
        The forecast's rows, ``cameras`` transfers each (``camera``, ``centre``,
        ``source_row``, ``row``, ``last``), one per row set in camera-row order.
    cfg : In(engine_config_layout(params))
        ``temporal[k]`` (without ``follow``): window centre of camera ``k``'s temporal
        lane, sampled with each row's first pixel; ``stereo[j]``: of pair ``j``'s stereo
        lane, sampled with each paired row's first descriptor column, the temporal
        lanes' ``bits_latency`` clocks later (integer pixels, ``centre_fmt``, saturated to
        ``±centre_range``); ``enable``: 0 drops row sets (counted), sampled with each
        set's first column; ``half_width``: every temporal lane's run-time window
        half-width (``centre ± w`` within the built window, sampled with each row's
        first pixel; out of range: the built maximum, ``status.half_width_error``).
    o : Out(stream.Signature(hdl.pose_solver.measurement_layout(params.router.solver)))
        The pose solver's input (``slot, row, time, shift, cue, conf, last``).
    status : Out(engine_status_layout(params))
        ``row_sets``, ``dropped``, ``stereo_skipped[j]`` (the fork's) and ``router``
        (the router's counters); all wrap. ``half_width_error``: ``cfg.half_width``
        is out of range (live). With ``follow`` also ``forecast_skipped``,
        ``unforecast`` (the fork's join), ``malformed`` (forecast rows discarded) and
        ``out_of_range[k]`` (the lanes' ring stores, saturating).

    Latency :attr:`latency` clocks from a row set's last column to its first solver
    transfer (66 with K_s = 1, 67 with K_s = 2 on 256-pixel rows; checked in the cocotb
    benches). Throughput: one column per clock (with shared matchers one per
    ``matcher_ports`` clocks) while the lanes and ``o`` keep up (the
    router needs K · cameras + a few clocks per row, far fewer than the row width).
    Backpressure on ``o`` fills the router's lane FIFOs, then stalls the lanes, the
    fork and ``rows``. With ``follow`` a row set's first column also waits for its
    forecast row (no clock is lost when the row is there first). Reset empties the
    pipeline; every reference row is invalid until a frame has passed.
    """

    def __init__(self, params=None):
        params = default_engine_params() if params is None else params
        if not isinstance(params, EngineParams):
            raise TypeError(f"params must be an EngineParams, not {params!r}")
        self.params = params
        self.fork = RowSetFork(params)
        self.temporal_lanes = [RowDescriptor(params.temporal, params.follow, paired=True,
                                             own_matcher=False)
                               for _ in range(params.cameras)]
        self.temporal_slices = [RegisterSlice(params.temporal.input_layout(params.follow,
                                                                           paired=True))
                                for _ in range(params.cameras)]
        self.forecast_rows = ForecastRows(params) if params.follow else None
        follow = {"forecast": In(stream.Signature(params.forecast_layout()))} \
            if params.follow else {}
        self.stereo_lanes = [StereoRowDescriptor(params.stereo, shared=True, own_matcher=False)
                             for _ in params.pairs]
        # lanes share shift matchers, ``matcher_ports`` at a time
        self.temporal_matchers = [ShiftMatcher(params.temporal, ports=len(group)) for group
                                  in params.matcher_groups(params.cameras)]
        self.stereo_matchers = [ShiftMatcher(params.stereo, ports=len(group)) for group
                                in params.matcher_groups(len(params.pairs))]
        # the stereo join's ``ready`` waits for both cameras' columns: registered, it does
        # not run on into the other temporal lane's FIR and framer (issue 17, 14 LUT
        # levels in the board top without them)
        self.stereo_slices = [[RegisterSlice(descriptor_layout(params.stereo, 1))
                               for _ in "ab"] for _ in params.pairs]
        self.router = MeasurementRouter(params.router)
        super().__init__({
            "rows": In(stream.Signature(params.aligned_layout())),
            **follow,
            "cfg": In(engine_config_layout(params)),
            "o": Out(stream.Signature(measurement_layout(params.router.solver))),
            "status": Out(engine_status_layout(params)),
        })

    @property
    def latency(self):
        """Clocks from a row set's last column to its row's first solver transfer when
        nothing stalls: the fork's input register, a temporal lane's input slice, the
        later of the lanes' last measurements (temporal segment K − 1; stereo segment
        K_s − 1, its lane after the temporal lanes' FIRs), then the router, whose count
        from a ticket includes the clock a measurement takes into its lane FIFO and the
        K_s clocks that take the stereo measurements, all but the last overlapping their
        arrival (66 clocks with K_s = 1, 67 with K_s = 2 on 256-pixel rows, measured in
        the cocotb benches). With shared matchers (``matcher_ports`` P > 1) a row's
        results wait for up to P − 1 engine jobs of the other lanes' last segments (148
        clocks with P = 2 on 256-pixel rows), with columns coming every P clocks, the rate
        the matchers take them at; faster, the lanes back up and the latency grows."""
        t, s = self.params.temporal, self.params.stereo
        lane = self.temporal_lanes[0]
        temporal = max(matcher.last_port_latency for matcher in self.temporal_matchers)
        stereo = max(matcher.last_port_latency for matcher in self.stereo_matchers)
        lanes = self.temporal_slices[0].latency + max(
            lane.columns_latency + temporal + t.segments - 1,
            lane.bits_latency + RegisterSlice.latency + self.stereo_lanes[0].columns_latency
            + stereo + s.segments - 1)
        return self.fork.latency + lanes + self.router.latency - s.segments

    def elaborate(self, platform):
        m = Module()
        m.submodules.fork = fork = self.fork
        m.submodules.router = router = self.router
        wiring.connect(m, wiring.flipped(self.rows), fork.i)
        m.d.comb += fork.enable.eq(self.cfg.enable)
        for k, lane in enumerate(self.temporal_lanes):
            m.submodules[f"temporal{k}"] = lane
            m.submodules[f"temporal{k}_slice"] = lane_slice = self.temporal_slices[k]
            wiring.connect(m, fork.temporal[k], lane_slice.i)
            wiring.connect(m, lane_slice.o, lane.i)
            m.d.comb += lane.half_width.eq(self.cfg.half_width)
            if self.params.follow:
                m.d.comb += self.status.out_of_range[k].eq(lane.out_of_range)
            else:
                m.d.comb += lane.centre.eq(self.cfg.temporal[k])
        for j, (lane, (a, b)) in enumerate(zip(self.stereo_lanes, self.params.pairs)):
            m.submodules[f"stereo{j}"] = lane
            for side, camera, lane_slice in zip("ab", (a, b), self.stereo_slices[j]):
                m.submodules[f"stereo{j}_slice_{side}"] = lane_slice
                connect_shared_bits(m, self.temporal_lanes[camera].bits, lane_slice.i)
                wiring.connect(m, lane_slice.o, getattr(lane, side))
            m.d.comb += lane.centre.eq(self.cfg.stereo[j])
        for kind, lanes, matchers, outputs in (
                ("temporal", self.temporal_lanes, self.temporal_matchers, router.temporal),
                ("stereo", self.stereo_lanes, self.stereo_matchers, router.stereo)):
            groups = self.params.matcher_groups(len(lanes))
            for g, (matcher, group) in enumerate(zip(matchers, groups)):
                m.submodules[f"{kind}_matcher{g}"] = matcher
                inputs, results = ((matcher.i, matcher.o) if matcher.ports > 1
                                   else ([matcher.i], [matcher.o]))
                for k, port, result in zip(group, inputs, results):
                    wiring.connect(m, lanes[k].columns, port)
                    wiring.connect(m, result, outputs[k])
        if self.params.follow:
            m.submodules.forecast_rows = forecast_rows = self.forecast_rows
            wiring.connect(m, wiring.flipped(self.forecast), forecast_rows.i)
            wiring.connect(m, forecast_rows.o, fork.forecast)
            m.d.comb += [self.status.forecast_skipped.eq(fork.status.forecast_skipped),
                         self.status.unforecast.eq(fork.status.unforecast),
                         self.status.malformed.eq(forecast_rows.malformed)]
        wiring.connect(m, fork.tickets, router.tickets)
        wiring.connect(m, router.o, wiring.flipped(self.o))
        m.d.comb += [self.status.half_width_error.eq(
                         saturate_half_width(self.params.temporal, self.cfg.half_width)[1]),
                     self.status.row_sets.eq(fork.status.row_sets),
                     self.status.dropped.eq(fork.status.dropped),
                     self.status.stereo_skipped.eq(fork.status.stereo_skipped),
                     self.status.router.eq(router.status)]
        return m

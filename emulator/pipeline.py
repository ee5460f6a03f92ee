"""The bit-accurate pipeline: simulated rows → row-descriptor lanes → router → pose solver.

Composed of the per-block models the cocotb benches check the HDL against (their own
functions and classes, not copies): :class:`emulator.row_descriptor.TemporalLaneModel`
(one per camera), :class:`emulator.row_descriptor.StereoLaneModel` (one per rectified
pair), :mod:`emulator.measurement.router` and :func:`emulator.pose_solver.pose_solver_model`.

What enters where the hardware's front end would be: each row of the dataset as a
:class:`emulator.descriptor.framer.FramedRow` (what the framer hands on for a clean row:
exactly ``width`` pixels, no reason bits), its time stamp the row's exposure time since
the first row in clocks of ``clk_hz``, the matcher's run-time centre 0. Rows go
through the lanes as row sets, all cameras' row ``y`` of frame ``i`` together, as the
row aligner delivers them. The camera-input and aligner models (flags of faulty rows)
are not in this path yet.

What a step means. The temporal lane compares row ``y`` with row ``y`` of the previous
frame, so the solved step of a row set is the rig's motion over one frame period, from
the pose of that row slot one frame earlier, in its body frame (``golden.tracker``'s
``Y`` with the ``"previous"`` reference). The solver's integrator, however, composes
each row's step onto the *previous row's* pose; its integrated pose is reported as the
hardware computes it, but it is not a trajectory estimate for this measurement (see
``docs/e2e.md``). With a forecast (:func:`run`'s ``forecast``) the lanes compare each
row with the previous frame's row the forecast names, at the forecast's window centre:
the step is still the one-frame motion, now measured around the prediction.
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from emulator.measurement.router import pose_rows, route_row, usable_cues
from emulator.pose.motion_track import MotionTrackModel
from emulator.pose.tracking_loop import TrackingLoopModel
from emulator.pose_solver import pose_solver_model
from emulator.descriptor.framer import FramedRow
from emulator.row_descriptor import StereoLaneModel, TemporalLaneModel

__all__ = ["PipelineResult", "run"]


@dataclass(frozen=True)
class PipelineResult:
    """What the pipeline model produced.

    Members
    -------
    temporal, stereo : list of dict
        Every lane measurement, in processing order.
    transfers : list of dict
        The router's output (the solver's input stream).
    rows : PoseRows
        The same transfers, one row per row set (the solver model's input).
    records : dict of ndarray
        The solver's pose records (:func:`emulator.pose_solver.pose_solver_model`).
    frame : ndarray (n,)
        Dataset frame of each record (``records["row"]`` is its row).
    seconds : float
        Wall time of the run.
    camera_rows : int
        Camera rows processed (``rows_per_s`` counts them per second of wall time).
    loop : dict of ndarray or None
        Closed loop only (``forecast`` given): per row set, in order, ``frame``, ``row``,
        ``slot``, the forecast ``centre`` and ``source_row`` (n, cameras) it used and its
        saturation flags, ``segment_rows`` (n, cameras, K) the rows its lanes read, and
        ``level`` (n, 6) the filter's level after the row's step (raw ``motion_fmt``);
        with a consistency stage also ``counts``, its counters
        (:class:`emulator.measurement.consistency.ConsistencyModel`), and ``row_counts``
        (records, 4): each record's row's ``(judged, outliers, confident,
        determinable)``, the tracking-status unit's per-row input.
    """
    temporal: list
    stereo: list
    transfers: list
    rows: object
    records: dict
    frame: np.ndarray
    seconds: float
    camera_rows: int
    loop: dict = None

    @property
    def rows_per_s(self):
        return self.camera_rows / self.seconds

    def steps(self, config):
        """Solved steps (n, 6) as floats (metres, radians); NaN where flagged."""
        fmt = config.router.solver.step_fmt
        step = fmt.to_float(np.asarray(self.records["step"]))
        return np.where(self.records["flags"][:, None] == 0, step, np.nan)


def _framed(dataset, camera, frame, row, config, t0):
    """Dataset row as the framer hands a clean row on; ``t0`` is the first row's
    exposure time (s), the zero of the time stamps."""
    lane = config.router.temporal
    ticks = int(round((dataset.cameras[camera].time[frame, row] - t0) * config.clk_hz))
    return FramedRow(pixels=dataset.cameras[camera].rows[frame, row].astype(np.int64),
                     camera=camera, frame=frame % (1 << lane.frame_bits), row=row,
                     t_first=ticks % (1 << lane.timestamp_bits), centre=0, bad=False,
                     padded=False)


def run(config, dataset, frames=None, *, progress=False, forecast=None, initial_motion=None,
        consistency=None, cue_fallback=False, restart=None):
    """Run the dataset (first ``frames`` frames, default all) through the pipeline of
    ``config`` (:class:`hdl.pipeline_config.PipelineConfig`); ``progress`` shows a bar
    over the frames.

    Each lane takes a whole frame of its rows at once (the lane models' batched path,
    equal to row by row); the router then takes the row sets in (frame, row) order.

    With ``forecast`` (:class:`hdl.pose.forecast_params.ForecastParams`) the loop is
    closed (issue 16): row by row, the forecast model
    (:class:`emulator.pose.forecast.ForecastModel`, started at ``initial_motion``, float
    (6,)) sets each temporal lane's window centre and the previous frame's row it reads
    (:class:`emulator.row_descriptor.FollowedReferenceStoreModel`), with the depth cue
    each segment had in the same row of the previous frame, and takes each row's solved
    step. The stereo lanes stay open loop (centre 0). With ``consistency``
    (:class:`hdl.measurement.consistency_params.ConsistencyParams`, closed loop only)
    each row's transfers pass :class:`emulator.measurement.consistency.ConsistencyModel`
    against the forecast's predicted shifts (with the row's own depth cues) before the
    solver. With ``cue_fallback`` a segment whose stereo match fails takes its pair's
    last usable cue of the same row (the previous frame's; a store of
    ``pairs × K_s × height`` cues). With ``restart`` = ``(frame, motion)`` (closed loop
    only) the loop restarts before that frame's first row at ``motion`` (float (6,)),
    its row slots counted from that row (:meth:`TrackingLoopModel.restart`, where the
    gateware's ``restart`` takes effect)."""
    from tqdm import tqdm
    router = config.router
    cams = range(router.cameras)
    frames = min(len(c.rows) for c in dataset.cameras) if frames is None else frames
    height, k, k_s = router.temporal.height, router.temporal.segments, router.stereo.segments
    follow = forecast is not None
    temporal_lanes = [TemporalLaneModel(router.temporal, follow) for _ in cams]
    stereo_lanes = [StereoLaneModel(router.stereo) for _ in router.pairs]
    temporal, stereo, transfers, record_frames = [], [], [], []
    fallback = {}                 # row -> {(camera A, stereo segment): last usable cue}
    t0 = min(float(cam.time[0, 0]) for cam in dataset.cameras)
    if consistency is not None and not follow:
        raise ValueError("consistency needs forecast (it judges shifts against it)")
    if restart is not None and not follow:
        raise ValueError("restart needs forecast (it restarts the loop)")
    loop = _Loop(config, forecast, initial_motion, dataset, t0, consistency) if follow \
        else None
    start = time.perf_counter()
    for frame in tqdm(range(frames), desc="emulator", unit="frame", disable=not progress,
                      leave=False):
        rows = [[_framed(dataset, n, frame, row, config, t0) for row in range(height)]
                for n in cams]
        t = None if follow else [lane.process_rows(rows[n])
                                 for n, lane in zip(cams, temporal_lanes)]
        s = [lane.process_pairs(rows[a], rows[b])
             for lane, (a, b) in zip(stereo_lanes, router.pairs)]
        if restart is not None and frame == restart[0]:
            loop.restart(frame, restart[1])
        for row in range(height):
            if follow:
                t_row = loop.measure(temporal_lanes, [rows[n][row] for n in cams], frame)
            else:
                t_row = [m for per_camera in t for m in per_camera[row * k:(row + 1) * k]]
            s_row = [m for per_pair in s for m in per_pair[row * k_s:(row + 1) * k_s]]
            out = route_row(router, t_row, s_row, fallback.get(row) if cue_fallback else None)
            if cue_fallback:
                fallback[row] = {**fallback.get(row, {}), **usable_cues(router, s_row)}
            if follow:
                out = loop.close(out, frame, row)
            temporal += t_row
            stereo += s_row
            transfers += out
            record_frames += [frame] if out else []
    rows = pose_rows(router, transfers)
    records = pose_solver_model(router.solver, config.coef_raw, rows)
    seconds = time.perf_counter() - start
    return PipelineResult(temporal=temporal, stereo=stereo, transfers=transfers, rows=rows,
                          records=records, frame=np.array(record_frames), seconds=seconds,
                          camera_rows=frames * height * router.cameras,
                          loop=loop.history() if follow else None)


class _Loop:
    """The closed loop of :func:`run`: forecast → lane centres and row addresses →
    measurements → solved step → forecast. The back half, from the router's transfers to
    the forecast, is :class:`emulator.pose.tracking_loop.TrackingLoopModel` (the
    gateware's model); this adds the lanes and the row slots of the dataset's times."""

    def __init__(self, config, params, initial_motion, dataset, t0, consistency=None):
        if initial_motion is None:
            raise ValueError("initial_motion must be given with forecast")
        self.config, self.params = config, params
        self.model = TrackingLoopModel(params, config.coef_raw, config.row_coef_raw,
                                       params.motion_fmt.quantize(initial_motion),
                                       consistency)
        self.time, self.t0 = dataset.cameras[0].time, t0
        self.t_r = dataset.rig.cameras[0].t_r
        self.log, self.row_counts = [], []
        # the motion track (the gateware loop's track) needs a whole frame of row periods
        frame_rows = config.frame_rows
        self.track = None if abs(frame_rows - round(frame_rows)) > 1e-6 else \
            MotionTrackModel(params, round(frame_rows), params.motion_fmt.quantize(initial_motion))

    def slot(self, frame, row):
        return int(round((self.time[frame, row] - self.t0) / self.t_r))

    def restart(self, frame, motion):
        """The loop restarted at ``motion`` (float (6,)) before ``frame``'s first row,
        which becomes row slot 0."""
        self.model.restart(self.params.motion_fmt.quantize(motion))
        if self.track is not None:
            self.track.restart(self.params.motion_fmt.quantize(motion))
        self.t0 = float(self.time[frame, 0])

    def measure(self, lanes, rows, frame):
        """The temporal measurements of one row set at the forecast centres and rows."""
        row = rows[0].row
        prediction = self.model.request(self.slot(frame, row), row)
        centres, sources = prediction["centre"], prediction["segment_rows"]
        return [m for lane, framed, centre, source in zip(lanes, rows, centres, sources)
                for m in lane.process_rows([replace(framed, centre=int(centre))],
                                           [source])]

    def close(self, transfers, frame, row):
        """Judge the row's transfers (with a consistency stage), keep its depth cues for
        the next frame and feed its step (if solved) to the forecast; returns the
        transfers the solver takes."""
        slot = self.slot(frame, row)
        motion = self.model.forecast.filter
        before = motion.level.copy(), motion.trend.copy()
        transfers, level = self.model.close(transfers, slot, row)
        p = self.model.prediction
        tracked = None if self.track is None else \
            self.track.update(slot, *before, None if self.model.step is None else level)
        self.log.append((frame, row, slot, p["centre"], p["centre_saturated"],
                         p["source_row"], p["row_saturated"], p["segment_rows"], level,
                         tracked))
        if self.model.row_counts is not None:
            self.row_counts.append(self.model.row_counts)
        return transfers

    def history(self):
        names = ("frame", "row", "slot", "centre", "centre_saturated", "source_row",
                 "row_saturated", "segment_rows", "level", "track")
        out = {name: np.array([entry[k] for entry in self.log])
               for k, name in enumerate(names)}
        if self.track is None:
            del out["track"]
        else:
            out["track_saturated"] = self.track.saturated
        if self.model.consistency is not None:
            out["counts"] = self.model.counts
            out["row_counts"] = np.array(self.row_counts, dtype=np.int64).reshape(-1, 4)
        return out

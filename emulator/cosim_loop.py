"""Co-simulation of the closed-loop top (issue 16) against the emulator's closed loop.

:func:`closed_loop_cosim` builds the whole :class:`hdl.top.RowtrackTop` of
``PipelineConfig.for_rig(rig, closed_loop=True)`` for a dataset's rig, plays every row of
the dataset's first frames on its DVP pins (:mod:`emulator.hdl_sim.cosim_bench`, the
open-loop co-simulation's bench), and compares, record by record, what the PS reads from
the FIFO, what the tracking loop's solver emitted (with its step), its motion track's ``Y``
of every row and every forecast row the engine took (each camera's window centre and source row) with
:func:`emulator.pipeline.run`'s closed loop on the same rows, the flags annotated by
:class:`emulator.pose.tracking_status.StatusUnitModel` as the gateware's status unit
does. Forecast → lane centre and row address → measurement → solver → forecast all run
in the HDL; nothing of the loop is fed from the model.

The loop runs from reset (the forecast filter at rest, the emulator's initial motion
0). Given an initial motion, the bench writes it to ``loop.initial`` and strobes
``loop.restart`` right after reset; a restart takes effect at the next frame boundary
of the forecast once the rows already forecast are solved (from frame 1 when written
after reset; :class:`hdl.pose.tracking_loop.TrackingLoop`), which
:func:`emulator.pipeline.run`'s ``restart=(frame, motion)`` models.

The emulator counts row slots from the dataset's time stamps, the hardware from the
row order and ``frame_rows`` (:mod:`hdl.pose.loop_requests`): the rig's frame period
must be a whole number of row periods, and the emulator's slots must be
``frame · frame_rows + row`` (checked). The records' time stamps are the HDL clock's:
``t_row`` is compared with the router's rule applied to the row sets the HDL front end
produced (the lowest camera's ``t_first``), whose pixels must be the dataset's.
"""

import hashlib
from dataclasses import dataclass

import numpy as np

from emulator.cosim import (camera_stimulus, checked_input, compare_records, latency_clocks,
                            pin_latencies, record_arrays, row_sets_from_columns, run_bench,
                            slice_rig)
from golden.tracker_params import DEFAULT_MOTION_GAIN
from hdl.descriptor.params import DEFAULT_SEGMENTS

__all__ = ["SOLVER_FIELDS", "FORECAST_FIELDS", "TRACK_FIELDS", "LoopCosimResult", "cut_rig", "cut_slice",
           "slice_dataset", "loop_expected", "judge", "closed_loop_cosim"]

#: Fields of the tracking loop's solver records compared (the solver's formats, before
#: the status unit and the output's narrowing): the step and the integrated pose.
SOLVER_FIELDS = ("row", "time", "flags", "q", "p", "step")
#: Fields of the forecast rows the engine takes compared: the camera row, and per camera
#: its lane's window centre and the previous frame's row each of its segments reads
#: (``segment_rows``).
FORECAST_FIELDS = ("row", "centre", "segment_rows")
#: Fields of the motion track's rows compared: ``Y`` (raw ``motion_fmt``, six axes).
TRACK_FIELDS = ("y",)


def cut_rig(rig, rows):
    """``rig`` (a :class:`golden.rig.Rig`) with ``rows`` rows around the optical centre,
    each read out over the same time as before (``t_r`` scaled by ``height / rows``), so
    the frame period stays a whole number of row periods when it was one with the
    full-height rows (stereo8: 600 → ``rows · 600/480``)."""
    return _cut(rig, rows, (rig.cameras[0].height - rows) / 2)


def _cut(rig, rows, first):
    """``rig`` with rows ``first … first + rows − 1`` of every camera (the same row
    directions: ``cy`` moves with the cut), each read out over ``height / rows`` row
    periods."""
    from golden.rig import Rig
    return Rig(name=rig.name, cameras=tuple(
        c.replace(height=rows, cy=c.cy - first, t_r=c.t_r * c.height / rows)
        for c in rig.cameras), row_points=rig.row_points, nominal_depth=rig.nominal_depth,
        allow_unobservable=rig.allow_unobservable)


def cut_slice(rig, cameras, rows, segments=DEFAULT_SEGMENTS):
    """The rig a run's closed-loop co-simulation plays: the ``cameras / 2`` stereo pairs
    of ``rig`` that observe the motion best (:func:`emulator.cosim.slice_rig`), cut to
    each camera's ``rows`` middle rows (:func:`_cut`). Returns ``(rig, chosen rig
    cameras, first row)``.

    Raises
    ------
    ValueError
        ``cameras`` not whole stereo pairs, ``rows`` beyond the height, or a frame
        period that is not a whole number of the cut rig's row periods (the hardware
        counts row slots per frame).
    """
    from golden.checks import check_int
    sub, chosen = slice_rig(rig, cameras, segments)
    height = sub.cameras[0].height
    check_int("rows", rows, 1, height)
    frame_rows = rows / (sub.cameras[0].fps * sub.cameras[0].t_r * height)
    if abs(frame_rows - round(frame_rows)) > 1e-6:
        raise ValueError(f"rows {rows}: a frame of the cut rig lasts {frame_rows:g} of its "
                         f"row periods; the hardware counts a whole number (choose rows so "
                         f"that rows · frame period / (height · t_r) is an integer)")
    first = (height - rows) // 2
    return _cut(sub, rows, first), chosen, first


def slice_dataset(dataset, cameras, rows, segments=DEFAULT_SEGMENTS):
    """The part of a run's ``dataset`` the closed-loop top co-simulates
    (:func:`cut_slice`'s cameras and rows), as a dataset of its own; ``(dataset, chosen
    dataset cameras, first row)``.

    The co-simulation compares the HDL with the emulator on the same input: the rows
    keep their pixels and are restamped to the cut rig's row times (frame ``f``'s row
    ``r`` at its first row's time + ``r · t_r'``), so that the emulator counts the row
    slots the hardware counts from the row order. The truth arrays are the kept rows'
    poses, at their own (not the new) times: what the first frame's motion is read from
    (:func:`emulator.hardware_path.first_frame_motion`)."""
    from golden.dataset import CameraRecording, Dataset
    cut, chosen, first = cut_slice(dataset.rig, cameras, rows, segments)
    kept = slice(first, first + rows)
    times = cut.cameras[0].t_r * np.arange(rows)
    recordings = [CameraRecording(
        rows=rec.rows[:, kept], time=rec.time[:, :1] + times,
        **{name: getattr(rec, name)[:, kept]
           for name in ("rotation", "position", "velocity", "angular_velocity")})
        for rec in (dataset.cameras[k] for k in chosen)]
    return Dataset(rig=cut, cameras=recordings, info=dict(dataset.info)), chosen, first


@dataclass(frozen=True)
class LoopCosimResult:
    """What a closed-loop co-simulation produced and how it compares.

    Members
    -------
    records, expected : dict
        PS FIFO records (HDL) and the emulator's, :data:`emulator.cosim.RECORD_FIELDS`
        arrays (``flags`` with the status bits).
    solver, solver_expected : dict
        The loop's solver records (HDL) and the emulator's, :data:`SOLVER_FIELDS`.
    forecasts, forecasts_expected : dict
        The forecast rows the engine took (HDL) and the emulator's,
        :data:`FORECAST_FIELDS` (``centre``: (rows, cameras); ``segment_rows``: (rows,
        cameras, K)).
    forecasts_ahead : int
        Forecast rows the engine took beyond the played rows (at most
        ``loop_delay_rows + 1``, left out of ``forecasts``; more are compared, and count
        as mismatches).
    track, track_expected : dict
        The motion track's ``Y`` of every row (HDL) and the emulator's,
        :data:`TRACK_FIELDS` (``y``: (rows, 6)).
    mismatches, solver_mismatches, forecast_mismatches, track_mismatches : int
        Differing fields of the four comparisons (:func:`emulator.cosim.compare_records`).
    first_mismatch : str or None
        The first difference of any.
    solved : int
        Records the emulator solved (flags 0), all of whose steps were compared.
    frames, row_sets : int
    rows_match : bool
        The HDL's row sets are the dataset's rows, in order, every camera present.
    slots : ndarray
        The emulator's row slot of every row (``frame · frame_rows + row``, frames counted
        from frame 1 after a restart there; checked).
    latency_clocks : int
        Largest clocks from a row set's last pixel at the pins to its record in the PS
        FIFO (-1 if the counts differ).
    record_latency_clocks : ndarray
        Per row set: clocks from its last pixel at the pins to the tracking loop's solver
        record (empty if the counts differ).
    forecast_after_record_clocks : ndarray
        Per row set ``k`` with a row ``k + 1 + loop_delay_rows`` in its frame: clocks
        from its solver record to that row's forecast (the first to include ``k``'s step)
        first offered to the engine; NaN when that forecast was offered before the
        record.
    forecast_lead_clocks : ndarray
        Per row set: clocks from the engine taking the row's forecast (its last
        transfer) to the row set's first column offered at the engine's input (> 0: the
        forecast was there first).
    clocks_per_row_set : float
        Mean clocks from a row set's first to its last column taken by the engine.
    row_period_clocks : float
        Mean clocks between consecutive row sets of a frame (first columns taken).
    engine_stall_clocks : int
        Clocks a row set's column was offered to the engine and not taken.
    status : dict
        Counters read at the end (engine, solver, loop, tracking status, cameras).
    clocks, wall_s, timings, clk_hz, uart_packets_match
        As :class:`emulator.cosim.CosimResult`.
    """
    records: dict
    expected: dict
    solver: dict
    solver_expected: dict
    forecasts: dict
    forecasts_expected: dict
    forecasts_ahead: int
    track: dict
    track_expected: dict
    mismatches: int
    solver_mismatches: int
    forecast_mismatches: int
    track_mismatches: int
    first_mismatch: str | None
    solved: int
    frames: int
    row_sets: int
    rows_match: bool
    slots: np.ndarray
    latency_clocks: int
    record_latency_clocks: np.ndarray
    forecast_after_record_clocks: np.ndarray
    forecast_lead_clocks: np.ndarray
    clocks_per_row_set: float
    row_period_clocks: float
    engine_stall_clocks: int
    status: dict
    clocks: int
    wall_s: float
    timings: dict
    clk_hz: float
    uart_packets_match: bool

    @property
    def all_mismatches(self):
        """Differing fields of all four comparisons."""
        return (self.mismatches + self.solver_mismatches + self.forecast_mismatches
                + self.track_mismatches)


def _config(rig, records, motion_gain=DEFAULT_MOTION_GAIN):
    """The board's closed-loop pipeline for ``rig`` (:func:`hdl.top.board_config`) with
    a PS FIFO deep enough for ``records`` records and the filter's ``motion_gain``."""
    from hdl.output.params import PoseOutputParams
    from hdl.top import board_config
    depth = 1 << max(records, 2).bit_length()
    return board_config(rig, pose_output=PoseOutputParams(fifo_depth=depth),
                        motion_gain=motion_gain)


def loop_expected(config, dataset, frames, times, initial_motion=None):
    """The emulator's closed loop on the first ``frames`` frames of ``dataset``, as the
    HDL must give it: ``(FIFO records, solver records, forecast rows, track rows, slots,
    packets)`` (:data:`emulator.cosim.RECORD_FIELDS`, :data:`SOLVER_FIELDS`,
    :data:`FORECAST_FIELDS`, :data:`TRACK_FIELDS`). ``times``: the time stamp of each record (the HDL row sets',
    router rule; the emulator's own where the HDL has fewer). Started as the gateware
    after reset: the forecast filter at rest (initial motion 0); with ``initial_motion``
    the loop restarted at it from frame 1 (``run``'s ``restart``: where the gateware's
    takes effect when written after reset); the flags through the status unit's model
    with the registers' reset settings."""
    from emulator.output import packets
    from emulator.pipeline import run
    from emulator.pose.tracking_status import StatusUnitModel, annotate
    from hdl.pose.status_params import top_status_params
    top = config.top
    result = run(config, dataset, frames, forecast=config.forecast(),
                 initial_motion=np.zeros(6),
                 consistency=config.consistency(), cue_fallback=True,
                 restart=None if initial_motion is None else (1, initial_motion))
    loop = result.loop
    slots = np.asarray(loop["slot"])
    frame = np.asarray(loop["frame"])
    if initial_motion is not None:      # counted again from frame 1's row 0
        frame = np.where(frame >= 1, frame - 1, frame)
    want = frame * int(config.frame_rows) + np.asarray(loop["row"])
    if not np.array_equal(slots, want):
        raise ValueError(f"the emulator's row slots are not frame · {int(config.frame_rows)}"
                         f" + row as the hardware counts them (first at row "
                         f"{int(np.argmax(slots != want))}): the dataset's rows are not "
                         f"read one per row period")
    rec = result.records
    n = len(rec["row"])
    time = np.array([times[k] if k < len(times) else rec["time"][k] for k in range(n)],
                    dtype=np.int64)
    counts = np.asarray(loop["row_counts"])
    flags = annotate(top_status_params(top), rec["flags"], *counts.T,
                     model=StatusUnitModel(top_status_params(top)))
    solver = {**{k: np.asarray(v) for k, v in rec.items()}, "time": time}
    poses = [{"row": rec["row"][k], "time": time[k], "flags": flags[k], "q": rec["q"][k],
              "p": rec["p"][k]} for k in range(n)]
    kept = [r for _, r in packets.keep_poses(top.pose_output, poses, 1)]
    packet = top.pose_output.packet
    uart = b"".join(packets.encode_packet(packet, r) for r in kept)
    forecasts = {"row": np.asarray(loop["row"], dtype=np.int64),
                 "centre": np.array(loop["centre"], dtype=np.int64).reshape(len(slots), -1),
                 "segment_rows": np.array(loop["segment_rows"], dtype=np.int64).reshape(
                     len(slots), top.forecast.cameras, top.forecast.segments)}
    track = {"row": forecasts["row"],
             "y": np.asarray(loop["track"], dtype=np.int64).reshape(len(slots), 6)}
    return record_arrays(packet, kept), solver, forecasts, track, slots, uart


def _solver_arrays(layout, columns):
    from emulator.hdl_sim.payload import unpack
    rows = [unpack(layout, raw) for _, raw in columns]
    return {name: np.array([[r[name][i] for i in sorted(r[name])] if isinstance(r[name], dict)
                            else r[name] for r in rows], dtype=np.int64).reshape(
                                (len(rows), -1) if rows and isinstance(rows[0][name], dict)
                                else (len(rows),))
            for name in SOLVER_FIELDS}


def _track_arrays(forecast, columns, rows):
    """The motion track's rows (:class:`ColumnMonitor` columns of ``Y``) as
    :data:`TRACK_FIELDS` arrays, each with the ``row`` of the solver record it follows
    (-1 beyond them)."""
    from amaranth.lib import data
    from emulator.hdl_sim.payload import unpack
    layout = data.ArrayLayout(forecast.motion_fmt.shape(), 6)
    y = np.array([[axis for _, axis in sorted(unpack(layout, raw).items())]
                  for _, raw in columns], dtype=np.int64).reshape(-1, 6)
    return {"row": np.array([rows[k] if k < len(rows) else -1 for k in range(len(y))],
                            dtype=np.int64), "y": y}


def _first_offers(columns, stalls):
    """The clock each transfer of a monitored stream (:class:`ColumnMonitor` columns and
    stalls) was first offered: its first stall clock after the previous transfer, else
    the clock it was taken."""
    stalls = np.asarray(stalls, dtype=np.int64)
    offers, previous = [], -1
    for clock, _ in columns:
        waiting = stalls[(stalls > previous) & (stalls < clock)]
        offers.append(int(waiting[0]) if len(waiting) else clock)
        previous = clock
    return offers


def _forecast_rows(layout, columns, stalls):
    """The forecast transfers the engine took as rows (a row ends with ``last``):
    :data:`FORECAST_FIELDS` arrays (each camera's in its ``camera`` column, -1 where a
    camera is missing), and per row the clock its first transfer was first offered and
    the clock its last was taken."""
    from emulator.hdl_sim.payload import unpack
    rows, current, offered, taken = [], {}, [], []
    for (clock, raw), offer in zip(columns, _first_offers(columns, stalls)):
        transfer = unpack(layout, raw)
        if not current:
            offered.append(offer)
        current[transfer["camera"]] = transfer
        if transfer["last"]:
            rows.append(current)
            taken.append(clock)
            current = {}
    cameras = max((len(r) for r in rows), default=0)
    segments = len(rows[0][0]["segment_rows"]) if rows and 0 in rows[0] else 0
    missing = [-1] * segments

    def segment_rows(transfer):            # the unpacked array, in segment order
        return [transfer["segment_rows"][n] for n in range(segments)]

    arrays = {"row": np.array([r[max(r)]["row"] for r in rows], dtype=np.int64),
              "centre": np.array([[r[c]["centre"] if c in r else -1 for c in range(cameras)]
                                  for r in rows], dtype=np.int64).reshape(len(rows), cameras),
              "segment_rows": np.array([[segment_rows(r[c]) if c in r else missing
                                         for c in range(cameras)] for r in rows],
                                       dtype=np.int64).reshape(len(rows), cameras, segments)}
    return arrays, offered[:len(rows)], taken


def _forecast_after_record(record_clocks, forecast_offers, frames_of_sets, delay):
    """Per row set ``k`` with a row set ``k + 1 + delay`` in its frame (the first whose
    forecast includes ``k``'s step at loop delay ``delay``): clocks from ``k``'s solver
    record to that row's forecast first offered (NaN: offered before the record)."""
    gaps = []
    n = min(len(record_clocks), len(forecast_offers), len(frames_of_sets))
    for k in range(n - 1 - delay):
        if frames_of_sets[k] == frames_of_sets[k + 1 + delay]:
            gap = forecast_offers[k + 1 + delay] - record_clocks[k]
            gaps.append(gap if gap > 0 else np.nan)
    return np.array(gaps, dtype=float)


def _rows_match(sets, images, frame_bits):
    """The row sets are the images' rows (cameras, frames, rows, width) in order."""
    n_cams, n_frames, height, _ = images.shape
    if len(sets) != n_frames * height:
        return False
    for k, row_set in enumerate(sets):
        frame, row = divmod(k, height)
        if sorted(row_set) != list(range(n_cams)):
            return False
        for cam, beats in row_set.items():
            if (beats[0]["frame"], beats[0]["row"]) != (frame % (1 << frame_bits), row) or \
                    [b["data"] for b in beats] != images[cam, frame, row].tolist():
                return False
    return True


def _forecast_leads(forecasts, forecast_taken, sets, set_offers):
    """Per row set: clocks from the engine taking its forecast row (the last transfer)
    to the set's first column offered at the engine's input; NaN when the forecast row
    for it (same camera row, same position in the order) did not come."""
    leads = []
    for k, (row_set, offered) in enumerate(zip(sets, set_offers)):
        row = next(iter(row_set.values()))[0]["row"]
        leads.append(offered - forecast_taken[k]
                     if k < len(forecast_taken) and forecasts["row"][k] == row else np.nan)
    return np.array(leads, dtype=float)


def _design_key(config):
    """What the closed-loop top's Verilog is built from: its parameters and the contents
    of the stores built into it (rigs of another geometry, e.g. another slice's cameras,
    share the parameters but not the coefficients)."""
    digest = hashlib.sha256(repr(config.top).encode())
    for store in (config.coef_store, *config.forecast_stores):
        digest.update(np.ascontiguousarray(store).tobytes())
    return digest.hexdigest()


def closed_loop_cosim(dataset, *, row_period_s, frames=3, initial_motion=None,
                      sim="verilator", waves=False, seed=None, build_dir="build/cosim_loop",
                      progress=False, motion_gain=DEFAULT_MOTION_GAIN):
    """Co-simulate the first ``frames`` frames of every camera and row of ``dataset``
    (its rig must fit the top's register map, e.g. :func:`cut_rig` of stereo8) through
    the closed-loop HDL top and compare with the emulator; a :class:`LoopCosimResult`.

    ``row_period_s``: how long each camera's row lasts on the pins (the loop needs its
    rows no faster than it closes; the hardware counts row slots by the row order, not
    by time, so a cut rig's stretched ``t_r`` need not be played), e.g. the uncut rig's
    ``t_r``; see :func:`emulator.cosim.camera_stimulus`. ``initial_motion`` (float (6,),
    e.g. :func:`emulator.hardware_path.first_frame_motion`): the PS writes it to
    ``loop.initial`` and strobes ``loop.restart`` right after reset, so that the loop
    tracks frame 1 on from it (the papers' first frame given); None: the loop runs from
    reset at rest. ``motion_gain``: the forecast filter's gain law, the top's and the
    emulator's."""
    from golden.checks import check_int
    from hdl.top import RowtrackTop
    dataset = checked_input(dataset, sim)
    n_frames, height, width = dataset.cameras[0].rows.shape
    check_int("frames", frames, 2, n_frames)
    config = _config(dataset.rig, frames * height, motion_gain)
    params = config.top
    say = print if progress else (lambda *_: None)
    images = np.stack([c.rows[:frames] for c in dataset.cameras])
    stim = {**camera_stimulus(images, params.clk_hz, row_period_s), "loop": True,
            "initial": None if initial_motion is None else
            [int(v) for v in params.forecast.motion_fmt.quantize(initial_motion)]}
    say(f"[cosim-loop] {len(images)} cameras × {frames} frames × {height} rows of {width} "
        f"pixels on {sim}, rows of {row_period_s * 1e6:.3g} µs, frame "
        f"{int(config.frame_rows)} row periods")
    timings = {}
    top = RowtrackTop(params, coefficients=config.coef_store,
                      forecast_stores=config.forecast_stores)
    out = run_bench(top, stim, build_dir, name="rowtrack_loop", sim=sim, waves=waves,
                    seed=seed, tag=f"{len(images)}x{width}x{height}", timings=timings,
                    progress=progress, cache_key=_design_key(config))
    result = judge(config, dataset, frames, out, timings, initial_motion)
    say(f"[cosim-loop] {result.row_sets} row sets, {len(result.records['row'])} records, "
        f"{result.mismatches} + {result.solver_mismatches} + {result.forecast_mismatches} "
        f"+ {result.track_mismatches} mismatches; counters {result.status}")
    return result


def judge(config, dataset, frames, out, timings=None, initial_motion=None):
    """The :class:`LoopCosimResult` of the bench's record ``out`` of the first ``frames``
    frames of ``dataset`` through the closed-loop top of ``config`` (a
    :class:`~hdl.pipeline_config.PipelineConfig`): the HDL's FIFO records, solver records
    and forecast rows against :func:`loop_expected` (``initial_motion`` as there), and
    the loop's timing."""
    from hdl.pose.engine import record_layout
    params = config.top
    height = dataset.cameras[0].rows.shape[1]
    images = np.stack([c.rows[:frames] for c in dataset.cameras])
    sets, spans = row_sets_from_columns(params.camera.aligned_layout(), out["columns"])
    time_mask = (1 << params.solver.time_bits) - 1
    times = [s[min(s)][0]["t_first"] & time_mask for s in sets]
    expected, solver_expected, forecasts_expected, track_expected, slots, uart = \
        loop_expected(config, dataset, frames, times, initial_motion)
    records = record_arrays(params.pose_output.packet, out["fifo_records"])
    solver = _solver_arrays(record_layout(params.solver), out["loop_records"])
    forecasts, forecast_offers, forecast_taken = _forecast_rows(
        params.engine.forecast_layout(), out["forecasts"], out["forecast_stalls"])
    # the rows after the last one played that the loop delay let the loop forecast
    ahead = min(max(len(forecasts["row"]) - len(forecasts_expected["row"]), 0),
                params.forecast.loop_delay_rows + 1)
    forecasts = {name: value[:len(value) - ahead] for name, value in forecasts.items()}
    track = _track_arrays(params.forecast, out["track"], solver["row"])
    frames_of_sets = [k // height for k in range(len(sets))]
    mismatches, first = compare_records(records, expected, frames_of_sets)
    solver_mismatches, solver_first = compare_records(solver, solver_expected,
                                                      frames_of_sets, SOLVER_FIELDS)
    forecast_mismatches, forecast_first = compare_records(
        forecasts, forecasts_expected, frames_of_sets, FORECAST_FIELDS)
    track_mismatches, track_first = compare_records(track, track_expected, frames_of_sets,
                                                    TRACK_FIELDS)
    same_count = len(sets) == len(out["fifo_clocks"])
    record_clocks = [clock for clock, _ in out["loop_records"]]
    column_offers = dict(zip((clock for clock, _ in out["columns"]),
                             _first_offers(out["columns"], out["engine_stalls"])))
    firsts = [first for first, _ in spans]
    return LoopCosimResult(
        records=records, expected=expected, solver=solver, solver_expected=solver_expected,
        forecasts=forecasts, forecasts_expected=forecasts_expected, forecasts_ahead=ahead,
        track=track, track_expected=track_expected,
        mismatches=mismatches, solver_mismatches=solver_mismatches,
        forecast_mismatches=forecast_mismatches, track_mismatches=track_mismatches,
        first_mismatch=first or (solver_first and f"solver {solver_first}")
        or (forecast_first and f"forecast {forecast_first}")
        or (track_first and f"track {track_first}"),
        solved=int(np.count_nonzero(solver_expected["flags"] == 0)), frames=frames,
        row_sets=len(sets),
        rows_match=_rows_match(sets, images, params.camera.frame_bits), slots=slots,
        latency_clocks=latency_clocks(out, sets, frames_of_sets, out["fifo_clocks"])
        if same_count else -1,
        record_latency_clocks=np.array(
            pin_latencies(out, sets, frames_of_sets, record_clocks)
            if len(record_clocks) == len(sets) else [], dtype=float),
        forecast_after_record_clocks=_forecast_after_record(
            record_clocks, forecast_offers, frames_of_sets, params.forecast.loop_delay_rows),
        forecast_lead_clocks=_forecast_leads(forecasts, forecast_taken, sets,
                                             [column_offers[first] for first in firsts]),
        clocks_per_row_set=float(np.mean([b - a + 1 for a, b in spans])) if spans else 0.0,
        row_period_clocks=float(np.mean(
            [b - a for k, (a, b) in enumerate(zip(firsts, firsts[1:]))
             if frames_of_sets[k] == frames_of_sets[k + 1]] or [np.nan])),
        engine_stall_clocks=len(out["engine_stalls"]), status=out["status"],
        clocks=out["clocks"], wall_s=out["wall_s"], timings=timings or {},
        clk_hz=float(params.clk_hz),
        uart_packets_match=out["uart"] == uart and not out["uart_framing_errors"])

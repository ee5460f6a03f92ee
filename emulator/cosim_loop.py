"""Co-simulation of the closed-loop top (issue 16) against the emulator's closed loop.

:func:`closed_loop_cosim` builds the whole :class:`hdl.top.RowtrackTop` of
``PipelineConfig.for_rig(rig, closed_loop=True)`` for a dataset's rig, plays every row of
the dataset's first frames on its DVP pins (:mod:`emulator.hdl_sim.cosim_bench`, the
open-loop co-simulation's bench with the PS starting the loop), and compares, record by
record, what the PS reads from the FIFO and what the tracking loop's solver emitted
(with its step) with :func:`emulator.pipeline.run`'s closed loop on the same rows, the
flags annotated by :class:`emulator.pose.tracking_status.StatusUnitModel` as the
gateware's status unit does. Forecast → lane centre and row address → measurement →
solver → forecast all run in the HDL; nothing of the loop is fed from the model.

The emulator counts row slots from the dataset's time stamps, the hardware from the
row order and ``frame_rows`` (:mod:`hdl.pose.loop_requests`): the rig's frame period
must be a whole number of row periods, and the emulator's slots must be
``frame · frame_rows + row`` (checked). The records' time stamps are the HDL clock's:
``t_row`` is compared with the router's rule applied to the row sets the HDL front end
produced (the lowest camera's ``t_first``), whose pixels must be the dataset's.
"""

from dataclasses import dataclass

import numpy as np

from emulator.cosim import (camera_stimulus, checked_input, compare_records, latency_clocks,
                            record_arrays, row_sets_from_columns, run_bench)

__all__ = ["SOLVER_FIELDS", "LoopCosimResult", "cut_rig", "loop_expected",
           "closed_loop_cosim"]

#: Fields of the tracking loop's solver records compared (the solver's formats, before
#: the status unit and the output's narrowing): the step and the integrated pose.
SOLVER_FIELDS = ("row", "time", "flags", "q", "p", "step")


def cut_rig(rig, rows):
    """``rig`` (a :class:`golden.rig.Rig`) with ``rows`` rows around the optical centre,
    each read out over the same time as before (``t_r`` scaled by ``height / rows``), so
    the frame period stays a whole number of row periods when it was one with the
    full-height rows (stereo8: 600 → ``rows · 600/480``)."""
    cam = rig.cameras[0]
    return rig.replace_cameras(height=rows, cy=(rows - 1) / 2,
                               t_r=cam.t_r * cam.height / rows)


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
    mismatches, solver_mismatches : int
        Differing fields of the two comparisons (:func:`emulator.cosim.compare_records`).
    first_mismatch : str or None
        The first difference of either.
    solved : int
        Records the emulator solved (flags 0), all of whose steps were compared.
    frames, row_sets : int
    rows_match : bool
        The HDL's row sets are the dataset's rows, in order, every camera present.
    slots : ndarray
        The emulator's row slot of every row (``frame · frame_rows + row``, checked).
    latency_clocks : int
        Largest clocks from a row set's last pixel at the pins to its record in the PS
        FIFO (-1 if the counts differ).
    forecast_lead_clocks : ndarray
        Per row set: clocks from the engine taking the row's forecast (its last
        transfer) to the row set's first column offered at the engine's input (> 0: the
        forecast was there first).
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
    mismatches: int
    solver_mismatches: int
    first_mismatch: str | None
    solved: int
    frames: int
    row_sets: int
    rows_match: bool
    slots: np.ndarray
    latency_clocks: int
    forecast_lead_clocks: np.ndarray
    engine_stall_clocks: int
    status: dict
    clocks: int
    wall_s: float
    timings: dict
    clk_hz: float
    uart_packets_match: bool


def _config(rig, records):
    from hdl.output.params import PoseOutputParams
    from hdl.pipeline_config import PipelineConfig
    from hdl.top_params import DEFAULT_SEGMENTS
    depth = 1 << max(records, 2).bit_length()
    return PipelineConfig.for_rig(rig, closed_loop=True, stereo_segments=DEFAULT_SEGMENTS,
                                  pose_output=PoseOutputParams(fifo_depth=depth))


def loop_expected(config, dataset, frames, times):
    """The emulator's closed loop on the first ``frames`` frames of ``dataset``, as the
    HDL must give it: ``(FIFO records, solver records, slots, packets)``. ``times``: the
    time stamp of each record (the HDL row sets', router rule; the emulator's own where
    the HDL has fewer). Started as ``rowtrack run``'s hardware path
    (:func:`emulator.hardware_path.first_frame_motion`), its flags through the status
    unit's model with the registers' reset settings."""
    from emulator.hardware_path import first_frame_motion
    from emulator.output import packets
    from emulator.pipeline import run
    from emulator.pose.tracking_status import StatusUnitModel, annotate
    from hdl.pose.status_params import top_status_params
    top = config.top
    result = run(config, dataset, frames, forecast=config.forecast(),
                 initial_motion=first_frame_motion(dataset),
                 consistency=config.consistency(), cue_fallback=True)
    loop = result.loop
    slots = np.asarray(loop["slot"])
    want = np.asarray(loop["frame"]) * int(config.frame_rows) + np.asarray(loop["row"])
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
    return record_arrays(packet, kept), solver, slots, uart


def _solver_arrays(layout, columns):
    from emulator.hdl_sim.payload import unpack
    rows = [unpack(layout, raw) for _, raw in columns]
    return {name: np.array([[r[name][i] for i in sorted(r[name])] if isinstance(r[name], dict)
                            else r[name] for r in rows], dtype=np.int64).reshape(
                                (len(rows), -1) if rows and isinstance(rows[0][name], dict)
                                else (len(rows),))
            for name in SOLVER_FIELDS}


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


def _forecast_leads(params, forecasts, sets, spans, stalls):
    """Per row set: clocks from its forecast row's last transfer taken by the engine to
    its first column offered (the first stall clock inside the set's span, else the
    clock its first column was taken); NaN when the forecast row did not come."""
    from emulator.hdl_sim.payload import unpack
    layout = params.engine.forecast_layout()
    ends = [(clock, unpack(layout, raw)["row"]) for clock, raw in forecasts
            if unpack(layout, raw)["last"]]
    stalls = np.asarray(stalls, dtype=np.int64)
    leads, previous = [], -1
    for k, ((first, _), row_set) in enumerate(zip(spans, sets)):
        waiting = stalls[(stalls > previous) & (stalls < first)]
        offered = int(waiting[0]) if len(waiting) else first
        row = next(iter(row_set.values()))[0]["row"]
        leads.append(offered - ends[k][0] if k < len(ends) and ends[k][1] == row
                     else np.nan)
        previous = spans[k][1]
    return np.array(leads, dtype=float)


def closed_loop_cosim(dataset, *, frames=3, sim="verilator", waves=False, seed=None,
                      build_dir="build/cosim_loop", progress=False):
    """Co-simulate the first ``frames`` frames of every camera and row of ``dataset``
    (its rig must fit the top's register map, e.g. :func:`cut_rig` of stereo8) through
    the closed-loop HDL top and compare with the emulator; a :class:`LoopCosimResult`."""
    from golden.checks import check_int
    from hdl.pose.engine import record_layout
    from hdl.top import RowtrackTop
    from emulator.hardware_path import first_frame_motion
    dataset = checked_input(dataset, sim)
    n_frames, height, width = dataset.cameras[0].rows.shape
    check_int("frames", frames, 2, n_frames)
    config = _config(dataset.rig, frames * height)
    params = config.top
    say = print if progress else (lambda *_: None)
    images = np.stack([c.rows[:frames] for c in dataset.cameras])
    initial = params.forecast.motion_fmt.quantize(first_frame_motion(dataset))
    stim = {**camera_stimulus(images, params.clk_hz),
            "loop": {"initial": [int(v) for v in initial],
                     "frame_rows": int(config.frame_rows)}}
    say(f"[cosim-loop] {len(images)} cameras × {frames} frames × {height} rows of {width} "
        f"pixels on {sim}, frame {int(config.frame_rows)} row periods")
    timings = {}
    top = RowtrackTop(params, coefficients=config.coef_store,
                      forecast_stores=(config.coef_raw, config.row_coef_raw))
    out = run_bench(top, stim, build_dir, name="rowtrack_loop", sim=sim, waves=waves,
                    seed=seed, tag=f"{len(images)}x{width}x{height}", timings=timings,
                    progress=progress, cache_key=repr(params))

    sets, spans = row_sets_from_columns(params.camera.aligned_layout(), out["columns"])
    time_mask = (1 << params.solver.time_bits) - 1
    times = [s[min(s)][0]["t_first"] & time_mask for s in sets]
    expected, solver_expected, slots, uart = loop_expected(config, dataset, frames, times)
    records = record_arrays(params.pose_output.packet, out["fifo_records"])
    solver = _solver_arrays(record_layout(params.solver), out["loop_records"])
    frames_of_sets = [k // height for k in range(len(sets))]
    mismatches, first = compare_records(records, expected, frames_of_sets)
    solver_mismatches, solver_first = compare_records(solver, solver_expected,
                                                      frames_of_sets, SOLVER_FIELDS)
    latency = latency_clocks(out, sets, frames_of_sets, out["fifo_clocks"]) \
        if len(sets) == len(out["fifo_clocks"]) else -1
    say(f"[cosim-loop] {len(sets)} row sets, {len(out['fifo_records'])} records, "
        f"{mismatches} + {solver_mismatches} mismatches; counters {out['status']}")
    return LoopCosimResult(
        records=records, expected=expected, solver=solver, solver_expected=solver_expected,
        mismatches=mismatches, solver_mismatches=solver_mismatches,
        first_mismatch=first or (solver_first and f"solver {solver_first}"),
        solved=int(np.count_nonzero(solver_expected["flags"] == 0)), frames=frames,
        row_sets=len(sets),
        rows_match=_rows_match(sets, images, params.camera.frame_bits), slots=slots,
        latency_clocks=latency,
        forecast_lead_clocks=_forecast_leads(params, out["forecasts"], sets, spans,
                                             out["engine_stalls"]),
        engine_stall_clocks=len(out["engine_stalls"]), status=out["status"],
        clocks=out["clocks"], wall_s=out["wall_s"], timings=timings,
        clk_hz=float(params.clk_hz),
        uart_packets_match=out["uart"] == uart and not out["uart_framing_errors"])

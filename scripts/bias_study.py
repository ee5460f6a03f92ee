"""How biased are the hardware path's measurements? (issue 16)

The closed loop's figure mixes measurement errors with the forecast filter's dynamics.
This study takes the dynamics out: the forecast is frozen at the true motion (the paper
motion turns and moves at constant rates, so its true one-frame motion is the same on
every row; the filter starts there and moves by ``alpha`` = 0.004 of each innovation,
the smallest the scalar gain's prior format takes), and the raw solved steps (the
hardware's ``Ŷ + δ``, golden (b)'s ``measured``) are compared with the true motion row
by row. Their **mean** error is the measurement model's bias (what a filter cannot
average away), their standard deviation its noise.

Usage: ``PYTHONPATH=. .venv/bin/python scripts/bias_study.py [--segments 8]
[--stereo-segments 8] [--frames 4] [--only name,name]`` on hw_tracking's stereo20 paper
sequence (12 frames, noise σ = 2; the first ``--frames`` used). Runs (``--only``):

* ``golden_b``: golden (b) with ``segments`` (its own depth: 16 blocks, per pixel);
* ``hw``: the hardware path (:func:`emulator.hardware_path.closed_loop` settings) with
  ``segments`` and ``stereo_segments``;
* ``oracle_own`` / ``oracle_stereo``: the hardware path with gap_study's cue swaps
  (each camera's own true disparity over its segment's compared columns / camera A's
  true disparity over the stereo segment, for both cameras); ``oracle_own_a`` /
  ``oracle_own_b``: "own" for camera A (B) of each pair, "stereo" for the other;
* ``column_cue``: the hardware path with each temporal segment's cue taken from the
  stereo segments its columns overlap (:func:`column_cue_patch`), the measured cues;
  ``centre_cue``: the same cues interpolated at the segment's centre column
  (:func:`centre_cue_patch`).
"""

import argparse
import sys
import time
from dataclasses import replace

import numpy as np

import gap_study

FROZEN = {"motion_gain": "scalar", "alpha": 0.004, "beta": 0.0}
#: Per-axis scale of the printed figures: cm, 1e-4 rad.
UNITS = np.array([100, 100, 100, 1e4, 1e4, 1e4])


def golden_steps(dataset, segments):
    """(frames, rows, raw measured steps) of golden (b) with a frozen forecast."""
    from emulator.e2e import _golden_slots
    from emulator.hardware_path import golden_b_params
    from golden.tracker import track
    result = track(dataset, replace(golden_b_params(1), segments=segments, **FROZEN))
    height = dataset.rig.cameras[0].height
    frames = len(dataset.cameras[0].rows)
    fr = np.repeat(np.arange(1, frames), height)
    rw = np.tile(np.arange(height), frames - 1)
    return fr, rw, result.measured[_golden_slots(result, dataset, fr, rw)]


def hardware_steps(dataset, config, patch=None):
    """(frames, rows, raw solved steps) of the hardware path with a frozen forecast."""
    run = gap_study.hardware(dataset, None, config=config, patch=patch,
                             forecast_changes=FROZEN)
    return run[3]


def column_cue_patch(config):
    """The router's cue of each temporal segment: the overlap-weighted mean of the
    usable stereo cues over the segment's columns (centre 0) as camera A sees them —
    camera A's own columns, camera B's shifted by the pair's disparity (B sees a point
    ``d`` columns left of A; ``d`` the cue the router gives the segment today, stereo
    segment ``k·K_s // K``). Instead of today's ``k·K_s // K`` alone, whose columns are
    A's from the stereo lane's first comparable column (76 on stereo20, 26 for the
    temporal lanes). A segment no usable stereo cue overlaps gets no weight."""
    import emulator.pipeline as pl
    from emulator.measurement.router import usable_cues
    from golden.descriptor import segment_bounds
    lane, stereo = config.router.temporal, config.router.stereo
    temporal_bounds = segment_bounds(lane.width, lane.descriptor, lane.match)
    stereo_bounds = segment_bounds(stereo.width, stereo.descriptor, stereo.match)
    original = pl.route_row

    def route_row(params, temporal, stereo_records, fallback=None):
        out = original(params, temporal, stereo_records, fallback)
        fmt = params.solver.cue_fmt
        cues = {**(fallback or {}), **usable_cues(params, stereo_records)}
        edge = {(m["camera"], m["segment"]): m["edge_hit"] for m in temporal}
        for t in out:
            n, k = divmod(t["slot"], lane.segments)
            a = params.pair_of[n]
            shift = 0.0
            if a != n:
                own = cues.get((a, k * stereo.segments // lane.segments))
                shift = fmt.to_float(own) if own is not None else 0.0
            lo = max(temporal_bounds[k][0] + shift, stereo_bounds[0][0])
            hi = min(temporal_bounds[k][1] + shift, stereo_bounds[-1][1])
            if hi <= lo:                    # outside the stereo lane's columns: the nearest
                j = 0 if temporal_bounds[k][1] + shift <= stereo_bounds[0][0] else -1
                lo, hi = stereo_bounds[j][0], stereo_bounds[j][0] + 1
            total = weight = 0.0
            for j, (s_lo, s_hi) in enumerate(stereo_bounds):
                overlap = max(0.0, min(hi, s_hi) - max(lo, s_lo))
                if overlap > 0 and (a, j) in cues:
                    total += overlap * fmt.to_float(cues[(a, j)])
                    weight += overlap
            if weight > 0 and not edge[(n, k)]:
                t["cue"] = int(fmt.quantize(total / weight))
            else:
                t["conf"] = 0
        return out
    return gap_study.patched(pl, "route_row", route_row)


def centre_cue_patch(config):
    """As :func:`column_cue_patch`, but the hardware-friendly form: the stereo cues
    interpolated linearly at the segment's centre column (camera B's shifted by its
    disparity) between the two stereo segment centres around it (equally spaced: a
    constant reciprocal), the nearer alone where the other is not usable, the end
    segment's beyond the first or last centre (no extrapolation)."""
    import emulator.pipeline as pl
    from emulator.measurement.router import usable_cues
    from golden.descriptor import segment_bounds
    lane, stereo = config.router.temporal, config.router.stereo
    temporal_centres = [(lo + hi - 1) / 2 for lo, hi in
                        segment_bounds(lane.width, lane.descriptor, lane.match)]
    stereo_centres = np.array([(lo + hi - 1) / 2 for lo, hi in
                               segment_bounds(stereo.width, stereo.descriptor, stereo.match)])
    original = pl.route_row

    def route_row(params, temporal, stereo_records, fallback=None):
        out = original(params, temporal, stereo_records, fallback)
        fmt = params.solver.cue_fmt
        cues = {**(fallback or {}), **usable_cues(params, stereo_records)}
        edge = {(m["camera"], m["segment"]): m["edge_hit"] for m in temporal}
        for t in out:
            n, k = divmod(t["slot"], lane.segments)
            a = params.pair_of[n]
            x = temporal_centres[k]
            if a != n:
                own = cues.get((a, k * stereo.segments // lane.segments))
                x += fmt.to_float(own) if own is not None else 0.0
            x = min(max(x, stereo_centres[0]), stereo_centres[-1])
            j = min(int(np.searchsorted(stereo_centres, x, side="right")) - 1,
                    len(stereo_centres) - 2) if len(stereo_centres) > 1 else 0
            w = 0.0 if len(stereo_centres) == 1 else \
                (x - stereo_centres[j]) / (stereo_centres[j + 1] - stereo_centres[j])
            near = [(j, 1 - w), (j + 1, w)] if len(stereo_centres) > 1 else [(0, 1.0)]
            got = [(fmt.to_float(cues[(a, i)]), v) for i, v in near if (a, i) in cues]
            if len(got) == 2:
                cue = got[0][0] * got[0][1] + got[1][0] * got[1][1]
            elif got:
                cue = got[0][0]
            if got and not edge[(n, k)]:
                t["cue"] = int(fmt.quantize(cue))
            else:
                t["conf"] = 0
        return out
    return gap_study.patched(pl, "route_row", route_row)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--segments", type=int, default=8)
    ap.add_argument("--stereo-segments", type=int, default=8)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--only", default=None)
    args = ap.parse_args(argv)
    from emulator.benches.hw_tracking import MOTIONS
    from emulator.benches.tracker import _first_frames, noisy_sequence
    from emulator.e2e import true_steps
    from hdl.pipeline_config import PipelineConfig
    dataset = _first_frames(noisy_sequence("stereo20", "paper", MOTIONS["paper"]),
                            args.frames)
    config = PipelineConfig.for_rig(dataset.rig, segments=args.segments,
                                    stereo_segments=args.stereo_segments)
    runs = {
        "golden_b": lambda: golden_steps(dataset, args.segments),
        "hw": lambda: hardware_steps(dataset, config),
        "oracle_own": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, "own")),
        "oracle_stereo": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, "stereo")),
        "oracle_own_a": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, own_role="A")),
        "oracle_own_b": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, own_role="B")),
        "column_cue": lambda: hardware_steps(dataset, config, column_cue_patch),
        "centre_cue": lambda: hardware_steps(dataset, config, centre_cue_patch),
    }
    wanted = list(runs) if args.only is None else args.only.split(",")
    unknown = sorted(set(wanted) - set(runs))
    if unknown:
        ap.error(f"--only: unknown runs {unknown}; choose from {sorted(runs)}")
    print(f"K = {args.segments}, K_s = {args.stereo_segments}, frames 1..{args.frames - 1};"
          " errors of the raw steps in cm and 1e-4 rad (Tx Ty Tz θx θy θz)", flush=True)
    for name in wanted:
        start = time.time()
        frames, rows, steps = runs[name]()
        error = (steps - true_steps(dataset, frames, rows)) * UNITS
        error = error[np.all(np.isfinite(error), axis=1)]
        for label, values in (("mean", error.mean(axis=0)), ("std", error.std(axis=0))):
            print(f"{name:14s} {label:4s} " + " ".join(f"{v:+8.4f}" for v in values),
                  flush=True)
        print(f"{name:14s} rows {len(error)}, {time.time() - start:.0f} s", flush=True)


if __name__ == "__main__":
    sys.exit(main())

"""Where does the hardware path lose accuracy against golden (b)? (issue 16)

Controlled swaps inside the emulator's closed loop (:func:`emulator.pipeline.run`), one
change each, on a simulated stereo20 cut; and, for the metric and the linearisation,
the matching swaps inside golden (b). Every figure is a per-row Y RMS against truth over
the hardware's rows of frames >= 1 (camera 0's row times), divided per axis by golden
(b)'s trajectory figure on the same rows (the ``rowtrack run`` ratio).

Usage: ``PYTHONPATH=. .venv/bin/python scripts/gap_study.py --rows 32 --frames 3
[--seed 1] [--trajectory paper] [--only name,name] [--json out.json]`` (``PYTHONPATH=.``:
the checkout's own packages, not an installed copy's; the script's own directory comes
first on ``sys.path``).

Swaps are monkeypatches or parameter changes in this script only (product code
untouched):

* ``hw``: the hardware path as ``rowtrack run`` runs it (filter level).
* ``hw_steps``: the same run's raw solved steps.
* ``hw_traj``: the same run's outputs turned into a pose track as golden (b) builds its
  own (:func:`trajectory_steps`), scored like golden (b)'s figure.
* ``float_solver``: the loop's fixed-point solve replaced by float64 (golden.pose_lsq)
  on the same routed measurements and float coefficients.
* ``no_consistency``: the consistency stage (and its P/(P-Δ) time factor) off.
* ``no_scale_ceiling``: the consistency stage's scale ceiling at its format's top.
* ``depth_weight``: golden (b)'s depth-sensitivity weight on the stage's confidences.
* ``oracle_cue``: every segment's cue (both cameras of a pair, each its own) replaced
  by the true disparity f·b·mean(1/Z) over the segment's compared columns;
  ``oracle_cue_stereo``: the true disparity over the stereo segment the router maps the
  temporal segment to, camera A's, for both cameras (a perfect stereo lane).
* ``float_match``: the lanes' shifts and peak ratios replaced by golden.descriptor.match
  of the same rows, stored reference row and centre.
* ``coef_zero`` / ``coef_centre`` / ``coef_mean``: float solve with coefficients at
  centre 0 (control) / at the run-time centre's segment centres / averaged over them.
* ``k8``: 8 temporal and 8 stereo segments; ``k8_ks4``: 8 temporal, 4 stereo.
* ``alpha05``: (filter) the forecast filter's level gain 0.05 instead of 0.1.
* golden side: ``gb_motion`` (golden (b)'s filter motion instead of its trajectory),
  ``gb_steps`` (its raw measured ``Ŷ + δ``), ``gb_linear_plain``/``gb_linear_time``
  (golden (b) with the linear predicted shift A·Ŷ, without/with the reference-time
  factor, instead of the exact projection g(Ŷ)), one golden feature off at a time
  (``gb_k4``, ``gb_blocks4``, ``gb_no_depth_weight``, ``gb_no_ceiling``, ``gb_alpha05``)
  and ``gb_hwlike`` (segments=4, disparity_blocks=4, shift_sigma=1e6, consistency_k=0,
  scale_ceiling=1e6).
"""

import argparse
import contextlib
import json
import sys
import time
from dataclasses import replace

import numpy as np

from golden.pose_lsq import UNKNOWNS
from hdl.fixed import Overflow, Rounding, resize


def make_dataset(rows, frames, seed, trajectory):
    from golden.rig import load_rig
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    rig = load_rig("stereo20")
    if rows is not None:
        fps = rig.cameras[0].fps
        rig = rig.replace_cameras(height=rows, cy=(rows - 1) / 2, t_r=1 / (fps * rows))
    return simulate(rig, default_scene_spec(seed), make_trajectory(trajectory, seed=seed),
                    frames / rig.cameras[0].fps, seed=seed)


def rms(a, b):
    d = np.asarray(a, float) - np.asarray(b, float)
    return np.sqrt(np.nanmean(d * d, axis=0))


# --- swaps -------------------------------------------------------------------------------

@contextlib.contextmanager
def patched(module, name, value):
    old = getattr(module, name)
    setattr(module, name, value)
    try:
        yield
    finally:
        setattr(module, name, old)


def _solve_patch(solve):
    """The closed loop's solve replaced by ``solve(pose_rows) -> StepResult``: the loop
    accumulates the fixed-point system (the information gain still reads it) and then
    solves; the rows are caught where they are accumulated."""
    import emulator.pose.tracking_loop as tl
    caught = {}
    accumulate = tl.accumulate

    def catch(params, coef_raw, rows):
        caught["rows"] = rows
        return accumulate(params, coef_raw, rows)

    def solve_system(params, normal, rhs, overrun, pivot_log2=None):
        return solve(caught["rows"])
    stack = contextlib.ExitStack()
    stack.enter_context(patched(tl, "accumulate", catch))
    stack.enter_context(patched(tl, "solve_system", solve_system))
    return stack


def float_solver_patch(config):
    """The loop's solve -> float64 solve quantized into step_fmt."""
    from emulator.e2e import float_steps
    from emulator.pose_solver import StepResult
    fmt = config.router.solver.step_fmt

    def solve(rows):
        step = float_steps(config, rows)
        ok = np.all(np.isfinite(step), axis=1)
        raw = np.array([[int(fmt.quantize(v)) for v in s] if o else [0] * 6
                        for s, o in zip(step, ok)], dtype=np.int64)
        return StepResult(step=raw, flags=np.where(ok, 0, 1))
    return _solve_patch(solve)


class _Current:
    """The frame the loop is measuring (set by the patched _Loop.measure)."""
    frame = 0
    centres = None


def _track_frame():
    import emulator.pipeline as pl
    original = pl._Loop.measure

    def measure(self, lanes, rows, frame):
        _Current.frame = frame
        out = original(self, lanes, rows, frame)
        _Current.centres = self.model.prediction["centre"]
        return out
    return patched(pl._Loop, "measure", measure)


def oracle_cue_patch(dataset, config, columns="own", own_role=None):
    """route_row's cues replaced by the true disparity: ``columns`` "own": of each
    camera's own temporal segment (its columns at the run-time centre); "stereo": camera
    A's over the stereo segment the router maps the temporal segment to, for both
    cameras of the pair (what a perfect stereo lane would give the hardware).
    ``own_role`` "A" or "B": "own" for that camera of each pair, "stereo" for the other."""
    import emulator.pipeline as pl
    from golden.depth import stereo_pairs
    from golden.depth_maps import OracleDepth
    from golden.descriptor import segment_bounds
    oracle = OracleDepth(dataset)
    lane, solver = config.router.temporal, config.router.solver
    fb = {}
    for a, b, focal_baseline in stereo_pairs(dataset.rig):
        fb[a] = fb[b] = focal_baseline
    cache = {}
    original = pl.route_row

    def inv(n, frame):
        if (n, frame) not in cache:
            h = lane.height
            cache[(n, frame)] = oracle.inverse_depth(n, frame, np.arange(h))
        return cache[(n, frame)]

    def route_row(params, temporal, stereo, fallback=None):
        out = original(params, temporal, stereo, fallback)
        by_slot = {(m["camera"], m["segment"]): m for m in temporal}
        for t in out:
            n, k = divmod(t["slot"], lane.segments)
            m = by_slot[(n, k)]
            role = "A" if params.pair_of[n] == n else "B"
            if (columns == "own") if own_role is None else role == own_role:
                centre = int(_Current.centres[n]) if _Current.centres is not None else 0
                lo, hi = segment_bounds(lane.width, lane.descriptor, lane.match, centre)[k]
                z = inv(n, _Current.frame)[t["row"], lo:hi]
            else:
                stereo_lane = params.stereo
                ks = k * stereo_lane.segments // lane.segments
                lo, hi = segment_bounds(stereo_lane.width, stereo_lane.descriptor,
                                        stereo_lane.match)[ks]
                z = inv(params.pair_of[n], _Current.frame)[t["row"], lo:hi]
            cue = fb[n] * np.nanmean(z)
            t["cue"] = int(solver.cue_fmt.quantize(cue))
            usable = not m["edge_hit"] and np.isfinite(cue)
            conf = resize(np.array([m["confidence"]]), lane.confidence_fmt, solver.conf_fmt,
                          Rounding.HALF_EVEN, Overflow.SATURATE)[0]
            t["conf"] = int(conf) if usable else 0
        return out
    stack = contextlib.ExitStack()
    stack.enter_context(_track_frame())
    stack.enter_context(patched(pl, "route_row", route_row))
    return stack


def float_match_patch(dataset, config):
    """The temporal lanes' measurements replaced by the float matcher's on the same
    current row, stored reference row and centre."""
    import emulator.row_descriptor as rd
    from golden.descriptor import describe, match, strength
    lane = config.router.temporal
    pixels = {}
    original = rd.TemporalLaneModel.process_rows

    def desc(n, frame):
        if (n, frame) not in pixels:
            p = np.asarray(dataset.cameras[n].rows[frame], dtype=np.float64)
            pixels[(n, frame)] = (describe(p, lane.descriptor), strength(p, lane.descriptor))
        return pixels[(n, frame)]

    def process_rows(self, rows, sources=None):
        out = original(self, rows, sources)
        if sources is None:
            return out
        frame = _Current.frame
        for r, (row, source) in enumerate(zip(rows, sources)):
            if frame == 0:
                continue
            bits, strong = desc(row.camera, frame)
            ref, _ = desc(row.camera, frame - 1)
            source = np.broadcast_to(source, (lane.segments,))
            # each segment is compared with its own followed row: one match per row used
            matched = {int(s): match(bits[row.row][None], ref[s][None], lane.descriptor,
                                     lane.match, int(row.centre),
                                     cur_strong=strong[row.row][None])
                       for s in np.unique(source)}
            for k in range(lane.segments):
                m = matched[int(source[k])]
                rec = out[r * lane.segments + k]
                if rec["no_reference"]:
                    continue
                good = not (m.textureless[0, k] or m.edge_hit[0, k])
                if not good:
                    rec["confidence"] = 0
                    continue
                shift = float(m.shift[0, k])
                integer = int(np.floor(shift + 0.5))
                rec["shift"] = integer
                rec["subpixel"] = int(lane.subpixel_fmt.quantize(shift - integer))
                rec["confidence"] = int(lane.confidence_fmt.quantize(
                    float(m.peak_ratio[0, k]), overflow=Overflow.SATURATE))
                rec["edge_hit"] = 0
        return out
    stack = contextlib.ExitStack()
    stack.enter_context(_track_frame())
    stack.enter_context(patched(rd.TemporalLaneModel, "process_rows", process_rows))
    return stack


def _cue_scales(rig):
    from golden.depth import stereo_pairs
    scales = np.full(len(rig.cameras), np.nan)
    for a, b, focal_baseline in stereo_pairs(rig):
        scales[[a, b]] = 1.0 / focal_baseline
    return scales


def coefficient_patch(dataset, config, how):
    """The loop's solve (float64) with coefficients of each camera's segments at its
    run-time window centre (the lane's actual compared columns): ``how`` "centre": at
    the segments' centre columns; "mean": averaged over every column of the segment;
    "zero": the store's columns (centre 0), the float_solver swap's control."""
    from golden.descriptor import segment_bounds
    from golden.pose_lsq import ShiftCoefficients, shift_coefficients, solve_step
    from emulator.pose_solver import StepResult
    lane, solver = config.router.temporal, config.router.solver
    rig, k = dataset.rig, lane.segments
    scales = _cue_scales(rig)
    rows = np.arange(lane.height, dtype=float)
    tables = {}

    def table(n, centre):
        key = (n, centre if how != "zero" else 0)
        if key not in tables:
            bounds = segment_bounds(lane.width, lane.descriptor, lane.match, key[1])
            cam = rig.cameras[n]
            if how == "mean":
                out = np.stack([shift_coefficients(
                    cam, np.arange(lo, hi, dtype=float)[None, :], rows[:, None],
                    scales[n]).table().mean(axis=1) for lo, hi in bounds])
            else:
                columns = np.array([(lo + hi - 1) / 2 for lo, hi in bounds])[:, None]
                out = shift_coefficients(cam, columns, rows[None, :], scales[n]).table()
            tables[key] = out                       # (K, rows, 9)
        return tables[key]
    fmt = solver.step_fmt

    def solve(pose_rows):
        centres = _Current.centres
        row = int(pose_rows.row[0])
        coef = np.stack([table(slot // k, int(centres[slot // k]))[slot % k, row]
                         for slot in pose_rows.slot[0]])[None]
        weight = np.where(pose_rows.present, solver.conf_fmt.to_float(pose_rows.conf), 0.0)
        solution = solve_step(ShiftCoefficients.from_table(coef), solver.cue_fmt.to_float(
            pose_rows.cue), solver.shift_fmt.to_float(pose_rows.shift), weight)
        step = np.asarray(solution.step, dtype=float).reshape(-1, 6)
        ok = np.asarray(solution.ok).reshape(-1) & (weight.sum(axis=1) > 0)
        raw = np.array([[int(fmt.quantize(v)) for v in st] if o else [0] * 6
                        for st, o in zip(step, ok)], dtype=np.int64)
        return StepResult(step=raw, flags=np.where(ok, 0, 1))
    stack = contextlib.ExitStack()
    stack.enter_context(_track_frame())
    stack.enter_context(_solve_patch(solve))
    return stack


def depth_weight_patch(config, shift_sigma=0.3, disparity_sigma=1.0):
    """Golden (b)'s depth-sensitivity weight in the consistency stage: each
    measurement's confidence times ``1 / (1 + (|a_t·T̂| σ_d / shift_sigma)²)`` with
    ``a_t`` the translation coefficients of its slot and row (pixels of shift per pixel
    of disparity per metre, the store's: cue scale ``1/(f·b)``) and ``T̂`` the row's
    forecast translation: how far a disparity error of ``σ_d`` pixels moves its predicted
    shift (the golden's ``σ_w = σ_d/(f·B)`` with ``B`` the pair's baseline)."""
    import emulator.pose.tracking_loop as tl
    forecast_close = tl.TrackingLoopModel.close

    def close(self, transfers, slot, row):
        if transfers and self.consistency is not None:
            p = self.params
            motion = p.motion_fmt.to_float(self.prediction["motion"])
            coef = config.table[:, row, 0:3]          # (slots, 3)
            moved = np.abs(coef @ motion[:3]) * disparity_sigma
            weight = 1.0 / (1.0 + (moved / shift_sigma) ** 2)
            transfers = [{**t, "conf": int(np.floor(t["conf"] * weight[t["slot"]] + 0.5))}
                         for t in transfers]
        return forecast_close(self, transfers, slot, row)
    return patched(tl.TrackingLoopModel, "close", close)


# --- runs --------------------------------------------------------------------------------

def hardware(dataset, frames, *, config=None, consistency=True, forecast_changes=None,
             consistency_changes=None, patch=None):
    """(frames, rows, level, steps) of a closed-loop run with one swap."""
    from emulator.hardware_path import first_frame_motion, hardware_config
    from emulator.pipeline import run
    config = config or hardware_config(dataset.rig)
    forecast = config.forecast(**(forecast_changes or {}))
    with (patch(config) if patch else contextlib.nullcontext()):
        result = run(config, dataset, frames, forecast=forecast,
                     initial_motion=first_frame_motion(dataset),
                     consistency=config.consistency(**(consistency_changes or {}))
                     if consistency else None,
                     cue_fallback=True)
    loop = result.loop
    scored = loop["frame"] > 0
    level = forecast.motion_fmt.to_float(loop["level"])
    steps = result.steps(config)
    later = result.frame > 0
    return (loop["frame"][scored], loop["row"][scored], level[scored],
            (result.frame[later], result.records["row"][later], steps[later]),
            (loop["frame"], loop["row"], level))


def trajectory_steps(dataset, run, levels_all, pose_alpha=0.02, trends=None):
    """Y of each scored row from a pose track built like golden (b)'s from the hardware
    path's own outputs (float; the golden's ``Tracker._step`` pose logic with a scalar
    pull; the trend term only with ``trends``): the first frame's poses given, each
    row's pose carried on from the previous row's at the filter's current rate (level
    before the row, plus half a frame of the row's trend, / frame period) and pulled by
    ``pose_alpha`` towards the pose the row's solved step gives from the same row one
    frame earlier. ``levels_all``: (frame, row, level) of every loop row in order,
    frame 0 included; ``trends`` the filter's trend (per update) after each of them."""
    from golden.pose_lsq import body_step
    from golden.tracker_motion import compose
    rec = dataset.cameras[0]
    period = 1.0 / dataset.rig.cameras[0].fps
    half = 0.5 * period / dataset.rig.cameras[0].t_r
    frames_all, rows_all, level_all = levels_all
    if trends is None:
        trends = np.zeros_like(level_all)
    (sf, sr, st) = run[3]
    step_of = {(int(f), int(r)): s for f, r, s in zip(sf, sr, st)}
    poses = {}
    last = None
    current = None
    for f, r, lev, trend in zip(frames_all, rows_all, level_all, trends):
        f, r = int(f), int(r)
        t = rec.time[f, r]
        if f == 0:
            poses[(f, r)] = (rec.rotation[f, r], rec.position[f, r])
        else:
            rate = (current + half * trend) / period
            rotation, position = compose(*last[:2], rate * (t - last[2]))
            step = step_of.get((f, r))
            if step is not None and np.all(np.isfinite(step)) and (f - 1, r) in poses:
                target = compose(*poses[(f - 1, r)], step)
                rotation, position = compose(rotation, position, pose_alpha * body_step(
                    rotation, position, *target))
            poses[(f, r)] = (rotation, position)
        last, current = (*poses[(f, r)], t), lev
    return np.array([body_step(*poses[(int(f) - 1, int(r))], *poses[(int(f), int(r))])
                     for f, r in zip(run[0], run[1])])


def golden_b(dataset, delay=1, *, linear=None, **changes):
    """Golden (b) run; ``linear`` "plain": predicted shifts ``A·Ŷ`` (the hardware's linear
    model about 0) instead of the exact projection ``g(Ŷ)``; "time": ``A·Ŷ·(P − Δ)/P``
    (the followed reference row's time, as the hardware's consistency stage scales)."""
    from emulator.hardware_path import golden_b_params
    from golden import tracker as gt
    params = golden_b_params(delay).replace(**changes) if changes else golden_b_params(delay)
    if linear is None:
        return gt.track(dataset, params)
    entry, equations, reference = gt.Tracker._entry, gt.Tracker._equations, \
        gt.Tracker._reference

    def _reference(self, n, frame, rows, rotations, positions, inverse_depth):
        self._source = np.asarray(rows)
        original = self.reference.rows

        def rows_of(n_, frame_, source):
            self._source = np.asarray(source)
            return original(n_, frame_, source)
        self.reference.rows = rows_of
        try:
            return reference(self, n, frame, rows, rotations, positions, inverse_depth)
        finally:
            del self.reference.rows

    def _entry(self, n, frame, rows, slot_ids, forecasts):
        e = entry(self, n, frame, rows, slot_ids, forecasts)
        e.forecasts, e.source = forecasts, self._source
        return e

    def _equations(self, e):
        equations(self, e)
        e.expected = np.einsum("bkj,bj->bk", e.design, e.forecasts)
        if linear == "time":
            period = self.slots.period / self.slots.t_r
            e.expected = e.expected * ((period - (e.source - e.rows)) / period)[:, None]
    with patched(gt.Tracker, "_entry", _entry), patched(gt.Tracker, "_equations", _equations), \
            patched(gt.Tracker, "_reference", _reference):
        return gt.track(dataset, params)


def _golden_measured(track_result, dataset, frames, rows):
    """Golden (b)'s raw measured motion ``Ŷ + δ`` of each row's slot (NaN: no step)."""
    from emulator.e2e import _golden_slots
    return track_result.measured[_golden_slots(track_result, dataset, frames, rows)]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=32)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--trajectory", default="paper")
    ap.add_argument("--only", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    from emulator.e2e import golden_steps, golden_trajectory_steps, true_steps
    from hdl.pipeline_config import PipelineConfig
    t0 = time.time()
    ds = make_dataset(args.rows, args.frames, args.seed, args.trajectory)
    print(f"dataset {time.time() - t0:.0f}s", flush=True)
    base = hardware(ds, args.frames)
    frames, rows = base[0], base[1]
    truth = true_steps(ds, frames, rows)
    gb = golden_b(ds)
    gold = rms(golden_trajectory_steps(gb, ds, frames, rows), truth)
    results = {"golden_b": gold.tolist(), "true_motion": rms(truth, 0 * truth).tolist()}

    def report(name, err):
        ratio = err / gold
        results[name] = {"rms": err.tolist(), "ratio": ratio.tolist()}
        print(f"{name:16s} " + " ".join(f"{r:6.2f}" for r in ratio) + "   rms " +
              " ".join(f"{v:.2e}" for v in err), flush=True)

    print("swap             " + " ".join(f"{a:>6s}" for a in UNKNOWNS))
    print("golden_b rms     " + " ".join(f"{v:.2e}" for v in gold))
    report("hw", rms(base[2], truth))
    sf, sr, st = base[3]
    report("hw_steps", rms(st, true_steps(ds, sf, sr)))
    report("hw_traj", rms(trajectory_steps(ds, base, base[4]), truth))
    wanted = None if args.only is None else set(args.only.split(","))

    def want(name):
        return wanted is None or name in wanted

    def level_of(run):
        return rms(run[2], true_steps(ds, run[0], run[1]))

    from emulator.hardware_path import hardware_config
    scale_top = hardware_config(ds.rig).consistency().scale_fmt.max_value
    swaps = {
        "float_solver": lambda: hardware(ds, args.frames, patch=float_solver_patch),
        "no_consistency": lambda: hardware(ds, args.frames, consistency=False),
        "oracle_cue": lambda: hardware(ds, args.frames,
                                       patch=lambda c: oracle_cue_patch(ds, c)),
        "oracle_cue_stereo": lambda: hardware(
            ds, args.frames, patch=lambda c: oracle_cue_patch(ds, c, "stereo")),
        "float_match": lambda: hardware(ds, args.frames,
                                        patch=lambda c: float_match_patch(ds, c)),
        "coef_zero": lambda: hardware(ds, args.frames,
                                      patch=lambda c: coefficient_patch(ds, c, "zero")),
        "coef_centre": lambda: hardware(ds, args.frames,
                                        patch=lambda c: coefficient_patch(ds, c, "centre")),
        "coef_mean": lambda: hardware(ds, args.frames,
                                      patch=lambda c: coefficient_patch(ds, c, "mean")),
        "k8": lambda: hardware(ds, args.frames, config=PipelineConfig.for_rig(
            ds.rig, segments=8, stereo_segments=8)),
        "k8_ks4": lambda: hardware(ds, args.frames, config=PipelineConfig.for_rig(
            ds.rig, segments=8, stereo_segments=4)),
        "alpha05": lambda: hardware(ds, args.frames, forecast_changes={"alpha": 0.05}),
        "no_scale_ceiling": lambda: hardware(
            ds, args.frames, consistency_changes={"scale_ceiling": scale_top}),
        "depth_weight": lambda: hardware(ds, args.frames, patch=depth_weight_patch),
    }
    for name, fn in swaps.items():
        if want(name):
            t = time.time()
            try:
                report(name, level_of(fn()))
            except Exception as exc:   # a swap that cannot run is reported, not fatal
                print(f"{name}: {exc!r}", flush=True)
            print(f"   ({time.time() - t:.0f}s)", flush=True)
    if want("gb_motion"):
        report("gb_motion", rms(golden_steps(gb, ds, frames, rows), truth))
    if want("gb_steps"):
        report("gb_steps", rms(_golden_measured(gb, ds, frames, rows), truth))
    for kind in ("plain", "time"):
        if want(f"gb_linear_{kind}"):
            report(f"gb_linear_{kind}", rms(golden_trajectory_steps(
                golden_b(ds, linear=kind), ds, frames, rows), truth))
    for name, changes in (("gb_k4", {"segments": 4}), ("gb_blocks4", {"disparity_blocks": 4}),
                          ("gb_no_depth_weight", {"shift_sigma": 1e6}),
                          ("gb_no_ceiling", {"scale_ceiling": 1e6}),
                          ("gb_alpha05", {"alpha": 0.05})):
        if want(name):
            report(name, rms(golden_trajectory_steps(golden_b(ds, **changes), ds, frames,
                                                     rows), truth))
    if want("gb_hwlike"):
        report("gb_hwlike", rms(golden_trajectory_steps(golden_b(
            ds, segments=4, disparity_blocks=4, shift_sigma=1e6, consistency_k=0.0,
            scale_ceiling=1e6), ds, frames, rows), truth))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())

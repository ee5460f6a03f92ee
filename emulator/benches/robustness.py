"""Benchmark of the golden tracker on scenes it was not tuned on (issue 18, the stress
suite): randomized rooms, clutter, far walls beyond the stereo range and every texture
family (:mod:`golden.stress_scenes`), per rig and motion, measured depth.

Per run: the stress dataset of a seed (half-size images, :data:`SCALE`; the first frame
given), tracked with the default parameters except ``disparity_blocks`` (blocks of about
the full-size width). A run is *lost* when some row slot is reported ``LOST``; a
*silent failure* is a run with a row whose integrated position error exceeds
:data:`SILENT_T_CM` (or rotation error :data:`SILENT_R_RAD`) while that row is reported
plainly tracking (status ``TRACKING``, not drifted since a loss). Figures per rig:
``tracked_fraction`` (runs never lost), ``median_abs_t_cm`` and ``worst_abs_t_cm`` (over
runs, each run's largest per-axis RMS position error over its tracked rows),
``lost_runs``, ``silent_failures``, ``runs`` and ``skipped_seeds`` (seeds whose motion
would take a camera into a surface, replaced by the next seed).
"""

import os
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

RIGS = ("stereo8", "stereo20")
MOTIONS = ("paper", "head")
#: Runs per rig and motion (the issue asks for at least 20).
RUNS = 20
SCALE, DURATION, NOISE = 0.5, 0.25, 2.0
DISPARITY_BLOCKS = 8
#: A row reported plainly tracking with a larger error than this is a silent failure.
SILENT_T_CM, SILENT_R_RAD = 5.0, 0.05
#: Target of issue 18: at least this share of runs never lost.
NEVER_LOST = 0.95


def run_one(rig_name, motion, seed):
    """One stress run: its figures, or None when the seed's motion is not clear of the
    scene (``check_clearance`` refuses it)."""
    from golden.rig import preset
    from golden.pose_lsq import body_step
    from golden.stress_scenes import stress_dataset
    from golden.tracker import TrackerParams, track
    from golden.tracker_motion import ground_truth_track
    from golden.tracking_status import TrackingStatus
    try:
        dataset = stress_dataset(seed, preset(rig_name), motion, DURATION, scale=SCALE,
                                 noise=NOISE)
    except ValueError:
        return None
    result = track(dataset, TrackerParams(disparity_blocks=DISPARITY_BLOCKS))
    tracked = result.tracked
    true_rot, true_pos = ground_truth_track(dataset).at(result.times[tracked])
    t_cm = 100 * np.abs(result.positions[tracked] - true_pos)
    r_rad = np.abs(body_step(true_rot, true_pos, result.rotations[tracked],
                             result.positions[tracked])[:, 3:]).max(axis=1)
    status = result.status[tracked]
    plain = (status == TrackingStatus.TRACKING) & ~result.drifted[tracked]
    bad = (t_cm.max(axis=1) > SILENT_T_CM) | (r_rad > SILENT_R_RAD)
    return {"lost": bool(np.any(status == TrackingStatus.LOST)),
            "silent": bool(np.any(bad & plain)),
            "abs_t_cm": float(np.sqrt(np.mean(t_cm ** 2, axis=0)).max())}


def _runs(rig, motion, workers):
    """:data:`RUNS` accepted runs from seed 0 on, and how many seeds were skipped."""
    runs, seed, skipped = [], 0, 0
    with ProcessPoolExecutor(workers) as pool:
        while len(runs) < RUNS:
            seeds = range(seed, seed + RUNS - len(runs))
            for s, out in zip(seeds, pool.map(run_one, [rig] * len(seeds),
                                              [motion] * len(seeds), seeds)):
                if out is None:
                    skipped += 1
                else:
                    runs.append(out)
                print(f"robustness {rig} {motion} seed {s}: "
                      f"{'skipped' if out is None else out}", file=sys.stderr, flush=True)
            seed += len(seeds)
    return runs, skipped


def summarize(runs):
    """Figures of a list of :func:`run_one` results."""
    errors = [r["abs_t_cm"] for r in runs]
    lost = sum(r["lost"] for r in runs)
    return {"runs": len(runs), "lost_runs": lost,
            "tracked_fraction": 1 - lost / len(runs),
            "silent_failures": sum(r["silent"] for r in runs),
            "median_abs_t_cm": float(np.median(errors)), "worst_abs_t_cm": float(max(errors))}


def measure(rigs=RIGS, motions=MOTIONS):
    workers = max(1, os.cpu_count() or 1)
    figures = {}
    for rig in rigs:
        runs, skipped = [], 0
        for motion in motions:
            got, skip = _runs(rig, motion, workers)
            figures.update({f"{rig}.{motion}.{k}": v for k, v in summarize(got).items()})
            runs += got
            skipped += skip
        figures.update({f"{rig}.{k}": v for k, v in summarize(runs).items()})
        figures[f"{rig}.skipped_seeds"] = skipped
    return figures


def report(figures):
    f = figures
    rows = []
    for rig in RIGS:
        for key, label in [(f"{rig}.{m}", f"{rig}, {m}") for m in MOTIONS] + [(rig, f"{rig}, all")]:
            if f"{key}.runs" not in f:
                continue
            met = f[f"{key}.tracked_fraction"] >= NEVER_LOST and f[f"{key}.silent_failures"] == 0
            rows.append(f"| {label} | {f[f'{key}.runs']} | {f[f'{key}.tracked_fraction']:.0%} | "
                        f"{f[f'{key}.lost_runs']} | {f[f'{key}.silent_failures']} | "
                        f"{f[f'{key}.median_abs_t_cm']:.2f} | {f[f'{key}.worst_abs_t_cm']:.2f} | "
                        f"{'met' if met else 'MISSED'} |")
    skipped = ", ".join(f"{rig} {f[f'{rig}.skipped_seeds']}" for rig in RIGS
                        if f"{rig}.skipped_seeds" in f)
    return f"""# Robustness: the golden tracker on the stress suite

{RUNS} runs per rig and motion of `golden.stress_scenes` (rooms 3–10 m, clutter near
the rig, far walls beyond the stereo range, every texture family, per-face contrast),
images at {SCALE:g} × the rig's size, {DURATION * 1000:.0f} ms, noise σ = {NOISE:g}, the first
frame given, measured stereo depth (`disparity_blocks` = {DISPARITY_BLOCKS}). Lost: some row
reported LOST. Silent failure: a row reported plainly tracking (not drifted) with a
position error above {SILENT_T_CM:g} cm or a rotation error above {SILENT_R_RAD:g} rad. Errors:
per run the largest per-axis RMS of the integrated position error. Seeds skipped (motion
into a surface): {skipped}. Target (issue 18): ≥ {NEVER_LOST:.0%} of runs never lost and no
silent failure.

| rig, motion | runs | never lost | lost runs | silent failures | median abs T (cm) | worst abs T (cm) | target |
|---|---|---|---|---|---|---|---|
{chr(10).join(rows)}
"""

"""Study: read the hardware path's one-frame motion Y from a pose track instead of the
forecast filter's level (docs/e2e_gap.md section 6 item 3).

Runs the emulator's closed loop (`emulator.hardware_path.closed_loop`, the hw_tracking
benchmark's sequence and gain law) once, logging per loop row the filter's level and
trend and the solved step, then scores causal output estimators built from those values
against truth, as ratios to golden (b)'s figures of the same sequence in
docs/results/figures.json:

* ``level``: the filter's level (the benchmark's figure; a check that the run is the
  benchmark's);
* ``pose``: golden (b)'s pose track (``golden.tracker.Tracker._step``) in float on the
  hardware's outputs: carried at ``(level + half a frame of trend) / P``, pulled by a
  scalar ``pose_alpha`` towards the previous frame's pose composed with the solved step;
* ``linear``: the same recursion in Y space, the hardware-friendly form: a ring of the
  last P per-slot increments ``v``, ``Y`` their sum; per slot ``u = Y − v(s − P)``,
  ``c = rate``, ``v = c + a (m − u − c)`` (``c`` without a step), ``Y = u + v``, ``m``
  the solved step (:func:`emulator.pose.motion_track.track_float`);
* ``linear_level``: the same with ``m`` the filter's level after the row (the hardware
  model's law, :mod:`emulator.pose.motion_track`).

Run from the checkout: ``PYTHONPATH=. .venv/bin/python scripts/pose_track_study.py
[--rig stereo20] [--motion paper] [--gain information]``; the loop log is cached in
build/pose_track_study/.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

AXES = ("Tx", "Ty", "Tz", "θx", "θy", "θz")
sys.path.insert(0, str(Path(__file__).parent))      # gap_study, the other study script


def run_loop(rig, motion, gain, cache):
    """The closed loop's per-row log: frame, row, slot, level, trend (float), and the
    solved steps keyed by (frame, row)."""
    if cache.exists():
        return dict(np.load(cache))
    from emulator.benches.hw_tracking import MOTIONS
    from emulator.benches.tracker import noisy_sequence
    from emulator.hardware_path import closed_loop
    from emulator.pose import tracking_loop
    trends = []
    close = tracking_loop.TrackingLoopModel.close

    def logged(self, transfers, slot, row):
        out = close(self, transfers, slot, row)
        trends.append(self.forecast.filter.trend.copy())
        return out

    tracking_loop.TrackingLoopModel.close = logged
    dataset = noisy_sequence(rig, motion, MOTIONS[motion])
    path = closed_loop(dataset, forecast_changes={"motion_gain": gain}, progress=True)
    tracking_loop.TrackingLoopModel.close = close
    loop = path.result.loop
    fmt = path.forecast.motion_fmt
    sf, sr, steps = path.steps()
    log = {"frame": loop["frame"], "row": loop["row"], "slot": loop["slot"],
           "level": fmt.to_float(loop["level"]), "trend": fmt.to_float(np.array(trends)),
           "step_frame": sf, "step_row": sr, "step": steps,
           "period_slots": 1.0 / (dataset.rig.cameras[0].fps * dataset.rig.cameras[0].t_r)}
    cache.parent.mkdir(parents=True, exist_ok=True)
    np.savez(cache, **log)
    return log


def linear_track(log, pose_alpha, period, target="step"):
    """Y of every loop row from the Y-space recursion
    (:func:`emulator.pose.motion_track.track_float`) on the logged values: the rate from
    the level before each row and the trend after it, the pull towards the row's solved
    step (``target="step"``) or the filter's level after it (``"level"``, the hardware's
    law)."""
    from emulator.pose.motion_track import track_float
    steps = {(int(f), int(r)): s for f, r, s in zip(log["step_frame"], log["step_row"],
                                                   log["step"])}
    before = np.vstack([log["level"][:1], log["level"][:-1]])
    rows = []
    for f, r, s, current, level, trend in zip(log["frame"], log["row"], log["slot"], before,
                                              log["level"], log["trend"]):
        step = steps.get((int(f), int(r)))
        solved = step is not None and np.all(np.isfinite(step))
        rows.append((int(s), current, trend,
                     (step if target == "step" else level) if solved else None))
    return track_float(period, pose_alpha, log["level"][0], rows)


def pose_track(dataset, log, pose_alpha):
    """Y of every loop row of frames ≥ 1 from golden (b)'s pose track in float
    (``scripts/gap_study.py``'s, with the trend term)."""
    from gap_study import trajectory_steps
    scored = log["frame"] > 0
    run = (log["frame"][scored], log["row"][scored], None,
           (log["step_frame"], log["step_row"], log["step"]))
    return trajectory_steps(dataset, run, (log["frame"], log["row"], log["level"]),
                            pose_alpha, log["trend"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rig", default="stereo20")
    parser.add_argument("--motion", default="paper")
    parser.add_argument("--gain", default="information")
    parser.add_argument("--pose-alpha", type=float, default=0.02)
    args = parser.parse_args()
    from emulator.benches.hw_tracking import MOTIONS
    from emulator.benches.tracker import noisy_sequence
    from emulator.e2e import true_steps
    cache = Path("build/pose_track_study") / f"{args.rig}_{args.motion}_{args.gain}.npz"
    log = run_loop(args.rig, args.motion, args.gain, cache)
    dataset = noisy_sequence(args.rig, args.motion, MOTIONS[args.motion])
    period = int(round(float(log["period_slots"])))
    figures = json.loads(Path("docs/results/figures.json").read_text())
    prefix = f"hw_tracking.{args.rig}.{args.motion}." + \
             ("information." if args.gain == "information" else "")
    if prefix + "golden_b_rms_t_cm.x" not in figures:
        prefix = f"hw_tracking.{args.rig}.{args.motion}." + \
                 ("scalar." if args.gain == "scalar" else "")
    golden = np.array([figures[f"{prefix}golden_b_rms_t_cm.{a}"] / 100 for a in "xyz"]
                      + [figures[f"{prefix}golden_b_rms_r_rad.{a}"] for a in "xyz"])
    scored = log["frame"] > 0
    truth = true_steps(dataset, log["frame"][scored], log["row"][scored])
    estimates = {"level": log["level"][scored],
                 "linear": linear_track(log, args.pose_alpha, period)[scored],
                 "linear_level": linear_track(log, args.pose_alpha, period, "level")[scored],
                 "pose": pose_track(dataset, log, args.pose_alpha)}
    print(f"{args.rig} {args.motion} {args.gain}: P = {period} slots, "
          f"pose_alpha {args.pose_alpha}; ratio to golden (b) {prefix}")
    print("estimator | " + " | ".join(AXES))
    for name, values in estimates.items():
        rms = np.sqrt(np.nanmean(np.square(values - truth), axis=0))
        print(f"{name} | " + " | ".join(f"{x:.2f}" for x in rms / golden)
              + "   rms " + " ".join(f"{x:.3g}" for x in rms))


if __name__ == "__main__":
    main()

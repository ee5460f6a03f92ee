"""Why the board rig does not track: the motion filter's gain law (issues 16 and 17).

On the hw_tracking benchmark's own sequences (:func:`emulator.benches.tracker.noisy_sequence`,
12 frames) of a rig, per-row one-frame motion Y RMS against truth:

* ``golden``: golden (b) (``reference="previous"``, ``follow_rows=True``, the hardware
  path's loop delay) with ``motion_gain`` ``"scalar"`` (the hardware's law) and
  ``"information"``;
* ``hardware``: the emulator's closed loop (:func:`emulator.benches.hw_tracking.hardware_path`)
  with its filter's level moved by golden's information gain instead of the scalar
  ``alpha``. The gain is computed in float from each solved row's normal matrix (the
  accumulator's, :func:`emulator.pose_solver.accumulate`) and a running typical one
  (golden's smoothing), and fed to the unchanged fixed-point filter as the value whose
  scalar update gives the same level: ``predicted + K (value - predicted) / alpha``. A
  monkeypatch of :meth:`emulator.pose.tracking_loop.TrackingLoopModel.close` in this
  script only: no hardware computes it yet (docs/board_rig.md).

Usage: ``PYTHONPATH=. .venv/bin/python scripts/board_gain_study.py [--rig stereo8-board]
[--motion paper] [--only golden|hardware]``; about 30 s (golden) and 2.5 min (hardware)
per motion.
"""

import argparse
import dataclasses

import numpy as np

from golden.tracker_solve import TYPICAL_SMOOTHING


def golden_runs(dataset):
    from emulator.hardware_path import golden_b_params, hardware_config
    from golden.metrics import evaluate
    from golden.tracker import track
    delay = hardware_config(dataset.rig).forecast().loop_delay_rows
    for gain in ("scalar", "information"):
        params = dataclasses.replace(golden_b_params(delay), motion_gain=gain)
        m = evaluate(track(dataset, params), dataset)
        yield f"golden (b), {gain} gain", m["rms_t_cm"], m["rms_r_rad"], None


def _normal_matrix(solver, coef_raw, rows):
    from emulator.pose_solver import UPPER, accumulate
    normal, _ = accumulate(solver, coef_raw, rows)
    n = np.zeros((6, 6))
    for (i, j), value in zip(UPPER, normal):
        n[i, j] = n[j, i] = float(value.fmt.to_float(np.asarray(value.raw, dtype=object))[0])
    return n


def with_information_gain():
    """Patch the emulator's loop: each solved row's step replaced by the value that moves
    the scalar filter as the information gain would."""
    import emulator.pose.tracking_loop as loop
    from golden.temporal_filter import information_gain
    solve_rows, close = loop.solve_rows, loop.TrackingLoopModel.close
    typical = {}

    def solve_with_gain(self, solver, coef_raw, rows):
        result = solve_rows(solver, coef_raw, rows)
        if result.flags[0] != 0:
            return result
        n = _normal_matrix(solver, coef_raw, rows)
        before = typical.get(id(self))
        typical[id(self)] = n if before is None else \
            (1 - TYPICAL_SMOOTHING) * before + TYPICAL_SMOOTHING * n
        if before is None:
            return result
        filt, step_fmt = self.forecast.filter, solver.step_fmt
        p = filt.params
        alpha = p.alpha_raw / 2 ** p.gain_fmt.frac_bits
        predicted = (filt.level + filt.trend).astype(float) / 2 ** p.motion_fmt.frac_bits
        value = result.step[0].astype(float) / 2 ** step_fmt.frac_bits
        value = predicted + information_gain(n, before, alpha) @ (value - predicted) / alpha
        top = 2 ** (step_fmt.int_bits + step_fmt.frac_bits - 1) - 1
        raw = np.clip(np.round(value * 2 ** step_fmt.frac_bits), -top, top)
        result.step[0] = raw.astype(np.int64)
        return result

    def patched_close(self, transfers, slot, row):
        loop.solve_rows = lambda *args: solve_with_gain(self, *args)
        try:
            return close(self, transfers, slot, row)
        finally:
            loop.solve_rows = solve_rows

    loop.TrackingLoopModel.close = patched_close


def hardware_run(dataset):
    """The patched loop (:func:`with_information_gain`, applied once) on ``dataset``."""
    from emulator.benches.hw_tracking import hardware_path
    f = hardware_path(dataset)
    yield ("hardware path, information gain (float)",
           [f[f"rms_t_cm.{a}"] for a in "xyz"], [f[f"rms_r_rad.{a}"] for a in "xyz"],
           f["solved_fraction"])
    yield ("the true motion itself", [f[f"motion_rms_t_cm.{a}"] for a in "xyz"],
           [f[f"motion_rms_r_rad.{a}"] for a in "xyz"], None)


def main():
    from emulator.benches.hw_tracking import MOTIONS
    from emulator.benches.tracker import noisy_sequence
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rig", default="stereo8-board")
    parser.add_argument("--motion", choices=tuple(MOTIONS), action="append")
    parser.add_argument("--only", choices=("golden", "hardware"))
    args = parser.parse_args()
    if args.only != "golden":
        with_information_gain()
    for motion in args.motion or tuple(MOTIONS):
        dataset = noisy_sequence(args.rig, motion, MOTIONS[motion])
        runs = []
        if args.only != "hardware":
            runs += list(golden_runs(dataset))
        if args.only != "golden":
            runs += list(hardware_run(dataset))
        for label, t_cm, r_rad, solved in runs:
            extra = "" if solved is None else f", {solved:.1%} solved"
            print(f"{args.rig} {motion}: {label}: "
                  f"{' / '.join(f'{v:.3f}' for v in t_cm)} cm, "
                  f"{' / '.join(f'{v:.2e}' for v in r_rad)} rad{extra}", flush=True)


if __name__ == "__main__":
    main()

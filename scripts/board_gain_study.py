"""Why the board rig does not track: the motion filter's gain law (issues 16 and 17).

On the hw_tracking benchmark's own sequences (:func:`emulator.benches.tracker.noisy_sequence`,
12 frames) of a rig, per-row one-frame motion Y RMS against truth:

* ``golden``: golden (b) (``reference="previous"``, ``follow_rows=True``, the hardware
  path's loop delay) with ``motion_gain`` ``"scalar"`` (the hardware's law) and
  ``"information"``;
* ``hardware``: the emulator's closed loop
  (:func:`emulator.benches.hw_tracking.hardware_path`) with the gateware's scalar gain and
  with the information gain (:mod:`emulator.pose.information_gain`, the bit-accurate
  model of the hardware to come; docs/board_rig.md).

Usage: ``PYTHONPATH=. .venv/bin/python scripts/board_gain_study.py [--rig stereo8-board]
[--motion paper] [--only golden|hardware]``; about 30 s (golden) and 7 min (hardware)
per motion.
"""

import argparse


def golden_runs(dataset):
    from emulator.hardware_path import golden_b_params, hardware_config
    from golden.metrics import evaluate
    from golden.tracker import track
    delay = hardware_config(dataset.rig).forecast().loop_delay_rows
    for gain in ("scalar", "information"):
        params = golden_b_params(delay, gain)
        m = evaluate(track(dataset, params), dataset)
        yield f"golden (b), {gain} gain", m["rms_t_cm"], m["rms_r_rad"], None


def hardware_runs(dataset):
    """The emulator's closed loop (:func:`emulator.benches.hw_tracking.hardware_path`) on
    ``dataset`` with both gain laws, and the true motion."""
    from emulator.benches.hw_tracking import hardware_path
    for gain in ("scalar", "information"):
        f = hardware_path(dataset, motion_gain=gain)
        yield (f"hardware path, {gain} gain",
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
    for motion in args.motion or tuple(MOTIONS):
        dataset = noisy_sequence(args.rig, motion, MOTIONS[motion])
        runs = []
        if args.only != "hardware":
            runs += list(golden_runs(dataset))
        if args.only != "golden":
            runs += list(hardware_runs(dataset))
        for label, t_cm, r_rad, solved in runs:
            extra = "" if solved is None else f", {solved:.1%} solved"
            print(f"{args.rig} {motion}: {label}: "
                  f"{' / '.join(f'{v:.3f}' for v in t_cm)} cm, "
                  f"{' / '.join(f'{v:.2e}' for v in r_rad)} rad{extra}", flush=True)


if __name__ == "__main__":
    main()

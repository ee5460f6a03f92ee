"""Benchmark of the main job: ``rowtrack run``'s default scenario, measured.

The same run as ``make run`` (stereo20 640×480, four frames of the papers' motion, seed
1, a co-simulated slice of the closed-loop HDL top), reported as ``e2e.*``: ``hdl_mismatches``,
``pose_rate_hz`` (delivered: the cameras' row sets per second, or the capacity if
lower), ``pose_capacity_hz`` and ``latency_us`` at the co-simulation's clock,
``emulator_rows_per_s``, ``hdl_cycles_per_s``, ``hdl_rows_per_s`` and their ratio ``speed_ratio`` (camera rows per
second of the emulator over those of the HDL simulation), and the accuracy figures
(the hardware path's closed loop and golden (b) with the same loop delay against truth,
the default golden tracker; the emulator against float64 on its own measurements).
``hdl_cycles_per_s`` and ``speed_ratio`` use the wall time of the
simulation itself (:attr:`emulator.cosim_loop.LoopCosimResult.wall_s`, not the model
build).
"""

from emulator.report import accuracy_section, hardware_section, tolerance_section, wall_times
from emulator.report import metrics as run_metrics


def measure():
    from emulator.cli import build_parser
    from emulator.commands.run import check_inputs, run_job
    args = build_parser().parse_args(["run", "--no-progress"])
    outcome = run_job(check_inputs(args), progress=False)
    figures = run_metrics(outcome)
    figures["failures"] = len(outcome.all_failures())
    return figures


def report(figures):
    f = figures
    walls = ", ".join(f"{phase} {seconds:.1f} s" for phase, seconds in wall_times(f)
                      if phase != "total")
    return f"""# End-to-end run (`rowtrack run`, default scenario)

Rig `{f['rig']}`: {f['cameras']} cameras, {f['rows']} rows, {f['frames']} frames, K =
{f['segments']} segments per camera row; the papers' motion, seed 1. Wall time
{f['wall_s.total']:.0f} s ({walls}) on this machine (2 cores shared). Comparison failures:
{f['failures']}. Design and reading: [docs/e2e.md](../e2e.md).

## Hardware (co-simulated slice of the closed-loop HDL top)

{hardware_section(f)}

## Accuracy

{accuracy_section(f)}

## Hardware path ↔ truth and golden (b): tolerances

{tolerance_section(f)}
"""

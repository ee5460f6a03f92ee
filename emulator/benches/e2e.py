"""Benchmark of the main job: ``rowtrack run``'s default scenario, measured.

The same run as ``make run`` (stereo20 640×480, four frames of the papers' motion, seed
1, a co-simulated slice of the HDL top), reported as ``e2e.*``: ``hdl_mismatches``,
``pose_rate_hz`` and ``latency_us`` at the co-simulation's clock, ``emulator_rows_per_s``,
``hdl_cycles_per_s``, ``hdl_rows_per_s`` and their ratio ``speed_ratio`` (camera rows per
second of the emulator over those of the HDL simulation), and the accuracy figures
(golden tracker, emulator and the float hardware scheme against truth; emulator against
the float scheme). Without a co-simulation (``emulator.cosim.cosim_slice`` missing) the
HDL figures are absent and the page says so.
"""

from emulator.report import metrics as run_metrics
from golden.pose_lsq import UNKNOWNS


def measure():
    from emulator.cli import build_parser
    from emulator.commands.run import check_inputs, run_job
    try:
        from emulator.cosim import cosim_slice  # noqa: F401
        extra = []
    except ImportError:
        extra = ["--cosim-rows", "0"]
    args = build_parser().parse_args(["run", "--no-progress", *extra])
    outcome = run_job(check_inputs(args), progress=False)
    figures = run_metrics(outcome)
    figures["failures"] = len(outcome.all_failures())
    return figures


def _six(figures, key, fmt=".2e"):
    return " | ".join(format(figures[f"{key}.{n}"], fmt) for n in UNKNOWNS)


def _hardware(f):
    if "hdl_mismatches" not in f:
        return ("No co-simulation: `emulator.cosim.cosim_slice` was not available when "
                "this page was measured, so there are no HDL figures (mismatches, pose "
                "rate, latency, cycles/s, speed ratio).")
    return f"""| figure | value |
|---|---|
| co-simulated slice | {f['cosim.cameras']} cameras × {f['cosim.frames']} frames × {f['cosim.rows']} rows |
| HDL ↔ emulator mismatches (must be 0) | {f['hdl_mismatches']} of {f['hdl_records']} records |
| UART packets equal the emulator's | {f['uart_packets_match']} |
| clocks per row set | {f['clocks_per_row_set']} |
| pose rate `e2e.pose_rate_hz` = clk_hz / clocks_per_row_set | {f['pose_rate_hz']:,.0f} row sets/s at {f['clk_hz'] / 1e6:g} MHz (needed: {f['row_sets_needed_per_s']:,.0f}) |
| latency `e2e.latency_us` | {f['latency_clocks']} clocks = {f['latency_us']:.3f} µs |
| HDL simulation `e2e.hdl_cycles_per_s` | {f['hdl_cycles_per_s']:,.0f} cycles/s = {f['hdl_rows_per_s']:,.2f} camera rows/s |
| emulator `e2e.emulator_rows_per_s` | {f['emulator_rows_per_s']:,.0f} camera rows/s |
| emulator / HDL simulation, camera rows/s (issue: ≥ 100×) | {f['speed_ratio']:,.1f}× |"""


def report(figures):
    f = figures
    return f"""# End-to-end run (`rowtrack run`, default scenario)

Rig `{f['rig']}`: {f['cameras']} cameras, {f['rows']} rows, {f['frames']} frames, K =
{f['segments']} segments per camera row; the papers' motion, seed 1. Wall time
{f['wall_s.total']:.0f} s
(simulate {f['wall_s.simulate']:.1f} s, golden tracker {f['wall_s.golden']:.1f} s, emulator
{f['wall_s.emulator']:.1f} s, comparisons {f['wall_s.compare']:.1f} s{f", co-simulation {f['wall_s.cosim']:.1f} s" if 'wall_s.cosim' in f else ''});
comparison failures: {f['failures']}. Design and reading: [docs/e2e.md](../e2e.md).

## Hardware

{_hardware(f)}

## Accuracy

Golden tracker (default parameters) against truth, per-row Y RMS: T x/y/z
{f['golden.rms_t_cm.x']:.4f} / {f['golden.rms_t_cm.y']:.4f} / {f['golden.rms_t_cm.z']:.4f} cm,
θ {f['golden.rms_r_deg.x']:.4f} / {f['golden.rms_r_deg.y']:.4f} / {f['golden.rms_r_deg.z']:.4f}°;
render error {f['golden.render_px']:.3f} px RMS.

One-frame steps per row set, per-axis RMS (m, rad):

| comparison | Tx | Ty | Tz | θx | θy | θz |
|---|---|---|---|---|---|---|
| emulator ↔ truth | {_six(f, 'emulator_vs_truth.rms')} |
| golden scheme (float) ↔ truth | {_six(f, 'scheme_vs_truth.rms')} |
| golden tracker ↔ truth | {_six(f, 'golden_vs_truth.rms')} |
| emulator ↔ golden scheme | {_six(f, 'emulator_vs_scheme.rms')} |
| emulator ↔ golden scheme, largest | {_six(f, 'emulator_vs_scheme.max_abs')} |
| emulator ↔ float64 solve of its own measurements | {_six(f, 'emulator_vs_float.rms')} |

Measurements: {f['measurement.within_subpixel']:.2%} of {f['measurement.well_textured']}
well-textured shifts agree with the float scheme within 1/16 px; the largest difference
is {f['measurement.max_shift_px']:.3f} px.
"""

"""``build/report/`` of ``rowtrack run``: ``report.md``, PNG plots and ``metrics.json``.

The figures come from one :class:`Outcome` (what :func:`emulator.commands.run.run_job`
produced); :func:`metrics` is also what ``rowtrack bench --only e2e`` reports. The
judged comparison is the hardware path's closed loop against truth and against golden
(b) with the same loop delay (:mod:`emulator.e2e`); the default golden tracker's
accuracy is reported beside it. Resource
estimates are not measured here: they are read from ``docs/results/figures.json``
(``top.*``, written by ``rowtrack bench --only top``), and the report says so.
"""

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from emulator.e2e import (FLOAT_TOLERANCE, GOLDEN_B_RATIO, SHARE_OF_MOTION, SHIFT_BOUND,
                          SOLVED_FRACTION, SUBPIXEL_SHARE, SUBPIXEL_TOLERANCE, WELL_TEXTURED)
from golden.metrics import AXES
from golden.pose_lsq import UNKNOWNS
from golden.tracking_status import status_summary

__all__ = ["Outcome", "metrics", "golden_failures", "cosim_failures", "resources", "write_report", "table",
           "PHASES", "wall_times", "benchmark_figures", "accuracy_section",
           "tolerance_section", "hardware_section", "FIGURES_JSON"]

FIGURES_JSON = Path(__file__).resolve().parent.parent / "docs" / "results" / "figures.json"

#: Accuracy figures of golden.metrics.evaluate carried into metrics.json.
ACCURACY = ("rms_t_cm", "rms_r_deg", "abs_t_cm", "abs_r_deg", "render_px",
            "render_px_max", "update_fraction")


@dataclass
class Outcome:
    """Everything one run produced (see :func:`emulator.commands.run.run_job`)."""
    job: object
    dataset: object
    golden: object                   # golden.tracker.TrackResult, default parameters
    accuracy: dict                   # golden.metrics.evaluate of it
    golden_b: object                 # golden.tracker.TrackResult, reference (b)
    hardware: object                 # emulator.e2e.HardwarePath
    comparison: dict                 # emulator.e2e.compare_closed_loop
    failures: list                   # emulator.e2e.check_closed_loop + co-simulation
    cosim: object = None             # emulator.cosim_loop.LoopCosimResult, None when skipped
    walls: dict = field(default_factory=dict)

    @property
    def emulated(self):
        """The emulator's :class:`emulator.pipeline.PipelineResult` (the closed loop)."""
        return self.hardware.result

    def all_failures(self):
        return list(self.failures) + golden_failures(self.golden) + cosim_failures(self.cosim)

    def summary(self):
        m = metrics(self)
        lines = [f"{m['rig']}: {m['cameras']} cameras × {m['frames']} frames × {m['rows']} "
                 f"rows in {m['wall_s.total']:.1f} s",
                 f"hardware path (closed loop, {m.get('motion_gain', 'scalar')} gain, delay "
                 f"{m['loop_delay_rows']} row = "
                 f"{m['loop_delay_clocks']} clocks) vs truth, per-row Y RMS (m, rad): "
                 f"{m['estimate']} {_six(m, 'emulator_vs_truth.rms')}; filter level "
                 f"{_six(m, 'emulator_level_vs_truth.rms')}; solved steps "
                 f"{_six(m, 'emulator_steps_vs_truth.rms')}; {m['solved_fraction']:.1%} of "
                 f"rows solved",
                 f"golden (b), same delay, vs truth: {_six(m, 'golden_b_vs_truth.rms')}",
                 f"true one-frame motion RMS: {_six(m, 'true_motion.rms')}",
                 f"hardware ÷ golden (b): {_six(m, 'ratio_to_golden_b', '.2f')} (bound "
                 f"{m['tolerance.golden_b_ratio']}); ÷ true motion: "
                 f"{_six(m, 'share_of_motion', '.3f')} (bound "
                 f"{m['tolerance.share_of_motion']})",
                 f"golden tracker (default) vs truth: per-row Y RMS T "
                 f"{_triple(m, 'golden.rms_t_cm', 4)} cm, θ {_triple(m, 'golden.rms_r_deg', 4)}°; "
                 f"status {m['golden.status']}",
                 f"emulator vs float64 solve of its own measurements: step RMS "
                 f"{_six(m, 'emulator_vs_float.rms')}; pose vs truth RMS "
                 f"{_six(m, 'emulator_pose_vs_truth.rms')}",
                 f"lanes vs float matcher on the loop's rows and centres: "
                 f"{m['lanes.within_subpixel']:.1%} of {m['lanes.well_textured']} "
                 f"well-textured shifts within 1/16 px, worst {m['lanes.max_shift_px']:.3f} px",
                 f"emulator: {m['emulator_rows_per_s']:.0f} camera rows/s"]
        if self.cosim is None:
            lines.append("HDL co-simulation: " + ("skipped (--cosim-rows 0)"
                                                  if self.job.cosim is None else "failed"))
        else:
            lines.append(f"HDL co-simulation: {m['hdl_records']} records, "
                         f"{m['hdl_mismatches']} mismatches; {m['pose_rate_hz']:.4g} pose "
                         f"updates/s delivered (capacity {m['pose_capacity_hz']:.4g} row "
                         f"sets/s) and {m['latency_us']:.3g} µs latency at "
                         f"{m['clk_hz'] / 1e6:g} MHz; {m['hdl_cycles_per_s']:.3g} cycles/s "
                         f"simulated; emulator/HDL speed {m['speed_ratio']:.3g}×")
        return "\n".join(lines)


def _triple(m, key, digits):
    return "/".join(f"{m[f'{key}.{a}']:.{digits}f}" for a in AXES)


def _six(m, key, fmt=".2g"):
    return " ".join(format(m[f"{key}.{n}"], fmt) for n in UNKNOWNS)


def _count(records):
    """Number of pose records in a dict of raw arrays."""
    return len(np.asarray(records["row"]))


def golden_failures(result):
    """The golden tracker's failure line: when it lost tracking (none if it never did)."""
    lost = status_summary(result)["lost_at_ms"]
    return [] if lost is None else [
        f"golden tracker: tracking lost at {lost:.1f} ms (its accuracy figures after that "
        f"are not a tracking result)"]


def cosim_failures(cosim):
    """Failure messages of a co-simulated slice (none when skipped)."""
    if cosim is None:
        return []
    failures = []
    if not _count(cosim.records):
        failures.append("HDL ↔ emulator: the co-simulated slice produced no pose record")
    if not cosim.rows_match:
        failures.append("HDL ↔ emulator: the HDL front end's row sets are not the slice's "
                        "rows")
    # one line for every kind that differs: the result keeps only the first difference
    # of all of them
    counts = [f"{count} mismatching {what} field(s)"
              for what, count in (("PS FIFO record", cosim.mismatches),
                                  ("solver record", cosim.solver_mismatches),
                                  ("forecast row", cosim.forecast_mismatches),
                                  ("motion track row", cosim.track_mismatches)) if count]
    if counts:
        failures.append(f"HDL ↔ emulator: {', '.join(counts)}; first difference: "
                        f"{cosim.first_mismatch}")
    if not cosim.uart_packets_match:
        failures.append("HDL ↔ emulator: the UART packets differ from the emulator's")
    if _count(cosim.records) and not cosim.solved:
        failures.append("HDL ↔ emulator: no row set of the co-simulated slice was solved, "
                        "so the solver's arithmetic was not compared (try more "
                        "--cosim-rows, --cosim-cameras or --cosim-frames)")
    return failures


def _flat(prefix, values):
    """A metrics entry: lists of three become ``prefix.x/.y/.z``."""
    if isinstance(values, list) and len(values) == 3:
        return {f"{prefix}.{a}": v for a, v in zip(AXES, values)}
    return {prefix: values}


def metrics(outcome):
    """The run's figures, flat dotted keys without the ``e2e.`` prefix (metrics.json
    and the e2e benchmark add it)."""
    job, dataset, cosim = outcome.job, outcome.dataset, outcome.cosim
    router = job.config.router
    camera = dataset.rig.cameras[0]
    m = {"rig": dataset.rig.name, "cameras": router.cameras, "frames": job.frames,
         "rows": router.temporal.height, "segments": router.temporal.segments,
         "row_sets_needed_per_s": camera.fps * camera.height,
         "emulator_rows_per_s": outcome.emulated.rows_per_s,
         "emulator_camera_rows": outcome.emulated.camera_rows}
    for name in ACCURACY:
        m.update(_flat(f"golden.{name}", outcome.accuracy[name]))
    status = status_summary(outcome.golden)
    m.update({"golden.status": status["status"], "golden.lost_at_ms": status["lost_at_ms"],
              "golden.tracking_fraction": status["tracking_fraction"]})
    m.update({k: v for k, v in outcome.comparison.items() if k != "emulator_rows_per_s"})
    m.update({"tolerance.golden_b_ratio": GOLDEN_B_RATIO,
              "tolerance.share_of_motion": SHARE_OF_MOTION,
              "tolerance.solved_fraction": SOLVED_FRACTION,
              "tolerance.float": FLOAT_TOLERANCE,
              "tolerance.lanes_within_subpixel": SUBPIXEL_SHARE,
              "tolerance.lanes_max_shift_px": SHIFT_BOUND})
    m.update({f"wall_s.{k}": v for k, v in outcome.walls.items()})
    m["tolerance_failures"] = len(outcome.failures)
    if cosim is not None:
        hdl_rows_per_s = cosim.row_sets * job.cosim["cameras"] / cosim.wall_s
        capacity = cosim.clk_hz / cosim.clocks_per_row_set
        m.update({"hdl_mismatches": int(cosim.all_mismatches),
                  "hdl_fifo_mismatches": int(cosim.mismatches),
                  "hdl_solver_mismatches": int(cosim.solver_mismatches),
                  "hdl_forecast_mismatches": int(cosim.forecast_mismatches),
                  "hdl_track_mismatches": int(cosim.track_mismatches),
                  "hdl_forecast_rows": _count(cosim.forecasts),
                  "hdl_track_rows": _count(cosim.track),
                  "hdl_records": _count(cosim.records),
                  "hdl_solved_records": int(cosim.solved),
                  "hdl_expected": _count(cosim.expected), "clk_hz": cosim.clk_hz,
                  "clocks_per_row_set": cosim.clocks_per_row_set,
                  # what the hardware could take, and what it delivers: one update
                  # per row set the cameras send, unless it cannot keep up
                  "pose_capacity_hz": capacity,
                  "pose_rate_hz": min(m["row_sets_needed_per_s"], capacity),
                  "latency_clocks": cosim.latency_clocks,
                  "latency_us": 1e6 * cosim.latency_clocks / cosim.clk_hz,
                  "hdl_clocks": cosim.clocks, "hdl_wall_s": cosim.wall_s,
                  "hdl_cycles_per_s": cosim.clocks / cosim.wall_s,
                  "hdl_rows_per_s": hdl_rows_per_s,
                  "speed_ratio": outcome.emulated.rows_per_s / hdl_rows_per_s,
                  "uart_packets_match": bool(cosim.uart_packets_match),
                  "cosim.rows": job.cosim["rows"], "cosim.cameras": job.cosim["cameras"],
                  "cosim.first_row": job.cosim["first_row"],
                  "cosim.dataset_cameras": list(job.cosim["dataset_cameras"]),
                  "cosim.frames": job.cosim["frames"], "cosim.sim": job.sim})
    return m


#: The run's phases in the order they run (``e2e.wall_s.<phase>``).
PHASES = ("simulate", "emulator", "golden_b", "golden", "compare", "cosim",
          "cosim_elaborate", "cosim_build", "cosim_simulate", "total")


def wall_times(m):
    """``(phase, seconds)`` of the run's figures ``m``, in :data:`PHASES` order (the
    order of a dict read back from figures.json is not the run's)."""
    return [(phase, m[f"wall_s.{phase}"]) for phase in PHASES if f"wall_s.{phase}" in m]


def _json_safe(value):
    if isinstance(value, (np.integer, np.floating, np.bool_)):
        value = value.item()
    return None if isinstance(value, float) and not math.isfinite(value) else value


def benchmark_figures(path=FIGURES_JSON):
    """The figures ``rowtrack bench`` measured (``docs/results/figures.json``); empty
    when the file is missing or unreadable."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}


def resources(rig, path=FIGURES_JSON):
    """The synthesis and timing figures ``top.<rig>.*`` of ``rig``'s board top from
    ``docs/results/figures.json`` (empty when the file or the figures are missing)."""
    prefix = f"top.{rig}."
    return {k[len(prefix):]: v for k, v in benchmark_figures(path).items()
            if k.startswith(prefix)}


def _ms(times):
    return 1000 * (np.asarray(times) - times[0])


def _plots(outcome, out):
    """Write the PNGs; returns their file names."""
    from emulator.commands.track import plot_trajectory
    from emulator.e2e import golden_trajectory_steps, relative_poses, true_steps
    from emulator.report_plots import emulator_camera_confidence, plot_confidence, plot_axes
    job, dataset, hardware = outcome.job, outcome.dataset, outcome.hardware
    t0 = dataset.cameras[0].time[0, 0]
    frames, rows, estimate, label = hardware.estimate()
    label = f"hardware path ({label})"
    ms = 1000 * (dataset.cameras[0].time[frames, rows] - t0)
    step_frames, step_rows, steps = hardware.steps()
    step_ms = 1000 * (dataset.cameras[0].time[step_frames, step_rows] - t0)
    truth = true_steps(dataset, frames, rows)
    golden_b = golden_trajectory_steps(outcome.golden_b, dataset, frames, rows)
    pose_frames, pose_rows, poses = relative_poses(job.config, hardware.result, dataset,
                                                   outcome.golden_b)
    pose_ms = 1000 * (dataset.cameras[0].time[pose_frames, pose_rows] - t0)
    plot_axes(out / "trajectory.png", pose_ms, poses,
              "trajectory: each row's pose relative to the same row of frame 0 (the "
              "hardware's pose records; golden (b) with the same loop delay; truth)")
    plot_axes(out / "steps.png", ms,
              {"truth": truth, "golden (b), same delay": golden_b,
               label: estimate},
              "per-row one-frame motion Y: truth, golden (b), the hardware path's closed loop",
              extra={"hardware path (solved steps)": (step_ms, steps)})
    plot_axes(out / "step_errors.png", ms,
              {"golden (b) − truth": golden_b - truth,
               f"{label} − truth": estimate - truth},
              "per-axis error of the per-row one-frame motion Y over time")
    plot_trajectory(out / "golden_trajectory.png", outcome.golden, dataset, outcome.accuracy)
    plot_confidence(out / "confidence.png", _ms(outcome.golden_b.times),
                    outcome.golden_b.camera_confidence, step_ms,
                    emulator_camera_confidence(job.config, hardware.result)[
                        hardware.result.frame > 0], golden_label="golden (b)")
    return ["trajectory.png", "steps.png", "step_errors.png", "golden_trajectory.png",
            "confidence.png"]


def table(rows):
    """A two-column Markdown table of ``(figure, value)`` rows."""
    return "\n".join(["| figure | value |", "|---|---|"]
                     + [f"| {name} | {value} |" for name, value in rows])


def _axes_row(m, key, names, fmt=".2e"):
    return " / ".join(format(m[f"{key}.{n}"], fmt) for n in names)


def accuracy_section(m):
    """Markdown: the hardware path and golden (b) against truth, and the default golden
    tracker's accuracy."""
    return "\n".join([
        f"Per-row one-frame motion Y = [Tx Ty Tz θx θy θz] (m, rad) against truth, RMS "
        f"per axis (`emulator.e2e.compare_closed_loop`); the hardware path's closed loop "
        f"with a loop delay of {m['loop_delay_rows']} row(s) = {m['loop_delay_clocks']} "
        f"clocks and the {m.get('motion_gain', 'scalar')} gain, golden (b) with the same delay and "
        f"gain:", "",
        table([(name, _axes_row(m, key, UNKNOWNS)) for name, key in (
            (f"hardware path ↔ truth ({m['estimate']}: the estimate judged)",
             "emulator_vs_truth.rms"),
            ("hardware path's filter level ↔ truth (reported)", "emulator_level_vs_truth.rms"),
            ("hardware path's solved steps ↔ truth", "emulator_steps_vs_truth.rms"),
            ("golden (b), same delay ↔ truth (Y from its trajectory: the judge's "
             "reference)", "golden_b_vs_truth.rms"),
            ("golden (b)'s filter motion ↔ truth (reported)", "golden_b_motion_vs_truth.rms"),
            ("hardware path ↔ golden (b)", "emulator_vs_golden_b.rms"),
            ("golden tracker (default) ↔ truth", "golden_vs_truth.rms"),
            ("true one-frame motion (for scale)", "true_motion.rms"),
            ("hardware's integrated pose ↔ truth, relative to frame 0 (RMS)",
             "emulator_pose_vs_truth.rms"))]
              + [("rows of frames ≥ 1 solved by the hardware path",
                  f"{m['solved_fraction']:.1%}")]),
        "",
        "Golden float tracker (default parameters) against ground truth "
        "(`golden.metrics.evaluate`; reported, not judged):", "",
        table([(f"{what}, {q} x/y/z ({unit})", _axes_row(m, f"golden.{key}", AXES, ".4f"))
               for what, key_t, key_r in (("per-row Y RMS", "rms_t_cm", "rms_r_deg"),
                                          ("trajectory RMS", "abs_t_cm", "abs_r_deg"))
               for q, key, unit in (("T", key_t, "cm"), ("θ", key_r, "deg"))]
              + [("render error RMS / max (px)",
                  f"{m['golden.render_px']:.3f} / {m['golden.render_px_max']:.3f}")]),
        "",
        "The hardware path is the emulator's closed measurement loop (forecast → lane "
        "centres and followed rows → measurements → consistency → solver → forecast), "
        "started at the true motion of the first tracked row (the papers' first frame "
        "given). The solver's pose ring composes each row's step onto the same row one "
        "frame earlier: its poses are relative to the first frame's rows "
        "(`emulator.e2e.pose_errors`). See docs/e2e.md."])


def tolerance_section(m):
    """Markdown: the hardware path against its stated tolerances, per axis."""
    rows = [(f"rows of frames ≥ 1 solved (tolerance: ≥ {SOLVED_FRACTION:.0%})",
             f"{m['solved_fraction']:.1%}")]
    for name in UNKNOWNS:
        ratio, share = m[f"ratio_to_golden_b.{name}"], m[f"share_of_motion.{name}"]
        rows.append((f"{name}: hardware ÷ golden (b) (tolerance: ≤ {GOLDEN_B_RATIO})",
                     f"{ratio:.2f} {'met' if ratio <= GOLDEN_B_RATIO else '**MISSED**'}"))
        rows.append((f"{name}: hardware ÷ true motion (tolerance: ≤ {SHARE_OF_MOTION})",
                     f"{share:.3f} {'met' if share <= SHARE_OF_MOTION else '**MISSED**'}"))
    rows.append((f"emulator ↔ float64 solve of its own measurements, step RMS per axis "
                 f"(tolerance: ≤ {FLOAT_TOLERANCE:g})",
                 _axes_row(m, "emulator_vs_float.rms", UNKNOWNS)))
    rows += [(f"lanes ↔ float matcher (same rows, centres and followed rows), "
              f"well-textured (float and lane peak ratio ≥ {WELL_TEXTURED})", m["lanes.well_textured"]),
             (f"within {SUBPIXEL_TOLERANCE} px (tolerance: ≥ {SUBPIXEL_SHARE:.0%})",
              f"{m['lanes.within_subpixel']:.2%}"),
             (f"largest difference (tolerance: ≤ {SHIFT_BOUND} px)",
              f"{m['lanes.max_shift_px']:.3f} px ({m.get('lanes.worst_at')})")]
    return table(rows)


def hardware_section(m):
    """Markdown: the co-simulated slice (rate, latency, speeds), or why there is none."""
    if "hdl_mismatches" not in m:
        return ("No co-simulation figures in this run (`--cosim-rows 0`, or the "
                "co-simulation failed: see the failures above).")
    return table([
        ("slice", f"{m['cosim.cameras']} cameras (dataset cameras "
                  f"{', '.join(map(str, m['cosim.dataset_cameras']))}) × {m['cosim.frames']} "
                  f"frames × rows {m['cosim.first_row']}–"
                  f"{m['cosim.first_row'] + m['cosim.rows'] - 1}, {m['cosim.sim']}: these "
                  f"rows cut as a rig of their own (restamped to its row times) through the "
                  f"closed-loop top, given the slice's true frame-1 motion after reset "
                  f"(`loop.initial`, `loop.restart`), against the emulator's closed loop "
                  f"on the same rows"),
        ("pose records HDL / expected", f"{m['hdl_records']} / {m['hdl_expected']}"),
        ("records with a solved step, every field compared (a slice of fewer than three "
         "stereo20 pairs cannot observe all six axes: its rows are not solved)",
         m["hdl_solved_records"]),
        ("forecast rows the engine took (each camera's window centre and source row), "
         "compared", m["hdl_forecast_rows"]),
        ("motion track rows (each row's Y) compared", m["hdl_track_rows"]),
        ("HDL ↔ emulator mismatches: PS FIFO + solver records + forecast rows + motion "
         "track rows (must be 0)",
         f"{m['hdl_mismatches']} ({m['hdl_fifo_mismatches']} + "
         f"{m['hdl_solver_mismatches']} + {m['hdl_forecast_mismatches']} + "
         f"{m['hdl_track_mismatches']})"),
        ("UART packets equal the emulator's", m["uart_packets_match"]),
        ("clocks per row set", m["clocks_per_row_set"]),
        ("pose updates delivered `e2e.pose_rate_hz` (one per row set the cameras send: "
         "fps × rows, unless above the capacity)",
         f"{m['pose_rate_hz']:,.0f} updates/s (the cameras send "
         f"{m['row_sets_needed_per_s']:,.0f} row sets/s)"),
        ("capacity `e2e.pose_capacity_hz` = clk_hz / clocks_per_row_set",
         f"{m['pose_capacity_hz']:,.0f} row sets/s at {m['clk_hz'] / 1e6:g} MHz"),
        ("latency `e2e.latency_us`", f"{m['latency_clocks']} clocks = "
                                     f"{m['latency_us']:.3f} µs"),
        ("wall time: Verilog, simulator model build, simulation (`e2e.wall_s.cosim_*`)",
         " / ".join(f"{m.get(f'wall_s.cosim_{k}', math.nan):.1f} s"
                    for k in ("elaborate", "build", "simulate"))),
        ("HDL simulation `e2e.hdl_cycles_per_s` (clocks / wall time of the simulation, "
         "without building the simulator model)",
         f"{m['hdl_cycles_per_s']:,.0f} cycles/s = {m['hdl_rows_per_s']:,.2f} camera rows/s "
         f"({m['hdl_clocks']:,} clocks in {m['hdl_wall_s']:.1f} s)"),
        ("emulator `e2e.emulator_rows_per_s`", f"{m['emulator_rows_per_s']:,.0f} camera rows/s"),
        ("emulator / HDL simulation, camera rows/s (issue: ≥ 100×)",
         f"{m['speed_ratio']:,.1f}×")])


def _markdown(outcome, m, plots):
    job = outcome.job
    source = (f"dataset `{job.dataset_path}`" if job.dataset_path is not None
              else f"simulated, `{job.trajectory}` motion, seed {job.seed}")
    failures = outcome.all_failures()
    res = resources(m["rig"])
    if res:
        resource_text = (f"From `docs/results/figures.json` (`top.{m['rig']}.*`, yosys "
                         "`synth_xilinx` of the rig's closed-loop board top and a "
                         "co-simulated slice of it, measured by `rowtrack bench --only top`; "
                         "not by this run):\n\n" + table(sorted(res.items())))
    else:
        resource_text = (f"`docs/results/figures.json` holds no `top.{m['rig']}.*` figures "
                         "(`rowtrack bench --only top` measures the boards' rigs: "
                         "docs/results/top.md).")
    walls = table([(phase, f"{seconds:.1f} s") for phase, seconds in wall_times(m)])
    return "\n".join([
        "# rowtrack run", "",
        f"**{'FAILED' if failures else 'PASSED'}**" + "".join(f"\n- {f}" for f in failures),
        "",
        f"Rig `{m['rig']}`: {m['cameras']} cameras, {m['rows']} rows, {m['frames']} frames "
        f"({source}); K = {m['segments']} segments per camera row.", "",
        "## Accuracy", "", accuracy_section(m), "",
        "## Hardware path ↔ truth and golden (b): tolerances", "", tolerance_section(m), "",
        "## Hardware (co-simulated slice of the HDL top)", "", hardware_section(m), "",
        "## Resource estimates", "", resource_text, "",
        "## Wall time", "", walls, "",
        "## Plots", ""] + [f"![{p}]({p})" for p in plots]) + "\n"


def write_report(outcome, out):
    """Write report.md, the PNGs and metrics.json (keys prefixed ``e2e.``) to ``out``;
    returns the paths of report.md and metrics.json."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plots = _plots(outcome, out)
    m = metrics(outcome)
    (out / "metrics.json").write_text(json.dumps(
        {f"e2e.{k}": _json_safe(v) for k, v in m.items()}, indent=1, sort_keys=True))
    (out / "report.md").write_text(_markdown(outcome, m, plots))
    return [out / "report.md", out / "metrics.json"]

"""Benchmark of the row-descriptor lanes (issue 7): throughput and latency of 640-pixel
rows on the generated Verilog (cocotb + Verilator, every measurement checked against
the model), resources and logic depth from synth_xilinx, and the model's agreement
with the golden float matcher (the hardware equals the model bit for bit)."""

import json
import tempfile
from pathlib import Path

import numpy as np

from emulator.synth import XC7Z020, synth_report

N_CAMERAS = 8
SEED = 7
#: Targets from issue 7.
LUT_TARGET, BRAM_TARGET, LATENCY_TARGET, SUBPIXEL_TARGET = 2500, 10, 64, 1 / 16
#: "Confident" for the textureless / periodic figures (peak ratio, offset κ = 16).
CONFIDENT = 1.5


def _simulate(lane, name):
    from sim_tests.common.cocotb_runner import run_cocotb
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "figures.json"
        run_cocotb(lane, name=name, tag="full", sim="verilator", seed=SEED,
                   test_module="sim_tests.cocotb.row_descriptor.figures_bench",
                   extra_env={"ROWTRACK_FIGURES": str(path)})
        return json.loads(path.read_text())


def _golden_agreement(params):
    """Sub-pixel error on textured and simulator rows, confidence order, and the
    largest confidence of textureless and periodic rows."""
    from emulator.row_descriptor import against_golden, confidences, subpixel_errors
    from golden.dataset import Dataset
    from sim_tests.cocotb.row_descriptor.stimulus import (moving_rows, periodic_rows,
                                                          simulator_dataset)
    from sim_tests.common.cocotb_runner import BUILD_ROOT
    rng = np.random.default_rng(SEED)
    frames, _ = moving_rows(rng, 2, 400, params.width, noise=1.5)
    textured = subpixel_errors(frames[1], frames[0], rng.integers(-10, 11, 400), params)
    data = Dataset.load(simulator_dataset(BUILD_ROOT / "row_descriptor-yaw-dataset.npz"))
    rows = np.stack([data.cameras[k].rows for k in (0, 2)])
    cur, ref = rows[:, 1:].reshape(-1, params.width), rows[:, :-1].reshape(-1, params.width)
    simulated = subpixel_errors(cur, ref, np.zeros(len(cur), dtype=int), params)

    noisy = [moving_rows(rng, 2, 50, params.width, noise=noise)[0] for noise in (2, 8, 20, 35)]
    g, m = confidences(np.concatenate([f[1] for f in noisy]),
                       np.concatenate([f[0] for f in noisy]), params)
    i, j = np.triu_indices(len(g), 1)
    apart = np.abs(g[i] - g[j]) > params.confidence_fmt.lsb
    concordance = (np.sign(g[i] - g[j]) == np.sign(m[i] - m[j]))[apart].mean()

    flat = []
    for noise in (0, 1, 2):
        pixels = np.clip(np.round(97 + rng.normal(0, noise, (2, 100, params.width))), 0, 255)
        flat += [against_golden(pixels[1, y], pixels[0, y], 0, params)[1]["confidence"].max()
                 for y in range(100)]
    periodic = []
    for period in (5, 7, 9, 13, 17):
        pixels = periodic_rows(rng, 2, 40, params.width, period)
        pixels = np.clip(pixels + rng.normal(0, 2, pixels.shape), 0, 255).astype(np.uint8)
        periodic += [against_golden(pixels[1, y], pixels[0, y], 0, params)[1]["confidence"].max()
                     for y in range(40)]
    to_ratio = params.confidence_fmt.to_float
    return {
        "max_subpx_err_px": round(float(max(textured.max(), simulated.max())), 5),
        "subpx.textured_max_px": round(float(textured.max()), 5),
        "subpx.textured_segments": len(textured),
        "subpx.simulator_max_px": round(float(simulated.max()), 5),
        "subpx.simulator_segments": len(simulated),
        "confidence.order_kept": round(float(concordance), 5),
        "textureless.max_confidence": float(to_ratio(max(flat))),
        "periodic.max_confidence": float(to_ratio(max(periodic))),
    }


def measure():
    from hdl.row_descriptor import RowDescriptor, StereoRowDescriptor
    from hdl.row_descriptor_params import STEREO_640X480, TEMPORAL_640X480
    temporal = _simulate(RowDescriptor(TEMPORAL_640X480), "row_descriptor")
    stereo = _simulate(StereoRowDescriptor(STEREO_640X480), "stereo_row_descriptor")
    lane = synth_report(RowDescriptor(TEMPORAL_640X480), "row_descriptor")
    pair = synth_report(StereoRowDescriptor(STEREO_640X480), "stereo_row_descriptor")
    n = N_CAMERAS
    figures = {
        "px_per_clock": round(temporal["px_per_clock"], 4),
        "pixels_played": temporal["pixels"],
        "latency_clocks": temporal["latency_clocks"],
        "latency_first_clocks": temporal["latency_first_clocks"],
        "latency_spread_clocks": temporal["latency_spread"],
        "hdl_mismatches": temporal["mismatches"] + stereo["mismatches"],
        "measurements_checked": temporal["measurements"] + stereo["measurements"],
        "lut_per_camera": lane["lut"], "ff_per_camera": lane["ff"],
        "bram36_per_camera": lane["bram36"], "dsp48_per_camera": lane["dsp48"],
        "lut_levels": lane["lut_levels"],
        "cameras8.lut": n * lane["lut"], "cameras8.ff": n * lane["ff"],
        "cameras8.bram36": n * lane["bram36"], "cameras8.dsp48": n * lane["dsp48"],
        "cameras8.lut_pct": round(100 * n * lane["lut"] / XC7Z020["lut"], 1),
        "cameras8.bram36_pct": round(100 * n * lane["bram36"] / XC7Z020["bram36"], 1),
        "stereo.px_per_clock": round(stereo["px_per_clock"], 4),
        "stereo.latency_clocks": stereo["latency_clocks"],
        "stereo.lut": pair["lut"], "stereo.ff": pair["ff"], "stereo.bram36": pair["bram36"],
        "stereo.dsp48": pair["dsp48"], "stereo.lut_levels": pair["lut_levels"],
    }
    figures.update(_golden_agreement(TEMPORAL_640X480))
    return figures


def report(figures):
    from hdl.row_descriptor_params import STEREO_640X480, TEMPORAL_640X480
    f = figures
    t, s = TEMPORAL_640X480, STEREO_640X480
    verdict = lambda ok: "met" if ok else "**missed**"
    rows = "\n".join(f"| {key} | {value} |" for key, value in sorted(f.items()))
    return f"""# Row descriptor and shift matcher

`hdl/row_descriptor.py`: `RowDescriptor` (temporal lane, one camera) with
`TEMPORAL_640X480` — 640×480, σ = {t.descriptor.sigma}, window
[{t.match.shift_min}, {t.match.shift_max}] around a run-time centre (±{t.centre_range}),
{t.segments} segments, {t.scan_lanes} scan lanes — and `StereoRowDescriptor` (camera
pair) with `STEREO_640X480` (window [{s.match.shift_min}, {s.match.shift_max}],
{s.segments} segment).

Throughput and latency: {f['pixels_played'] // t.width} rows of 640 pixels (three
frames of 24 rows) played at one pixel per clock into the generated Verilog (cocotb +
Verilator, `sim_tests/cocotb/row_descriptor/figures_bench.py`); every one of the
{f['measurements_checked']} measurements compared with `emulator/row_descriptor.py`
({f['hdl_mismatches']} mismatches). Resources: Yosys `synth_xilinx -family xc7` of one
lane; the eight-camera figures are eight lanes (they share nothing). LUT levels: the
longest register-to-register path in LUTs (no vendor timing here).

| target (issue 7) | measured | |
|---|---|---|
| 1 pixel per clock, no bubbles between rows | {f['px_per_clock']} px/clk | {verdict(f['px_per_clock'] >= 1.0)} |
| last pixel → last measurement of the row ≤ {LATENCY_TARGET} clocks | {f['latency_clocks']} clocks ({t.segments} measurements; first after {f['latency_first_clocks']}); stereo {f['stereo.latency_clocks']} | {verdict(max(f['latency_clocks'], f['stereo.latency_clocks']) <= LATENCY_TARGET)} |
| ≤ {LUT_TARGET} LUTs per 640×480 camera | {f['lut_per_camera']} | {verdict(f['lut_per_camera'] <= LUT_TARGET)} |
| ≤ {BRAM_TARGET} BRAM36 per 640×480 camera | {f['bram36_per_camera']} | {verdict(f['bram36_per_camera'] <= BRAM_TARGET)} |
| 150 MHz-friendly logic depth | {f['lut_levels']} LUT levels (stereo {f['stereo.lut_levels']}) | estimate only |
| sub-pixel shift within ±1/16 px of golden on well-textured rows | max {f['max_subpx_err_px']} px ({f['subpx.textured_segments']} textured, {f['subpx.simulator_segments']} simulator segments) | {verdict(f['max_subpx_err_px'] <= SUBPIXEL_TARGET)} |
| confidence ordering preserved | {100 * f['confidence.order_kept']:.3f} % of segment pairs more than one step apart | |
| textureless / periodic rows never confident (< {CONFIDENT}) | max {f['textureless.max_confidence']} / {f['periodic.max_confidence']} | {verdict(max(f['textureless.max_confidence'], f['periodic.max_confidence']) < CONFIDENT)} |

Eight cameras: {f['cameras8.lut']} LUTs ({f['cameras8.lut_pct']} % of the xc7z020's
{XC7Z020['lut']}), {f['cameras8.bram36']} BRAM36 ({f['cameras8.bram36_pct']} % of
{XC7Z020['bram36']}), {f['cameras8.dsp48']} DSP48E1 (of {XC7Z020['dsp48']}).

| figure | value |
|---|---|
{rows}
"""

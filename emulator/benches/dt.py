"""Benchmark of the domain-transform work (issue 9).

Hardware: ``hdl.dt.filter`` at its default build (640-pixel rows, 8-bit values, window 8)
runs in the Amaranth simulator on rows of a synthetic scene, checked pixel for pixel
against the emulator; latency and throughput are counted from that run, resources come
from ``synth_xilinx``. Accuracy: the emulator against the float golden filter
(horizontal pass, then the whole filter), and the bounded vertical window against the
exact frame-buffered pass. Golden (issue 20): depth super-resolution on the real
development scene when its directory exists (:mod:`golden.dsr_benchmark`; a note in the
page otherwise) and on its synthetic twin, every method of
``golden.dsr_benchmark.METHODS`` ranked on both; one RF round against three on the real
targets; runtimes per megapixel.
"""

import math
import random
import time

import cv2
import numpy as np

from emulator.dt import filter as model
from emulator.synth import synth_report

__all__ = ["simulate_block", "measure", "report"]

#: (sigma_s pixels, sigma_r guide LSBs) for the accuracy figures.
SIGMAS = [(5.0, 30.0), (20.0, 50.0), (60.0, 100.0), (200.0, 255.0)]
#: Window lengths L for the vertical-window error table.
WINDOWS = [1, 2, 4, 8, 16, 32, 64]
#: Noise (std, depth units) on the low-resolution depth of the runtime scene.
DEPTH_NOISE = 2.0
#: Rounds of the measured DomainTransformRounds build (the golden default).
ROUNDS_HW = 3
#: Rounds compared for the hardware question (issue 20): does one RF round lose accuracy?
RF_ROUNDS = (1, 3)
#: RF settings of that comparison: sigma_s = RF_SIGMA_S sqrt(factor) pixels, sigma_r in
#: grey LSB (the hardware's units).
RF_SIGMA_S, RF_SIGMA_R = 16.0, 30.0


def simulate_block(params, frames, *, seed, valid_prob=1.0, ready_prob=1.0, rounds=None):
    """Stream ``frames`` through ``DomainTransformFilter(params)`` (or, with ``rounds``,
    ``DomainTransformRounds(params, rounds)``) in the Amaranth simulator.

    ``frames`` are ``(guide, value, sigma_s_raw, sigma_r_raw)``; the sigma registers change
    between frames only and are held for the block's settle time before the next one.
    ``valid_prob`` / ``ready_prob`` < 1 add random input gaps and output backpressure
    (``random.Random(seed)``). Returns ``(input cycles, outputs, component)`` with
    ``outputs`` a list of ``(cycle, value, last)``.
    """
    from amaranth.sim import Simulator
    from hdl.dt.filter import DomainTransformFilter
    from hdl.dt.rounds import DomainTransformRounds

    dut = DomainTransformFilter(params) if rounds is None else DomainTransformRounds(params, rounds)
    rng = random.Random(seed)
    expected = sum(f[0].size for f in frames)
    inputs, outputs = [], []

    async def source(ctx):
        registers = None
        for guide, value, sigma_s, sigma_r in frames:
            if (sigma_s, sigma_r) != registers:
                ctx.set(dut.i.valid, 0)
                ctx.set(dut.sigma_s, sigma_s)
                ctx.set(dut.sigma_r, sigma_r)
                await ctx.tick().repeat(dut.coefficient_settle_clocks)
                registers = (sigma_s, sigma_r)
            height = guide.shape[0]
            for y in range(height):
                for x in range(params.width):
                    while rng.random() >= valid_prob:
                        ctx.set(dut.i.valid, 0)
                        await ctx.tick()
                    ctx.set(dut.i.p.guide, int(guide[y, x]))
                    ctx.set(dut.i.p.value, int(value[y, x]))
                    ctx.set(dut.i.p.last, int(y == height - 1))
                    ctx.set(dut.i.valid, 1)
                    await ctx.tick().until(dut.i.ready)
        ctx.set(dut.i.valid, 0)

    async def sink(ctx):
        limit = 40 * expected + 40 * (dut.latency + 3 * params.width) + 2000
        for _ in range(limit):
            ctx.set(dut.o.ready, int(rng.random() < ready_prob))
            await ctx.tick()
            if len(outputs) == expected:
                return
        raise AssertionError(f"timeout: {len(outputs)} of {expected} pixels (seed {seed})")

    async def monitor(ctx):
        cycle = 0
        async for _, _, i_valid, i_ready, o_valid, o_ready, value, last in ctx.tick().sample(
                dut.i.valid, dut.i.ready, dut.o.valid, dut.o.ready, dut.o.p.value, dut.o.p.last):
            if i_valid and i_ready:
                inputs.append(cycle)
            if o_valid and o_ready:
                outputs.append((cycle, value, last))
            cycle += 1

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source, background=True)
    sim.add_testbench(sink)
    sim.add_process(monitor)
    sim.run()
    return inputs, outputs, dut


def _grey_scene(height, width, seed):
    from golden.dt_scenes import make_scene
    scene = make_scene(height, width, seed)
    return cv2.cvtColor(scene.guide, cv2.COLOR_BGR2GRAY).astype(np.int64), scene


def _hardware_figures(rounds=1):
    """Latency, throughput and tail from a simulated 640-pixel-wide frame, through one
    ``DomainTransformFilter`` or (``rounds`` > 1) a ``DomainTransformRounds``."""
    from hdl.dt.params import DtFilterParams
    params = DtFilterParams()
    guide, _ = _grey_scene(4, params.width, seed=11)
    s_raw, r_raw = model.sigma_register("sigma_s", 20.0), model.sigma_register("sigma_r", 50.0)
    inputs, outputs, dut = simulate_block(params, [(guide, guide, s_raw, r_raw)], seed=11,
                                          rounds=None if rounds == 1 else rounds)
    expected = model.filter_rounds(params, guide, guide, s_raw, r_raw, rounds).ravel().tolist()
    if [value for _, value, _ in outputs] != expected:
        raise AssertionError("dt_filter simulation differs from emulator.dt.filter")
    delays = {out[0] - cycle for out, cycle in zip(outputs, inputs)}
    if delays != {dut.latency}:
        raise AssertionError(f"latency {sorted(delays)} is not the block's {dut.latency}")
    span = outputs[-1][0] - outputs[0][0] + 1
    return params, {
        "px_per_clock": round(len(outputs) / span, 4),
        "latency_clocks": delays.pop(),
        "latency_rows": round(dut.latency / params.width, 3),
        "tail_clocks": outputs[-1][0] - inputs[-1],
        "width_px": params.width,
        "window_lines": params.window,
    }


def _rounds_accuracy(params, value_bits):
    """Each of ROUNDS_HW emulated rounds against one golden round with the round's sigmas."""
    from golden.dt import recursive_filter
    from hdl.dt.params import SIGMA_FMT
    params = params.replace(value_bits=value_bits)
    guide, scene = _grey_scene(480, params.width, seed=12)
    value = guide if value_bits == 8 else np.rint(scene.depth * 257).astype(np.int64)
    means, maxima = [], []
    for sigma_s, sigma_r in SIGMAS:
        current = value
        for s_raw, r_raw in zip(*(model.round_registers(model.sigma_register(n, v), ROUNDS_HW)
                                  for n, v in (("sigma_s", sigma_s), ("sigma_r", sigma_r)))):
            out = model.filter_frame(params, guide, current, s_raw, r_raw)
            err = np.abs(out - recursive_filter(
                current.astype(float), guide.astype(float), sigma_s=SIGMA_FMT.to_float(s_raw),
                sigma_r=SIGMA_FMT.to_float(r_raw), iterations=1, vertical_window=params.window))
            means.append(float(err.mean()))
            maxima.append(float(err.max()))
            current = out
    return {"pass_mean_err_lsb": round(max(means), 4), "pass_max_err_lsb": round(max(maxima), 4)}


def _golden_horizontal(guide, value, sigma_s, sigma_r):
    from golden.dt import domain_derivative, rf_anticausal, rf_causal, rf_weights
    weights = rf_weights(domain_derivative(guide.astype(float), sigma_s, sigma_r, axis=1), sigma_s)
    return rf_anticausal(rf_causal(value.astype(float), weights, axis=1), weights, axis=1)


def _accuracy_figures(params, value_bits):
    """Emulator against golden on a 480x640 scene, per sigma setting (LSB of the values)."""
    from golden.dt import recursive_filter
    params = params.replace(value_bits=value_bits)
    guide, scene = _grey_scene(480, params.width, seed=12)
    value = guide if value_bits == 8 else np.rint(scene.depth * 257).astype(np.int64)
    figures = {}
    for sigma_s, sigma_r in SIGMAS:
        s_raw, r_raw = (model.sigma_register(n, v) for n, v in
                        (("sigma_s", sigma_s), ("sigma_r", sigma_r)))
        w_h, w_v = model.frame_weights(params, guide, s_raw, r_raw)
        horizontal = model.horizontal_pass(params, value, w_h)
        h_err = np.abs(model.output(params, horizontal)
                       - _golden_horizontal(guide, value, sigma_s, sigma_r))
        exact = model.output(params, model.vertical_pass(params, horizontal, w_v,
                                                         window=guide.shape[0]))
        full_err = np.abs(exact - recursive_filter(value.astype(float), guide.astype(float),
                                                   sigma_s=sigma_s, sigma_r=sigma_r,
                                                   iterations=1))
        key = f"s{sigma_s:g}_r{sigma_r:g}"
        figures[f"h_mean_err_lsb.{key}"] = round(float(h_err.mean()), 4)
        figures[f"h_max_err_lsb.{key}"] = round(float(h_err.max()), 4)
        figures[f"full_mean_err_lsb.{key}"] = round(float(full_err.mean()), 4)
        figures[f"full_max_err_lsb.{key}"] = round(float(full_err.max()), 4)
        for window in WINDOWS:
            windowed = model.output(params, model.vertical_pass(params, horizontal, w_v, window))
            err = np.abs(windowed - exact)
            figures[f"window_mean_err_lsb.{key}.L{window}"] = round(float(err.mean()), 4)
            figures[f"window_max_err_lsb.{key}.L{window}"] = int(err.max())
    return figures


def _method_scores(cases, prefix):
    """RMSE of every ranked method per factor and their geometric means."""
    from golden import dsr_benchmark as dsr
    figures, seconds = {}, 0.0
    for name in dsr.METHODS:
        per_factor = []
        for factor in dsr.FACTORS:
            start = time.perf_counter()
            errors = [dsr.rmse(dsr.run_method(name, case), case.truth)
                      for case in cases if case.factor == factor]
            if name == "dts":
                seconds += time.perf_counter() - start
            per_factor.append(dsr.geomean(errors))
            figures[f"{prefix}.method.{name}.{factor}x"] = round(per_factor[-1], 3)
        figures[f"{prefix}.method.{name}.geomean"] = round(dsr.geomean(per_factor), 3)
    return figures, seconds


def _rf_rounds(cases):
    """Confidence-normalised RF of the dev targets (grey guide) with 1 and with 3 rounds."""
    from golden.dsr_benchmark import rmse
    from golden.dt import recursive_filter
    figures = {}
    for case in cases:
        grey = cv2.cvtColor(case.guide.astype(np.float32), cv2.COLOR_BGR2GRAY) * 255.0
        stacked = np.stack([case.confidence * case.target, case.confidence], axis=-1)
        for rounds in RF_ROUNDS:
            out = recursive_filter(stacked, grey, sigma_s=RF_SIGMA_S * math.sqrt(case.factor),
                                   sigma_r=RF_SIGMA_R, iterations=rounds)
            figures[f"dev.rf_rounds{rounds}.{case.factor}x"] = round(
                rmse(out[..., 0] / out[..., 1], case.truth), 3)
    return figures


def _dsr_figures():
    """Depth super-resolution: the synthetic twin, and the real dev scene when present."""
    from golden import dsr_benchmark as dsr
    scenes = dsr.synthetic_scenes()
    figures, _ = _method_scores(dsr.synthetic_cases(scenes), "synth")
    figures["synth.scenes"] = len(scenes)
    figures["synth.height"], figures["synth.width"] = scenes[0].depth.shape
    try:
        cases = dsr.load_dev()
    except FileNotFoundError as exc:
        figures["dev.missing"] = str(exc)
        return figures
    dev, seconds = _method_scores(cases, "dev")
    figures.update(dev)
    for factor in dsr.FACTORS:
        figures[f"dev.rmse.{factor}x"] = dev[f"dev.method.dts.{factor}x"]
        figures[f"dev.fbs_rmse.{factor}x"] = round(
            dsr.rmse(cases[dsr.FACTORS.index(factor)].reference, cases[0].truth), 3)
    figures["dev.geomean"] = dev["dev.method.dts.geomean"]
    figures["dev.fbs_geomean"] = round(dsr.geomean(
        [figures[f"dev.fbs_rmse.{f}x"] for f in dsr.FACTORS]), 3)
    figures["dev.runtime_s_per_mp"] = round(seconds / (len(cases) * cases[0].truth.size / 1e6), 3)
    for key in [f"{f}x" for f in dsr.FACTORS] + ["geomean"]:
        figures[f"rank_tau.{key}"] = round(dsr.kendall_tau(
            [figures[f"dev.method.{m}.{key}"] for m in dsr.METHODS],
            [figures[f"synth.method.{m}.{key}"] for m in dsr.METHODS]), 3)
    figures.update(_rf_rounds(cases))
    return figures


def _runtime_figures():
    """Seconds per megapixel on a 1536x1024 (1.57 MP) scene, best of two runs."""
    from hdl.dt.params import DtFilterParams
    from golden.dt import normalized_convolution, recursive_filter
    from golden.dt_scenes import bicubic_target, downsample, make_scene
    from golden.dts import dts, target_confidence
    scene = make_scene(1024, 1536, seed=13)
    megapixels = scene.depth.size / 1e6
    guide = scene.guide / 255.0
    target = bicubic_target(downsample(scene.depth, 8, DEPTH_NOISE, seed=13), 8)
    grey = cv2.cvtColor(scene.guide, cv2.COLOR_BGR2GRAY).astype(np.int64)
    hardware = DtFilterParams(width=grey.shape[1])
    s_raw, r_raw = model.sigma_register("s", 20.0), model.sigma_register("r", 50.0)
    jobs = {
        "dts": lambda: dts(target, guide, target_confidence(target)),
        "rf": lambda: recursive_filter(guide, sigma_s=60.0, sigma_r=0.4),
        "nc": lambda: normalized_convolution(guide, sigma_s=60.0, sigma_r=0.4),
        "emulator": lambda: model.filter_frame(hardware, grey, grey, s_raw, r_raw),
    }
    figures = {"runtime_image_mp": round(megapixels, 3)}
    for name, job in jobs.items():
        best = math.inf
        for _ in range(2):
            start = time.perf_counter()
            job()
            best = min(best, time.perf_counter() - start)
        figures[f"runtime_s_per_mp.{name}"] = round(best / megapixels, 3)
    return figures


def measure():
    from hdl.dt.filter import DomainTransformFilter
    from hdl.dt.rounds import DomainTransformRounds
    params, figures = _hardware_figures()
    synth = synth_report(DomainTransformFilter(params), "dt_filter")
    figures.update({key: synth[key] for key in ("lut", "ff", "bram36", "dsp48", "lut_levels")})
    synth16 = synth_report(DomainTransformFilter(params.replace(value_bits=16)), "dt_filter16")
    figures.update({f"v16.{key}": synth16[key] for key in ("lut", "ff", "bram36", "dsp48")})
    for bits in (8, 16):
        prefix = "" if bits == 8 else "v16."
        accuracy = _accuracy_figures(params, bits)
        figures.update({prefix + key: value for key, value in accuracy.items()})
        figures[prefix + "mean_err_lsb"] = max(v for k, v in accuracy.items()
                                               if k.startswith("h_mean_err_lsb."))
        figures[prefix + "max_err_lsb"] = max(v for k, v in accuracy.items()
                                              if k.startswith("h_max_err_lsb."))
    _, chain = _hardware_figures(rounds=ROUNDS_HW)
    figures.update({f"rounds{ROUNDS_HW}.{key}": chain[key]
                    for key in ("px_per_clock", "latency_clocks", "latency_rows")})
    synth = synth_report(DomainTransformRounds(params, ROUNDS_HW), f"dt_rounds{ROUNDS_HW}")
    figures.update({f"rounds{ROUNDS_HW}.{key}": synth[key]
                    for key in ("lut", "ff", "bram36", "dsp48")})
    for bits in (8, 16):
        figures.update({f"rounds{ROUNDS_HW}.v{bits}.{key}": value
                        for key, value in _rounds_accuracy(params, bits).items()})
    figures.update(_dsr_figures())
    figures.update(_runtime_figures())
    return figures


def _settings():
    return [f"s{s:g}_r{r:g}" for s, r in SIGMAS]


def _accuracy_table(figures, prefix, bits):
    rows = []
    for (sigma_s, sigma_r), key in zip(SIGMAS, _settings()):
        rows.append(f"| {bits} | {sigma_s:g} | {sigma_r:g} "
                    f"| {figures[f'{prefix}h_mean_err_lsb.{key}']} "
                    f"| {figures[f'{prefix}h_max_err_lsb.{key}']} "
                    f"| {figures[f'{prefix}full_mean_err_lsb.{key}']} "
                    f"| {figures[f'{prefix}full_max_err_lsb.{key}']} |")
    return "\n".join(rows)


def _window_rows(figures, prefix, bits):
    rows = []
    for (sigma_s, sigma_r), key in zip(SIGMAS, _settings()):
        cells = [f"{figures[f'{prefix}window_mean_err_lsb.{key}.L{w}']} / "
                 f"{figures[f'{prefix}window_max_err_lsb.{key}.L{w}']}" for w in WINDOWS]
        rows.append(f"| {bits} | {sigma_s:g} | {sigma_r:g} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


#: Method names of golden.dsr_benchmark.METHODS as the tables show them.
METHOD_LABELS = {
    "bicubic": "bicubic target",
    "grid3d": "FBS-like 3-D grey bilateral grid (sigma_xy 8, sigma_l 8/255, lam 1)",
    "dts_wide": "DTS, wide colour edges (sigma_s 24, sigma_r 0.2, L1, lam 2, colour only)",
    "dts_colour": "DTS, per-factor rule, colour only",
    "dts": "DTS, per-factor rule with the target channel (default)",
}


def _method_rows(f, prefix):
    from golden.dsr_benchmark import FACTORS
    return "\n".join(f"| {label} | " + " | ".join(
        str(f[f"{prefix}.method.{name}.{k}"]) for k in [f"{x}x" for x in FACTORS] + ["geomean"])
        + " |" for name, label in METHOD_LABELS.items())


def _order(f, prefix, key):
    return " < ".join(sorted(METHOD_LABELS, key=lambda m: f[f"{prefix}.method.{m}.{key}"]))


def _dev_section(f):
    from golden.dsr_benchmark import DATA_ENV, FACTORS
    if "dev.missing" in f:
        return f"""Not measured: {f['dev.missing']}. The development data is not part of the
repository; point `{DATA_ENV}` at it and rerun the benchmark."""
    factors = [f"{k}x" for k in FACTORS]
    gains = " | ".join(f"{f[f'dev.fbs_rmse.{k}'] - f[f'dev.rmse.{k}']:+.3f}" for k in factors)
    taus = " | ".join(str(f[f"rank_tau.{k}"]) for k in factors + ["geomean"])
    rf = "\n".join(f"| {r} | " + " | ".join(str(f[f"dev.rf_rounds{r}.{k}"]) for k in factors)
                   + " |" for r in RF_ROUNDS)
    return f"""The Middlebury "Art" scene of the noisy depth super-resolution benchmark of the FBS
and DTS papers (guide 1376x1088, noisy low-resolution disparity, bicubic target, the
benchmark's confidence); RMSE on the 8-bit disparity scale over the whole image.

| | 2x | 4x | 8x | 16x | geomean |
|---|---|---|---|---|---|
| FBS (Barron & Poole 2016, the benchmark's result files) | {' | '.join(str(f[f'dev.fbs_rmse.{k}']) for k in factors)} | {f['dev.fbs_geomean']} |
| DTS (`DtsParams.for_factor`) | {' | '.join(str(f[f'dev.rmse.{k}']) for k in factors)} | {f['dev.geomean']} |
| FBS minus DTS | {gains} | {f['dev.fbs_geomean'] - f['dev.geomean']:+.3f} |

DTS runtime: {f['dev.runtime_s_per_mp']} s per megapixel (15 iterations, numpy, one core).

All ranked methods on the development scene (every DTS row weighs the data by
(t / median t)^2, `disparity_power` 2):

| method | 2x | 4x | 8x | 16x | geomean |
|---|---|---|---|---|---|
{_method_rows(f, 'dev')}

Order by geomean, best first: {_order(f, 'dev', 'geomean')}.

Rank agreement of the synthetic twin with the development scene (Kendall's tau over the
{len(METHOD_LABELS)} methods; 1 is the same order):

| 2x | 4x | 8x | 16x | geomean |
|---|---|---|---|---|
| {taus} |

### One RF round or three (hardware question)

Confidence-normalised RF, `RF(c t) / RF(c)`, of the development targets along the grey
guide (sigma_s = {RF_SIGMA_S:g} sqrt(factor) px, sigma_r = {RF_SIGMA_R:g} LSB, golden,
exact vertical pass), RMSE against the ground truth with one round
(`DomainTransformFilter`) and three (the golden default, `DomainTransformRounds`):

| rounds | 2x | 4x | 8x | 16x |
|---|---|---|---|---|
{rf}"""


def report(f):
    return f"""# Domain-transform filter and solver

See `docs/dt/dt.md` for the algorithm and the hardware structure.

## Streaming filter `hdl/dt/filter.py` (default build)

{f['width_px']}-pixel rows, 8-bit guide and values, vertical window L = {f['window_lines']}.
Simulated in the Amaranth simulator on a synthetic scene, every output checked against
`emulator/dt/filter.py`; resources from Yosys `synth_xilinx` (xc7).

| figure | value |
|---|---|
| pixels per clock (within and across rows) | {f['px_per_clock']} |
| latency, clocks (every pixel) | {f['latency_clocks']} ({f['latency_rows']} rows) |
| last output after the last input pixel (filler rows flush the frame), clocks | {f['tail_clocks']} |
| LUT / FF | {f['lut']} / {f['ff']} |
| BRAM36 | {f['bram36']} |
| DSP48E1 | {f['dsp48']} |
| LUT levels (longest path) | {f['lut_levels']} |
| 16-bit values: LUT / FF / BRAM36 / DSP48E1 | {f['v16.lut']} / {f['v16.ff']} / {f['v16.bram36']} / {f['v16.dsp48']} |

### Three rounds: `DomainTransformRounds` (golden default schedule)

The same build as {ROUNDS_HW} chained stages with the registers scaled by the schedule and
the guide carried through FIFOs; simulated the same way, every output checked against
`emulator.dt.filter.filter_rounds`.

| figure | value |
|---|---|
| pixels per clock | {f[f'rounds{ROUNDS_HW}.px_per_clock']} |
| latency, clocks | {f[f'rounds{ROUNDS_HW}.latency_clocks']} ({f[f'rounds{ROUNDS_HW}.latency_rows']} rows) |
| LUT / FF | {f[f'rounds{ROUNDS_HW}.lut']} / {f[f'rounds{ROUNDS_HW}.ff']} |
| BRAM36 | {f[f'rounds{ROUNDS_HW}.bram36']} |
| DSP48E1 | {f[f'rounds{ROUNDS_HW}.dsp48']} |
| worst round against one golden round with its sigmas, 8-bit: mean / max LSB | {f[f'rounds{ROUNDS_HW}.v8.pass_mean_err_lsb']} / {f[f'rounds{ROUNDS_HW}.v8.pass_max_err_lsb']} |
| the same, 16-bit | {f[f'rounds{ROUNDS_HW}.v16.pass_mean_err_lsb']} / {f[f'rounds{ROUNDS_HW}.v16.pass_max_err_lsb']} |

(Rounds measured per pass on the 480x640 scene below, all four sigma settings, window
{f['window_lines']}.)

## Emulator against the float golden filter

Error in LSB of the output on a 480x640 synthetic scene (8-bit: the grey guide filters
itself; 16-bit: a depth map scaled to 16 bits, guided by the grey image). "Horizontal"
is the causal + anti-causal row pass (issue target: mean <= 1, max <= 2 LSB); "full" is
the whole round with an exact (frame-buffered) vertical anti-causal pass.

| bits | sigma_s (px) | sigma_r (LSB) | horizontal mean | horizontal max | full mean | full max |
|---|---|---|---|---|---|---|
{_accuracy_table(f, '', 8)}
{_accuracy_table(f, 'v16.', 16)}

Worst horizontal figures: 8-bit mean {f['mean_err_lsb']} / max {f['max_err_lsb']} LSB;
16-bit mean {f['v16.mean_err_lsb']} / max {f['v16.max_err_lsb']} LSB.

## Bounded vertical window against the exact pass

The hardware's vertical anti-causal pass sees L lines; each cell is mean / max
difference in output LSB against the exact pass (both in the emulator's fixed point).
The error decays like a**L with a = exp(-sqrt(2)/sigma_s): long for large sigma_s.

| bits | sigma_s | sigma_r | {' | '.join(f'L={w}' for w in WINDOWS)} |
|---|---|---|{'---|' * len(WINDOWS)}
{_window_rows(f, '', 8)}
{_window_rows(f, 'v16.', 16)}

## Depth super-resolution: development scene (real data)

{_dev_section(f)}

## Depth super-resolution: synthetic twin

{f['synth.scenes']} scenes of {f['synth.width']}x{f['synth.height']} from `golden/dt_scenes.py` made to look like the real
data and degraded as the real benchmark (`golden/dsr_benchmark.py`): disparity on the
dev scene's range (66-217), objects at half colour contrast against their background,
multi-scale guide texture (std 8 LSB), guide blurred by 1 px; the low-resolution
disparity is the block average with depth-dependent noise (std 660 / disparity) rounded
to 8 bits, bicubic-upsampled (OpenCV), with the benchmark's confidence pattern. RMSE
geometric mean over the scenes.

| method | 2x | 4x | 8x | 16x | geomean |
|---|---|---|---|---|---|
{_method_rows(f, 'synth')}

Order by geomean, best first: {_order(f, 'synth', 'geomean')}.

## Runtime (this machine, one core, numpy)

Seconds per megapixel on a {f['runtime_image_mp']} MP image: DTS (defaults)
{f['runtime_s_per_mp.dts']}, RF (3 rounds, colour) {f['runtime_s_per_mp.rf']},
NC (3 rounds, colour) {f['runtime_s_per_mp.nc']}, hardware emulator (one round, grey)
{f['runtime_s_per_mp.emulator']}.
"""

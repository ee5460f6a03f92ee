"""Benchmark of the domain-transform work (issue 9).

Hardware: ``hdl.dt.filter`` at its default build (640-pixel rows, 8-bit values, window 8)
runs in the Amaranth simulator on rows of a synthetic scene, checked pixel for pixel
against the emulator; latency and throughput are counted from that run, resources come
from ``synth_xilinx``. Accuracy: the emulator against the float golden filter
(horizontal pass, then the whole filter), and the bounded vertical window against the
exact frame-buffered pass. Golden: DTS against bicubic upsampling on the project's
synthetic depth set (:mod:`golden.dt_scenes`), and runtimes per megapixel.
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
FACTORS = [2, 4, 8, 16]
#: Noise (std, depth units) on the low-resolution depth of the DTS set.
DEPTH_NOISE = 2.0


def simulate_block(params, frames, *, seed, valid_prob=1.0, ready_prob=1.0):
    """Stream ``frames`` through ``DomainTransformFilter(params)`` in the Amaranth simulator.

    ``frames`` are ``(guide, value, sigma_s_raw, sigma_r_raw)``; the sigma registers change
    between frames only and are held for the block's settle time before the next one.
    ``valid_prob`` / ``ready_prob`` < 1 add random input gaps and output backpressure
    (``random.Random(seed)``). Returns ``(input cycles, outputs, component)`` with
    ``outputs`` a list of ``(cycle, value, last)``.
    """
    from amaranth.sim import Simulator
    from hdl.dt.filter import DomainTransformFilter

    dut = DomainTransformFilter(params)
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
        limit = 40 * expected + 40 * params.width * (params.window + 3) + 2000
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


def _hardware_figures():
    """Latency, throughput and tail from a simulated 640-pixel-wide frame."""
    from hdl.dt.filter import DtFilterParams
    params = DtFilterParams()
    guide, _ = _grey_scene(4, params.width, seed=11)
    s_raw, r_raw = model.sigma_register("sigma_s", 20.0), model.sigma_register("sigma_r", 50.0)
    inputs, outputs, dut = simulate_block(params, [(guide, guide, s_raw, r_raw)], seed=11)
    expected = model.filter_frame(params, guide, guide, s_raw, r_raw).ravel().tolist()
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


def _dts_figures():
    from golden.dt_scenes import bicubic_target, downsample, make_set, rmse
    from golden.dts import dts, target_confidence
    scenes = make_set()
    figures = {}
    for factor in FACTORS:
        bicubic, solved = [], []
        for k, scene in enumerate(scenes):
            target = bicubic_target(downsample(scene.depth, factor, DEPTH_NOISE, seed=k), factor)
            out = dts(target, scene.guide / 255.0, target_confidence(target))
            bicubic.append(rmse(target, scene.depth))
            solved.append(rmse(out, scene.depth))
        figures[f"bicubic_rmse.{factor}x"] = round(float(np.exp(np.mean(np.log(bicubic)))), 3)
        figures[f"dts_rmse.{factor}x"] = round(float(np.exp(np.mean(np.log(solved)))), 3)
    figures["dts_set.scenes"] = len(scenes)
    figures["dts_set.height"], figures["dts_set.width"] = scenes[0].depth.shape
    return figures


def _runtime_figures():
    """Seconds per megapixel on a 1536x1024 (1.57 MP) scene, best of two runs."""
    from hdl.dt.filter import DtFilterParams
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
    figures.update(_dts_figures())
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


def report(f):
    dts_rows = "\n".join(f"| {k}x | {f[f'bicubic_rmse.{k}x']} | {f[f'dts_rmse.{k}x']} | "
                         f"{f[f'bicubic_rmse.{k}x'] / f[f'dts_rmse.{k}x']:.2f} |"
                         for k in FACTORS)
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

## Domain transform solver: depth super-resolution

{f['dts_set.scenes']} scenes of {f['dts_set.width']}x{f['dts_set.height']} from `golden/dt_scenes.py` (slanted planes and objects, textured guide
with false edges); the low-resolution depth is the block average plus Gaussian noise
(std {DEPTH_NOISE}, depth range 0..255), bicubic-upsampled (OpenCV) to the target. DTS
runs with its defaults and `target_confidence`. RMSE in depth units, geometric mean over
the scenes.

| factor | bicubic RMSE | DTS RMSE | gain |
|---|---|---|---|
{dts_rows}

## Runtime (this machine, one core, numpy)

Seconds per megapixel on a {f['runtime_image_mp']} MP image: DTS (defaults)
{f['runtime_s_per_mp.dts']}, RF (3 rounds, colour) {f['runtime_s_per_mp.rf']},
NC (3 rounds, colour) {f['runtime_s_per_mp.nc']}, hardware emulator (one round, grey)
{f['runtime_s_per_mp.emulator']}.
"""

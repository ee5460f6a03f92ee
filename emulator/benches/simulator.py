"""Benchmark of the golden rolling-shutter simulator: rendering throughput on one core.

Renders one full second of the stereo20 rig (20 cameras, 640×480, 120 fps: 2400
frames, 737 Mpx) moving with the papers' test motion (1.4 m/s, 120°/s) through the
default room, sensor noise on, with OpenCV limited to one thread. Frames are streamed
and dropped (no dataset is kept), so the figure is rendering plus sensor, not disk.
"""

import time

import cv2

#: Rendered sequence length (s) and the sensor noise (gray levels) of the run.
DURATION = 1.0
NOISE = 2.0
SEED = 1


def measure():
    from golden.rig import PRESETS, preset
    from golden.scene import build_scene, default_scene_spec
    from golden.simulator import render_frames, schedule
    from golden.trajectory import make_trajectory

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        rig = preset("stereo20").replace_cameras(noise_sigma=NOISE)
        spec = default_scene_spec(SEED)
        start = time.perf_counter()
        scene = build_scene(spec)
        scene_seconds = time.perf_counter() - start
        trajectory = make_trajectory("paper")
        times = schedule(rig, DURATION, SEED)
        pixels = frames = 0
        start = time.perf_counter()
        for _, _, rows in render_frames(rig, scene, trajectory, times, SEED):
            pixels += rows.size
            frames += 1
        seconds = time.perf_counter() - start
    finally:
        cv2.setNumThreads(threads)
    figures = {
        "mpx_per_s": round(pixels / seconds / 1e6, 2),
        "one_second_s": round(seconds, 1),
        "frames": frames,
        "megapixels": round(pixels / 1e6, 1),
        "scene_build_s": round(scene_seconds, 2),
        "scene_texels_m": round(scene.atlas.texels / 1e6, 1),
    }
    for name in PRESETS:
        verdict = preset(name).observability
        figures[f"rig.{name}.rank"] = verdict.rank
        figures[f"rig.{name}.condition"] = round(verdict.condition, 2)
    return figures


def report(figures):
    rigs = "\n".join(
        f"| {name} | {figures[f'rig.{name}.rank']} | {figures[f'rig.{name}.condition']} |"
        for name in sorted({key.split('.')[1] for key in figures if key.startswith("rig.")}))
    verdict = "meets" if figures["mpx_per_s"] >= 10 else "MISSES"
    return f"""# Golden simulator: rendering throughput

`golden/` renders every row of every camera at its own time and pose by ray casting
(vectorized numpy, `cv2.remap` for the mip-mapped texture lookups). The run renders
{DURATION:g} s of the **stereo20** rig (20 cameras, 640×480, 120 fps) with the papers' test
motion (v = 1.4 m/s, ω = 120°/s) through the default furnished room, sensor noise
σ = {NOISE:g} gray levels, OpenCV on one thread.

| figure | value |
|---|---|
| throughput (one core) | **{figures['mpx_per_s']} Mpx/s** (target ≥ 10: {verdict}) |
| one second of stereo20 | {figures['one_second_s']} s for {figures['frames']} frames ({figures['megapixels']} Mpx) |
| scene build (textures, atlas, mip levels) | {figures['scene_build_s']} s, {figures['scene_texels_m']} M texels |

Observability of the preset rigs (stacked per-row constraints, worst row, nominal depth
2 m; `golden/observability.py`):

| rig | rank | condition |
|---|---|---|
{rigs}
"""

"""Stimulus for the row-descriptor tests and benches: moving textured rows, square waves
at the largest cost, camera beats, and bad input (short, long, interrupted rows, reason
bits, stray beats).

Plain numpy and dicts, no simulator: the Amaranth-simulator tests, the cocotb benches
and the benchmark build the same streams from the same seeds.
"""

import numpy as np
from scipy.ndimage import gaussian_filter1d

__all__ = ["moving_rows", "periodic_rows", "square_rows", "row_beats", "frame_beats",
           "inject_faults", "simulator_dataset"]


def moving_rows(rng, n_frames, height, width, *, max_step=6.0, blur=2.5, noise=1.0,
                textureless_rows=()):
    """Frames ``(F, H, W)`` of uint8 rows; row ``y`` is its own smooth random texture
    moving by a random sub-pixel step per frame, and ``shifts[f, y]`` is its true shift
    against frame ``f − 1`` (content moved right by that many pixels).

    Rows listed in ``textureless_rows`` are flat (plus noise) in every frame.
    """
    pad = int(max_step * n_frames) + 64
    base = gaussian_filter1d(rng.uniform(0, 255, (height, width + 2 * pad)), blur, axis=-1)
    base = (base - base.mean(axis=-1, keepdims=True)) * 4 + 128
    steps = rng.uniform(-max_step, max_step, (n_frames, height))
    steps[0] = 0
    offsets = np.cumsum(steps, axis=0)
    x = np.arange(width)
    rows = np.empty((n_frames, height, width))
    for f in range(n_frames):
        for y in range(height):
            rows[f, y] = np.interp(x + pad - offsets[f, y], np.arange(width + 2 * pad), base[y])
    rows[:, list(textureless_rows)] = 97.0
    rows += rng.normal(0, noise, rows.shape)
    return np.clip(np.round(rows), 0, 255).astype(np.uint8), steps


def periodic_rows(rng, n_frames, height, width, period=9):
    """Rows of a sinusoid of ``period`` pixels moving by a random step per frame: the
    shift is ambiguous modulo the period, so no match may be confident."""
    x = np.arange(width)
    phase = rng.uniform(0, period, (n_frames, height, 1))
    rows = 128 + 90 * np.sin(2 * np.pi * (x - phase) / period)
    return np.clip(np.round(rows), 0, 255).astype(np.uint8)


def square_rows(n_frames, height, width, period=16):
    """Rows of a square wave (``period`` pixels, half 0, half 255) that moves by half a
    period per frame: each frame's descriptor bits are the complement of the previous
    frame's (the kernel sums to zero and is symmetric about a column, the wave's edges
    lie between columns, so no response is 0), and every shift that is a multiple of
    ``period`` costs a whole segment: the largest cost a matcher holds."""
    if period % 2:
        raise ValueError(f"period must be even, not {period}")
    x = np.arange(width)
    phase = (np.arange(n_frames) * period // 2)[:, None, None]
    rows = np.where((x + phase) % period < period // 2, 255, 0)
    return np.broadcast_to(rows, (n_frames, height, width)).astype(np.uint8)


def row_beats(pixels, *, camera, frame, row, t_first=0, flags=0):
    """The beats of one row as a camera input delivers it (flags with ``last``)."""
    n = len(pixels)
    return [{"data": int(v), "first": int(x == 0), "last": int(x == n - 1),
             "camera": camera, "frame": frame, "row": row, "t_first": t_first,
             "t_last": t_first + n - 1 if x == n - 1 else 0,
             "flags": flags if x == n - 1 else 0}
            for x, v in enumerate(pixels)]


def frame_beats(frames, *, camera=0, frame0=0, frame_bits=16, t0=0):
    """Beats of every row of ``frames`` ``(F, H, W)``, frame by frame, row by row."""
    beats = []
    n_frames, height, width = frames.shape
    for f in range(n_frames):
        for y in range(height):
            t = t0 + (f * height + y) * width
            beats += row_beats(frames[f, y], camera=camera,
                               frame=(frame0 + f) % (1 << frame_bits), row=y, t_first=t)
    return beats


def inject_faults(rng, beats, width, count):
    """``beats`` with ``count`` faults at random rows (never the last, so the stream
    ends with a complete row): a short row, a long row, a row missing its ``last``
    (interrupted by the next ``first``), reason bits, or stray beats before a row.
    Returns the new beat list."""
    starts = [i for i, b in enumerate(beats) if b["first"]]
    chosen = set(rng.choice(len(starts) - 1, size=min(count, len(starts) - 1),
                            replace=False).tolist())
    out = []
    for k, start in enumerate(starts):
        row = [dict(b) for b in beats[start:start + width]]
        if k in chosen:
            kind = rng.integers(5)
            if kind == 0:                        # short: HREF fell early
                cut = int(rng.integers(1, width - 1))
                row = row[:cut]
                row[-1]["last"] = 1
            elif kind == 1:                      # long: extra beats after the width
                extra = [dict(row[-1], last=0, first=0, data=int(rng.integers(256)))
                         for _ in range(int(rng.integers(1, 5)))]
                row[-1]["last"] = 0
                row = row + extra
                row[-1]["last"] = 1
            elif kind == 2:                      # interrupted: no last, next row begins
                row = row[:int(rng.integers(2, width))]
                row[-1]["last"] = 0
            elif kind == 3:                      # reason bits
                row[-1]["flags"] = int(rng.integers(1, 128))
            else:                                # stray beats before the row
                out += [dict(row[1], first=0, last=0) for _ in range(int(rng.integers(1, 4)))]
        out += row
    return out


def simulator_dataset(path, seed=3):
    """Path of a golden-simulator dataset, simulated once and kept at ``path`` (under
    ``build/``): the radial4 rig with 1.5 DN sensor noise yawing at 30°/s about the
    world's vertical axis for three frames at 120 fps. Cameras 0 and 2 (not rolled) see
    the scene slide along their rows by about 2 px per frame, so each row matches the
    same row of the previous frame, as the temporal lane assumes."""
    import math

    from golden.rig import preset
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import ScrewTrajectory, SpeedProfile
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        rig = preset("radial4").replace_cameras(noise_sigma=1.5)
        yaw = ScrewTrajectory(axis=(0, 0, 1), angular_speed=SpeedProfile.constant(
            math.radians(30)), kind="yaw")
        simulate(rig, default_scene_spec(seed), yaw, 3 / 120, seed=seed).save(path)
    return path

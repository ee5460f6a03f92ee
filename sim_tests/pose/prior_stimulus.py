"""Stimulus of the information gain's tests (model and gateware): the stereo20 rig cut to
32 rows (its solver and coefficient store), rows of random measurements on it, the
prior store's framed rows and their expected ``M`` from the model."""

import numpy as np

from emulator.pose.information_gain import PriorInformation
from emulator.pose_solver import PoseRows, accumulate

__all__ = ["ROWS", "ENTRIES", "cut_stereo20", "measurement_rows", "normals", "framed",
           "expected_totals"]

ROWS = 32
#: Entries of a normal matrix (upper triangle).
ENTRIES = 21


def cut_stereo20():
    """The stereo20 pipeline cut to its :data:`ROWS` middle rows."""
    from golden.rig import preset
    from hdl.pipeline_config import PipelineConfig
    rig = preset("stereo20")
    return PipelineConfig.for_rig(rig.replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                                      t_r=1 / (120 * ROWS)))


def measurement_rows(params, rng, n, cameras=None):
    """``n`` random rows of measurements of every segment of ``cameras`` (default all):
    shifts of a few pixels, cues and confidences in their usual ranges."""
    solver = params.solver
    k = params.segments
    cameras = range(params.cameras) if cameras is None else cameras
    slots = np.array([c * k + s for c in cameras for s in range(k)])
    m = len(slots)
    shape = (n, m)
    return PoseRows(slot=np.broadcast_to(slots, shape).copy(),
                    shift=solver.shift_fmt.quantize(rng.normal(scale=2.0, size=shape)),
                    cue=solver.cue_fmt.quantize(rng.uniform(10, 60, size=shape)),
                    conf=solver.conf_fmt.quantize(rng.uniform(0.3, 1.0, size=shape)),
                    present=np.ones(shape, dtype=bool),
                    row=rng.integers(ROWS, size=n), time=np.zeros(n, dtype=np.int64))



def normals(config, params, rng, count):
    """``count`` rows' normal matrices (21 raw ints): mostly accumulated from random
    measurements on all or 3 cameras, every tenth at the extremes of ``normal_fmt``."""
    fmt = params.solver.normal_fmt
    out = []
    for r in range(count):
        if r % 10 == 7:
            out.append([int(v) for v in rng.choice([fmt.min_raw, fmt.max_raw, 0], ENTRIES)])
            continue
        cameras = None if r % 3 else sorted(rng.choice(params.cameras, 3, replace=False))
        normal, _ = accumulate(params.solver, config.coef_raw,
                               measurement_rows(params, rng, 1, cameras))
        out.append([int(v.raw[0]) for v in normal])
    return out


def framed(matrices, keeps):
    """Rows for the prior store: (entries [(value, last)], keep verdict) each."""
    return [([(v, int(k == ENTRIES - 1)) for k, v in enumerate(n)], int(keep))
            for n, keep in zip(matrices, keeps)]


def expected_totals(params, rows):
    """The model's ``M = N + Λ'`` of every well-formed row of :func:`framed`-like rows
    (None for a malformed one, whose verdict cannot keep it), and the model after."""
    model = PriorInformation(params)
    out = []
    for entries, keep in rows:
        values = [v for v, _ in entries]
        if len(values) != ENTRIES or not entries[-1][1]:
            out.append(None)
            continue
        prior = model.updated(values)
        out.append([int(n) + int(v) for n, v in zip(values, prior)])
        if keep:
            model.keep(prior)
    return out, model

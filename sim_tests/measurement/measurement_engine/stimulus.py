"""Stimulus for the measurement-engine tests: golden-simulator rows of a four-camera
rig played as row sets, with missing cameras, disabled sets, bad rows and run-time
centres.

Plain numpy and dicts, no simulator: the Amaranth-simulator tests and the cocotb bench
build the same row sets from the same seeds.
"""

from dataclasses import dataclass

import numpy as np

from golden.depth import stereo_pairs
from golden.rig import Rig, preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory
from hdl.front_end.params import CameraParams
from hdl.measurement.engine_params import EngineParams
from hdl.pose.params import PoseSolverParams
from emulator.hdl_sim.row_stimulus import row_beats

__all__ = ["WIDTH", "HEIGHT", "FRAMES", "small_rig", "engine_params", "Stimulus",
           "make_stimulus", "priming_frame", "simulated_dataset"]

#: Rows of 256 pixels (the narrowest the default 4-segment lanes accept), 6 rows per
#: frame, 4 frames: three have a temporal reference.
WIDTH, HEIGHT, FRAMES = 256, 6, 4
#: Frame number of the first frame: the numbers wrap during the sequence.
FRAME0 = (1 << 16) - 2


def small_rig():
    """The first two pairs of the stereo20 rig (one level, one rolled 90°), cut down to
    ``WIDTH × HEIGHT`` pixels with the rows spread over a 120 fps frame."""
    full = preset("stereo20").replace_cameras(width=WIDTH, cx=(WIDTH - 1) / 2, height=HEIGHT,
                                              cy=(HEIGHT - 1) / 2, t_r=1 / (120 * HEIGHT))
    return Rig(name="stereo4-small", cameras=full.cameras[:4], allow_unobservable=True)


def engine_params(rig):
    """Engine parameters for ``rig``'s cameras and rectified pairs."""
    camera = CameraParams(n_cameras=len(rig.cameras), max_width=WIDTH, max_height=HEIGHT)
    solver = PoseSolverParams(slots=4 * len(rig.cameras), rows=HEIGHT)
    pairs = tuple((a, b) for a, b, _ in stereo_pairs(rig))
    return EngineParams.for_cameras(camera, solver, pairs)


@dataclass(frozen=True)
class Stimulus:
    """Row sets (``{camera: beats}``) and the ``cfg`` in force for each."""
    row_sets: list
    configs: list


def _config(params, rng, enable, half_width=None):
    """Random centres (``half_width``: over the whole port, out of range included,
    unless given)."""
    span_t = params.temporal.centre_range + 2        # also exercise the saturation
    span_s = params.stereo.centre_range + 2
    cfg = {"temporal": [int(c) for c in rng.integers(-span_t, span_t + 1, params.cameras)],
           "stereo": [int(c) for c in rng.integers(-span_s, span_s + 1, len(params.pairs))],
           "enable": int(enable), "half_width": half_width}
    if half_width is None:
        cfg["half_width"] = int(rng.integers(1 << params.temporal.half_width_fmt.width))
    return cfg


def _damage(rng, beats, width):
    """A short row (``last`` early) or a row with reason bits."""
    beats = [dict(b) for b in beats]
    if rng.random() < 0.5:
        beats = beats[:int(rng.integers(2, width - 1))]
        beats[-1].update(last=1, flags=1)
    else:
        beats[-1]["flags"] = int(rng.integers(1, 128))
    return beats


def make_stimulus(params, dataset, rng, *, faults, clk_hz=100e6):
    """Every row of every frame of ``dataset`` as a row set, frame by frame.

    With ``faults``, sets lose a camera or a whole pair, carry a bad row, or are sent
    with ``enable`` 0; the first frame is always complete and enabled (so later frames
    have references), and the centres and the temporal half-width change from set to
    set. Without, centres are fixed and non-zero, the half-width is the built maximum
    and every set is complete.
    """
    t0 = min(float(cam.time[0, 0]) for cam in dataset.cameras)
    fixed = _config(params, rng, True, params.temporal.max_half_width)
    row_sets, configs = [], []
    for f in range(FRAMES):
        for y in range(HEIGHT):
            row_set = {}
            for k, cam in enumerate(dataset.cameras):
                ticks = int(round((cam.time[f, y] - t0) * clk_hz)) % (1 << 32)
                row_set[k] = row_beats(cam.rows[f, y], camera=k,
                                       frame=(FRAME0 + f) % (1 << 16), row=y, t_first=ticks)
            cfg = fixed
            if faults and f > 0:
                cfg = _config(params, rng, rng.random() > 0.2)
                kind = rng.integers(5)
                if kind == 0:                                  # one camera lost
                    del row_set[int(rng.integers(params.cameras))]
                elif kind == 1:                                # a whole pair lost
                    for k in params.pairs[int(rng.integers(len(params.pairs)))]:
                        del row_set[k]
                elif kind == 2:                                # a bad row
                    k = int(rng.integers(params.cameras))
                    row_set[k] = _damage(rng, row_set[k], params.temporal.width)
            row_sets.append(row_set)
            configs.append(cfg)
    return Stimulus(row_sets=row_sets, configs=configs)


def priming_frame(params):
    """A frame of black rows from every camera, numbered so that it is no reference for
    :func:`make_stimulus`'s first frame: it fills every lane's reference store with
    the same bits in the hardware and in a fresh model, whatever an earlier test left."""
    frame = (FRAME0 - 3) % (1 << 16)
    black = np.zeros(params.temporal.width, dtype=np.uint8)
    row_sets = [{k: row_beats(black, camera=k, frame=frame, row=y) for k in range(params.cameras)}
                for y in range(params.temporal.height)]
    cfg = {"temporal": [0] * params.cameras, "stereo": [0] * len(params.pairs), "enable": 1,
           "half_width": params.temporal.max_half_width}
    return Stimulus(row_sets=row_sets, configs=[cfg] * len(row_sets))


def simulated_dataset(rig, seed):
    """The golden simulator's rows of ``rig`` moving along the papers' trajectory."""
    return simulate(rig, default_scene_spec(seed), make_trajectory("paper"), FRAMES / 120,
                    seed=seed)

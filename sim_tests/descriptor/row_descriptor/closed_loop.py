"""Stimulus of the following lane's bench: one camera's rows, window centres and source
rows from a real closed-loop emulator run (docs/e2e.md, "Closed loop in the pipeline
model"): the stereo20 rig cut to its 32 middle rows, three frames of the papers' motion
(seed 1), forecast delay 1 row, started at the true one-frame motion of the first
tracked row, as ``sim_tests/top/test_pipeline.py`` runs it."""

import pickle

import numpy as np

from emulator.e2e import true_steps
from emulator.pipeline import run
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory
from hdl.pipeline_config import PipelineConfig

__all__ = ["ROWS", "FRAMES", "closed_loop_stimulus", "loop_lane"]

ROWS, FRAMES, SEED, SEGMENTS = 32, 3, 1, 4


def closed_loop_stimulus(path):
    """Path of an ``.npz`` made once and kept at ``path`` (under ``build/``): ``pixels``
    (F, H, W) of the camera whose forecast reads rows above its own most (the direction
    the ring's D limits), its ``centre`` and ``source`` (F·H, K: each segment's row) as
    the loop set them, ``camera``, and the pipeline's measurements of that camera as
    ``expected`` (F·H·K, fields ``fields``); the
    pipeline's lane parameters beside it (:func:`loop_lane`)."""
    if path.exists() and path.with_suffix(".pkl").exists():
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    rig = preset("stereo20").replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                             t_r=1 / (120 * ROWS))
    dataset = simulate(rig, default_scene_spec(SEED), make_trajectory("paper"),
                       FRAMES / 120, seed=SEED)
    config = PipelineConfig.for_rig(rig, segments=SEGMENTS)
    result = run(config, dataset, forecast=config.forecast(loop_delay_rows=1),
                 initial_motion=true_steps(dataset, [1], [0])[0])
    loop = result.loop
    upward = np.clip(loop["row"][:, None] - loop["source_row"], 0, None).sum(axis=0)
    camera = int(np.argmax(upward))
    measured = [m for m in result.temporal if m["camera"] == camera]
    fields = sorted(measured[0])
    np.savez(path, pixels=dataset.cameras[camera].rows[:FRAMES], camera=camera,
             centre=loop["centre"][:, camera], source=loop["segment_rows"][:, camera],
             fields=np.array(fields),
             expected=np.array([[m[k] for k in fields] for m in measured], dtype=np.int64))
    path.with_suffix(".pkl").write_bytes(pickle.dumps(config.router.temporal))
    return path


def loop_lane(path):
    """The temporal lane parameters of the run saved at ``path``."""
    return pickle.loads(path.with_suffix(".pkl").read_bytes())

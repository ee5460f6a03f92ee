"""How far content moves across rows in one frame on the stereo20 rig (640×480, 120 fps):
the measurement behind the followed store's default D
(``RowDescriptorParams.max_row_displacement``, docs/descriptor/row_descriptor.md).

For every camera, frame and row, the scene point seen at each of the K = 4 segment
centres (true depth from the scene, true row poses of the golden trajectory) is
projected into the same camera at the same row of the previous frame; ``d`` = row −
that row, averaged over the segments and rounded, is the displacement the forecast's
row address asks for (the ring serves ``d ≤ D + 1``; content moving up, ``d < 0``, is
always served). No images are rendered. Default: 12 frames of the papers' motion and of
one head motion; RUN_SLOW=1: 120 frames (one second) of three head motions.
"""

import os

import numpy as np
import pytest

from golden.depth_maps import scene_depth
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import schedule
from golden.trajectory import make_trajectory
from hdl.descriptor.params import TEMPORAL_640X480
from hdl.pipeline_config import segment_centres

SLOW = bool(os.environ.get("RUN_SLOW"))
FRAMES = 120 if SLOW else 12


def row_displacements(rig, trajectory, frames, seed=0):
    """``d`` (rounded mean over the segment centres) of every camera, frame ≥ 1 and row."""
    spec = default_scene_spec(seed)
    columns = np.array(segment_centres(TEMPORAL_640X480)).round().astype(int)
    out = []
    for cam, times in zip(rig.cameras, schedule(rig, (frames + 0.5) / 120, seed)):
        n, height = times.shape
        rotation, position = trajectory.pose(times.ravel())
        rotation = rotation.reshape(n, height, 3, 3) @ cam.R
        centre = position.reshape(n, height, 3) + np.einsum(
            "fhij,j->fhi", rotation @ cam.R.T, cam.c)
        rays = np.einsum("fhij,hcj->fhci", rotation, cam.rays[:, columns])
        points = centre[:, :, None] + scene_depth(spec, centre[:, :, None], rays)[..., None] * rays
        seen = np.einsum("fhji,fhcj->fhci", rotation[:-1], points[1:] - centre[:-1, :, None])
        before = cam.project(seen)[..., 1]
        out.append(np.rint((np.arange(height)[None, :, None] - before).mean(axis=2)))
    d = np.concatenate([x.ravel() for x in out])
    return d[np.isfinite(d)]


@pytest.mark.parametrize("motion, seeds", [("paper", (0,)), ("head", (0, 1, 2) if SLOW else (0,))])
def test_the_default_row_displacement_covers_twice_the_measured_motion(motion, seeds):
    """The ring's default D serves at least twice the largest downward displacement
    measured (in one second: paper 10 rows, three head motions 13 rows)."""
    rig = preset("stereo20")
    d = np.concatenate([row_displacements(rig, make_trajectory(motion, seed=s), FRAMES, s)
                        for s in seeds])
    print(f"{motion} ({FRAMES} frames, seeds {seeds}): {d.size} rows, d from "
          f"{d.min():.0f} to {d.max():.0f}, |d| median {np.median(abs(d)):.0f}, "
          f"99th percentile {np.percentile(abs(d), 99):.0f}")
    assert d.size > 0.9 * len(rig.cameras) * (FRAMES - 1) * TEMPORAL_640X480.height
    assert 2 <= d.max() and 2 * d.max() <= TEMPORAL_640X480.row_displacement + 1

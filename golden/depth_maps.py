"""Per-camera depth for rigs without stereo pairs (CVPR 2018 §3.3), and the oracle.

:class:`OracleDepth` is the simulator's true depth (ray cast into the dataset's scene at
the true row poses). It exists for ablations only — it tells how much of the tracker's
error comes from depth — and every result made with it is labelled ``oracle``.
"""

import numpy as np

from .scene import scene_from_config
from .tracker_geometry import rotate

__all__ = ["OracleDepth", "scene_depth"]


def scene_depth(spec, origins, directions):
    """Ray parameter of the first surface hit in the scene ``spec`` (room + boxes).

    ``origins`` (..., 3) and ``directions`` (..., 3) in world metres; with directions
    whose camera z component is 1 the result is the camera depth Z.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / directions
        lo, hi = (spec.room_lo - origins) * inverse, (spec.room_hi - origins) * inverse
        hit = np.min(np.where(directions > 0, hi, lo), axis=-1)          # leave the room
        for box in spec.boxes:
            a = (np.array(box.lo) - origins) * inverse
            b = (np.array(box.hi) - origins) * inverse
            near = np.max(np.fmin(a, b), axis=-1)
            far = np.min(np.fmax(a, b), axis=-1)
            enters = (near <= far) & (near > 0) & (near < hit)
            hit = np.where(enters, near, hit)
    return hit


class OracleDepth:
    """True inverse depth of camera rows, from the dataset's scene and ground truth.

    Parameters
    ----------
    dataset : golden.dataset.Dataset
    """

    def __init__(self, dataset):
        self.spec = scene_from_config(dataset.info["scene"], "dataset scene")
        self.rig, self.recordings = dataset.rig, dataset.cameras

    def inverse_depth(self, n, frame, rows, rotations=None, positions=None):
        """1/Z (B, W) of rows ``rows`` of frame ``frame`` of camera ``n`` at their true
        poses (the tracker's predicted poses are ignored)."""
        cam, rec = self.rig.cameras[n], self.recordings[n]
        rotation, position = rec.rotation[frame, rows], rec.position[frame, rows]
        directions = rotate(rotation @ cam.R, cam.rays[rows])
        origins = (position + rotation @ cam.c)[:, None, :]
        return 1.0 / scene_depth(self.spec, origins, directions)

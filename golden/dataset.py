"""The simulator's dataset file: rows, per-row times and ground-truth poses, calibration.

One ``.npz`` (NumPy zip, no pickles) per simulation; ``docs/simulator.md`` documents the
keys for readers outside Python. Camera ``k`` of the rig stores:

=========================  ================  ==============================================
key                        shape, dtype      meaning
=========================  ================  ==============================================
``cam{k}_rows``            (F, H, W) uint8   the rows as read out, frame by frame
``cam{k}_time``            (F, H) float64    exposure start of each row (s)
``cam{k}_rotation``        (F, H, 3, 3) f64  rig → world rotation at that time
``cam{k}_position``        (F, H, 3) f64     rig origin in the world (m)
``cam{k}_velocity``        (F, H, 3) f64     rig linear velocity, world frame (m/s)
``cam{k}_angular_velocity`` (F, H, 3) f64    rig angular velocity, world frame (rad/s)
=========================  ================  ==============================================

and for all N cameras: ``K`` (N, 3, 3), ``distortion`` (N, 2) = (k1, k2), ``extrinsic_rotation``
(N, 3, 3) camera → rig, ``extrinsic_position`` (N, 3) camera centre in the rig, ``timing``
(N, 4) = (fps, t_r, t_f, t_e), ``image_size`` (N, 2) = (W, H). ``info`` is a JSON string
with the full rig configuration (loadable by :func:`golden.rig.rig_from_config`), the
scene, the trajectory, seed, duration and the rig's observability verdict.
"""

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .rig import rig_from_config

__all__ = ["FORMAT", "VERSION", "CameraRecording", "Dataset"]

FORMAT = "rowtrack-rs-dataset"
VERSION = 1

_PER_CAMERA = ("rows", "time", "rotation", "position", "velocity", "angular_velocity")


@dataclass
class CameraRecording:
    """Everything one camera captured; arrays as in the module table."""
    rows: np.ndarray
    time: np.ndarray
    rotation: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray


@dataclass
class Dataset:
    """A simulated sequence: the rig, one :class:`CameraRecording` per camera, and
    ``info`` (seed, duration, scene, trajectory, observability)."""
    rig: object
    cameras: list
    info: dict

    def camera_pose(self, k):
        """Camera-to-world rotation (F, H, 3, 3) and centre (F, H, 3) of camera ``k`` at
        each of its rows."""
        rec, cam = self.cameras[k], self.rig.cameras[k]
        return rec.rotation @ cam.R, rec.position + rec.rotation @ cam.c

    def row_order(self):
        """Every row in readout-time order: a structured array of (time, camera, frame,
        row), what a live cluster would deliver to the hardware."""
        parts = []
        for k, rec in enumerate(self.cameras):
            frames, rows = np.meshgrid(np.arange(rec.time.shape[0]), np.arange(rec.time.shape[1]),
                                       indexing="ij")
            part = np.empty(rec.time.size, dtype=[("time", "f8"), ("camera", "i4"),
                                                  ("frame", "i4"), ("row", "i4")])
            part["time"], part["camera"] = rec.time.ravel(), k
            part["frame"], part["row"] = frames.ravel(), rows.ravel()
            parts.append(part)
        merged = np.concatenate(parts)
        return merged[np.argsort(merged, order=("time", "camera"), kind="stable")]

    def save(self, path, compress=False):
        cams = self.rig.cameras
        arrays = {
            "format": np.array(FORMAT), "version": np.array(VERSION),
            "info": np.array(json.dumps({**self.info, "rig": self.rig.to_config()})),
            "K": np.array([c.K for c in cams]),
            "distortion": np.array([(c.k1, c.k2) for c in cams]),
            "extrinsic_rotation": np.array([c.R for c in cams]),
            "extrinsic_position": np.array([c.c for c in cams]),
            "timing": np.array([(c.fps, c.t_r, c.t_f, c.t_e) for c in cams]),
            "image_size": np.array([(c.width, c.height) for c in cams]),
        }
        for k, rec in enumerate(self.cameras):
            for name in _PER_CAMERA:
                arrays[f"cam{k}_{name}"] = getattr(rec, name)
        (np.savez_compressed if compress else np.savez)(Path(path), **arrays)

    @classmethod
    def load(cls, path):
        """Read a dataset written by :meth:`save`.

        Raises
        ------
        ValueError
            If the file is not a rowtrack dataset of a supported version.
        """
        with np.load(Path(path), allow_pickle=False) as data:
            if "format" not in data or str(data["format"]) != FORMAT:
                raise ValueError(f"{path} is not a {FORMAT} file")
            if int(data["version"]) != VERSION:
                raise ValueError(f"{path} has dataset version {int(data['version'])}; "
                                 f"this reader supports version {VERSION}")
            info = json.loads(str(data["info"]))
            rig = rig_from_config(info.pop("rig"), str(path))
            cameras = [CameraRecording(**{name: data[f"cam{k}_{name}"] for name in _PER_CAMERA})
                       for k in range(len(rig.cameras))]
        return cls(rig=rig, cameras=cameras, info=info)

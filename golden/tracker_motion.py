"""Rig poses sampled in time: composition with small-motion steps and interpolation.

A pose is world-from-body ``(R, p)``. A step ``Y = [Tx Ty Tz θx θy θz]`` is expressed in
the body frame of the earlier pose (the convention of :mod:`golden.pose_lsq`):
``(R, p) ⊕ Y = (R exp([θ]×), p + R T)``, and :func:`golden.pose_lsq.body_step` is its
inverse. The tracker keeps its estimate as a :class:`PoseTrack` (one pose per row slot)
and looks poses up at arbitrary times (reference rows of the previous frame, other
cameras' row times), so interpolation is part of the model, not of the plots.
"""

import numpy as np

from .checks import check_int
from .pose_lsq import body_step
from .rotations import exp_so3

__all__ = ["compose", "PoseTrack", "ground_truth_track"]


def compose(rotation, position, step):
    """``(R, p) ⊕ Y`` for stacks of poses (..., 3, 3), (..., 3) and steps (..., 6)."""
    step = np.asarray(step, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    new_position = np.asarray(position, dtype=float) + np.einsum("...ij,...j->...i",
                                                                 rotation, step[..., :3])
    return rotation @ exp_so3(step[..., 3:]), new_position


class PoseTrack:
    """Poses at increasing times, grown one sample at a time, read at any time.

    Between samples the position is linear and the rotation follows the geodesic
    (``R_a exp(f·log(R_aᵀ R_b))``); outside the sampled span the first or last pose is
    held unless an extrapolation step rate is set with :meth:`set_extrapolation`.

    Parameters
    ----------
    capacity : int
        Largest number of samples.
    """

    @classmethod
    def from_samples(cls, times, rotations, positions):
        """A full track holding the given samples (times increasing)."""
        track = cls(len(times))
        track.times[:], track.rotations[:], track.positions[:] = times, rotations, positions
        track.count = len(times)
        return track

    def __init__(self, capacity):
        check_int("capacity", capacity, 1)
        self.times = np.empty(capacity)
        self.rotations = np.empty((capacity, 3, 3))
        self.positions = np.empty((capacity, 3))
        self.count = 0
        self._rate = np.zeros(6)

    def append(self, time, rotation, position):
        if self.count and time <= self.times[self.count - 1]:
            raise ValueError(f"time must increase: {time!r} after "
                             f"{self.times[self.count - 1]!r}")
        if self.count == len(self.times):
            raise ValueError(f"pose track is full ({self.count} samples)")
        k = self.count
        self.times[k], self.rotations[k], self.positions[k] = time, rotation, position
        self.count += 1

    def set_extrapolation(self, rate):
        """Body-frame step per second (6) used beyond the last sample (zero: hold)."""
        self._rate = np.asarray(rate, dtype=float)

    @property
    def last_time(self):
        return self.times[self.count - 1]

    def at(self, times):
        """Rotations (..., 3, 3) and positions (..., 3) at ``times`` (...)."""
        times = np.asarray(times, dtype=float)
        flat = times.ravel()
        n = self.count
        if n == 0:
            raise ValueError("pose track is empty")
        t, rot, pos = self.times[:n], self.rotations[:n], self.positions[:n]
        k = np.clip(np.searchsorted(t, flat, side="right") - 1, 0, max(n - 2, 0))
        if n == 1:
            rotation, position = rot[k].copy(), pos[k].copy()
        else:
            frac = np.clip((flat - t[k]) / (t[k + 1] - t[k]), 0.0, 1.0)
            step = body_step(rot[k], pos[k], rot[k + 1], pos[k + 1])
            rotation = rot[k] @ exp_so3(frac[:, None] * step[:, 3:])
            position = pos[k] + frac[:, None] * (pos[k + 1] - pos[k])
        beyond = flat > t[-1]
        if np.any(beyond) and np.any(self._rate):
            dt = (flat[beyond] - t[-1])[:, None]
            rotation[beyond], position[beyond] = compose(rot[-1], pos[-1], dt * self._rate)
        return rotation.reshape(times.shape + (3, 3)), position.reshape(times.shape + (3,))


def ground_truth_track(dataset):
    """The recorded ground-truth rig poses of every camera row, merged in time order."""
    times = np.concatenate([rec.time.ravel() for rec in dataset.cameras])
    rotations = np.concatenate([rec.rotation.reshape(-1, 3, 3) for rec in dataset.cameras])
    positions = np.concatenate([rec.position.reshape(-1, 3) for rec in dataset.cameras])
    times, first = np.unique(times, return_index=True)
    return PoseTrack.from_samples(times, rotations[first], positions[first])

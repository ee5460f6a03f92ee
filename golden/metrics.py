"""Accuracy of a tracker run against the dataset's ground truth.

Two kinds of error, never mixed:

* **Per-row estimation variables** (the papers' Table 1): the unknown of every row is
  ``Y``, the rig's motion over one frame period (from the same row slot one frame
  earlier, :mod:`golden.tracker`). ``Y`` estimated (from the tracker's poses at the two
  times) against ``Y`` true (from the ground truth at the same two times), RMS per axis
  over all tracked rows: translation in cm, rotation in rad and degrees.
* **Integrated trajectory**: the estimated pose against the true pose at each row,
  which drifts (errors chain from frame to frame): RMS and final error per axis, and the
  rendering error of a virtual point 1 m in front of the head drawn on an HMD display.

Rendering error (TVCG 2016 §5, CVPR 2018 §4): a point fixed 1 m ahead of the true head
pose, drawn with the estimated pose on one eye of an HTC-Vive-class display,
1080 × 1200 pixels per eye; we take a 100° horizontal field of view with square pixels
(f = 540 / tan 50° = 453.1 px, 105.9° vertically), the eye at the rig origin looking
along the rig's forward axis. The error is the distance in display pixels from where
the point should appear.
"""

import math

import numpy as np

from .pose_lsq import body_step
from .tracker_motion import PoseTrack, ground_truth_track

__all__ = ["HMD_WIDTH", "HMD_HEIGHT", "HMD_HFOV_DEG", "hmd_focal", "render_error",
           "evaluate", "AXES"]

HMD_WIDTH, HMD_HEIGHT = 1080, 1200
HMD_HFOV_DEG = 100.0
#: Axis names of the rig frame (x right, y down, z forward).
AXES = ("x", "y", "z")


def hmd_focal(width=HMD_WIDTH, hfov_deg=HMD_HFOV_DEG):
    """Display focal length in pixels for a horizontal field of view."""
    return (width / 2) / math.tan(math.radians(hfov_deg) / 2)


def render_error(true_rotation, true_position, rotation, position, distance=1.0,
                 focal=None):
    """Display-pixel offsets (...) of a point ``distance`` m ahead of the true pose when
    drawn with the estimated pose (rotations (..., 3, 3), positions (..., 3))."""
    focal = hmd_focal() if focal is None else focal
    ahead = true_position + distance * true_rotation[..., :, 2]
    seen = np.einsum("...ji,...j->...i", rotation, ahead - position)
    return focal * np.hypot(seen[..., 0], seen[..., 1]) / seen[..., 2]


def _rms(values):
    return np.sqrt(np.mean(np.square(values), axis=0))


def evaluate(result, dataset):
    """Metrics of a :class:`golden.tracker.TrackResult` on its dataset (a flat dict;
    per-axis figures are lists x, y, z)."""
    gt = ground_truth_track(dataset)
    est = PoseTrack.from_samples(result.times, result.rotations, result.positions)
    tracked = result.tracked
    times = result.times[tracked]
    if not len(times):
        raise ValueError("the result has no tracked rows")
    period = result.period
    true_rot, true_pos = gt.at(times)
    est_rot, est_pos = result.rotations[tracked], result.positions[tracked]
    motion_true = body_step(*gt.at(times - period), true_rot, true_pos)
    motion_est = body_step(*est.at(times - period), est_rot, est_pos)
    step_error = motion_est - motion_true
    position_error = est_pos - true_pos
    rotation_error = body_step(true_rot, true_pos, est_rot, est_pos)[:, 3:]
    render = render_error(true_rot, true_pos, est_rot, est_pos)
    condition = result.condition[tracked]
    solved = ~np.isnan(condition)          # a system was formed (inf: rank deficient)
    rms_r = _rms(step_error[:, 3:])
    return {
        "rows": int(len(times)),
        "seconds": float(times[-1] - times[0] + dataset.rig.cameras[0].t_r),
        "rms_t_cm": (100 * _rms(step_error[:, :3])).tolist(),
        "rms_r_rad": rms_r.tolist(),
        "rms_r_deg": np.degrees(rms_r).tolist(),
        "abs_t_cm": (100 * _rms(position_error)).tolist(),
        "abs_r_rad": _rms(rotation_error).tolist(),
        "abs_r_deg": np.degrees(_rms(rotation_error)).tolist(),
        "final_t_cm": (100 * position_error[-1]).tolist(),
        "final_r_deg": np.degrees(rotation_error[-1]).tolist(),
        "render_px": float(_rms(render)),
        "render_px_max": float(np.max(render)),
        "update_fraction": float(np.mean(result.updated[tracked])),
        "cond_median": float(np.median(condition[solved])) if solved.any() else math.nan,
        "cond_max": float(np.max(condition[solved])) if solved.any() else math.nan,
        "equations_median": float(np.median(result.equations[tracked])),
    }

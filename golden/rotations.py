"""Rotation helpers (float64, vectorized over leading axes).

Conventions used throughout :mod:`golden`: a rotation matrix maps vectors of the child
frame into the parent frame (``x_parent = R @ x_child``); rotation vectors are axis ×
angle in radians; camera frames are x right, y down, z forward (OpenCV).
"""

import numpy as np

__all__ = ["hat", "exp_so3", "left_jacobian", "rotation_angle", "orientation_ypr",
           "is_rotation"]


def hat(v):
    """Skew-symmetric matrices ``[v]×`` of vectors ``v`` (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _series(theta):
    """(sin θ/θ, (1−cos θ)/θ², (θ−sin θ)/θ³), accurate also for θ → 0."""
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    t2 = theta * theta
    a = np.where(small, 1 - t2 / 6, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24, (1 - np.cos(safe)) / safe**2)
    c = np.where(small, 1 / 6 - t2 / 120, (safe - np.sin(safe)) / safe**3)
    return a, b, c


def exp_so3(rotvec):
    """Rotation matrices of rotation vectors (..., 3) -> (..., 3, 3) (Rodrigues)."""
    rotvec = np.asarray(rotvec, dtype=float)
    theta = np.linalg.norm(rotvec, axis=-1)
    a, b, _ = _series(theta)
    k = hat(rotvec)
    return np.eye(3) + a[..., None, None] * k + b[..., None, None] * (k @ k)


def left_jacobian(rotvec):
    """Left Jacobian of SO(3): ``d/dt exp(φ) = [J_l(φ) φ̇]× exp(φ)`` (..., 3, 3)."""
    rotvec = np.asarray(rotvec, dtype=float)
    theta = np.linalg.norm(rotvec, axis=-1)
    _, b, c = _series(theta)
    k = hat(rotvec)
    return np.eye(3) + b[..., None, None] * k + c[..., None, None] * (k @ k)


def rotation_angle(rotation):
    """Angle in radians of rotation matrices (..., 3, 3)."""
    trace = np.trace(np.asarray(rotation, dtype=float), axis1=-2, axis2=-1)
    return np.arccos(np.clip((trace - 1) / 2, -1.0, 1.0))


def orientation_ypr(yaw_deg=0.0, pitch_deg=0.0, roll_deg=0.0):
    """Camera-to-rig rotation from yaw, pitch and roll in degrees.

    Both frames are x right, y down, z forward. Roll turns the camera about its optical
    axis (positive: clockwise as seen from behind the camera, so 90° makes image rows
    run vertically), then pitch tilts it (positive: looks up), then yaw turns it
    (positive: looks right).
    """
    y, p, r = np.radians([yaw_deg, pitch_deg, roll_deg])
    cy, sy, cp, sp, cr, sr = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    yaw = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    pitch = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    roll = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    return yaw @ pitch @ roll


def is_rotation(matrix, tol=1e-6):
    """True if ``matrix`` is a 3×3 proper rotation within ``tol``."""
    m = np.asarray(matrix, dtype=float)
    return (m.shape == (3, 3) and np.allclose(m @ m.T, np.eye(3), atol=tol)
            and abs(np.linalg.det(m) - 1) < tol)

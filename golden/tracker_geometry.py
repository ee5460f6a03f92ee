"""Where a current row's points sit in a reference row, and the segment equations.

A measurement compares the current row of camera ``n`` (pose ``(R, p)`` of the rig at
the row's time) with a *reference row*: a row whose pixel ``u`` shows the scene along
the direction ``R_view R_n r(u)`` from the camera centre ``C_src(u)``. For the previous
frame's stored row (reference (b)) ``R_view`` and ``C_src`` are that row's estimated
pose; for the homography reference (a) ``R_view`` is the rotation the previous frame was
warped to and ``C_src(u)`` the centre of the previous-frame row each pixel was taken
from (rotation-only warping keeps the source centres).

The point seen at current pixel ``u`` (ray ``r(u)``, inverse depth ``w``) lies at
``X = R (R_n r/w + c_n) + p``; it appears in the reference at
``v(u) = π(R_nᵀ R_viewᵀ (X − C_src))`` (π: projection with the Brown lens), and the
matcher's shift is ``s = u_x − v_x(u)`` (descriptor convention ``cur[x] ≈ ref[x − s]``).
A segment's shift is modelled as the mean of its pixels' shifts, so its equation uses
the mean over the segment's pixels of the per-pixel design rows of
:func:`golden.pose_lsq.shift_coefficients` (not the centre pixel's row).
"""

import numpy as np

from .pose_lsq import ShiftCoefficients, design_rows, shift_coefficients

__all__ = ["rotate", "project", "camera_poses", "reference_pixels", "DesignTable", "segment_means"]


def rotate(matrices, vectors):
    """``M v`` for one 3×3 matrix per row (..., 3, 3) and that row's vectors (..., W, 3).

    Written as nine broadcast products: several times faster than ``einsum`` or batched
    ``matmul`` on 3×3 blocks.
    """
    m = np.asarray(matrices, dtype=float)[..., None, :, :]
    return (m[..., 0] * vectors[..., 0:1] + m[..., 1] * vectors[..., 1:2]
            + m[..., 2] * vectors[..., 2:3])


def project(camera, points):
    """Pixel positions ``(x, y)`` of camera-frame points (..., 3); NaN behind the camera."""
    z = points[..., 2]
    ahead = z > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = camera.normalized_to_pixel(points[..., 0] / z, points[..., 1] / z)
    return np.where(ahead, x, np.nan), np.where(ahead, y, np.nan)


def camera_poses(camera, rotations, positions):
    """Camera-to-world rotations (..., 3, 3) and camera centres (..., 3) of ``camera``
    for rig poses (world-from-rig ``rotations``, ``positions``)."""
    rotations = np.asarray(rotations, dtype=float)
    return rotations @ camera.R, positions + rotations @ camera.c


def reference_pixels(camera, rays, inverse_depth, rotation, position, view_rotation,
                     source_centre):
    """Pixel positions ``(x, y)`` (..., W) in the reference row of the points seen by the
    current pixels.

    Parameters
    ----------
    camera : golden.camera.Camera
    rays : (..., W, 3)
        Current pixels' rays in camera coordinates (z = 1).
    inverse_depth : (..., W)
        1/Z of the current pixels (0 for points at infinity, NaN for unknown).
    rotation, position : (..., 3, 3), (..., 3)
        Rig pose at the current row.
    view_rotation : (..., 3, 3) or (..., W, 3, 3)
        Rig rotation the reference row is seen with (per pixel when a row is put together
        from several stored rows: one more dimension than ``rays``).
    source_centre : (..., W, 3) or (..., 1, 3)
        Camera centre (world) each reference pixel was captured from.
    """
    w = np.asarray(inverse_depth, dtype=float)[..., None]
    body = rays @ camera.R.T + w * camera.c                       # body frame, scaled by w
    world = rotate(rotation, body) + w * (np.asarray(position)[..., None, :] - source_centre)
    view_rotation = np.asarray(view_rotation, dtype=float)
    if view_rotation.ndim == np.ndim(rays) + 1:                   # one rotation per pixel
        seen = np.einsum("...ji,...j->...i", view_rotation, world)
    else:
        seen = rotate(np.swapaxes(view_rotation, -1, -2), world)
    return project(camera, seen @ camera.R)


class DesignTable:
    """The nine precomputed coefficients of pixels ``columns`` of every row of a camera
    (the hardware's coefficient store), computed on first use and kept."""

    def __init__(self, camera, columns):
        self.camera, self.columns = camera, np.asarray(columns, dtype=float)
        self._table = None

    def rows(self, rows, inverse_depth):
        """Per-pixel design rows (B, C, 6) of image rows ``rows`` with inverse depths
        ``inverse_depth`` (B, C) at the table's columns."""
        if self._table is None:
            cam = self.camera
            px, py = np.meshgrid(self.columns, np.arange(cam.height, dtype=float))
            self._table = shift_coefficients(cam, px, py).table()
        return design_rows(ShiftCoefficients.from_table(self._table[rows]), inverse_depth)


def segment_means(values, valid, lo, hi):
    """Means over the valid pixels of segments with per-row column ranges.

    Parameters
    ----------
    values : (B, W) or (B, W, C)
    valid : (B, W) bool
    lo, hi : (B, K) int
        Column range ``[lo, hi)`` of each row's K segments.

    Returns
    -------
    means : (B, K) or (B, K, C)
        NaN for a segment without valid pixels.
    fraction : (B, K)
        Share of the segment's pixels that are valid.
    """
    values = np.asarray(values, dtype=float)
    extra = values.ndim - valid.ndim
    clean = np.where(valid.reshape(valid.shape + (1,) * extra), values, 0.0)
    total = np.cumsum(np.concatenate([np.zeros_like(clean[:, :1]), clean], axis=1), axis=1)
    count = np.cumsum(np.concatenate([np.zeros((len(valid), 1)), valid], axis=1), axis=1)

    def between(cumulative):
        shape = lo.shape + (1,) * (cumulative.ndim - 2)
        return (np.take_along_axis(cumulative, hi.reshape(shape), 1)
                - np.take_along_axis(cumulative, lo.reshape(shape), 1))

    n = between(count)
    with np.errstate(divide="ignore", invalid="ignore"):
        means = between(total) / n.reshape(n.shape + (1,) * extra)
    return means, n / (hi - lo)

"""One rolling-shutter camera: pinhole intrinsics, Brown lens, shutter timing, mounting.

Timing follows the thesis (§ rolling shutter): row ``y`` of frame ``i`` starts its
exposure at ``t = τ0 + y·t_r + i/fps`` and ``1/fps = H·t_r + t_f + t_e``. A parameter set
that breaks this relation is rejected, never clamped. The exposure of a row spans
``[t, t + t_e]``.
"""

import math
from dataclasses import dataclass, fields, replace
from functools import cached_property

import numpy as np

from .checks import check_int, check_number
from .lens import LENS_PRESETS, distort, fold_radius, radial_factor, undistort
from .rotations import is_rotation

__all__ = ["Camera", "focal_for_vfov"]

_IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

#: Relative tolerance of the timing relation 1/fps = H·t_r + t_f + t_e.
TIMING_RTOL = 1e-9


def focal_for_vfov(vfov_deg, height, k1=0.0, k2=0.0):
    """Focal length in pixels that gives a true vertical field of view of ``vfov_deg``
    through the lens (k1, k2), measured along the centre column."""
    if not 0 < vfov_deg < 180:
        raise ValueError(f"vfov_deg must be in (0, 180), not {vfov_deg!r}")
    ru = math.tan(math.radians(vfov_deg) / 2)
    if ru > fold_radius(k1, k2):
        raise ValueError(f"vfov_deg {vfov_deg} reaches beyond the fold radius of lens "
                         f"(k1={k1}, k2={k2})")
    return (height / 2) / (ru * radial_factor(ru * ru, k1, k2))


@dataclass(frozen=True, kw_only=True)
class Camera:
    """A rolling-shutter camera of a rig (float64 model; no widths).

    Parameters
    ----------
    name : str
    width, height : int
        Image size in pixels; rows are read top to bottom.
    fx, fy, cx, cy : float
        Pinhole intrinsics in pixels (pixel centres at integer coordinates).
    k1, k2 : float
        Brown radial distortion on normalized coordinates.
    fps, t_r, t_f, t_e : float
        Frame rate (1/s), row readout time, idle/blanking time and exposure time (s);
        ``1/fps = height·t_r + t_f + t_e`` must hold.
    rotation : 3×3 nested tuple
        Camera-to-rig rotation (camera x right, y down, z forward).
    position : 3-tuple
        Camera centre in the rig frame (m).
    trigger_offset : float
        τ0: start of frame 0 (s), in ``[0, 1/fps)``.
    trigger_jitter : float
        Standard deviation (s) of a random per-frame trigger error; the recorded row
        times include it.
    noise_sigma : float
        Standard deviation of additive Gaussian sensor noise in gray levels (8-bit scale).
    exposure_samples : int
        1: each row is captured instantaneously at its row time. N > 1: the row is the
        mean of N renders at the midpoints of N equal parts of ``[t, t + t_e]`` (motion
        blur; needs ``t_e > 0``).
    """
    name: str = "cam"
    width: int = 640
    height: int = 480
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    fps: float = 120.0
    t_r: float
    t_f: float = 0.0
    t_e: float = 0.0
    rotation: tuple = _IDENTITY
    position: tuple = (0.0, 0.0, 0.0)
    trigger_offset: float = 0.0
    trigger_jitter: float = 0.0
    noise_sigma: float = 0.0
    exposure_samples: int = 1

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise TypeError(f"name must be a non-empty string, not {self.name!r}")
        for name in ("width", "height", "exposure_samples"):
            check_int(name, getattr(self, name), 1)
        for name in ("fx", "fy", "fps", "t_r"):
            check_number(name, getattr(self, name), 0, low_open=True)
        for name in ("cx", "cy", "k1", "k2"):
            check_number(name, getattr(self, name))
        for name in ("t_f", "t_e", "trigger_offset", "trigger_jitter", "noise_sigma"):
            check_number(name, getattr(self, name), 0)
        rotation = np.asarray(self.rotation, dtype=float)
        if not is_rotation(rotation):
            raise ValueError(f"rotation must be a 3×3 proper rotation matrix, not {self.rotation!r}")
        position = np.asarray(self.position, dtype=float)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise ValueError(f"position must be 3 finite numbers, not {self.position!r}")
        object.__setattr__(self, "rotation", tuple(map(tuple, rotation.tolist())))
        object.__setattr__(self, "position", tuple(position.tolist()))
        self._check_timing()
        if self.exposure_samples > 1 and self.t_e == 0:
            raise ValueError(f"exposure_samples {self.exposure_samples} needs an exposure "
                             f"time t_e > 0")
        self._check_lens()

    def _check_timing(self):
        period = 1.0 / self.fps
        used = self.height * self.t_r + self.t_f + self.t_e
        if abs(used - period) > TIMING_RTOL * period:
            raise ValueError(
                f"infeasible timing: fps, t_r, t_f, t_e must satisfy 1/fps = H·t_r + t_f + t_e "
                f"(H = height = {self.height}), but 1/fps = {period:.9g} s and "
                f"H·t_r + t_f + t_e = {used:.9g} s")
        if self.trigger_offset >= period:
            raise ValueError(f"trigger_offset must be less than 1/fps = {period:.9g} s, "
                             f"not {self.trigger_offset!r}")

    def _check_lens(self):
        corners_x = (np.array([0, self.width - 1]) - self.cx) / self.fx
        corners_y = (np.array([0, self.height - 1]) - self.cy) / self.fy
        rd = np.hypot(corners_x[:, None], corners_y[None, :]).max()
        r_fold = fold_radius(self.k1, self.k2)
        if math.isfinite(r_fold) and rd >= r_fold * radial_factor(r_fold**2, self.k1, self.k2):
            raise ValueError(f"lens k1={self.k1}, k2={self.k2} folds over inside the image "
                             f"(corner radius {rd:.4g} in normalized coordinates)")

    replace = replace

    @classmethod
    def from_fov(cls, *, vfov_deg=60.0, width=640, height=480, lens="Pinhole", k1=None,
                 k2=None, fps=120.0, t_f=0.0, t_e=0.0, **kwargs):
        """A camera with square pixels, centred principal point and ``t_r`` derived from
        ``fps``, ``t_f`` and ``t_e``; ``lens`` names a :data:`LENS_PRESETS` entry unless
        ``k1``/``k2`` are given."""
        if lens not in LENS_PRESETS:
            raise ValueError(f"lens must be one of {', '.join(LENS_PRESETS)}, not {lens!r}")
        k1 = LENS_PRESETS[lens][0] if k1 is None else k1
        k2 = LENS_PRESETS[lens][1] if k2 is None else k2
        check_number("fps", fps, 0, low_open=True)
        readout = 1.0 / fps - t_f - t_e
        if readout <= 0:
            raise ValueError(f"infeasible timing: t_f + t_e = {t_f + t_e:.9g} s leaves no "
                             f"readout time in 1/fps = {1 / fps:.9g} s (fps, t_f, t_e)")
        f = focal_for_vfov(vfov_deg, height, k1, k2)
        return cls(width=width, height=height, fx=f, fy=f, cx=(width - 1) / 2,
                   cy=(height - 1) / 2, k1=k1, k2=k2, fps=fps, t_r=readout / height,
                   t_f=t_f, t_e=t_e, **kwargs)

    def to_dict(self):
        """Plain-data form (rig config files and dataset metadata use it)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["rotation"] = [list(row) for row in self.rotation]
        out["position"] = list(self.position)
        return out

    # --- geometry ------------------------------------------------------------------

    @property
    def K(self):
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])

    @property
    def R(self):
        """Camera-to-rig rotation (3×3 array)."""
        return np.array(self.rotation)

    @property
    def c(self):
        """Camera centre in the rig frame (3-array)."""
        return np.array(self.position)

    def pixel_to_normalized(self, px, py):
        """Undistorted normalized coordinates (x/z, y/z) of pixel positions."""
        return undistort((np.asarray(px) - self.cx) / self.fx,
                         (np.asarray(py) - self.cy) / self.fy, self.k1, self.k2)

    def normalized_to_pixel(self, xu, yu):
        """Pixel positions of undistorted normalized coordinates."""
        xd, yd = distort(np.asarray(xu, dtype=float), np.asarray(yu, dtype=float),
                         self.k1, self.k2)
        return xd * self.fx + self.cx, yd * self.fy + self.cy

    def project(self, points_cam):
        """Pixel positions (..., 2) of points (..., 3) in camera coordinates."""
        p = np.asarray(points_cam, dtype=float)
        px, py = self.normalized_to_pixel(p[..., 0] / p[..., 2], p[..., 1] / p[..., 2])
        return np.stack([px, py], axis=-1)

    @cached_property
    def rays(self):
        """Ray of every pixel in camera coordinates, scaled to z = 1: float64 (H, W, 3)."""
        xs, ys = np.meshgrid(np.arange(self.width, dtype=float),
                             np.arange(self.height, dtype=float))
        xu, yu = self.pixel_to_normalized(xs, ys)
        return np.stack([xu, yu, np.ones_like(xu)], axis=-1)

    @cached_property
    def pixel_pitch(self):
        """Largest spacing, on the z = 1 plane, between a pixel's ray and its neighbours'
        (H, W): the lens stretches undistorted space by 1/(dr_d/dr_u) radially and by
        r_u/r_d tangentially."""
        r2 = np.square(self.rays[..., 0]) + np.square(self.rays[..., 1])
        radial = 1.0 / (1 + r2 * (3 * self.k1 + 5 * self.k2 * r2))
        tangential = 1.0 / radial_factor(r2, self.k1, self.k2)
        return np.maximum(radial, tangential) / min(self.fx, self.fy)

    # --- timing --------------------------------------------------------------------

    def row_times(self, frames, jitter=0.0):
        """Exposure start of every row: ``τ0 + jitter + y·t_r + i/fps``, shape (F, H).

        ``frames`` are frame indices ``i``; ``jitter`` (scalar or one per frame) is the
        frame's trigger error in seconds.
        """
        frames = np.atleast_1d(np.asarray(frames, dtype=float))
        start = self.trigger_offset + frames / self.fps + np.broadcast_to(jitter, frames.shape)
        return start[:, None] + np.arange(self.height) * self.t_r

    def frame_count(self, duration):
        """Frames whose start ``τ0 + i/fps`` lies in ``[0, duration)``."""
        return max(0, math.ceil((duration - self.trigger_offset) * self.fps - 1e-9))

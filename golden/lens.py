"""Brown radial lens distortion with two terms and its numerical inverse.

On normalized image coordinates, ``x_d = x_u (1 + k1 r² + k2 r⁴)`` with ``r² = x_u² + y_u²``
(DESIGN.md §1, CVPR 2018 eq. 5). The renderer needs the inverse for every pixel (distorted
pixel → undistorted ray); it is solved on the radius by safeguarded Newton iteration to
machine precision, so a round trip is exact to ~1e-12 px rather than the ~1e-3 px of the
usual fixed-point iteration.
"""

import math

import numpy as np

__all__ = ["LENS_PRESETS", "radial_factor", "distort", "undistort", "fold_radius"]

#: (k1, k2) of the lenses in CVPR 2018 §4.4 (real: OV5647, GoPro4, Zed; simulated:
#: SCam1, SCam2, Pinhole).
LENS_PRESETS = {
    "Pinhole": (0.0, 0.0),
    "OV5647": (-0.31, 0.083),
    "GoPro4": (-0.27, 0.11),
    "Zed": (-0.17, 0.023),
    "SCam1": (0.15, 0.05),
    "SCam2": (0.05, 0.05),
}


def radial_factor(r2, k1, k2):
    """``1 + k1 r² + k2 r⁴`` for squared undistorted radii ``r2``."""
    return 1.0 + r2 * (k1 + k2 * r2)


def distort(xu, yu, k1, k2):
    """Distorted normalized coordinates of undistorted ones."""
    factor = radial_factor(np.square(xu) + np.square(yu), k1, k2)
    return xu * factor, yu * factor


def fold_radius(k1, k2):
    """Largest undistorted radius up to which ``r_d(r_u)`` increases (inf if it always does).

    Beyond it the lens would fold the image over itself and has no inverse.
    """
    # d r_d / d r_u = 1 + 3 k1 r² + 5 k2 r⁴; its smallest positive root in r².
    roots = np.roots([5 * k2, 3 * k1, 1.0]) if k2 != 0 else (
        np.array([-1 / (3 * k1)]) if k1 != 0 else np.array([]))
    real = [r.real for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0]
    return math.sqrt(min(real)) if real else math.inf


def undistort(xd, yd, k1, k2, max_iter=60):
    """Undistorted normalized coordinates of distorted ones (inverse of :func:`distort`).

    Raises
    ------
    ValueError
        If a point lies beyond the radius where the lens folds over (no inverse).
    """
    xd, yd = np.asarray(xd, dtype=float), np.asarray(yd, dtype=float)
    rd = np.hypot(xd, yd)
    if k1 == 0 and k2 == 0:
        return xd.copy(), yd.copy()
    r_fold = fold_radius(k1, k2)
    rd_max = r_fold * radial_factor(r_fold**2, k1, k2) if math.isfinite(r_fold) else math.inf
    if np.any(rd > rd_max):
        raise ValueError(f"lens (k1={k1}, k2={k2}) folds over at distorted radius "
                         f"{rd_max:.6g}; points up to radius {rd.max():.6g} have no inverse")
    lo = np.zeros_like(rd)
    hi = np.full_like(rd, r_fold if math.isfinite(r_fold) else max(1.0, 4 * rd.max()))
    if not math.isfinite(r_fold):  # grow the bracket until it holds every root
        while np.any(hi * radial_factor(hi**2, k1, k2) < rd):
            hi *= 2
    r = np.clip(rd, lo, hi)
    for _ in range(max_iter):
        r2 = r * r
        g = r * radial_factor(r2, k1, k2) - rd
        lo = np.where(g < 0, r, lo)
        hi = np.where(g > 0, r, hi)
        step = g / (1 + r2 * (3 * k1 + 5 * k2 * r2))
        new = r - step
        outside = ~((new > lo) & (new < hi))
        new = np.where(outside, 0.5 * (lo + hi), new)
        if np.all(np.abs(new - r) <= 1e-15 * np.maximum(1.0, r)):
            r = new
            break
        r = new
    scale = np.divide(r, rd, out=np.ones_like(rd), where=rd > 0)
    return xd * scale, yd * scale

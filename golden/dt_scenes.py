"""The project's synthetic depth-upsampling set for the domain-transform solver.

Each scene is a colour guide image and its true depth (disparity-like units, 0..255):
a slanted background plane with a handful of objects in front (ellipses and rotated
rectangles, each at its own depth, with an optional slant), coloured and textured so
that the guide has both true edges (object outlines) and false ones (texture and
painted patches that have no depth edge). The low-resolution observation is the depth
averaged over ``factor x factor`` blocks plus Gaussian noise; :func:`bicubic_target`
brings it back to full resolution, which is the solver's target and the baseline it is
measured against.

Everything is seeded (``numpy.random.default_rng(seed)``): the same seed gives the same
scene on every machine.
"""

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Scene", "make_scene", "make_set", "downsample", "bicubic_target", "rmse"]


@dataclass(frozen=True)
class Scene:
    """A guide image with its true depth.

    Members
    -------
    guide : uint8 array (H, W, 3)
        Colour image (BGR, as OpenCV writes it).
    depth : float64 array (H, W)
        True depth, 0..255.
    """
    guide: np.ndarray
    depth: np.ndarray


def _grid(height, width):
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    return yy / height, xx / width


def _object_mask(kind, yy, xx, rng):
    cy, cx = rng.uniform(0.15, 0.85, size=2)
    ry, rx = rng.uniform(0.08, 0.3, size=2)
    if kind == "ellipse":
        return ((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 <= 1.0
    angle = rng.uniform(0.0, np.pi)
    u = (xx - cx) * np.cos(angle) + (yy - cy) * np.sin(angle)
    v = -(xx - cx) * np.sin(angle) + (yy - cy) * np.cos(angle)
    return (np.abs(u) <= rx) & (np.abs(v) <= ry)


def _texture(yy, xx, rng, strength):
    """Stripes and smooth noise: guide edges with no depth edge behind them."""
    freq = rng.uniform(8.0, 30.0)
    angle = rng.uniform(0.0, np.pi)
    stripes = np.sin(2 * np.pi * freq * (xx * np.cos(angle) + yy * np.sin(angle)))
    return strength * (stripes > 0.6)[..., None] * rng.uniform(-1, 1, size=3)


def make_scene(height, width, seed, *, objects=5, slanted=True, textured=True, contrast=1.0):
    """One seeded scene; ``slanted=False`` gives piecewise-constant depth.

    ``contrast`` < 1 mixes each object's colour with what lies behind it (a depth edge
    with a weak colour edge, as in real scenes); the random draws are the same.
    """
    rng = np.random.default_rng(seed)
    yy, xx = _grid(height, width)
    tilt = rng.uniform(-40, 40, size=2) if slanted else np.zeros(2)
    depth = rng.uniform(30, 80) + tilt[0] * yy + tilt[1] * xx
    colour = np.empty((height, width, 3))
    colour[...] = rng.uniform(40, 215, size=3)
    if textured:
        colour += _texture(yy, xx, rng, 35.0)
    for k in range(objects):
        mask = _object_mask("ellipse" if k % 2 == 0 else "rect", yy, xx, rng)
        slope = rng.uniform(-30, 30, size=2) if slanted else np.zeros(2)
        plane = rng.uniform(90, 230) + slope[0] * (yy - yy[mask].mean()) + slope[1] * (xx - xx[mask].mean())
        depth = np.where(mask, plane, depth)
        fill = rng.uniform(20, 235, size=3)
        if textured and rng.random() < 0.6:
            fill = fill + _texture(yy, xx, rng, 30.0)
        colour = np.where(mask[..., None], contrast * fill + (1 - contrast) * colour, colour)
    if textured:  # painted patches: colour edges on a smooth surface
        for _ in range(2):
            patch = _object_mask("rect", yy, xx, rng)
            colour = np.where(patch[..., None], colour + rng.uniform(-60, 60, size=3), colour)
    colour += rng.normal(0.0, 2.0, size=colour.shape)
    guide = np.clip(np.rint(colour), 0, 255).astype(np.uint8)
    return Scene(guide=guide, depth=np.clip(depth, 0.0, 255.0))


def make_set(height=384, width=512, count=4, seed=2019):
    """The benchmark's scenes: ``count`` seeded scenes of ``height x width``."""
    return [make_scene(height, width, seed + k) for k in range(count)]


def downsample(depth, factor, noise, seed):
    """Block-average ``depth`` by ``factor`` and add Gaussian noise of std ``noise``."""
    height, width = depth.shape
    if height % factor or width % factor:
        raise ValueError(f"factor must divide the image size {depth.shape}, not {factor}")
    low = depth.reshape(height // factor, factor, width // factor, factor).mean(axis=(1, 3))
    return low + np.random.default_rng(seed).normal(0.0, noise, size=low.shape)


def bicubic_target(low, factor):
    """Bicubic upsampling by ``factor`` (OpenCV): the solver's target and the baseline."""
    height, width = low.shape
    return cv2.resize(low, (width * factor, height * factor), interpolation=cv2.INTER_CUBIC)


def rmse(estimate, truth):
    return float(np.sqrt(np.mean((np.asarray(estimate) - np.asarray(truth)) ** 2)))

"""The noisy depth super-resolution benchmark of the FBS and DTS papers, and its synthetic twin.

Real data: one scene (Middlebury "Art") of the benchmark used by Barron & Poole (ECCV
2016) and Bapat & Frahm (CVPR 2019): a colour guide, a noisy low-resolution disparity at
2x, 4x, 8x and 16x, its bicubic upsampling (the target), the benchmark's confidence and
the FBS result, all at full size. :func:`load_dev` reads it from :func:`data_dir`
(``$ROWTRACK_DSR_DEV`` or ``../shared/data/dsr_dev`` next to the repository). Protocol:
results on the 8-bit disparity scale, RMSE against the ground truth over the whole image,
geometric mean over the factors.

Synthetic twin (:func:`synthetic_scenes`, :func:`degrade`): the project's synthetic
scenes (:mod:`golden.dt_scenes`) made to look like real data, with the benchmark's
degradation as measured on the development scene:

* the low-resolution disparity is the ``f x f`` block average (it fits the dev scene's
  input better than point sampling or a bicubic/bilinear decimation);
* noise is Gaussian with std ``NOISE_KAPPA / disparity`` (depth-dependent: 8.2 at
  disparity 78, 3.4 at 200 on the dev scene), then rounded to 8 bits;
* the target is OpenCV's bicubic upsampling (the benchmark's own differs by < 1.1 RMS);
* the confidence is :func:`benchmark_confidence`, the benchmark's pattern.

Methods compared (:data:`METHODS`): the bicubic target, an FBS-like solver in a 3-D
grey bilateral grid (:func:`grid_solver`), DTS with wide colour edges (``sigma_r`` 0.2,
L1, no target channel: the edge settings of the earlier defaults), DTS with the
per-factor rule but colour edges only, and DTS with the per-factor rule (the default).
"""

import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .dt import _count, _positive
from .dts import DtsParams, dts

__all__ = ["FACTORS", "NOISE_KAPPA", "DATA_ENV", "DsrCase", "data_dir", "load_dev",
           "benchmark_confidence", "degrade", "synthetic_scenes", "synthetic_cases",
           "grid_solver", "METHODS",
           "run_method", "kendall_tau", "rmse", "geomean"]

#: Upsampling factors of the benchmark (file index k: factor 2**k).
FACTORS = (2, 4, 8, 16)
#: Noise std times disparity on the 8-bit scale, measured on the dev scene's 2x and 8x
#: inputs against the block-averaged ground truth in flat areas (6.5 ... 6.8 x 100).
NOISE_KAPPA = 660.0
#: Disparities below this get the noise of this one in the synthetic twin (the dev
#: scene's nearest-to-infinity surface is at 66).
MIN_DISPARITY = 64.0
#: Std of the benchmark's confidence bump, in low-resolution pixels.
CONFIDENCE_SIGMA = 0.25
#: Colour contrast of the twin's objects against their background (1: the plain set).
GUIDE_CONTRAST = 0.5
#: Blur of the twin's guide, pixels.
GUIDE_BLUR = 1.0
#: Std of the twin's multi-scale guide texture, LSB.
GUIDE_TEXTURE = 8.0
#: The twin's disparities span the dev scene's ground truth range.
DISPARITY_RANGE = (66.0, 217.0)
#: Environment variable naming the development data directory.
DATA_ENV = "ROWTRACK_DSR_DEV"


@dataclass(frozen=True)
class DsrCase:
    """One factor of one scene, everything at full resolution.

    Members
    -------
    factor : int
    guide : float64 (H, W, 3), colour in [0, 1]
    target : float64 (H, W), bicubic upsampling on the 8-bit disparity scale
    confidence : float64 (H, W), in [0, 1]
    truth : float64 (H, W), 8-bit disparity scale
    reference : float64 (H, W) or None, the FBS result where the benchmark has one
    """
    factor: int
    guide: np.ndarray
    target: np.ndarray
    confidence: np.ndarray
    truth: np.ndarray
    reference: np.ndarray | None = None


def data_dir():
    """``$ROWTRACK_DSR_DEV``, else ``shared/data/dsr_dev`` beside the repository."""
    if os.environ.get(DATA_ENV):
        return Path(os.environ[DATA_ENV])
    return Path(__file__).resolve().parents[2] / "shared" / "data" / "dsr_dev"


def _read(path, scale):
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise FileNotFoundError(f"{path} is missing or unreadable")
    return image.astype(np.float64) * scale


def load_dev(directory=None, *, shrink=1):
    """The development scene's cases for every factor in :data:`FACTORS`.

    ``shrink`` > 1 keeps the top-left ``1/shrink`` of each side (a crop, trimmed to a
    multiple of 16 pixels, so the factors and the noise keep their meaning), for quick
    tests.

    Raises
    ------
    FileNotFoundError
        If the directory or a file is missing; the message names the directory and
        :data:`DATA_ENV`.
    """
    directory = Path(directory) if directory is not None else data_dir()
    scene = directory / "art_big"
    if not scene.is_dir():
        raise FileNotFoundError(f"no development scene in {str(directory)!r} (set {DATA_ENV} "
                                f"to the directory holding art_big/)")
    shrink = _count("shrink", shrink)
    guide = _read(scene / "guide.png", 1 / 255)
    truth = _read(scene / "ground_truth.png", 1.0)
    h, w = truth.shape
    crop = (slice(0, h // shrink // 16 * 16), slice(0, w // shrink // 16 * 16))
    cases = []
    for k, factor in enumerate(FACTORS, start=1):
        target, confidence, fbs = (_read(scene / f"{name}_{k}_n.png", s) for name, s in
                                   (("bicubic", 255 / 65535), ("confidence", 1 / 65535),
                                    ("fbs", 255 / 65535)))
        cases.append(DsrCase(factor, guide[crop], target[crop], confidence[crop], truth[crop],
                             fbs[crop]))
    return cases


def benchmark_confidence(shape, factor):
    """The benchmark's confidence: a separable Gaussian bump (std ``CONFIDENCE_SIGMA``
    low-resolution pixels) around every low-resolution pixel's centre; constant
    ``exp(-1)`` at 2x, 1 at the centres at 4x and up (as the dev scene's files)."""
    factor = _count("factor", factor, minimum=2)

    def profile(n):
        offset = (np.arange(n) % factor + 0.5) / factor - 0.5
        return np.exp(-offset ** 2 / (2 * CONFIDENCE_SIGMA ** 2))

    return profile(shape[0])[:, None] * profile(shape[1])[None, :]


def degrade(depth, factor, seed):
    """The benchmark's degradation of a true disparity map (8-bit scale).

    Returns ``(target, confidence)``: the bicubic upsampling of the block-averaged,
    depth-dependently noisy, 8-bit rounded low-resolution disparity, and
    :func:`benchmark_confidence`. ``numpy.random.default_rng(seed)`` draws the noise.
    """
    factor = _count("factor", factor, minimum=2)
    height, width = depth.shape
    if height % factor or width % factor:
        raise ValueError(f"factor must divide the image size {depth.shape}, not {factor}")
    low = depth.reshape(height // factor, factor, width // factor, factor).mean(axis=(1, 3))
    std = NOISE_KAPPA / np.maximum(low, MIN_DISPARITY)
    low = np.clip(np.rint(low + np.random.default_rng(seed).normal(size=low.shape) * std), 0, 255)
    target = cv2.resize(low, (width, height), interpolation=cv2.INTER_CUBIC)
    return target, benchmark_confidence(depth.shape, factor)


def _fractal(shape, rng, octaves=6):
    """Unit-std colour noise with energy at every scale (sum of blurred white noises)."""
    out = np.zeros((*shape, 3))
    for octave in range(octaves):
        layer = cv2.GaussianBlur(rng.normal(size=(*shape, 3)), (0, 0), 2.0 ** octave)
        out += layer / layer.std()
    return out / out.std()


def synthetic_scenes(count=4, height=384, width=512, seed=2019):
    """The twin's scenes, :func:`golden.dt_scenes.make_scene` made to look like real data:

    * objects at ``GUIDE_CONTRAST`` of their colour contrast against what lies behind
      them (real depth edges often show weakly in colour);
    * multi-scale colour texture of std ``GUIDE_TEXTURE`` LSB (matches the median colour
      step between neighbours of the dev guide, 3.0 LSB, after the blur);
    * the guide blurred by a Gaussian of ``GUIDE_BLUR`` pixels (optics);
    * disparity mapped linearly onto ``DISPARITY_RANGE`` (which sets the noise level).
    """
    from .dt_scenes import Scene, make_scene
    scenes = []
    for k in range(count):
        scene = make_scene(height, width, seed + k, contrast=GUIDE_CONTRAST)
        texture = GUIDE_TEXTURE * _fractal(scene.depth.shape, np.random.default_rng(seed + k))
        guide = cv2.GaussianBlur(scene.guide + texture, (0, 0), GUIDE_BLUR)
        depth = scene.depth - scene.depth.min()
        low, high = DISPARITY_RANGE
        scenes.append(Scene(guide=np.clip(np.rint(guide), 0, 255).astype(np.uint8),
                            depth=low + depth * (high - low) / max(depth.max(), 1e-12)))
    return scenes


def synthetic_cases(scenes, seed=2019):
    """:class:`DsrCase` for every scene and factor (noise seed ``seed + scene index``)."""
    cases = []
    for index, scene in enumerate(scenes):
        for factor in FACTORS:
            target, confidence = degrade(scene.depth, factor, seed + index)
            cases.append(DsrCase(factor, scene.guide / 255.0, target, confidence, scene.depth))
    return cases


def grid_solver(target, guide, confidence, *, sigma_xy, sigma_l, lam, iterations=60):
    """FBS-like solver in a 3-D bilateral grid (x, y, luma), as Mazumdar et al. (2017).

    Pixels are splatted with trilinear weights to a grid with spacing ``sigma_xy``
    pixels and ``sigma_l`` luma (luma in [0, 1]); on the grid, Jacobi iterations minimise
    ``lam sum n (y - B y)**2 + sum w (y - t_grid)**2`` (``n``: splatted pixel mass, ``w``:
    splatted confidence, ``B``: the mass-normalised ``[1, 2, 1]`` blur along each axis);
    the result is sliced back at the pixels with the same weights.
    """
    sigma_xy, sigma_l, lam = (_positive(n, v) for n, v in
                              (("sigma_xy", sigma_xy), ("sigma_l", sigma_l), ("lam", lam)))
    iterations = _count("iterations", iterations)
    luma = cv2.cvtColor(np.asarray(guide, np.float32), cv2.COLOR_BGR2GRAY).astype(np.float64)
    yy, xx = np.mgrid[0:target.shape[0], 0:target.shape[1]]
    position = [yy.ravel() / sigma_xy, xx.ravel() / sigma_xy, luma.ravel() / sigma_l]
    base = [np.floor(p).astype(int) for p in position]
    shape = tuple(int(b.max()) + 2 for b in base)
    corners = []                                    # (flat vertex index, weight) x 8
    for offsets in np.ndindex(2, 2, 2):
        index = np.ravel_multi_index([b + o for b, o in zip(base, offsets)], shape)
        weight = np.prod([(p - b) if o else (1 - (p - b))
                          for p, b, o in zip(position, base, offsets)], axis=0)
        corners.append((index, weight))

    def splat(values):
        return sum(np.bincount(i, w * values, math.prod(shape)) for i, w in corners).reshape(shape)

    def blur(v):
        for axis in range(3):
            p = np.pad(v, [(1, 1) if a == axis else (0, 0) for a in range(3)])
            v = (np.take(p, range(0, shape[axis]), axis) + 2 * v
                 + np.take(p, range(2, shape[axis] + 2), axis)) / 4
        return v

    mass = splat(np.ones(target.size))
    weight = splat(confidence.ravel())
    data = splat((confidence * target).ravel())
    norm = np.maximum(blur(mass), 1e-12)
    y = data / np.maximum(weight, 1e-12)
    for _ in range(iterations):
        y = (lam * mass * blur(mass * y) / norm + data) / (lam * mass + weight + 1e-12)
    return sum(w * y.ravel()[i] for i, w in corners).reshape(target.shape)


#: Methods ranked by the benchmarks: name -> function of a :class:`DsrCase`.
METHODS = {
    "bicubic": lambda case: case.target,
    "grid3d": lambda case: grid_solver(case.target, case.guide, case.confidence,
                                       sigma_xy=8.0, sigma_l=8 / 255, lam=1.0),
    "dts_wide": lambda case: dts(case.target, case.guide, case.confidence,
                                 DtsParams(sigma_s=24.0, sigma_r=0.2, lam=2.0, norm="l1",
                                           depth_sigma=None)),
    "dts_colour": lambda case: dts(case.target, case.guide, case.confidence,
                                   DtsParams.for_factor(case.factor, depth_sigma=None)),
    "dts": lambda case: dts(case.target, case.guide, case.confidence,
                            DtsParams.for_factor(case.factor)),
}


def run_method(name, case):
    """``METHODS[name]`` on ``case``."""
    if name not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, not {name!r}")
    return METHODS[name](case)


def kendall_tau(a, b):
    """Kendall's rank agreement of two score lists (1: the same order, -1: reversed)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1 or a.size < 2:
        raise ValueError(f"scores must be two equal-length lists of at least 2, not "
                         f"shapes {a.shape} and {b.shape}")
    i, j = np.triu_indices(a.size, k=1)
    return float(np.mean(np.sign(a[i] - a[j]) * np.sign(b[i] - b[j])))


def rmse(estimate, truth):
    return float(np.sqrt(np.mean((np.asarray(estimate) - np.asarray(truth)) ** 2)))


def geomean(values):
    return float(np.exp(np.mean(np.log(values))))

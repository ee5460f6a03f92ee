"""The domain transform solver (DTS, Bapat & Frahm, CVPR 2019), float64 reference.

Confidence-weighted edge-aware optimization: find ``x`` close to a target ``t`` where
the confidence ``c`` is high and smooth along the guide elsewhere. The cost is

    E(x) = lam/2 sum (x - xbar)**2 + 1/2 sum c rho(x - t)

where ``xbar`` is the edge-aware local mean of ``x`` (a box in the domain transform's
coordinate, :class:`golden.dt.BoxBounds`) and ``rho`` is the square (L2) or the
Charbonnier function ``eps**2 (sqrt(1 + (r/eps)**2) - 1)`` (robust). The solver
alternates a horizontal and a vertical half-step, each with a fresh 1-D box mean, and
sets every pixel to the minimiser of its own terms with ``xbar`` held fixed:

    x <- (lam xbar + w t) / (lam + w),   w = c rho'(x - t) / (x - t)

(``w = c`` for L2; for Charbonnier ``w = c / sqrt(1 + ((x - t)/eps)**2)``, an
iteratively reweighted step). Each update is a convex combination of ``xbar`` and ``t``,
so it is stable for every confidence and every ``lam``.

The data weight is the confidence times ``(t / median t) ** disparity_power``: the
inverse noise variance of a disparity map whose noise std falls as ``1 / t``.

The domain transform's guide is the colour image and, with ``depth_sigma`` set, the
target itself as one more channel: a change of ``depth_sigma`` times the target's robust
range (1st to 99th percentile) counts as much as a colour change of ``sigma_r``, so
smoothing stops at depth edges that the guide does not show. That channel is the target
after an edge-preserving (bilateral, OpenCV) filter with range std ``depth_smoothing``,
so that its noise does not look like edges.

With ``hard_threshold`` set, pixels whose confidence reaches it are pinned to the target
after every half-step (a hard constraint instead of a penalty).
"""

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from .checks import check_number
from .dt import NORMS, BoxBounds, _check_pair, _count, _image, _positive, transformed_coords

__all__ = ["DtsParams", "dts", "target_confidence"]

#: Per-factor rule for depth super-resolution (:meth:`DtsParams.for_factor`): spatial
#: extent ``SIGMA_S_PER_ROOT_FACTOR * sqrt(factor)`` pixels, smoothness weight
#: ``LAM_PER_FACTOR * factor``. Tuned on the development scene (docs/dt/dt.md).
SIGMA_S_PER_ROOT_FACTOR = 16.0
LAM_PER_FACTOR = 5.0 / 3.0
#: Spatial std, pixels, of the bilateral filter behind the target channel.
DEPTH_SMOOTHING_SPACE = 3.0


@dataclass(frozen=True, kw_only=True)
class DtsParams:
    """Settings of :func:`dts`.

    Parameters
    ----------
    sigma_s : float
        Spatial extent of the edge-aware mean, pixels (box radius ``sqrt(3) sigma_s``).
    sigma_r : float
        Range scale of the guide's edges, guide units (guides in [0, 1]).
    lam : float
        Weight of the smoothness term against the data term, > 0.
    iterations : int
        Rounds of one horizontal and one vertical half-step.
    norm : {"l1", "l2"}
        Norm of the guide's change across channels.
    depth_sigma : float or None
        Add the target as a guide channel whose change of ``depth_sigma`` times its
        robust range weighs like a colour change of ``sigma_r``; ``None``: colour only.
    depth_smoothing : float or None
        Range std, target units, of the bilateral filter (spatial std
        ``DEPTH_SMOOTHING_SPACE`` pixels) that smooths the target before it becomes the
        guide channel, so that noise does not look like depth edges; ``None``: the raw
        target. The default, 16, is about 3 noise stds of the benchmark's disparities
        (8-bit scale) at their median.
    disparity_power : float
        The data weight is ``c * (t / median t) ** disparity_power``: for a disparity
        target whose noise std falls as ``1 / t`` (stereo, and the benchmark's noise
        model) 2 weighs every pixel by its inverse noise variance; 0 switches it off.
    robust : float or None
        Charbonnier scale ``eps`` of the data term in target units; ``None`` is L2.
    hard_threshold : float or None
        Confidence at or above which pixels are pinned to the target; ``None``: no pins.

    The defaults are :meth:`for_factor` ``(4)``.
    """
    sigma_s: float = 32.0
    sigma_r: float = 0.08
    lam: float = 4 * LAM_PER_FACTOR
    iterations: int = 15
    norm: str = "l2"
    depth_sigma: float | None = 0.08
    depth_smoothing: float | None = 16.0
    disparity_power: float = 2.0
    robust: float | None = None
    hard_threshold: float | None = None

    def __post_init__(self):
        for name in ("sigma_s", "sigma_r", "lam"):
            _positive(name, getattr(self, name))
        _count("iterations", self.iterations)
        if self.norm not in NORMS:
            raise ValueError(f"norm must be one of {', '.join(NORMS)}, not {self.norm!r}")
        for name in ("depth_sigma", "depth_smoothing", "robust"):
            if getattr(self, name) is not None:
                _positive(name, getattr(self, name))
        check_number("disparity_power", self.disparity_power, 0)
        if self.hard_threshold is not None:
            check_number("hard_threshold", self.hard_threshold, 0, 1, low_open=True)

    replace = replace

    @classmethod
    def for_factor(cls, factor, **changes):
        """Settings for a target upsampled ``factor`` times: ``sigma_s`` grows with
        ``sqrt(factor)`` and ``lam`` with ``factor`` (an interpolated target is worth
        less the further it was stretched); ``changes`` override any field."""
        factor = _positive("factor", factor)
        return cls(**{"sigma_s": SIGMA_S_PER_ROOT_FACTOR * math.sqrt(factor),
                      "lam": LAM_PER_FACTOR * factor, **changes})


def _data_weight(residual, confidence, robust):
    if robust is None:
        return confidence
    return confidence / np.sqrt(1.0 + (residual / robust) ** 2)


def _solve_channel(target, guide, c, params):
    pinned = None if params.hard_threshold is None else c >= params.hard_threshold
    if params.disparity_power:
        median = float(np.median(target))
        if median <= 0:
            raise ValueError(f"disparity_power {params.disparity_power} needs a target with a "
                             f"positive median, not {median}")
        c = c * (np.maximum(target, 0.0) / median) ** params.disparity_power
    if params.depth_sigma is not None:
        low, high = np.percentile(target, [1.0, 99.0])
        scale = params.sigma_r / (params.depth_sigma * max(high - low, 1e-12))
        channel = target if params.depth_smoothing is None else cv2.bilateralFilter(
            target.astype(np.float32), -1, params.depth_smoothing, DEPTH_SMOOTHING_SPACE)
        guide = np.concatenate([guide.reshape(*target.shape, -1), (channel * scale)[..., None]],
                               axis=-1)
    radius = math.sqrt(3.0) * params.sigma_s
    boxes = [BoxBounds(transformed_coords(guide, params.sigma_s, params.sigma_r, axis, params.norm),
                       radius, axis) for axis in (1, 0)]
    x = target.copy()
    for _ in range(params.iterations):
        for box in boxes:
            w = _data_weight(x - target, c, params.robust)
            x = (params.lam * box.mean(x) + w * target) / (params.lam + w)
            if pinned is not None:
                x[pinned] = target[pinned]
    return x


def dts(target, guide, confidence=None, params=DtsParams()):
    """Edge-aware optimization of ``target`` along ``guide``.

    Parameters
    ----------
    target : array (H, W) or (H, W, C)
        Initial solution and data (e.g. an upsampled, noisy depth map), any units;
        channels are solved one by one.
    guide : array (H, W) or (H, W, C)
        Reference image, scaled so that ``params.sigma_r`` is in its units.
    confidence : array (H, W), optional
        Trust in each target pixel, in [0, 1]; default 1 everywhere.
    params : DtsParams

    Returns
    -------
    float64 array shaped like ``target``.
    """
    if not isinstance(params, DtsParams):
        raise TypeError(f"params must be a DtsParams, not {params!r}")
    target, guide = _check_pair(target, guide)
    if confidence is None:
        confidence = np.ones(target.shape[:2])
    confidence = _image("confidence", confidence)
    if confidence.shape != target.shape[:2]:
        raise ValueError(f"confidence must have shape {target.shape[:2]}, not {confidence.shape}")
    if confidence.min() < 0 or confidence.max() > 1:
        raise ValueError("confidence must lie in [0, 1]")
    if target.ndim == 3:
        return np.stack([_solve_channel(target[..., k], guide, confidence, params)
                         for k in range(target.shape[2])], axis=-1)
    return _solve_channel(target, guide, confidence, params)


def target_confidence(target, peak=0.3, edge_scale=0.01):
    """Confidence for an interpolated target when none was measured.

    Interpolation is least reliable across depth edges, where it blurs; this trusts a
    pixel ``peak * exp(-(|grad t| / s)**2)`` with ``s = edge_scale * (max t - min t)``,
    so the solver keeps the target in smooth areas and re-draws edges from the guide.
    (The defaults were chosen on the project's synthetic set, :mod:`golden.dt_scenes`.)
    """
    t = _image("target", target)
    t = t if t.ndim == 2 else t.mean(axis=2)
    check_number("peak", peak, 0, 1, low_open=True)
    scale = _positive("edge_scale", edge_scale) * max(float(t.max() - t.min()), 1e-12)
    gy, gx = np.gradient(t) if min(t.shape) > 1 else (np.zeros_like(t), np.zeros_like(t))
    return peak * np.exp(-(np.hypot(gx, gy) / scale) ** 2)

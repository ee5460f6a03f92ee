"""The domain transform solver (DTS, Bapat & Frahm, CVPR 2019), float64 reference.

Confidence-weighted edge-aware optimization: find ``x`` close to a target ``t`` where
the confidence ``c`` is high and smooth along the guide elsewhere. The cost is

    E(x) = lam/2 sum (x - xbar)**2 + 1/2 sum c rho(x - t)

where ``xbar`` is the edge-aware local mean of ``x`` (a box in the domain transform's
coordinate, :class:`golden.dt.BoxBounds`) and ``rho`` is the square (L2) or the
Charbonnier function ``eps**2 (sqrt(1 + (r/eps)**2) - 1)`` (robust). Gradient descent
alternates a horizontal and a vertical half-step, each with a fresh 1-D box mean:

    x <- x - alpha (lam (x - xbar) + 1/2 g_data),   g_data = c rho'(x - t)

Treating ``xbar`` as fixed during a step makes each half-step cheap (two prefix sums);
with ``alpha = lam = 0.99`` a pixel without confidence moves almost all the way to its
edge-aware mean, so information spreads along each line by a box radius per half-step,
and stops at guide edges. The step is stable for confidences in ``[0, 1]``: the box
mean's most negative frequency response is about -0.22, which keeps the update's
gain inside the unit circle.

With ``hard_threshold`` set, pixels whose confidence reaches it are pinned to the target
after every half-step (a hard constraint instead of a penalty).
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from .dt import NORMS, BoxBounds, _check_pair, _count, _image, _positive, transformed_coords

__all__ = ["DtsParams", "dts", "target_confidence"]


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
        Weight of the smoothness term, > 0.
    alpha : float
        Gradient step, > 0.
    iterations : int
        Rounds of one horizontal and one vertical half-step.
    norm : {"l1", "l2"}
        Norm of the guide's change across channels.
    robust : float or None
        Charbonnier scale ``eps`` of the data term in target units; ``None`` is L2.
    hard_threshold : float or None
        Confidence at or above which pixels are pinned to the target; ``None``: no pins.
    """
    sigma_s: float = 24.0
    sigma_r: float = 0.2
    lam: float = 0.99
    alpha: float = 0.99
    iterations: int = 15
    norm: str = "l1"
    robust: float | None = None
    hard_threshold: float | None = None

    def __post_init__(self):
        for name in ("sigma_s", "sigma_r", "lam", "alpha"):
            _positive(name, getattr(self, name))
        _count("iterations", self.iterations)
        if self.norm not in NORMS:
            raise ValueError(f"norm must be one of {', '.join(NORMS)}, not {self.norm!r}")
        if self.robust is not None:
            _positive("robust", self.robust)
        if self.hard_threshold is not None:
            _positive("hard_threshold", self.hard_threshold)
            if self.hard_threshold > 1:
                raise ValueError(f"hard_threshold must be in (0, 1], not {self.hard_threshold}")

    replace = replace


def _data_gradient(residual, confidence, robust):
    if robust is None:
        return confidence * residual
    return confidence * residual / np.sqrt(1.0 + (residual / robust) ** 2)


def dts(target, guide, confidence=None, params=DtsParams()):
    """Edge-aware optimization of ``target`` along ``guide``.

    Parameters
    ----------
    target : array (H, W) or (H, W, C)
        Initial solution and data (e.g. an upsampled, noisy depth map), any units.
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
    c = confidence[..., None] if target.ndim == 3 else confidence
    pinned = None if params.hard_threshold is None else np.broadcast_to(
        c >= params.hard_threshold, target.shape)

    radius = math.sqrt(3.0) * params.sigma_s
    boxes = [BoxBounds(transformed_coords(guide, params.sigma_s, params.sigma_r, axis, params.norm),
                       radius, axis) for axis in (1, 0)]
    x = target.copy()
    for _ in range(params.iterations):
        for box in boxes:
            smooth = x - box.mean(x)
            data = _data_gradient(x - target, c, params.robust)
            x = x - params.alpha * (params.lam * smooth + 0.5 * data)
            if pinned is not None:
                x[pinned] = target[pinned]
    return x


def target_confidence(target, peak=0.3, edge_scale=0.01):
    """Confidence for an interpolated target when none was measured.

    Interpolation is least reliable across depth edges, where it blurs; this trusts a
    pixel ``peak * exp(-(|grad t| / s)**2)`` with ``s = edge_scale * (max t - min t)``,
    so the solver keeps the target in smooth areas and re-draws edges from the guide.
    (The defaults were chosen on the project's synthetic set, :mod:`golden.dt_scenes`.)
    """
    t = _image("target", target)
    t = t if t.ndim == 2 else t.mean(axis=2)
    peak = _positive("peak", peak)
    if peak > 1:
        raise ValueError(f"peak must be in (0, 1], not {peak}")
    scale = _positive("edge_scale", edge_scale) * max(float(t.max() - t.min()), 1e-12)
    gy, gx = np.gradient(t) if min(t.shape) > 1 else (np.zeros_like(t), np.zeros_like(t))
    return peak * np.exp(-(np.hypot(gx, gy) / scale) ** 2)

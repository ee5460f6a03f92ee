"""Domain-transform edge-aware filters (Gastal & Oliveira 2011), float64 reference.

The domain transform maps each scanline of a guide image to a 1-D coordinate whose
steps grow with the guide's change: between neighbours ``n-1`` and ``n``

    d[n] = 1 + sigma_s / sigma_r * ||I[n] - I[n-1]||

with the L1 norm over channels (the paper) or the L2 norm (the form the thesis code also
uses). Filtering in that coordinate with an ordinary 1-D kernel gives an edge-aware
filter of the original image. Two kernels are provided:

* :func:`recursive_filter` (RF): the first-order recursion
  ``J[n] = (1 - a**d[n]) I[n] + a**d[n] J[n-1]`` with ``a = exp(-sqrt(2) / sigma_H)``,
  run causally and then anti-causally;
* :func:`normalized_convolution` (NC): a box of radius ``sqrt(3) sigma_H`` in the
  transformed coordinate.

Both alternate horizontal and vertical passes for ``iterations`` rounds with the
shrinking schedule ``sigma_H,i = sigma_s sqrt(3) 2**(N-i) / sqrt(4**N - 1)``
(:func:`sigma_schedule`), so that the variances of the rounds add up to ``sigma_s**2``.

The vertical anti-causal RF pass can be limited to a window of ``L`` lines
(``vertical_window``): row ``y`` then starts its backward recursion at row
``y + L - 1``, which is what a streaming implementation with ``L`` line buffers computes
(:mod:`hdl.dt.filter`); the error against the exact pass decays like ``a**L``.

Arrays are ``(H, W)`` or ``(H, W, C)``; the guide's units are those of ``sigma_r``.
"""

import math

import numpy as np

from .checks import check_int, check_number

__all__ = ["NORMS", "check_parameters", "sigma_schedule", "domain_derivative", "rf_weights", "rf_causal",
           "rf_anticausal", "rf_anticausal_window", "recursive_filter", "BoxBounds",
           "transformed_coords", "normalized_convolution"]

#: Norms accepted for the guide's change between neighbours.
NORMS = ("l1", "l2")


def _positive(name, value, allow_inf=False):
    """``value`` as a float, checked (:func:`golden.checks.check_number`) to be above 0."""
    check_number(name, value, 0, low_open=True, finite=not allow_inf)
    return float(value)


def _count(name, value, minimum=1):
    """``value`` as an int, checked (:func:`golden.checks.check_int`) to be ``minimum`` or
    more."""
    check_int(name, value, minimum)
    return int(value)


def _image(name, value):
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim not in (2, 3) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(f"{name} must be an (H, W) or (H, W, C) array, not shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def _check_pair(image, guide):
    image = _image("image", image)
    guide = image if guide is None else _image("guide", guide)
    if guide.shape[:2] != image.shape[:2]:
        raise ValueError(f"guide must have the image's height and width {image.shape[:2]}, "
                         f"not {guide.shape[:2]}")
    return image, guide


def check_parameters(sigma_s, sigma_r, iterations, norm):
    """Raise TypeError/ValueError, naming the parameter, for settings no filter accepts."""
    _positive("sigma_s", sigma_s)
    _positive("sigma_r", sigma_r, allow_inf=True)
    _count("iterations", iterations)
    if norm not in NORMS:
        raise ValueError(f"norm must be one of {', '.join(NORMS)}, not {norm!r}")


def sigma_schedule(sigma_s, iterations):
    """Per-round ``sigma_H`` so that ``iterations`` rounds have total spread ``sigma_s``."""
    sigma_s = _positive("sigma_s", sigma_s)
    n = _count("iterations", iterations)
    return [sigma_s * math.sqrt(3.0) * 2.0 ** (n - i) / math.sqrt(4.0 ** n - 1.0)
            for i in range(1, n + 1)]


def domain_derivative(guide, sigma_s, sigma_r, axis, norm="l1"):
    """Steps ``d[n]`` of the transformed coordinate along ``axis`` (0: down, 1: across).

    Entry 0 along the axis starts a line and is 0, so ``cumsum`` gives the transformed
    coordinate ``ct`` with ``ct[0] = 0``. ``sigma_r`` may be ``inf`` (no edge awareness:
    every step is 1).
    """
    sigma_s = _positive("sigma_s", sigma_s)
    sigma_r = _positive("sigma_r", sigma_r, allow_inf=True)
    if norm not in NORMS:
        raise ValueError(f"norm must be one of {', '.join(NORMS)}, not {norm!r}")
    if axis not in (0, 1):
        raise ValueError(f"axis must be 0 or 1, not {axis!r}")
    g = np.asarray(guide, dtype=np.float64)
    g = g[..., None] if g.ndim == 2 else g
    diff = np.diff(g, axis=axis)
    change = np.abs(diff).sum(axis=-1) if norm == "l1" else np.sqrt((diff ** 2).sum(axis=-1))
    steps = 1.0 + (sigma_s / sigma_r) * change
    pad = [(1, 0), (0, 0)] if axis == 0 else [(0, 0), (1, 0)]
    return np.pad(steps, pad)


def rf_weights(steps, sigma_h):
    """Feedback weights ``a**d`` of the recursive filter; 0 where a line starts."""
    a = math.exp(-math.sqrt(2.0) / _positive("sigma_h", sigma_h))
    weights = a ** steps
    weights[steps == 0] = 0.0
    return weights


def _along(values, axis):
    """View with the filtering axis as axis 1 (so loops run over it, vectorized across)."""
    return values if axis == 1 else np.swapaxes(values, 0, 1)


def _expand(weights, values):
    return weights[..., None] if values.ndim == 3 else weights


def rf_causal(values, weights, axis):
    """``J[n] = J[n] + w[n] (J[n-1] - J[n])`` along ``axis``, in place on a copy."""
    out = np.array(values, dtype=np.float64)
    f, w = _along(out, axis), _along(_expand(weights, out), axis)
    for n in range(1, f.shape[1]):
        f[:, n] += w[:, n] * (f[:, n - 1] - f[:, n])
    return out


def rf_anticausal(values, weights, axis):
    """``J[n] = J[n] + w[n+1] (J[n+1] - J[n])`` along ``axis``, from the far end."""
    out = np.array(values, dtype=np.float64)
    f, w = _along(out, axis), _along(_expand(weights, out), axis)
    for n in range(f.shape[1] - 2, -1, -1):
        f[:, n] += w[:, n + 1] * (f[:, n + 1] - f[:, n])
    return out


def rf_anticausal_window(values, weights, axis, window):
    """The anti-causal pass with each output's recursion limited to ``window`` lines.

    Output ``n`` starts at line ``min(n + window - 1, last)`` with the boundary value
    ``J = values`` there and recurses back to ``n``; ``window`` at least the line count
    is the exact pass (:func:`rf_anticausal`), ``window = 1`` leaves the values as they are.
    """
    window = _count("window", window)
    v = np.asarray(values, dtype=np.float64)
    length = _along(v, axis).shape[1]
    if window >= length:
        return rf_anticausal(v, weights, axis)
    f, w = _along(v, axis), _along(_expand(weights, v), axis)
    idx = np.arange(length)
    acc = f[:, np.minimum(idx + window - 1, length - 1)].copy()
    for t in range(window - 1, 0, -1):
        n = idx[idx + t <= length - 1]          # outputs whose window reaches line n + t
        q = n + t - 1
        acc[:, n] = f[:, q] + w[:, q + 1] * (acc[:, n] - f[:, q])
    out = np.empty_like(v)
    _along(out, axis)[...] = acc
    return out


def recursive_filter(image, guide=None, *, sigma_s, sigma_r, iterations=3, norm="l1",
                     vertical_window=None):
    """Domain-transform recursive filter (RF) of ``image`` with edges from ``guide``.

    Parameters
    ----------
    image : array (H, W) or (H, W, C)
        Values to filter.
    guide : array (H, W) or (H, W, C), optional
        Edges come from here (default: the image itself).
    sigma_s : float
        Spatial standard deviation, pixels.
    sigma_r : float
        Range standard deviation, guide units; ``inf`` gives the plain exponential filter.
    iterations : int
        Rounds of horizontal + vertical passes with :func:`sigma_schedule`.
    norm : {"l1", "l2"}
        Norm of the guide's change across channels.
    vertical_window : int, optional
        Lines seen by the vertical anti-causal pass (:func:`rf_anticausal_window`);
        ``None`` is the exact pass over the whole frame.
    """
    check_parameters(sigma_s, sigma_r, iterations, norm)
    image, guide = _check_pair(image, guide)
    dx = domain_derivative(guide, sigma_s, sigma_r, axis=1, norm=norm)
    dy = domain_derivative(guide, sigma_s, sigma_r, axis=0, norm=norm)
    out = image
    for sigma_h in sigma_schedule(sigma_s, iterations):
        wx, wy = rf_weights(dx, sigma_h), rf_weights(dy, sigma_h)
        out = rf_anticausal(rf_causal(out, wx, axis=1), wx, axis=1)
        out = rf_causal(out, wy, axis=0)
        out = (rf_anticausal(out, wy, axis=0) if vertical_window is None
               else rf_anticausal_window(out, wy, axis=0, window=vertical_window))
    return out


class BoxBounds:
    """Where every box of radius ``radius`` in the transformed coordinate starts and ends.

    ``lo[l, n]`` and ``hi[l, n]`` bound (half-open) the samples ``m`` of line ``l`` with
    ``|ct[l, m] - ct[l, n]| <= radius``. Found once, they serve every :meth:`mean` over
    the same guide (the solver reuses them in each of its iterations). All lines are
    searched at once: each line is shifted past the previous one's end so one sorted
    array and two ``searchsorted`` calls find every bound.
    """

    def __init__(self, coords, radius, axis):
        radius = _positive("radius", radius)
        if axis not in (0, 1):
            raise ValueError(f"axis must be 0 or 1, not {axis!r}")
        ct = _along(np.asarray(coords, dtype=np.float64), axis)
        lines, length = ct.shape
        gap = ct[:, -1].max() + 2.0 * radius + 1.0
        flat = (ct + gap * np.arange(lines)[:, None]).ravel()
        start = (np.arange(lines) * length)[:, None]
        self.axis = axis
        self.lo = np.searchsorted(flat, flat - radius, side="left").reshape(lines, length) - start
        self.hi = np.searchsorted(flat, flat + radius, side="right").reshape(lines, length) - start
        self.count = (self.hi - self.lo).astype(np.float64)

    def mean(self, values):
        """Box means of ``values`` (same height and width as the coordinates)."""
        v = _along(np.asarray(values, dtype=np.float64), self.axis)
        lo, hi, count = self.lo, self.hi, self.count
        if v.ndim == 3:
            lo = np.broadcast_to(lo[..., None], v.shape)
            hi = np.broadcast_to(hi[..., None], v.shape)
            count = count[..., None]
        sums = np.cumsum(v, axis=1)
        sums = np.concatenate([np.zeros_like(sums[:, :1]), sums], axis=1)
        mean = (np.take_along_axis(sums, hi, axis=1)
                - np.take_along_axis(sums, lo, axis=1)) / count
        out = np.empty(np.shape(values), dtype=np.float64)
        _along(out, self.axis)[...] = mean
        return out


def transformed_coords(guide, sigma_s, sigma_r, axis, norm="l1"):
    """The domain transform ``ct`` along ``axis``: cumulative :func:`domain_derivative`."""
    return np.cumsum(domain_derivative(guide, sigma_s, sigma_r, axis=axis, norm=norm), axis=axis)


def normalized_convolution(image, guide=None, *, sigma_s, sigma_r, iterations=3, norm="l1"):
    """Domain-transform normalized convolution (NC): box filters in the transformed domain.

    Parameters are those of :func:`recursive_filter`; round ``i`` uses a box of radius
    ``sqrt(3) sigma_H,i``.
    """
    check_parameters(sigma_s, sigma_r, iterations, norm)
    image, guide = _check_pair(image, guide)
    ctx = transformed_coords(guide, sigma_s, sigma_r, axis=1, norm=norm)
    cty = transformed_coords(guide, sigma_s, sigma_r, axis=0, norm=norm)
    out = image
    for sigma_h in sigma_schedule(sigma_s, iterations):
        radius = math.sqrt(3.0) * sigma_h
        out = BoxBounds(ctx, radius, axis=1).mean(out)
        out = BoxBounds(cty, radius, axis=0).mean(out)
    return out

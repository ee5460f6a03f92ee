"""Row descriptors and shift matching, in float64: the specification of the hardware's
per-camera measurement engine (``hdl/row_descriptor.py``).

Descriptor (TVCG 2016 §3.3): convolve the row with the second derivative of a Gaussian
and keep the sign, one bit per pixel. Matching: Hamming distance between the current
row's bits and a reference row's bits over integer shifts, the best shift refined to
sub-pixel by a parabola through the three costs around the minimum, and the peak ratio
(second-best / best cost) as confidence.

Conventions shared with the emulator and the HDL
------------------------------------------------
* Kernel: ``g''(u) = (u²/σ⁴ − 1/σ²)·exp(−u²/2σ²)`` sampled at ``u = −R..R`` with
  ``R = ceil(3σ)``, made zero-sum (a constant row gives a zero response) and scaled so
  the largest magnitude is 1.
* Borders: the response is defined only where the whole kernel lies on the row,
  ``x ∈ [R, W − R)``; no padding. Border bits are never compared.
* Bit: ``1`` where the response is ``> 0``, else ``0``.
* Shift ``d``: the current row's content sits ``d`` pixels to the right of where it was
  in the reference, ``cur[x] ≈ ref[x − d]``. ``cost(d) = Σₓ [cur[x] ≠ ref[x − d]]`` over a
  column range that is the same for every ``d`` in the window, so costs are comparable:
  ``x ∈ [R + max(d_max, 0), W − R + min(d_min, 0))``. That range is split into K equal
  segments (the radial formulation's virtual cameras), each matched on its own.
* Argmin: the smallest ``d`` with the lowest cost. Second minimum: the lowest cost at
  ``|d − d*| ≥ 2`` (the minimum's own slopes are not a rival peak).
* Sub-pixel: ``δ = (C₋₁ − C₊₁) / (2 (C₋₁ − 2 C₀ + C₊₁))``; ``δ = 0`` when ``d*`` is on the
  window edge (flagged) or the denominator is zero.
* Peak ratio: ``min((C₂ + κ) / (C₁ + κ), cap)`` with the offset ``κ =
  peak_ratio_offset`` columns; ``cap`` when ``C₁ + κ = 0`` and ``C₂ > 0``, 0 when both
  are 0. Without the offset (κ = 0, the papers' plain ratio) two tiny costs, say 0 and
  2 noise flips at two aliases of a periodic row, read as a perfect peak.
* Textureless: a segment of the current row with fewer than ``min_transitions`` bit
  changes, or (when the caller passes the row's strong columns) fewer than
  ``min_strong`` columns whose response magnitude is at least ``strong_response``, is
  flagged textureless and gets confidence 0. The second test is what catches a flat row
  under sensor noise: its sign bits are random and change all the time, and with short
  segments a random cost curve can show a deep, isolated minimum by chance.
"""

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from .checks import check_int, check_number

__all__ = ["DescriptorParams", "MatchParams", "MatchResult", "CostPeaks", "dog2_kernel",
           "response", "describe", "strength", "hamming_costs", "transitions",
           "strong_counts", "textureless", "cost_peaks", "match", "compare_range",
           "segment_bounds"]


@dataclass(frozen=True, kw_only=True)
class DescriptorParams:
    """Parameters of the row descriptor.

    Parameters
    ----------
    sigma : float
        Standard deviation of the Gaussian, pixels (0.5 to 8).
    strong_response : float
        A column is *strong* where the response magnitude (pixel values through the
        peak-normalized kernel) is at least this; sensor noise of σₙ gives a response of
        about 1.6 σₙ at σ = 2, an edge of contrast h about 1.5 h.
    """
    sigma: float = 2.0
    strong_response: float = 12.0

    def __post_init__(self):
        check_number("sigma", self.sigma, 0.5, 8.0)
        check_number("strong_response", self.strong_response, 0)

    replace = replace

    @property
    def radius(self):
        """Kernel half-width ``R = ceil(3σ)``; the kernel has ``2R + 1`` taps."""
        return math.ceil(3 * self.sigma)


@dataclass(frozen=True, kw_only=True)
class MatchParams:
    """Parameters of the shift matcher.

    Parameters
    ----------
    shift_min, shift_max : int
        Search window relative to the run-time centre (temporal default [−20, 20];
        stereo disparity [10, 70] with centre 0).
    segments : int
        Segments per row (virtual cameras), each giving its own measurement.
    peak_ratio_cap : float
        Upper bound of the peak-ratio confidence.
    peak_ratio_offset : int
        Columns added to both costs of the peak ratio (0: the plain ratio).
    min_transitions : int
        Fewer bit changes than this in a segment of the current row: textureless.
    min_strong : int
        Fewer strong columns than this in a segment of the current row: textureless.
    """
    shift_min: int = -20
    shift_max: int = 20
    segments: int = 1
    peak_ratio_cap: float = 2.0
    peak_ratio_offset: int = 16
    min_transitions: int = 4
    min_strong: int = 16

    def __post_init__(self):
        check_int("shift_min", self.shift_min)
        check_int("shift_max", self.shift_max)
        if self.shift_max - self.shift_min < 2:
            raise ValueError(f"shift window [{self.shift_min}, {self.shift_max}] must hold at "
                             f"least 3 shifts (parabola fit)")
        check_int("segments", self.segments, 1)
        check_int("min_transitions", self.min_transitions, 0)
        check_int("min_strong", self.min_strong, 0)
        check_int("peak_ratio_offset", self.peak_ratio_offset, 0)
        check_number("peak_ratio_cap", self.peak_ratio_cap, 1, low_open=True)

    replace = replace

    @property
    def n_shifts(self):
        return self.shift_max - self.shift_min + 1


#: Matcher preset for the stereo disparity of a camera pair (TVCG 2016).
STEREO_MATCH = MatchParams(shift_min=10, shift_max=70)


def dog2_kernel(params):
    """The float64 second-derivative-of-Gaussian kernel (zero-sum, peak magnitude 1)."""
    r = params.radius
    u = np.arange(-r, r + 1, dtype=np.float64)
    s2 = params.sigma ** 2
    k = (u * u / (s2 * s2) - 1.0 / s2) * np.exp(-u * u / (2 * s2))
    k -= k.mean()
    return k / np.abs(k).max()


def response(rows, params, kernel=None):
    """Filter response on the interior ``[R, W − R)`` of each row; shape ``(..., W − 2R)``.

    ``kernel`` (``2R + 1`` taps) replaces :func:`dog2_kernel`; with integer taps and
    integer rows the response is computed in exact integer arithmetic, which is how the
    emulator applies the hardware's quantized kernel with the same border convention.
    """
    k = dog2_kernel(params) if kernel is None else np.asarray(kernel)
    if k.shape != (2 * params.radius + 1,):
        raise ValueError(f"kernel must have {2 * params.radius + 1} taps, not {k.shape}")
    integer = k.dtype.kind in "iu" and np.asarray(rows).dtype.kind in "iu"
    rows = np.asarray(rows, dtype=np.int64 if integer else np.float64)
    width = rows.shape[-1]
    interior = width - 2 * params.radius
    if interior < 1:
        raise ValueError(f"rows of width {width} are too short for sigma {params.sigma}")
    # correlation with the (symmetric) kernel over the valid part only
    out = np.zeros(rows.shape[:-1] + (interior,), dtype=rows.dtype)
    for j, coeff in enumerate(k):
        out += coeff * rows[..., j:j + interior]
    return out


def describe(rows, params, kernel=None):
    """Descriptor bits of ``rows`` (``(..., W)``), as a bool array of the same shape.

    Border bits (``x < R`` or ``x ≥ W − R``) are ``False`` and never compared.
    ``kernel`` as in :func:`response`.
    """
    rows = np.asarray(rows)
    bits = np.zeros(rows.shape, dtype=bool)
    r = params.radius
    values = response(rows, params, kernel)
    bits[..., r:rows.shape[-1] - r] = values > _rounding_noise(values, rows, params, kernel)
    return bits


#: Relative size of float rounding noise in a response (a few hundred ulps of the sum of
#: |tap × pixel| over the kernel: far below any response a pixel step of 1 gives).
FLOAT_NOISE = 1e-12


def _rounding_noise(values, rows, params, kernel):
    """Largest float rounding error of :func:`response` on ``rows``: a flat stretch's
    exact response is 0 (the kernel's taps sum to zero), but in float it comes out as
    ±1e-14·pixel, which must not set a bit that the hardware's exact integer response
    leaves clear. 0 for exact integer arithmetic."""
    if values.dtype.kind in "iu":
        return 0
    k = dog2_kernel(params) if kernel is None else np.asarray(kernel)
    return FLOAT_NOISE * float(np.abs(k).sum()) * float(np.abs(rows).max(initial=0))


def strength(rows, params, kernel=None, threshold=None):
    """Strong columns of ``rows``: ``|response| ≥ threshold`` (default
    ``params.strong_response``), as a bool array like :func:`describe` (borders False).

    ``kernel`` as in :func:`response`; an integer kernel wants an integer threshold in
    the kernel's scale.
    """
    rows = np.asarray(rows)
    threshold = params.strong_response if threshold is None else threshold
    strong = np.zeros(rows.shape, dtype=bool)
    r = params.radius
    strong[..., r:rows.shape[-1] - r] = np.abs(response(rows, params, kernel)) >= threshold
    return strong


def compare_range(width, desc, match_params, centre=0):
    """Columns ``[lo, hi)`` of the current row compared for every shift of the window."""
    r = desc.radius
    d_min, d_max = centre + match_params.shift_min, centre + match_params.shift_max
    lo, hi = r + max(d_max, 0), width - r + min(d_min, 0)
    if hi - lo < match_params.segments * 2:
        raise ValueError(f"window [{d_min}, {d_max}] leaves {max(hi - lo, 0)} columns of a "
                         f"{width}-pixel row to compare, too few for "
                         f"{match_params.segments} segment(s)")
    return lo, hi


def segment_bounds(width, desc, match_params, centre=0):
    """``[(lo, hi), ...]`` of each segment, equal parts of :func:`compare_range`."""
    lo, hi = compare_range(width, desc, match_params, centre)
    k = match_params.segments
    edges = [lo + (hi - lo) * i // k for i in range(k + 1)]
    return list(zip(edges[:-1], edges[1:]))


@dataclass
class MatchResult:
    """Per-row (and per-segment) matching outcome; arrays of shape ``(..., K)``."""
    shift: np.ndarray            # d* + δ, pixels (float)
    int_shift: np.ndarray        # d*
    subpixel: np.ndarray         # δ in (−0.5, 0.5]
    peak_ratio: np.ndarray       # confidence, [0, cap]
    cost_min: np.ndarray
    cost_second: np.ndarray
    edge_hit: np.ndarray         # d* on the window edge
    textureless: np.ndarray
    costs: np.ndarray = field(repr=False)  # (..., K, n_shifts)


def hamming_costs(cur_bits, ref_bits, desc, match_params, centre=0):
    """Costs ``(..., K, n_shifts)`` for shifts ``centre + shift_min .. centre + shift_max``."""
    cur_bits = np.asarray(cur_bits, dtype=bool)
    ref_bits = np.asarray(ref_bits, dtype=bool)
    if cur_bits.shape != ref_bits.shape:
        raise ValueError(f"current {cur_bits.shape} and reference {ref_bits.shape} rows differ")
    width = cur_bits.shape[-1]
    bounds = segment_bounds(width, desc, match_params, centre)
    shifts = centre + np.arange(match_params.shift_min, match_params.shift_max + 1)
    costs = np.empty(cur_bits.shape[:-1] + (len(bounds), len(shifts)), dtype=np.int64)
    for i, d in enumerate(shifts):
        diff = cur_bits[..., :] != np.roll(ref_bits, d, axis=-1)  # ref[x − d] at x
        for k, (lo, hi) in enumerate(bounds):
            costs[..., k, i] = diff[..., lo:hi].sum(axis=-1)
    return costs


def transitions(cur_bits, desc, match_params, centre=0):
    """Bit changes of the current row inside each segment, ``(..., K)``."""
    cur_bits = np.asarray(cur_bits, dtype=bool)
    bounds = segment_bounds(cur_bits.shape[-1], desc, match_params, centre)
    change = cur_bits[..., 1:] != cur_bits[..., :-1]   # change[x-1]: between x-1 and x
    return np.stack([change[..., lo:hi - 1].sum(axis=-1) for lo, hi in bounds], axis=-1)


class CostPeaks(NamedTuple):
    """The integer facts :func:`match` derives from the costs, shape ``(..., K)`` each."""
    best: np.ndarray     # index of the first minimum
    c0: np.ndarray       # its cost
    c2: np.ndarray       # lowest cost at |index − best| ≥ 2
    cm: np.ndarray       # cost at best − 1 (clipped to the window)
    cp: np.ndarray       # cost at best + 1 (clipped to the window)
    edge: np.ndarray     # best on the window edge


def cost_peaks(costs):
    """First minimum, second minimum and the minimum's neighbours of ``(..., n)`` costs.

    Shared by the float matcher and the emulator (the hardware's costs are the same
    integers), so only the sub-pixel and confidence arithmetic differ between them.
    """
    costs = np.asarray(costs)
    n = costs.shape[-1]
    best = np.argmin(costs, axis=-1)                      # first minimum
    c0 = np.take_along_axis(costs, best[..., None], -1)[..., 0]
    far = np.abs(np.arange(n) - best[..., None]) >= 2
    c2 = np.where(far, costs, np.iinfo(np.int64).max).min(axis=-1)
    cm = np.take_along_axis(costs, np.clip(best - 1, 0, n - 1)[..., None], -1)[..., 0]
    cp = np.take_along_axis(costs, np.clip(best + 1, 0, n - 1)[..., None], -1)[..., 0]
    return CostPeaks(best, c0, c2, cm, cp, (best == 0) | (best == n - 1))


def strong_counts(cur_strong, desc, match_params, centre=0):
    """Strong columns of the current row inside each segment, ``(..., K)``."""
    cur_strong = np.asarray(cur_strong, dtype=bool)
    bounds = segment_bounds(cur_strong.shape[-1], desc, match_params, centre)
    return np.stack([cur_strong[..., lo:hi].sum(axis=-1) for lo, hi in bounds], axis=-1)


def textureless(cur_bits, desc, match_params, centre=0, cur_strong=None):
    """Textureless segments, ``(..., K)`` bool: too few bit changes, or (with
    ``cur_strong`` from :func:`strength`) too few strong columns."""
    flat = transitions(cur_bits, desc, match_params, centre) < match_params.min_transitions
    if cur_strong is not None:
        flat |= strong_counts(cur_strong, desc, match_params, centre) < match_params.min_strong
    return flat


def match(cur_bits, ref_bits, desc, match_params, centre=0, cur_strong=None):
    """Match descriptor rows; returns a :class:`MatchResult` with one entry per segment.

    Pass ``cur_strong`` (:func:`strength` of the current row) to flag noisy flat
    segments textureless as well.
    """
    costs = hamming_costs(cur_bits, ref_bits, desc, match_params, centre)
    best, c0, c2, cm, cp, edge = cost_peaks(costs)
    denom = cm - 2 * c0 + cp
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(edge | (denom == 0), 0.0, (cm - cp) / (2.0 * denom))
    cap, kappa = float(match_params.peak_ratio_cap), match_params.peak_ratio_offset
    best_k, second_k = c0 + kappa, c2 + kappa
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(best_k == 0, np.where(second_k > 0, cap, 0.0),
                         np.minimum(second_k / best_k, cap))
    flat = textureless(cur_bits, desc, match_params, centre, cur_strong)
    ratio = np.where(flat, 0.0, ratio)
    int_shift = centre + match_params.shift_min + best
    return MatchResult(shift=int_shift + delta, int_shift=int_shift, subpixel=delta,
                       peak_ratio=ratio, cost_min=c0, cost_second=c2, edge_hit=edge,
                       textureless=flat, costs=costs)

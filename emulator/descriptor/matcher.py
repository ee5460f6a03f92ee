"""The lanes' arithmetic, batched over rows (:mod:`emulator.row_descriptor`; gateware
:mod:`hdl.descriptor.fir` and :mod:`hdl.descriptor.matcher`): descriptor bits, Hamming
costs over the shift window, best shift, sub-pixel refinement and confidence in the
hardware's fixed point, and their comparison with :mod:`golden.descriptor`."""

from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from golden.descriptor import (cost_peaks, describe, match, segment_bounds, strength,
                               textureless)
from hdl.fixed import UQ, Overflow, Rounding, resize

__all__ = ["descriptor_bits", "hamming_costs", "measure_rows", "measure_segments",
           "window_bounds",
           "against_golden", "subpixel_errors", "confidences"]


@lru_cache(maxsize=32)
def _constants(params):
    """``(kernel taps, strong threshold, confidence cap)`` raw, quantized once per
    parameter set rather than once per batch (it dominates batches of one row)."""
    kernel = np.array(params.kernel_raw(), dtype=np.int64)
    kernel.setflags(write=False)
    return kernel, params.strong_raw(), params.cap_raw()


def descriptor_bits(pixels, params):
    """Descriptor bits and strong columns of rows ``(..., width)``: ``golden.descriptor``'s
    ``describe`` and ``strength`` with the quantized kernel and threshold, from one
    integer FIR pass (int32 where no sum can overflow it: several times faster)."""
    pixels = np.asarray(pixels, dtype=np.int64)
    kernel, threshold, _ = _constants(params)
    largest = int(np.abs(kernel).sum()) * int(np.abs(pixels).max(initial=0))
    rows = pixels.astype(np.int32 if largest < 2 ** 31 else np.int64)
    r, width = params.radius, pixels.shape[-1]
    interior = width - 2 * r
    response = np.zeros(rows.shape[:-1] + (interior,), dtype=rows.dtype)
    for j, tap in enumerate(kernel.astype(rows.dtype)):
        response += tap * rows[..., j:j + interior]
    bits, strong = np.zeros(pixels.shape, dtype=bool), np.zeros(pixels.shape, dtype=bool)
    bits[..., r:width - r] = response > 0
    strong[..., r:width - r] = np.abs(response) >= threshold
    return bits, strong


def _rounded_quotient(num, den, quotient_bits, fmt):
    """``floor(num / den)`` saturated to ``quotient_bits`` bits (den = 0 saturates), as the
    restoring divider computes it, then rounded half-up to ``fmt`` (one fraction bit
    fewer), saturating."""
    num, den = np.asarray(num, dtype=np.int64), np.asarray(den, dtype=np.int64)
    top = (1 << quotient_bits) - 1
    q = np.where(den > 0, num // np.maximum(den, 1), top)
    q = np.minimum(q, top)
    src = UQ(fmt.int_bits, fmt.frac_bits + 1)
    return resize(q, src, fmt, Rounding.HALF_UP, Overflow.SATURATE)


def _packed_words(bits):
    """Bits ``(..., L)`` packed into little-endian 64-bit words ``(..., ceil(L / 64))``,
    zero-padded (padding never counts: it is zero in every operand)."""
    packed = np.packbits(bits, axis=-1, bitorder="little")
    words = np.zeros(packed.shape[:-1] + (-(-bits.shape[-1] // 64) * 8,), dtype=np.uint8)
    words[..., :packed.shape[-1]] = packed
    return words.view(np.uint64)


def hamming_costs(cur_bits, ref_bits, centre, params):
    """``golden.descriptor.hamming_costs`` of rows ``(N, W)`` at one (clamped) centre,
    ``(N, K, n_shifts)``, as 64-bit popcounts: each segment's columns of the current rows
    and of every shifted reference row are packed into words, XORed and counted
    (``np.bitwise_count``), instead of one pass over the columns per shift."""
    m = params.match
    bounds = segment_bounds(params.width, params.descriptor, m, centre)
    lo, hi = bounds[0][0], bounds[-1][1]
    first, n = centre + m.shift_min, params.n_shifts
    # shift first + i compares cur[x] with ref[x - first - i], x in [lo, hi)
    shifted = sliding_window_view(ref_bits[:, lo - first - n + 1:hi - first], hi - lo,
                                  axis=-1)[:, ::-1]
    costs = np.empty((len(cur_bits), len(bounds), n), dtype=np.int64)
    for k, (a, b) in enumerate(bounds):
        diff = _packed_words(shifted[..., a - lo:b - lo])
        diff ^= _packed_words(cur_bits[:, None, a:b])
        costs[:, k] = np.bitwise_count(diff).sum(axis=-1)
    return costs


def _per_row(name, values, n):
    """``values`` as one entry per row of ``n`` (a single value is repeated)."""
    values = np.asarray(values)
    if values.size not in (1, n):
        raise ValueError(f"{name} must hold one value or one per row ({n}), not "
                         f"{values.size}")
    return np.broadcast_to(values.reshape(-1), (n,))


def window_bounds(half_widths, params):
    """First and last cost index ``(N,)`` of the run-time windows of saturated
    half-widths ``(N,)`` (``params.window_indices``)."""
    w = np.asarray(half_widths, dtype=np.int64)
    return (np.maximum(0, -w - params.match.shift_min),
            np.minimum(params.n_shifts - 1, w - params.match.shift_min))


def _windowed_peaks(costs, first, last, params):
    """:func:`golden.descriptor.cost_peaks` of ``(N, K, n)`` costs with the shifts
    outside each row's run-time window ``first … last`` ``(N,)`` read as the matcher's
    ``top`` (above every cost: ``cost_fmt`` holds ``max_segment_cost + 1``) and the edge
    at the run-time window's ends; the arithmetic of :mod:`hdl.descriptor.matcher`."""
    index = np.arange(params.n_shifts)
    outside = (index < first[:, None, None]) | (index > last[:, None, None])
    top = (1 << params.cost_fmt.width) - 1
    peaks = cost_peaks(np.where(outside, top, costs))._asdict()
    best = peaks["best"]
    peaks["edge"] = (best == first[:, None]) | (best == last[:, None])
    return peaks


def _cost_facts(cur_bits, ref_bits, centres, half_widths, params, cur_strong):
    """:func:`_windowed_peaks` and the textureless flags of rows ``(N, W)`` at clamped
    ``centres`` and saturated ``half_widths`` ``(N,)``: one batched call per distinct
    centre (it sets the compared columns and the shifts)."""
    n, k = len(cur_bits), params.segments
    facts = {name: np.zeros((n, k), dtype=np.int64)
             for name in ("best", "c0", "c2", "cm", "cp", "edge", "flat")}
    d, m = params.descriptor, params.match
    first, last = window_bounds(half_widths, params)
    for c in np.unique(centres):
        at = centres == c
        costs = hamming_costs(cur_bits[at], ref_bits[at], int(c), params)
        for name, value in _windowed_peaks(costs, first[at], last[at], params).items():
            facts[name][at] = value
        strong = None if cur_strong is None else cur_strong[at]
        facts["flat"][at] = textureless(cur_bits[at], d, m, int(c), strong)
    return facts


def measure_rows(cur_bits, ref_bits, centres, params, *, cur_strong=None, bad=False,
                 no_reference=False, half_widths=None):
    """Per-segment results of ``N`` rows, each field an int array of shape ``(N, K)``.

    ``cur_bits``, ``ref_bits`` (and ``cur_strong``, the current rows' strong columns, see
    ``golden.descriptor.textureless``): ``(N, W)``; ``centres``, ``bad``,
    ``no_reference``, ``half_widths`` (the run-time half-width, saturated by
    ``params.saturate_half_width``; ``None``: the built maximum): one per row (or one
    for all). Fields: ``shift`` (d*),
    ``subpixel`` (raw ``subpixel_fmt``: |δ| = floor(|C₋ − C₊|·2^f / D) rounded half-up
    on the magnitude, D = C₋ − 2C₀ + C₊; 0 on the window edge), ``confidence`` (raw
    ``confidence_fmt``: (c₂ + κ)/(c₁ + κ) floored to one extra fraction bit, saturated,
    rounded half-up, capped; cap when c₁ + κ = 0 < c₂ + κ; 0 when both are 0, and 0 when
    textureless, bad or without reference), and the flags.
    """
    cur_bits, ref_bits = np.asarray(cur_bits, dtype=bool), np.asarray(ref_bits, dtype=bool)
    n, k, m = len(cur_bits), params.segments, params.match
    centres = _per_row("centres", [params.clamp_centre(c) for c in np.ravel(centres)], n)
    bad = _per_row("bad", np.asarray(bad, dtype=bool), n)[:, None]
    no_reference = _per_row("no_reference", np.asarray(no_reference, dtype=bool), n)[:, None]
    if cur_strong is not None:
        cur_strong = np.asarray(cur_strong, dtype=bool)
    if half_widths is None:
        half_widths = params.max_half_width
    half_widths = _per_row("half_widths", [params.saturate_half_width(w)[0]
                                           for w in np.ravel(half_widths)], n)
    f = _cost_facts(cur_bits, ref_bits, centres, half_widths, params, cur_strong)
    c0, cm, cp, edge = f["c0"], f["cm"], f["cp"], f["edge"].astype(bool)
    sub = params.subpixel_frac_bits
    den = np.where(edge, 1, cm - 2 * c0 + cp)
    mag = _rounded_quotient(np.abs(cm - cp) << sub, den, params.subpixel_quotient_bits,
                            UQ(1, sub))
    subpixel = np.where(edge, 0, np.where(cm < cp, -mag, mag))
    cf, kappa = params.confidence_fmt, m.peak_ratio_offset
    best_k, second_k = c0 + kappa, f["c2"] + kappa
    ratio = _rounded_quotient(second_k << (cf.frac_bits + 1), best_k,
                              params.ratio_quotient_bits, cf)
    ratio = np.minimum(ratio, _constants(params)[2])
    ratio = np.where((best_k == 0) & (second_k == 0), 0, ratio)
    ratio = np.where((f["flat"] != 0) | bad | no_reference, 0, ratio)
    full = lambda flag: np.repeat(flag.astype(np.int64), k, axis=1)
    return {"segment": np.tile(np.arange(k), (n, 1)),
            "shift": centres[:, None] + m.shift_min + f["best"], "subpixel": subpixel,
            "confidence": ratio, "textureless": f["flat"], "edge_hit": f["edge"],
            "bad": full(bad), "no_reference": full(no_reference)}


def measure_segments(cur_bits, ref_bits, centre, params, *, cur_strong=None, bad=False,
                     no_reference=False, half_width=None):
    """:func:`measure_rows` of one row: each field an int array of shape ``(K,)``."""
    strong = None if cur_strong is None else np.asarray(cur_strong)[None]
    results = measure_rows(np.asarray(cur_bits)[None], np.asarray(ref_bits)[None], centre,
                           params, cur_strong=strong, bad=bad, no_reference=no_reference,
                           half_widths=half_width)
    return {key: value[0] for key, value in results.items()}


def against_golden(cur, ref, centre, params, half_width=None):
    """The golden float matcher and this model on the same rows (current and reference
    pixels, ``(W,)``): returns ``(golden MatchResult, model results, model shift in
    pixels)``; level 2 of the three levels of truth. With a run-time ``half_width`` the
    golden matcher searches the equivalent float window ``[−w, w] ∩ [shift_min,
    shift_max]`` (its compared columns follow that window, the model's the built one)."""
    c = params.clamp_centre(centre)
    d, m = params.descriptor, params.match
    if half_width is not None:
        w = params.saturate_half_width(half_width)[0]
        m = m.replace(shift_min=max(m.shift_min, -w), shift_max=min(m.shift_max, w))
    cur_f, ref_f = np.asarray(cur, dtype=np.float64), np.asarray(ref, dtype=np.float64)
    golden = match(describe(cur_f, d), describe(ref_f, d), d, m, c,
                   cur_strong=strength(cur_f, d))
    cur_bits, cur_strong = descriptor_bits(cur, params)
    ref_bits, _ = descriptor_bits(ref, params)
    model = measure_segments(cur_bits, ref_bits, c, params, cur_strong=cur_strong,
                             half_width=half_width)
    return golden, model, model["shift"] + params.subpixel_fmt.to_float(model["subpixel"])


def subpixel_errors(cur_rows, ref_rows, centres, params, min_ratio=1.5):
    """``|model − golden|`` shift (pixels) of every well-textured segment of the row
    pairs: golden finds it textured, off the window edge, with peak ratio ≥
    ``min_ratio``."""
    errors = []
    for cur, ref, centre in zip(cur_rows, ref_rows, centres):
        golden, _, shift = against_golden(cur, ref, centre, params)
        good = ~golden.textureless & ~golden.edge_hit & (golden.peak_ratio >= min_ratio)
        errors += list(np.abs(shift - golden.shift)[good])
    return np.array(errors)


def confidences(cur_rows, ref_rows, params):
    """Golden peak ratios and the model's confidences (as numbers) of every segment of
    the row pairs, centre 0: two flat arrays, for comparing their order."""
    golden_ratio, model_ratio = [], []
    for cur, ref in zip(cur_rows, ref_rows):
        golden, model, _ = against_golden(cur, ref, 0, params)
        golden_ratio += list(golden.peak_ratio)
        model_ratio += list(params.confidence_fmt.to_float(model["confidence"]))
    return np.array(golden_ratio), np.array(model_ratio)

"""Matcher columns of one camera's rows and the model's measurements of them, for the
shared matcher's tests (``ShiftMatcher(ports=P)``)."""

import numpy as np

from emulator.descriptor.matcher import descriptor_bits, measure_rows

__all__ = ["camera_columns"]


def camera_columns(params, rng, camera, pixels):
    """Columns of frames ``pixels`` ``(F, H, W)`` (``W = params.width``) as the lane's
    store hands them to the matcher, frame ``f`` against frame ``f − 1``, and the
    model's measurements (:func:`emulator.descriptor.matcher.measure_rows`).

    Each row gets a random centre (some beyond ``±centre_range``: saturated) and
    half-width; about one row in six is bad and one in eight has no reference. Returns
    ``(columns, expected)``: the ``pair_layout`` beats of every row in order, and the
    measurement dicts of ``(F − 1)·H`` rows, K each."""
    h, w, r = params.height, params.width, params.radius
    cur, strong = descriptor_bits(pixels[1:].reshape(-1, w).astype(np.int64), params)
    ref, _ = descriptor_bits(pixels[:-1].reshape(-1, w).astype(np.int64), params)
    n, cr = len(cur), params.centre_range
    centres = [params.clamp_centre(int(c)) for c in rng.integers(-cr - 2, cr + 3, n)]
    half_widths = [params.saturate_half_width(int(v))[0] for v in
                   rng.integers(params.min_half_width, params.max_half_width + 1, n)]
    bad, no_reference = rng.random(n) < 1 / 6, rng.random(n) < 1 / 8
    keys = [{"camera": camera, "frame": k // h, "row": k % h, "t_first": 1000 * k + camera}
            for k in range(n)]

    def column(k, x):
        bit = lambda bits: int(bits[k, x - r]) if x >= 2 * r else 0   # the FIR's border
        meta = {**keys[k], "centre": centres[k], "half_width": half_widths[k],
                "source": [k % h] * params.segments, "bad": int(bad[k]), "paired": 0}
        return {"cur": bit(cur), "ref": bit(ref), "strong": bit(strong),
                "no_reference": int(no_reference[k]), "pos": x, "first": int(x == 0),
                "last": int(x == w - 1), "meta": meta}

    results = measure_rows(cur, ref, centres, params, cur_strong=strong, bad=bad,
                           no_reference=no_reference, half_widths=half_widths)
    expected = [{**keys[k], **{f: int(v[k, s]) for f, v in results.items()}}
                for k in range(n) for s in range(params.segments)]
    return [column(k, x) for k in range(n) for x in range(w)], expected

"""golden.descriptor: the float specification of row descriptors and shift matching."""

import numpy as np
import pytest

from golden.descriptor import (STEREO_MATCH, DescriptorParams, MatchParams, compare_range,
                               cost_peaks, describe, dog2_kernel, match, response,
                               segment_bounds, strength)

SEED = 20261123


def textured_row(rng, width, shift=0.0, blur=3.0):
    """A smooth random texture sampled at ``x − shift`` (content moved right by ``shift``)."""
    from scipy.ndimage import gaussian_filter1d
    base = gaussian_filter1d(rng.uniform(0, 255, width + 200), blur)
    return np.interp(np.arange(width) + 100 - shift, np.arange(width + 200), base)


def test_kernel_is_zero_sum_symmetric_and_normalised():
    for sigma in (0.5, 1.3, 2.0, 4.0):
        k = dog2_kernel(DescriptorParams(sigma=sigma))
        assert len(k) == 2 * DescriptorParams(sigma=sigma).radius + 1
        assert abs(k.sum()) < 1e-12 and np.allclose(k, k[::-1]) and np.abs(k).max() == 1.0
        assert k[len(k) // 2] == -1.0  # g'' is most negative at the centre


def test_borders_are_never_set():
    p = DescriptorParams(sigma=2.0)
    bits = describe(np.random.default_rng(SEED).uniform(0, 255, (3, 100)), p)
    assert not bits[:, :p.radius].any() and not bits[:, 100 - p.radius:].any()


@pytest.mark.parametrize("shift", [-17.3, -4.5, -0.25, 0.0, 1.75, 9.6, 19.0])
def test_known_shifts_are_recovered(shift):
    rng = np.random.default_rng(SEED)
    desc, m = DescriptorParams(), MatchParams(segments=4)
    ref, cur = textured_row(rng, 640), None
    rng = np.random.default_rng(SEED)
    cur = textured_row(rng, 640, shift)
    r = match(describe(cur, desc), describe(ref, desc), desc, m)
    assert np.all(np.abs(r.shift - shift) < 0.35), r.shift
    assert np.all(r.peak_ratio > 1.3) and not r.textureless.any() and not r.edge_hit.any()


def test_centre_offset_moves_the_window():
    rng = np.random.default_rng(SEED)
    ref = textured_row(rng, 640)
    cur = textured_row(np.random.default_rng(SEED), 640, 33.2)
    desc = DescriptorParams()
    plain = match(describe(cur, desc), describe(ref, desc), desc, MatchParams())
    assert plain.peak_ratio[0] < 1.2  # 33 px is outside [-20, 20]: no confident match
    centred = match(describe(cur, desc), describe(ref, desc), desc, MatchParams(), centre=30)
    assert abs(centred.shift[0] - 33.2) < 0.35 and not centred.edge_hit.any()


def test_stereo_window():
    rng = np.random.default_rng(SEED)
    ref = textured_row(rng, 640)
    cur = textured_row(np.random.default_rng(SEED), 640, 42.4)
    desc = DescriptorParams()
    r = match(describe(cur, desc), describe(ref, desc), desc, STEREO_MATCH)
    assert abs(r.shift[0] - 42.4) < 0.35


def test_textureless_and_periodic_rows_are_never_confident():
    desc, m = DescriptorParams(), MatchParams(segments=2)
    flat = np.full(640, 97.0)
    r = match(describe(flat, desc), describe(flat, desc), desc, m)
    assert r.textureless.all() and (r.peak_ratio == 0).all()
    x = np.arange(640)
    periodic = 128 + 90 * np.sin(2 * np.pi * x / 9)
    r = match(describe(periodic, desc), describe(np.roll(periodic, 3), desc), desc, m)
    assert (r.peak_ratio < 1.2).all()


def test_segments_split_the_compared_range():
    desc = DescriptorParams(sigma=2.0)
    m = MatchParams(segments=3)
    lo, hi = compare_range(640, desc, m)
    assert (lo, hi) == (desc.radius + 20, 640 - desc.radius - 20)
    bounds = segment_bounds(640, desc, m)
    assert bounds[0][0] == lo and bounds[-1][1] == hi
    assert all(a[1] == b[0] for a, b in zip(bounds, bounds[1:]))


def test_integer_kernel_gives_exact_integer_response():
    """The emulator's path: integer taps on integer rows, computed in integers."""
    p = DescriptorParams()
    rows = np.random.default_rng(SEED).integers(0, 256, (4, 80))
    kernel = np.round(dog2_kernel(p) * 256).astype(np.int64)
    exact = response(rows, p, kernel)
    assert exact.dtype == np.int64
    assert np.array_equal(exact, np.round(response(rows.astype(float), p,
                                                   kernel.astype(float))).astype(np.int64))
    with pytest.raises(ValueError, match="kernel must have 13 taps"):
        response(rows, p, kernel[1:])


def test_cost_peaks():
    costs = np.array([[9, 4, 2, 3, 2, 8, 5],             # first minimum wins ties
                      [1, 6, 7, 7, 6, 5, 4]])            # minimum on the edge
    best, c0, c2, cm, cp, edge = cost_peaks(costs)
    assert best.tolist() == [2, 0] and c0.tolist() == [2, 1]
    assert c2.tolist() == [2, 4]      # index 4 (distance 2) and index 6: far minima
    assert cm.tolist() == [4, 1] and cp.tolist() == [3, 6] and edge.tolist() == [False, True]


def test_noisy_flat_rows_are_textureless_given_strength():
    """Sign bits of noise change all the time; the strong-column test still sees a
    flat row, where short segments could otherwise match by chance."""
    rng = np.random.default_rng(SEED)
    desc, m = DescriptorParams(), MatchParams(segments=8)
    textured = textured_row(rng, 640) * 0.5 + 64
    for _ in range(20):
        cur = 97 + rng.normal(0, 2, 640)
        ref = 97 + rng.normal(0, 2, 640)
        plain = match(describe(cur, desc), describe(ref, desc), desc, m)
        assert not plain.textureless.any()
        r = match(describe(cur, desc), describe(ref, desc), desc, m,
                  cur_strong=strength(cur, desc))
        assert r.textureless.all() and (r.peak_ratio == 0).all()
    r = match(describe(textured, desc), describe(textured, desc), desc, m,
              cur_strong=strength(textured, desc))
    assert not r.textureless.any()


def test_peak_ratio_offset_tames_tiny_costs_of_periodic_rows():
    """Short segments of a noisy periodic row: aliases with 0 and 2 flips would be a
    perfect peak for the plain ratio; the offset keeps them unconfident."""
    rng = np.random.default_rng(SEED)
    desc = DescriptorParams()
    x = np.arange(640)
    plain, offset = [], []
    for _ in range(60):
        rows = [np.round(128 + 90 * np.sin(2 * np.pi * (x - rng.uniform(0, 7)) / 7)
                         + rng.normal(0, 2, 640)) for _ in range(2)]
        cur, ref = describe(rows[1], desc), describe(rows[0], desc)
        plain += list(match(cur, ref, desc, MatchParams(segments=8, peak_ratio_offset=0)).peak_ratio)
        offset += list(match(cur, ref, desc, MatchParams(segments=8)).peak_ratio)
    assert max(plain) == 2.0 and max(offset) < 1.5


@pytest.mark.parametrize("kwargs, error, message", [
    ({"sigma": 0.1}, ValueError, "sigma must be a number between 0.5 and 8.0, not 0.1"),
    ({"sigma": "2"}, TypeError, "sigma must be a number"),
    ({"strong_response": -1}, ValueError, "strong_response must be a number at least 0, not -1"),
])
def test_bad_descriptor_params(kwargs, error, message):
    with pytest.raises(error, match=message):
        DescriptorParams(**kwargs)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"shift_min": 0, "shift_max": 1}, ValueError, "must hold at least 3 shifts"),
    ({"segments": 0}, ValueError, "segments must be an integer at least 1, not 0"),
    ({"min_strong": -2}, ValueError, "min_strong must be an integer at least 0, not -2"),
    ({"peak_ratio_offset": 1.5}, TypeError, "peak_ratio_offset must be an integer"),
    ({"shift_min": 1.5}, TypeError, "shift_min must be an integer"),
    ({"peak_ratio_cap": 1.0}, ValueError, "peak_ratio_cap must be a number greater than 1"),
])
def test_bad_match_params(kwargs, error, message):
    with pytest.raises(error, match=message):
        MatchParams(**kwargs)


def test_window_too_wide_for_the_row():
    with pytest.raises(ValueError, match="too few for 4 segment"):
        compare_range(50, DescriptorParams(), MatchParams(segments=4))


def test_flat_stretches_set_no_bit():
    """A flat stretch's exact response is 0, as the hardware's integer arithmetic gives;
    float rounding noise (±1e-14 × pixel) must not set its bits (it did for about half
    the pixel values, so the golden and the model disagreed on saturated rows)."""
    params = DescriptorParams()
    flats = np.repeat(np.arange(256, dtype=np.float64)[:, None], 64, axis=1)
    assert not describe(flats, params).any()
    row = np.zeros(128)
    row[40:] = 255.0                       # saturated step: only the columns near it respond
    bits = np.flatnonzero(describe(row, params))
    assert bits.size and np.all(np.abs(bits - 40) <= params.radius)

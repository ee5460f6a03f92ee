"""The float64 domain-transform filters (golden.dt): RF, NC and the windowed vertical pass."""

import numpy as np
import pytest
from scipy.signal import lfilter

from golden.dt import (domain_derivative, normalized_convolution, recursive_filter,
                       rf_anticausal, rf_anticausal_window, rf_weights, sigma_schedule)

SEED = 9


def _exponential_pass(x, a, axis):
    """Ordinary first-order recursive smoothing (causal, then anti-causal) with scipy."""
    def causal(v):
        return lfilter([1 - a], [1, -a], v, axis=0, zi=a * v[:1])[0]
    v = np.moveaxis(x, axis, 0)
    return np.moveaxis(causal(causal(v)[::-1])[::-1], 0, axis)


def test_rf_without_range_term_is_the_exponential_filter():
    rng = np.random.default_rng(SEED)
    image = rng.random((37, 53))
    guide = rng.random((37, 53, 3))  # ignored when sigma_r is infinite
    out = recursive_filter(image, guide, sigma_s=7.0, sigma_r=np.inf, iterations=3)
    expected = image
    for sigma_h in sigma_schedule(7.0, 3):
        a = np.exp(-np.sqrt(2) / sigma_h)
        expected = _exponential_pass(_exponential_pass(expected, a, axis=1), a, axis=0)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12)


def test_sigma_schedule_adds_up_to_sigma_s():
    for n in (1, 2, 3, 5):
        sigmas = sigma_schedule(12.0, n)
        assert np.isclose(np.sqrt(np.sum(np.square(sigmas))), 12.0)
        assert sigmas == sorted(sigmas, reverse=True)
    assert sigma_schedule(12.0, 1) == [pytest.approx(12.0)]


def _noisy_step(rng, shape=(40, 80), low=0.2, high=0.9, noise=0.03):
    clean = np.where(np.arange(shape[1]) < shape[1] // 2, low, high) * np.ones(shape)
    return clean, clean + rng.normal(0, noise, shape)


@pytest.mark.parametrize("filt", [recursive_filter, normalized_convolution])
def test_high_contrast_step_edge_is_preserved(filt):
    rng = np.random.default_rng(SEED)
    clean, noisy = _noisy_step(rng)
    edge = clean.shape[1] // 2
    out = filt(noisy, sigma_s=20.0, sigma_r=0.1)
    blurred = filt(noisy, sigma_s=20.0, sigma_r=np.inf)
    next_to_edge = out[:, edge - 1:edge + 1]
    assert np.abs(next_to_edge - clean[:, edge - 1:edge + 1]).max() < 0.06
    assert np.abs(blurred[:, edge - 1:edge + 1] - clean[:, edge - 1:edge + 1]).min() > 0.1
    # ...while it still smooths on either side of the edge.
    assert np.std(out[:, 5:edge - 5] - clean[:, 5:edge - 5]) < 0.3 * 0.03


@pytest.mark.parametrize("filt", [recursive_filter, normalized_convolution])
@pytest.mark.parametrize("norm", ["l1", "l2"])
def test_constant_image_is_a_fixed_point(filt, norm):
    rng = np.random.default_rng(SEED)
    image = np.full((21, 34, 2), 3.25)
    out = filt(image, rng.random((21, 34, 3)), sigma_s=9.0, sigma_r=0.05, norm=norm)
    np.testing.assert_allclose(out, image, rtol=0, atol=1e-12)


def test_l2_equals_l1_on_one_channel_and_differs_on_colour():
    rng = np.random.default_rng(SEED)
    grey, colour = rng.random((10, 12)), rng.random((10, 12, 3))
    for axis in (0, 1):
        np.testing.assert_allclose(domain_derivative(grey, 5, 0.2, axis, "l1"),
                                   domain_derivative(grey, 5, 0.2, axis, "l2"))
        l1 = domain_derivative(colour, 5, 0.2, axis, "l1")
        l2 = domain_derivative(colour, 5, 0.2, axis, "l2")
        assert np.all(l2 <= l1 + 1e-12) and np.any(l2 < l1 - 1e-3)


def test_vertical_window_converges_to_the_exact_pass():
    rng = np.random.default_rng(SEED)
    values, guide = rng.random((30, 7)), rng.random((30, 7))
    weights = rf_weights(domain_derivative(guide, 8.0, 0.5, axis=0), 8.0)
    exact = rf_anticausal(values, weights, axis=0)
    np.testing.assert_array_equal(rf_anticausal_window(values, weights, 0, window=1), values)
    np.testing.assert_allclose(rf_anticausal_window(values, weights, 0, window=30), exact)
    errors = [np.abs(rf_anticausal_window(values, weights, 0, window=L) - exact).max()
              for L in (1, 2, 4, 8, 16)]
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    # Row y's window ends at row y + L - 1: a change further down cannot reach it.
    bumped = values.copy()
    bumped[20] += 1.0
    windowed = rf_anticausal_window(bumped, weights, 0, window=4)
    np.testing.assert_array_equal(windowed[:17], rf_anticausal_window(values, weights, 0, 4)[:17])
    assert np.all(windowed[17:21] != rf_anticausal_window(values, weights, 0, 4)[17:21])


def test_bad_parameters_are_named():
    image = np.zeros((4, 5))
    with pytest.raises(ValueError, match="sigma_s must be a number greater than 0, not -1"):
        recursive_filter(image, sigma_s=-1, sigma_r=0.1)
    with pytest.raises(TypeError, match="sigma_r must be a number"):
        normalized_convolution(image, sigma_s=1, sigma_r="wide")
    with pytest.raises(ValueError, match="iterations must be an integer at least 1, not 0"):
        recursive_filter(image, sigma_s=1, sigma_r=0.1, iterations=0)
    with pytest.raises(ValueError, match="norm must be one of l1, l2, not 'l3'"):
        recursive_filter(image, sigma_s=1, sigma_r=0.1, norm="l3")
    with pytest.raises(ValueError, match="guide must have the image's height and width"):
        recursive_filter(image, np.zeros((4, 6)), sigma_s=1, sigma_r=0.1)
    with pytest.raises(ValueError, match="image must be an"):
        recursive_filter(np.zeros(5), sigma_s=1, sigma_r=0.1)

"""golden.temporal_filter: robust scale with Huber verdicts, Holt–Winters, information gain.

Set SEED to replay a run; the seed in use is printed.
"""

import os

import numpy as np
import pytest

from golden.temporal_filter import (BIWEIGHT_CK, DelayedForecast, HoltWinters, RobustScale,
                                    biweight_rho, huber_weight, information_gain)

SEED = int(os.environ.get("SEED", "5"))


def test_huber_weight_is_one_inside_and_k_over_x_outside():
    x = np.array([-5.0, -2.0, -0.5, 0.0, 1.0, 2.0, 4.0])
    assert np.allclose(huber_weight(x), [0.4, 1, 1, 1, 1, 1, 0.5])


def test_biweight_is_bounded_and_zero_at_zero():
    assert biweight_rho(0.0) == 0.0
    assert np.allclose(biweight_rho(np.array([2.0, 3.0, 100.0])), BIWEIGHT_CK)
    assert np.all(np.diff(biweight_rho(np.linspace(0, 2, 20))) > 0)


def test_scale_learns_the_noise_and_an_outlier_neither_passes_nor_inflates_it():
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    scale = RobustScale(1, initial=1.0, floor=0.01, smoothing=0.05)
    for value in rng.normal(0.0, 0.2, 600):
        scale.judge([0], [value])
    assert 0.14 < scale.scale[0] < 0.28, scale.scale      # τ-scale ≈ σ for normal data
    before = scale.scale[0]
    x, weight = scale.judge([0], [5.0])                    # a 25σ mismatch
    assert abs(x[0]) > 10 and weight[0] < 0.1
    assert scale.scale[0] < 1.1 * before                   # the bounded ρ caps its effect


def test_scale_floor_and_channels_are_independent():
    scale = RobustScale(2, initial=0.5, floor=0.1, smoothing=0.5)
    for _ in range(50):
        scale.judge([0], [0.0])
    assert scale.scale[0] == pytest.approx(0.1) and scale.scale[1] == pytest.approx(0.5)
    x, weight = scale.judge([0, 1], [np.nan, 0.1])
    assert weight[0] == 0 and weight[1] == 1 and scale.scale[0] == pytest.approx(0.1)


@pytest.mark.parametrize("kwargs, message", [
    (dict(channels=0, initial=1.0, floor=0.1), "channels must be an integer at least 1"),
    (dict(channels=2, initial=-1.0, floor=0.1), "initial must be a number greater than 0"),
    (dict(channels=2, initial=1.0, floor=0.1, smoothing=1.5),
     "smoothing must be a number greater than 0 and at most 1"),
])
def test_robust_scale_rejects_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RobustScale(kwargs.pop("channels"), **kwargs)


def test_holt_winters_follows_a_ramp_and_holds_its_forecast():
    hw = HoltWinters([0.0, 0.0], alpha=0.3, beta=0.2)
    for t in range(200):
        hw.update([2.0 * t, 5.0])
    assert np.allclose(hw.level, [2.0 * 199, 5.0], atol=1e-6)
    assert np.allclose(hw.forecast(3), [2.0 * 202, 5.0], atol=1e-6)
    level = hw.update(None)                                # no value: the forecast stands
    assert np.allclose(level, [2.0 * 200, 5.0], atol=1e-6)


def test_holt_winters_matrix_gain_generalises_alpha():
    a = HoltWinters([1.0, 2.0], alpha=0.25, beta=0.0)
    b = HoltWinters([1.0, 2.0], alpha=0.25, beta=0.0)
    assert np.allclose(a.update([3.0, -1.0]), b.update([3.0, -1.0], 0.25 * np.eye(2)))
    with pytest.raises(ValueError, match="alpha must be a number greater than 0 and at most 1"):
        HoltWinters([0.0], alpha=0.0, beta=0.1)


def _random_updates(rng, count):
    """Slots with gaps (blanking), values (some missing) and matrix gains."""
    slots = np.cumsum(rng.integers(1, 3, size=count))
    values = [None if rng.random() < 0.2 else rng.normal(size=3) for _ in range(count)]
    gains = [np.diag(rng.uniform(0.05, 0.3, size=3)) for _ in range(count)]
    return slots, values, gains


def test_delayed_forecast_without_delay_is_the_filters_own_bit_for_bit():
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    plain = HoltWinters(np.ones(3), alpha=0.1, beta=0.05)
    delayed = DelayedForecast(HoltWinters(np.ones(3), alpha=0.1, beta=0.05), 0)
    for slot, value, gain in zip(*_random_updates(rng, 50)):
        for ahead in (1, 2, 5):
            assert np.array_equal(delayed.forecast(slot, ahead, latest=slot - 1),
                                  plain.forecast(ahead))
        assert np.array_equal(delayed.forecast(slot), plain.forecast())
        assert np.array_equal(delayed.update(slot, value, gain), plain.update(value, gain))


def test_delayed_forecast_withholds_the_values_of_the_last_delay_slots():
    """Slots 10, 11, 13, 14 (12 is blanking): with a delay of 2 row periods, slot 14's
    forecast may use slot 11 (solved when slot 12 starts, known at 14) but not 13: the
    state after slot 11 extrapolated over two updates (13 and 14)."""
    filt = HoltWinters(np.zeros(2), alpha=0.5, beta=0.5)
    delayed = DelayedForecast(filt, 2)
    initial = filt.forecast()
    assert np.array_equal(delayed.forecast(10), initial)
    delayed.update(10, [1.0, 2.0])
    assert np.array_equal(delayed.forecast(11), initial)     # slot 10 not known yet
    delayed.update(11, [3.0, 1.0])
    level, trend = filt.level.copy(), filt.trend.copy()
    delayed.update(13, [4.0, -1.0])
    assert np.array_equal(delayed.forecast(14), level + 2 * trend)
    assert not np.allclose(delayed.forecast(14), filt.forecast())   # 13 withheld
    assert np.array_equal(DelayedForecast(filt, 0).forecast(14), filt.forecast())


@pytest.mark.parametrize("delay, error, message", [
    (-1, ValueError, "delay must be an integer at least 0, not -1"),
    (1.5, TypeError, "delay must be an integer, not 1.5"),
])
def test_delayed_forecast_rejects_a_bad_delay(delay, error, message):
    with pytest.raises(error, match=message):
        DelayedForecast(HoltWinters([0.0], alpha=0.1, beta=0.0), delay)


def test_information_gain_is_alpha_for_a_typical_measurement_and_small_where_it_is_weak():
    rng = np.random.default_rng(SEED)
    a = rng.normal(size=(40, 6))
    typical = a.T @ a
    assert np.allclose(information_gain(typical, typical, 0.1), 0.1 * np.eye(6))
    weak = a.copy()
    weak[:, 1] *= 1e-3                                     # direction 1 barely measured
    gain = information_gain(weak.T @ weak, typical, 0.1)
    assert abs(gain[1, 1]) < 1e-4 and abs(gain[0, 0] - 0.1) < 0.02

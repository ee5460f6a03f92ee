"""Temporal consistency: robust Holt–Winters smoothing with a Huber loss (Gelper, Fried
and Croux 2010, as used by CVPR 2018 §3.2.3 and its Algorithm 1).

For a series ``m_t`` with forecast ``m_{t|t−1} = m̃_{t−1} + B_{t−1}``:

* robust scale (τ²-scale recursion): ``σ̂²_t = λ ρ(r_t/σ̂_{t−1}) σ̂²_{t−1} + (1 − λ) σ̂²_{t−1}``
  with ``r_t = m_t − m_{t|t−1}`` and ρ the biweight (k = 2, c_k = 2.52), so a single
  outlier cannot blow the scale up;
* cleaning: ``m*_t = ψ(r_t/σ̂_t) σ̂_t + m_{t|t−1}`` with the Huber ψ (k = 2);
* smoothing: ``m̃_t = α m*_t + (1 − α)(m̃_{t−1} + B_{t−1})``,
  ``B_t = β (m̃_t − m̃_{t−1}) + (1 − β) B_{t−1}``.

The tracker uses these pieces (see ``docs/tracker.md``): :class:`RobustScale` judges
every measurement channel's innovation against the forecast (weight ``ψ(x)/x``,
outliers replaced by the forecast), and :class:`HoltWinters` smooths the per-row motion,
with :func:`information_gain` in place of the scalar α when a measurement constrains some
directions much less than usual. :class:`DelayedForecast` gives that filter's forecasts
as a loop with a solver latency sees them: a row's forecast includes only the values
solved some row periods before the row starts.
"""

import math
from collections import deque

import numpy as np

from .checks import check_int, check_number

__all__ = ["HUBER_K", "BIWEIGHT_CK", "SCALE_CEILING", "huber_weight", "biweight_rho",
           "RobustScale", "HoltWinters", "DelayedForecast", "information_gain"]

#: Huber and biweight tuning constant (Gelper et al.: k = 2).
HUBER_K = 2.0
#: Biweight normalisation for k = 2 (consistency of the τ²-scale at the normal law).
BIWEIGHT_CK = 2.52
#: Largest robust scale of the shift innovations (pixels) of the tracker (issue 18) and
#: of the hardware's consistency stage: a persistent bias beyond ``k`` times it stays an
#: outlier (see :class:`RobustScale`).
SCALE_CEILING = 1.0


def huber_weight(x, k=HUBER_K):
    """``ψ(x)/x``: 1 inside ``[−k, k]``, ``k/|x|`` outside."""
    ax = np.abs(np.asarray(x, dtype=float))
    with np.errstate(divide="ignore"):
        return np.where(ax <= k, 1.0, k / ax)


def biweight_rho(x, k=HUBER_K, ck=BIWEIGHT_CK):
    """Bounded biweight loss: ``c_k (1 − (1 − (x/k)²)³)`` inside ``[−k, k]``, ``c_k`` outside."""
    u = np.minimum((np.asarray(x, dtype=float) / k) ** 2, 1.0)
    return ck * (1.0 - (1.0 - u) ** 3)


class RobustScale:
    """Per-channel robust scale of innovations and the Huber verdict on each new one.

    Parameters
    ----------
    channels : int
        Number of independent series (camera × segment).
    initial, floor : float
        Starting scale and its lower bound (units of the series, here pixels); the floor
        keeps a noiseless series from declaring every later deviation an outlier.
    ceiling : float
        Upper bound of the scale. The biweight recursion grows the scale by a factor
        ``sqrt(1 + 1.52 λ)`` per sample a persistent bias stays beyond ``k`` scales, so
        without a bound any bias is accepted after a few dozen samples; with it, a bias
        beyond ``k · ceiling`` stays an outlier.
    smoothing : float
        λ of the scale recursion, in (0, 1].
    k : float
        Huber threshold in scales.
    """

    def __init__(self, channels, *, initial, floor, smoothing=0.1, k=HUBER_K,
                 ceiling=math.inf):
        check_int("channels", channels, 1)
        for name, value in (("initial", initial), ("floor", floor), ("k", k)):
            check_number(name, value, 0, low_open=True)
        check_number("ceiling", ceiling, floor, finite=False)
        check_number("smoothing", smoothing, 0, 1, low_open=True)
        self.floor, self.ceiling = float(floor), float(ceiling)
        self.scale = np.full(channels, min(max(float(initial), self.floor), self.ceiling))
        self.smoothing, self.k = float(smoothing), float(k)

    def judge(self, channels, innovations):
        """Standardised innovations ``x`` and consistency weights ``ψ(x)/x`` of new values
        on ``channels``; then update those channels' scales (NaN innovations skip)."""
        channels = np.asarray(channels)
        innovations = np.asarray(innovations, dtype=float)
        scale = self.scale[channels]
        x = innovations / scale
        weight = huber_weight(x, self.k)
        seen = np.isfinite(x)
        lam = self.smoothing
        new = scale[seen]**2 * (lam * biweight_rho(x[seen], self.k) + (1 - lam))
        self.scale[channels[seen]] = np.clip(np.sqrt(new), self.floor, self.ceiling)
        return x, np.where(seen, weight, 0.0)


class HoltWinters:
    """Double exponential smoothing of a vector series (level and trend).

    Parameters
    ----------
    level : array_like
        Initial level.
    alpha, beta : float
        Level and trend smoothing, in (0, 1] and [0, 1].
    """

    def __init__(self, level, *, alpha, beta):
        check_number("alpha", alpha, 0, 1, low_open=True)
        check_number("beta", beta, 0, 1)
        self.level = np.array(level, dtype=float)
        self.trend = np.zeros_like(self.level)
        self.alpha, self.beta = float(alpha), float(beta)

    def forecast(self, steps=1):
        """The level expected ``steps`` samples ahead."""
        return self.level + steps * self.trend

    def update(self, value=None, gain=None):
        """Take the next (already cleaned) value, or none (the forecast stands); returns
        the new level. ``gain`` (a matrix) replaces the scalar α: the level moves by
        ``gain (value − forecast)``."""
        predicted = self.forecast()
        if value is None:
            level = predicted
        else:
            innovation = np.asarray(value, dtype=float) - predicted
            level = predicted + (self.alpha * innovation if gain is None else gain @ innovation)
        self.trend = self.beta * (level - self.level) + (1 - self.beta) * self.trend
        self.level = level
        return level


class DelayedForecast:
    """A :class:`HoltWinters` filter updated once per occupied row slot, whose forecast for
    a slot may only use the values of slots solved ``delay`` row periods before it starts.

    The value of slot ``j`` is solved when its row ends, at the start of slot ``j + 1``; a
    solver latency of ``delay`` row periods makes it available at the start of slot
    ``j + 1 + delay``. The forecast for slot ``s`` is therefore made from the filter's
    state after the newest slot ``j ≤ s − 1 − delay`` and extrapolated with its trend over
    every update since (one per occupied slot, as :meth:`HoltWinters.forecast`). With
    ``delay = 0`` it is exactly ``filter.forecast(ahead)``. The filter itself always takes
    a new value on its newest state: only what the loop reads is late.

    Parameters
    ----------
    motion : HoltWinters
        The filter (its current state is the state before any slot).
    delay : int
        Loop delay in row periods, at least 0.
    """

    def __init__(self, motion, delay):
        check_int("delay", delay, 0)
        self.motion, self.delay, self.count = motion, delay, 0
        # (slot, updates so far, level, trend) of the newest delay + 1 states: the slots
        # are distinct, so a forecast's state is one of them
        self._states = deque([(-math.inf, 0, motion.level, motion.trend)], maxlen=delay + 1)

    def forecast(self, slot, ahead=1, latest=None):
        """The forecast for slot ``slot``, whose value will be the ``ahead``-th update from
        now, from the newest state of a slot at most ``slot − 1 − delay`` (and at most
        ``latest``: a batch predicted at once cannot use later states)."""
        limit = slot - 1 - self.delay if latest is None else min(latest, slot - 1 - self.delay)
        for state_slot, count, level, trend in reversed(self._states):
            if state_slot <= limit:
                return level + (self.count + ahead - count) * trend
        raise ValueError(f"slot {slot} is older than the states kept (delay {self.delay})")

    def update(self, slot, value=None, gain=None):
        """:meth:`HoltWinters.update` of the filter with slot ``slot``'s value (or none);
        returns the new level."""
        level = self.motion.update(value, gain)
        return self._record(slot, level)

    def reset(self, slot, level):
        """Restart the filter at ``level`` with no trend as slot ``slot``'s update (a
        re-acquisition: nothing of the earlier forecast survives); returns the level."""
        self.motion.level = np.array(level, dtype=float)
        self.motion.trend = np.zeros_like(self.motion.level)
        return self._record(slot, self.motion.level)

    def _record(self, slot, level):
        self.count += 1
        self._states.append((slot, self.count, level, self.motion.trend))
        return level


def information_gain(normal, typical, alpha):
    """Matrix gain of a level update weighted by how much a measurement tells.

    With ``normal`` the information (normal matrix) of this measurement and ``typical``
    that of a typical one, the gain is ``(Λ + N)⁻¹ N`` with the prior information
    ``Λ = (1 − α)/α · N_typical``: a typical measurement moves the level by α as in plain
    Holt–Winters, while in directions a measurement barely constrains (a camera lost,
    a near-degenerate system) the level keeps its forecast instead of taking the noise.
    """
    prior = (1.0 - alpha) / alpha * np.asarray(typical, dtype=float)
    return np.linalg.solve(prior + normal, normal)

"""The motion track: the hardware path's output one-frame motion ``Y`` per row, read like
golden (b)'s pose track instead of from the forecast filter's level (issue 16;
docs/pose/motion_track.md).

Golden (``golden.tracker.Tracker._step``) carries its pose from one row to the next at
the filter's rate and pulls it by ``pose_alpha`` — weighted per direction by the row's
information — towards the previous frame's pose composed with the row's measured step;
its ``Y`` is the step between its poses one frame apart, which averages the filter over
the last frame. The same recursion in ``Y`` space, with the track's per-row-period
increments ``v`` (the last ``P = frame_rows`` of them in a ring; ``Y`` is their sum), per
row period ``j``:

* ``u = Y − v(j − P)`` — the motion over the other ``P − 1`` row periods;
* ``c = L/P + B/2`` — the carry at the filter's rate (its level ``L`` and trend ``B``
  before the row's update, the trend brought up half a frame as golden's);
* ``v(j) = c + a·(m − u − c)`` for the row period of a solved row, ``c`` for any other
  (an unsolved row, the readout gap); ``a`` = ``track_alpha`` and ``m`` the filter's
  level after the row's update: the measured step as the filter took it, moved by the
  information gain, so that directions the row hardly determines pull as little as in
  golden (the raw step with a scalar pull lets them in: docs/pose/motion_track.md);
* ``Y = u + v(j)``.

Row periods skipped since the last row (the gap between frames) are carried first; only
the last ``P`` of them matter (after ``P`` carries every increment is ``c``, wherever the
ring's pointer stands). The ring's pointer advances by one per row period carried. Every sum is exact (``Y`` stays the ring's sum) unless a
value leaves ``motion_fmt``: then it saturates and :attr:`MotionTrackModel.saturated`
counts the row. The float form of the recursion, fed the same values, agrees to the
formats' rounding (``sim_tests/pose/test_motion_track.py``). The gateware,
:class:`hdl.pose.motion_track.MotionTrack`, equals it bit for bit
(``sim_tests/pose/test_motion_track_hdl.py``); the pipeline runs this model beside the
loop (:mod:`emulator.pipeline`) until the block is wired into the loop.
"""

import numpy as np

from emulator.pose.forecast import clamp, sum_format
from golden.checks import check_int
from hdl.fixed import UQ, Overflow, Rounding, mul, resize

__all__ = ["MotionTrackModel", "track_float"]


class MotionTrackModel:
    """The motion track on raw ``motion_fmt`` integers.

    Parameters
    ----------
    params : hdl.pose.forecast_params.ForecastParams
    frame_rows : int
        Row periods per frame ``P`` (the ring's length).
    level : array_like of int (6,)
        The motion at the start (raw ``motion_fmt``): every increment ``≈ level / P``.
    """

    def __init__(self, params, frame_rows, level):
        check_int("frame_rows", frame_rows, 1)
        self.params, self.frame_rows = params, frame_rows
        self.reciprocal = params.reciprocal_raw(frame_rows)
        #: Rows in which a value was saturated into ``motion_fmt``.
        self.saturated = 0
        self.restart(level)

    def restart(self, level):
        """Every increment the carry of a constant ``level`` (trend 0), ``Y`` their sum;
        the next row's period is the first the track takes."""
        clamps = []
        self.ring = np.tile(self._carry(np.asarray(level, dtype=np.int64),
                                        np.zeros(6, dtype=np.int64), clamps),
                            (self.frame_rows, 1))
        self.motion = clamp(self.params.motion_fmt, self.ring.sum(axis=0), clamps)
        self.saturated += any(clamps)
        self.slot, self.index = None, 0

    def _carry(self, level, trend, clamps):
        """``c = L/P + B/2``, each term rounded half-even into ``motion_fmt``."""
        p = self.params
        fmt = p.motion_fmt
        rate, rate_fmt = mul(self.reciprocal, p.reciprocal_fmt, level, fmt)
        rate = resize(rate, rate_fmt, fmt, Rounding.HALF_EVEN, Overflow.ERROR)    # 1/P ≤ 1
        half, half_fmt = mul(1, UQ(1, 1), trend, fmt)        # 0.5 · B
        half = resize(half, half_fmt, fmt, Rounding.HALF_EVEN, Overflow.ERROR)
        return clamp(fmt, rate + half, clamps)

    def update(self, slot, level, trend, target=None):
        """Row slot ``slot`` (increasing) with the filter's ``level`` and ``trend`` before
        its update (raw ``motion_fmt``) and the pull's target ``m``, the level after it
        (raw ``motion_fmt``; None if the row was not solved); returns ``Y`` after it (raw
        ``motion_fmt``)."""
        p = self.params
        fmt = p.motion_fmt
        # m − u − c of values within (−1, 1), (−2, 2), (−1, 1); a·that with a < 2 (the
        # formats hold ±8 and ±16)
        diff_fmt, pull_fmt = sum_format(fmt, 3), sum_format(fmt, 4)
        check_int("slot", slot, 0 if self.slot is None else self.slot + 1)
        clamps = []
        carry = self._carry(np.asarray(level, dtype=np.int64),
                            np.asarray(trend, dtype=np.int64), clamps)
        periods = 1 if self.slot is None else min(slot - self.slot, self.frame_rows)
        motion = self.motion
        for k in range(periods):
            index = self.index
            self.index = (index + 1) % self.frame_rows
            rest = motion - self.ring[index]
            increment = carry
            if k == periods - 1 and target is not None:
                m = fmt.raw(np.asarray(target, dtype=np.int64))
                pull, product_fmt = mul(p.track_alpha_raw, p.gain_fmt, m - rest - carry,
                                        diff_fmt)
                increment = clamp(fmt, carry + resize(pull, product_fmt, pull_fmt,
                                                      Rounding.HALF_EVEN, Overflow.ERROR),
                                  clamps)
            self.ring[index] = increment
            motion = clamp(fmt, rest + increment, clamps)
        self.motion, self.slot = motion, slot
        self.saturated += any(clamps)
        return motion


def track_float(frame_rows, track_alpha, level0, rows):
    """The recursion in float (m, rad): ``rows`` is an iterable of ``(slot, level, trend,
    target or None)`` as :meth:`MotionTrackModel.update` takes them; returns ``Y`` after
    each (n, 6). The reference of the fixed-point model."""
    ring = np.tile(np.asarray(level0, dtype=float) / frame_rows, (frame_rows, 1))
    motion, last, out = ring.sum(axis=0), None, []
    for slot, level, trend, target in rows:
        carry = np.asarray(level, dtype=float) / frame_rows + 0.5 * np.asarray(trend, float)
        first = slot if last is None else max(last + 1, slot - frame_rows + 1)
        for j in range(first, slot + 1):      # the ring indexed by the slot: the same sums
            rest = motion - ring[j % frame_rows]
            increment = carry
            if j == slot and target is not None:
                increment = carry + track_alpha * (np.asarray(target, float) - rest - carry)
            ring[j % frame_rows] = increment
            motion = rest + increment
        last = slot
        out.append(motion.copy())
    return np.array(out)

"""Tracking status of every row slot: tracking, degraded or lost — never a silent failure.

The tracker cannot see its own error, but it sees the symptoms of one: slots that stop
stepping, measurements that disagree with the forecast (innovations beyond the Huber
threshold), systems that are barely determined. :class:`StatusMonitor` keeps these over
a sliding window of recent slots and classifies each slot with the thresholds of
:class:`golden.tracker_params.TrackerParams` (``docs/tracker.md`` gives the measured
reasons):

* ``LOST``: the recent update fraction is below ``lost_update_fraction`` or the share of
  outlier innovations above ``lost_outlier_fraction``. Latched: the tracker re-acquires
  (widened search, no forecast) and the status stays ``LOST`` until a whole window after
  the loss meets the ``DEGRADED`` bounds again.
* ``DEGRADED``: update fraction below ``degraded_update_fraction``, outlier share above
  ``degraded_outlier_fraction``, median condition above ``degraded_condition`` or fewer
  than ``degraded_measurements`` confident measurements per stepped slot.
* ``TRACKING``: none of these.

Poses after a loss are also *drifted*: relative tracking resumes, the absolute pose keeps
whatever error the loss left.

Encoding (2 bits, so that it fits the HDL pose record's ``flags`` byte and the packet):
``0b00`` tracking, ``0b01`` degraded, ``0b10`` lost, ``0b11`` reserved (a receiver treats
it as lost). Flag layout (the hardware's too, ``hdl.output.params.FLAG_FIELDS``):
bits 3:0 are the solver's ``hdl.pose.params.PoseFlag``; bits 5:4 the status; bit 6
drifted since a loss; bit 7 reserved. Zero still means "a good pose".
"""

import enum
import math
from collections import deque

import numpy as np

__all__ = ["TrackingStatus", "STATUS_BITS", "STATUS_SHIFT", "DRIFTED_BIT", "pack_flags",
           "unpack_flags", "StatusMonitor", "lost_time", "status_summary", "describe_status"]


class TrackingStatus(enum.IntEnum):
    """A slot's status (its 2-bit code)."""
    TRACKING = 0b00
    DEGRADED = 0b01
    LOST = 0b10


#: Width of the status code and its proposed place in the pose record's flags byte.
STATUS_BITS = 2
STATUS_SHIFT = 4
#: Proposed flags bit: the pose comes after a loss (relative tracking, absolute drift).
DRIFTED_BIT = 6


def pack_flags(status, drifted):
    """The proposed flags-byte bits of ``status`` (array or scalar) and ``drifted``."""
    status = np.asarray(status, dtype=np.uint8)
    return (status << STATUS_SHIFT) | (np.asarray(drifted, dtype=np.uint8) << DRIFTED_BIT)


def unpack_flags(flags):
    """``(status, drifted)`` from flags bytes; the reserved code 0b11 reads as LOST."""
    flags = np.asarray(flags, dtype=np.uint8)
    code = (flags >> STATUS_SHIFT) & ((1 << STATUS_BITS) - 1)
    return np.minimum(code, int(TrackingStatus.LOST)), ((flags >> DRIFTED_BIT) & 1) == 1


class StatusMonitor:
    """Classifies slot after slot from the statistics of the last ``window`` slots.

    Parameters
    ----------
    window : int
        Slots in the sliding window.
    params : golden.tracker_params.TrackerParams
        Thresholds (``lost_*``, ``degraded_*``).
    """

    def __init__(self, window, params):
        self.window, self.params = int(window), params
        self._history = deque(maxlen=self.window)
        #: whether each of the last ``window`` determinable slots stepped
        self._updates = deque(maxlen=self.window)
        self.lost = False

    def _statistics(self):
        rows = np.array(self._history, dtype=float).reshape(-1, 5)
        stepped, judged, outliers, condition, confident = rows.T
        outlier_share = outliers.sum() / judged.sum() if judged.sum() else 0.0
        formed = np.isfinite(condition)
        median_condition = float(np.median(condition[formed])) if formed.any() else math.inf
        measurements = confident[stepped > 0].mean() if stepped.any() else 0.0
        updates = float(np.mean(self._updates)) if self._updates else 0.0
        return updates, outlier_share, median_condition, measurements

    def update(self, stepped, judged, outliers, condition, confident, determinable=True):
        """Status of a slot that ``stepped`` (bool) with ``judged`` innovations of which
        ``outliers`` were beyond the Huber threshold, the system's ``condition`` (NaN:
        none formed) and ``confident`` measurements with non-zero confidence.

        ``determinable``: the slot could have stepped had every usable segment matched
        (:meth:`golden.tracker_solve.SlotSolver.determinable`). The update fraction is
        that of the last ``window`` determinable slots: a slot the rig's geometry and
        timing leave undetermined (the readout gap between frames, frame-boundary rows
        without a reference) is no evidence of a loss, and a fraction of the few
        determinable slots of a window spanning the gap would be."""
        self._history.append((float(stepped), judged, outliers, condition, confident))
        if determinable:
            self._updates.append(float(stepped))
        p = self.params
        updates, outlier_share, condition, measurements = self._statistics()
        full = len(self._history) == self.window
        if ((len(self._updates) == self.window and updates < p.lost_update_fraction)
                or (full and outlier_share > p.lost_outlier_fraction)):
            if not self.lost:
                self._history.clear()      # a recovery must fill a whole new window
                self._updates.clear()
            self.lost = True
            return TrackingStatus.LOST
        degraded = (updates < p.degraded_update_fraction
                    or outlier_share > p.degraded_outlier_fraction
                    or condition > p.degraded_condition
                    or measurements < p.degraded_measurements)
        if self.lost:
            if not full or degraded:
                return TrackingStatus.LOST
            self.lost = False
        return TrackingStatus.DEGRADED if degraded else TrackingStatus.TRACKING


def lost_time(result):
    """Time (s since the first slot) of the first LOST slot of a TrackResult, or None."""
    lost = np.flatnonzero(result.status == TrackingStatus.LOST)
    return None if not len(lost) else float(result.times[lost[0]] - result.times[0])


def status_summary(result):
    """Plain-data status figures of a TrackResult (for the metrics and the JSON)."""
    tracked = result.tracked
    status = result.status[tracked]
    lost = lost_time(result)
    worst = TrackingStatus(int(status.max())) if len(status) else TrackingStatus.TRACKING
    return {"status": worst.name.lower(),
            "tracking_fraction": float(np.mean(status == TrackingStatus.TRACKING)),
            "degraded_fraction": float(np.mean(status == TrackingStatus.DEGRADED)),
            "lost_fraction": float(np.mean(status == TrackingStatus.LOST)),
            "lost_at_ms": None if lost is None else 1000 * lost,
            "drifted_fraction": float(np.mean(result.drifted[tracked])),
            "final_status": TrackingStatus(int(status[-1])).name.lower() if len(status)
            else "tracking"}


def describe_status(result):
    """One line: the worst status of the run and when tracking was lost."""
    s = status_summary(result)
    line = (f"status {s['status']}: tracking {s['tracking_fraction']:.1%}, degraded "
            f"{s['degraded_fraction']:.1%}, lost {s['lost_fraction']:.1%} of tracked rows")
    if s["lost_at_ms"] is not None:
        line += (f"; tracking lost at {s['lost_at_ms']:.1f} ms, final status "
                 f"{s['final_status']}, {s['drifted_fraction']:.1%} of rows drifted since")
    return line

"""Bit-accurate model of the tracking-status unit (:class:`hdl.pose.status_unit.StatusUnit`):
the specification the gateware equals bit for bit.

It is :class:`golden.tracking_status.StatusMonitor` in integers, from what the hardware
has per row (``docs/pose/tracking_status.md`` lists every difference):

* ``stepped``: the solver's record flags are 0 (the row was solved);
* ``formed``: not ``EMPTY`` (a system was formed); ``ill``: ``ILL`` (the solver's pivot
  check stands for the golden's condition number);
* ``judged``, ``outliers``, ``confident``: the row's counts, and ``determinable``: at
  least ``min_cameras`` cameras near enough in time to step
  (:meth:`hdl.pose.status_params.StatusParams.row_layout`).

Over the last ``window`` rows (a register; the history restarts when it changes, and
after a loss as in the golden) the unit keeps the sums ``S`` (stepped), ``J``
(judged), ``O`` (outliers), ``F`` (formed), ``I`` (ill) and ``C`` (confident, stepped
rows only) of ``n ≤ window`` rows, and over the last ``window`` *determinable* rows
(the golden's update fraction: a readout gap is no evidence of a loss) their number
``d ≤ window`` and ``U`` of them stepped; with the raw registers (fractions ``f`` in
``FRACTION_FMT`` with ``b`` fraction bits, ``m`` in ``MEASUREMENTS_FMT`` with ``c``):

* LOST if ``d = window`` and ``U·2**b < f_lu·d``, or if ``n = window`` and
  ``O·2**b > f_lo·J``; latched, both histories cleared at the loss;
* DEGRADED if ``U·2**b < f_du·d`` (with ``d = 0``: ``f_du > 0``), ``O·2**b > f_do·J``,
  ``F = 0``, ``I·2**b > f_di·F``, or ``C·2**c < m·S`` (with ``S = 0``: ``m > 0``);
* a latched loss stays LOST until a full window is not degraded;
* drifted from the first LOST row after the first TRACKING row (``acquired``) on, until
  ``clear``: the golden tracker is given its first frame and monitors only the rows
  after it; the hardware has no pose before it acquires (start-up rows are EMPTY, hence
  LOST), and a loss then leaves no drift behind.
"""

import math
from collections import deque

import numpy as np

from golden.checks import check_int
from hdl.pose.params import PoseFlag
from hdl.pose.status_params import (DRIFTED_BIT, FRACTION_FMT, MEASUREMENTS_FMT,
                                    ROW_COUNTS, STATUS_SHIFT, StatusParams, TrackingStatus)

__all__ = ["StatusUnitModel", "row_entry", "measurement_verdicts", "count_rows",
           "row_counts", "annotate", "golden_to_hardware",
           "hardware_to_golden"]

#: Fields of a history entry (one row), in the order the gateware packs them.
ENTRY_FIELDS = ("stepped", "formed", "ill", "judged", "outliers", "confident")


def row_entry(flags, judged, outliers, confident):
    """A row's history entry from its record ``flags`` (the solver's ``PoseFlag`` bits)
    and its counts; ``confident`` counts only on stepped rows (the golden averages it
    over them)."""
    flags = int(flags)
    stepped = flags == 0
    return {"stepped": int(stepped), "formed": int(not flags & PoseFlag.EMPTY),
            "ill": int(bool(flags & PoseFlag.ILL)), "judged": int(judged),
            "outliers": int(outliers), "confident": int(confident) if stepped else 0}


def measurement_verdicts(conf, verdict):
    """The verdict bits of a row's measurements (:func:`hdl.pose.row_counter.verdict_layout`)
    from the confidences the consistency stage judged (raw, after the far-camera
    zeroing) and its verdict (:meth:`emulator.measurement.consistency.ConsistencyModel.apply`):
    a confidence in, replaced as an outlier, a confidence out; ``last`` on the final
    one, which alone carries the row's ``determinable``."""
    conf = np.asarray(conf)
    last = len(conf) - 1
    return [{"judged": int(c > 0), "outliers": int(o), "confident": int(out != 0),
             "last": int(k == last), "determinable": int(k == last and verdict["determinable"])}
            for k, (c, o, out) in enumerate(zip(conf, verdict["outlier"], verdict["conf"]))]


def count_rows(verdicts, slots):
    """Per-row ``(judged, outliers, confident, determinable)`` of a run of measurement
    verdicts, as :class:`hdl.pose.row_counter.RowCounter` gives them: the counts sum
    (each stops at ``slots``), ``determinable`` is the last verdict's."""
    out, counts = [], [0] * len(ROW_COUNTS)
    for v in verdicts:
        counts = [min(c + int(v[name]), slots) for c, name in zip(counts, ROW_COUNTS)]
        if v["last"]:
            out.append((*counts, int(v["determinable"])))
            counts = [0] * len(ROW_COUNTS)
    return out


def row_counts(conf, verdict, slots):
    """A row's ``(judged, outliers, confident, determinable)`` from the consistency
    stage's verdict."""
    return count_rows(measurement_verdicts(conf, verdict), slots)[0]


class StatusUnitModel:
    """The unit's state and its per-row update.

    Parameters
    ----------
    params : StatusParams

    Members
    -------
    settings : dict
        Raw register values (:meth:`StatusParams.raw_settings` after reset); change
        them with :meth:`set_settings`.
    state : dict
        The ``status.state`` register's fields (:meth:`StatusParams.state_layout`).
    """

    def __init__(self, params):
        if not isinstance(params, StatusParams):
            raise TypeError(f"params must be a StatusParams, not {params!r}")
        self.params = params
        self.settings = params.raw_settings()
        self.clear()

    def clear(self):
        """The ``status.clear`` command: history, loss latch, drifted and counters."""
        self._history = deque()
        self._updates = deque()        # stepped, of the last ``window`` determinable rows
        self._window = None
        self.state = {"status": 0, "drifted": 0, "lost": 0, "acquired": 0, "window_error": 0,
                      "losses": 0,
                      "degraded_rows": 0, "lost_rows": 0}

    def set_settings(self, **raw):
        unknown = set(raw) - set(self.settings)
        if unknown:
            raise ValueError(f"unknown settings {sorted(unknown)}")
        self.settings = {**self.settings, **{k: int(v) for k, v in raw.items()}}

    def _effective_window(self):
        """``window`` taken into 1 … max_window (flagged when it was not)."""
        window = self.settings["window"]
        effective = min(max(window, 1), self.params.max_window)
        self.state["window_error"] = int(effective != window)
        return effective

    def update(self, flags, judged, outliers, confident, determinable):
        """The status bits of one record: its flags (``PoseFlag`` bits) with the status
        code at bits 5:4 and drifted at bit 6 (:data:`DRIFTED_BIT`); ``determinable``
        (0 or 1): the row's, from the consistency stage."""
        slots = self.params.slots
        for name, value, high in (("flags", flags, (1 << len(PoseFlag)) - 1),
                                  ("judged", judged, slots), ("outliers", outliers, slots),
                                  ("confident", confident, slots),
                                  ("determinable", determinable, 1)):
            check_int(name, value, 0, high)
        window = self._effective_window()
        if window != self._window:
            self._history, self._updates = deque(maxlen=window), deque(maxlen=window)
            self._window = window
        entry = row_entry(flags, judged, outliers, confident)
        self._history.append(entry)
        if determinable:
            self._updates.append(entry["stepped"])
        status = self._classify(window)
        state, count = self.state, (1 << self.params.count_bits) - 1
        if status == TrackingStatus.LOST:
            state["drifted"] |= state["acquired"]
            state["lost_rows"] = (state["lost_rows"] + 1) & count
        elif status == TrackingStatus.DEGRADED:
            state["degraded_rows"] = (state["degraded_rows"] + 1) & count
        else:
            state["acquired"] = 1
        state["status"] = int(status)
        return (int(flags) | int(status) << STATUS_SHIFT | state["drifted"] << DRIFTED_BIT)

    def sums(self):
        """The window sums, the row count ``n``, and over the determinable rows' window
        their count ``d`` and ``updated`` (stepped among them)."""
        out = {name: sum(e[name] for e in self._history) for name in ENTRY_FIELDS}
        return {**out, "n": len(self._history), "d": len(self._updates),
                "updated": sum(self._updates)}

    def verdicts(self, sums, window):
        """``(lost, degraded)`` of window ``sums`` with the window ``window`` (rows)."""
        s, b = self.settings, FRACTION_FMT.frac_bits
        stepped, judged, d = sums["stepped"], sums["judged"], sums["d"]
        outliers, formed = sums["outliers"], sums["formed"]

        def few_updates(fraction):
            return fraction > 0 if d == 0 else (sums["updated"] << b) < fraction * d

        lost = ((d == window and few_updates(s["lost_update_fraction"]))
                or (sums["n"] == window
                    and (outliers << b) > s["lost_outlier_fraction"] * judged))
        m = s["degraded_measurements"]
        few = (m > 0) if stepped == 0 else \
            (sums["confident"] << MEASUREMENTS_FMT.frac_bits) < m * stepped
        degraded = (few_updates(s["degraded_update_fraction"])
                    or (outliers << b) > s["degraded_outlier_fraction"] * judged
                    or formed == 0
                    or (sums["ill"] << b) > s["degraded_ill_fraction"] * formed
                    or few)
        return lost, degraded

    def _classify(self, window):
        state = self.state
        sums = self.sums()
        lost, degraded = self.verdicts(sums, window)
        full = sums["n"] == window
        if lost:
            if not state["lost"]:
                self._history.clear()          # a recovery must fill a whole new window
                self._updates.clear()
                state["losses"] = (state["losses"] + 1) & ((1 << self.params.count_bits) - 1)
            state["lost"] = 1
            return TrackingStatus.LOST
        if state["lost"]:
            if not full or degraded:
                return TrackingStatus.LOST
            state["lost"] = 0
        return TrackingStatus.DEGRADED if degraded else TrackingStatus.TRACKING


def annotate(params, flags, judged, outliers, confident, determinable, model=None):
    """Annotated flags of a run of records (sequences of ints); ``model`` continues a
    run (a fresh one by default)."""
    model = StatusUnitModel(params) if model is None else model
    return [model.update(*row)
            for row in zip(flags, judged, outliers, confident, determinable)]



# --- the golden monitor's inputs and the unit's, one for the other (agreement checks) ---

def golden_to_hardware(updated, condition, degraded_condition):
    """Solver flags standing for golden slots: 0 where the slot stepped, ``EMPTY``
    where no system was formed (NaN condition), ``ILL`` where the condition exceeds
    ``degraded_condition``, else ``SATURATED`` (formed, no step). A golden slot that
    stepped with a condition above the threshold has no hardware counterpart (an ILL
    row never steps): it maps to 0."""
    out = []
    for stepped, cond in zip(updated, condition):
        if stepped:
            out.append(0)
        elif not math.isfinite(cond):
            out.append(int(PoseFlag.EMPTY))
        else:
            out.append(int(PoseFlag.ILL if cond > degraded_condition else PoseFlag.SATURATED))
    return out


def hardware_to_golden(flags, degraded_condition):
    """``(stepped, condition)`` the golden monitor gets for records with these solver
    flags: NaN for ``EMPTY``; ``1.5 × degraded_condition`` for ``ILL`` and 1 otherwise,
    so that the golden's median (the mean of the middle two of an even count) exceeds
    the threshold exactly when more than half the formed rows are ILL, the unit's
    rule with ``degraded_ill_fraction`` 0.5."""
    stepped = [int(f) == 0 for f in flags]
    condition = [math.nan if int(f) & PoseFlag.EMPTY else
                 1.5 * degraded_condition if int(f) & PoseFlag.ILL else 1.0 for f in flags]
    return stepped, condition

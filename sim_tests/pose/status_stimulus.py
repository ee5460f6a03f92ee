"""Stimulus shared by the tracking-status tests (model against golden, gateware against
model, cocotb bench): small parameter sets, rows in regimes that trigger every rule, and
the golden monitor's classification of the same rows."""

import numpy as np

from emulator.pose.tracking_status import StatusUnitModel, hardware_to_golden
from golden.tracking_status import StatusMonitor, TrackingStatus
from golden.tracker_params import TrackerParams
from hdl.pose.params import PoseFlag, PoseSolverParams, solver_source
from hdl.pose.status_params import StatusParams

#: A small unit: 8 slots, windows up to 16 rows (reset 6).
SOLVER = PoseSolverParams(slots=8, rows=32, row_bits=6)
SMALL = StatusParams(slots=8, max_window=16, window=6)
#: The golden defaults with a 10-row window (status_window 0.25 of 40 rows).
TRACKER = TrackerParams()
DEFAULT = StatusParams.for_tracker(TRACKER, slots=16, frame_rows=40)

#: Row regimes: (flags choices, judged, outlier share, confident) of each; a row is
#: determinable with probability DETERMINABLE, except in a readout ``gap`` (never).
DETERMINABLE = 0.9
REGIMES = {
    "good": ((0,), (6, 16), (0.0, 0.1), (6, 16)),
    "outliers": ((0,), (6, 16), (0.5, 1.0), (6, 16)),
    "few": ((0,), (1, 8), (0.0, 0.2), (0, 6)),
    "unsolved": ((int(PoseFlag.SATURATED), int(PoseFlag.OVERRUN)), (4, 16), (0.0, 0.2),
                 (0, 16)),
    "empty": ((int(PoseFlag.EMPTY),), (0, 4), (0.0, 1.0), (0, 4)),
    "ill": ((int(PoseFlag.ILL),), (4, 16), (0.0, 0.3), (4, 16)),
    "mixed": ((0, 0, 0, int(PoseFlag.ILL), int(PoseFlag.EMPTY), int(PoseFlag.SATURATED)),
              (0, 16), (0.0, 0.6), (0, 16)),
    "gap": ((int(PoseFlag.EMPTY), int(PoseFlag.SATURATED)), (0, 4), (0.0, 0.5), (0, 2)),
}


def regime_row(rng, regime, slots):
    """One row ``(flags, judged, outliers, confident, determinable)`` of ``regime``."""
    flags, judged, share, confident = REGIMES[regime]
    j = int(rng.integers(min(judged[0], slots), min(judged[1], slots) + 1))
    o = min(j, int(round(j * rng.uniform(*share))))
    c = int(rng.integers(min(confident[0], slots), min(confident[1], slots) + 1))
    d = regime != "gap" and rng.random() < DETERMINABLE
    return int(rng.choice(flags)), j, o, c, int(d)


def regime_rows(rng, count, params, regimes=tuple(REGIMES)):
    """``count`` rows in runs of random regimes, each 1 to 3 windows long (good runs
    twice as likely, so that losses recover)."""
    rows, weights = [], np.array([3.0 if r == "good" else 1.0 for r in regimes])
    while len(rows) < count:
        regime = regimes[int(rng.choice(len(regimes), p=weights / weights.sum()))]
        length = int(rng.integers(1, 3 * params.window + 1))
        rows += [regime_row(rng, regime, params.slots) for _ in range(length)]
    return rows[:count]


def model_statuses(params, rows, settings=None):
    """``(status, drifted, flags)`` lists of the model on ``rows``."""
    model = StatusUnitModel(params)
    if settings:
        model.set_settings(**settings)
    flags = [model.update(*row) for row in rows]
    return [(f >> 4) & 3 for f in flags], [f >> 6 & 1 for f in flags], flags


def golden_statuses(params, rows, tracker=TRACKER):
    """``(status, drifted)`` of :class:`golden.tracking_status.StatusMonitor` (window and
    thresholds ``tracker``'s, window ``params.window``) on the same rows, through
    :func:`emulator.pose.tracking_status.hardware_to_golden`; drifted as the golden
    tracker sets it (from the first LOST slot on), counting only slots after the first
    TRACKING one (the golden tracker monitors only the rows after its given first
    frame; the unit's ``acquired``)."""
    monitor = StatusMonitor(params.window, tracker)
    stepped, condition = hardware_to_golden([r[0] for r in rows], tracker.degraded_condition)
    status, drifted, lost, acquired = [], [], False, False
    for (flags, judged, outliers, confident, determinable), s, c in zip(rows, stepped,
                                                                         condition):
        code = int(monitor.update(s, judged, outliers, c, confident, bool(determinable)))
        lost |= acquired and code == TrackingStatus.LOST
        acquired |= code == TrackingStatus.TRACKING
        status.append(code)
        drifted.append(int(lost))
    return status, drifted


def random_records(solver, rng, count):
    """Pose records with every field random (flags set by the rows)."""
    src = solver_source(solver)

    def fmt(f):
        return int(rng.integers(f.min_raw, f.max_raw + 1))

    return [{"row": int(rng.integers(0, 1 << src.row_bits)),
             "time": int(rng.integers(0, 1 << src.time_bits)),
             "q": [fmt(src.quaternion_fmt) for _ in range(4)],
             "p": [fmt(src.position_fmt) for _ in range(3)],
             "step": [fmt(src.step_fmt) for _ in range(6)]} for _ in range(count)]


def packable(record):
    """A record with its array fields as the index dicts ``pack`` takes."""
    return {k: dict(enumerate(v)) if isinstance(v, list) else v for k, v in record.items()}


def expected(params, records, rows, events=None):
    """The model's output records and final state for ``records`` with ``rows``;
    ``events`` (record index → settings dict or ``"clear"``) apply before a record."""
    model = StatusUnitModel(params)
    out = []
    for k, (record, row) in enumerate(zip(records, rows)):
        event = (events or {}).get(k)
        if event == "clear":
            model.clear()
        elif event:
            model.set_settings(**event)
        out.append({**record, "flags": model.update(*row)})
    return out, model.state


def random_verdicts(rng, rows, slots):
    """Measurement verdicts of ``rows`` rows of 1 to ``slots + 3`` measurements (the
    longer ones make the row counter's counts stop at ``slots``); ``determinable``
    random on every one (only the last's counts)."""
    out = []
    for _ in range(rows):
        n = int(rng.integers(1, slots + 4))
        bits = rng.random((n, 4)) < rng.uniform(0.1, 0.9, 4)
        out += [{"judged": int(j), "outliers": int(o), "confident": int(c),
                 "determinable": int(d), "last": int(k == n - 1)}
                for k, (j, o, c, d) in enumerate(bits)]
    return out

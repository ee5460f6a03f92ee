"""The tracking-status model (emulator/pose/tracking_status.py) against the golden
StatusMonitor (golden/tracking_status.py): constructed sequences in which each rule
triggers (lost by update fraction, lost by outliers, degraded by condition, by
measurements, by no system, latch and recovery, drifted), random runs of regimes
(SEED, printed), the window register, and the parameter checks."""

import os
from dataclasses import replace

import numpy as np
import pytest

from emulator.pose.tracking_status import (StatusUnitModel, golden_to_hardware,
                                           hardware_to_golden)
from golden.tracking_status import TrackingStatus, unpack_flags
from hdl.pose.params import PoseFlag, PoseSolverParams
from hdl.pose.status_params import (FLAG_BITS, FRACTION_FMT, StatusParams, status_source,
                                    top_status_params)
from hdl.top_params import TopParams

from sim_tests.pose.status_stimulus import (DEFAULT, TRACKER, golden_statuses,
                                            model_statuses, regime_row, regime_rows)

SEED = int(os.environ.get("SEED", "1"))
T, D, L = TrackingStatus.TRACKING, TrackingStatus.DEGRADED, TrackingStatus.LOST
W = DEFAULT.window
SAT, ILL, EMPTY = int(PoseFlag.SATURATED), int(PoseFlag.ILL), int(PoseFlag.EMPTY)
GOOD = (0, 10, 0, 10, 1)
#: A row in a readout gap: too few cameras near in time to step.
GAP = (EMPTY, 0, 0, 0, 0)


def both(rows, params=DEFAULT, tracker=TRACKER):
    """Model and golden on ``rows``: asserts they agree row by row; returns the
    statuses and drifted bits."""
    status, drifted, flags = model_statuses(params, rows)
    g_status, g_drifted = golden_statuses(params, rows, tracker)
    for k, (m, g) in enumerate(zip(status, g_status)):
        assert m == g, f"row {k}: model {TrackingStatus(m).name}, golden " \
                       f"{TrackingStatus(g).name}; rows {rows[max(0, k - W):k + 1]}"
    assert drifted == g_drifted
    assert [f & 0xF for f in flags] == [r[0] for r in rows]       # PoseFlag bits kept
    codes, drift = unpack_flags(np.array(flags, dtype=np.uint8))
    assert codes.tolist() == status and drift.astype(int).tolist() == drifted
    return status, drifted


def first(status, code):
    return status.index(code) if code in status else None


def test_window_follows_the_golden_tracker():
    """A quarter frame of row periods, as golden.tracker sizes its monitor."""
    assert W == 10
    assert StatusParams.for_tracker(TRACKER, slots=8, frame_rows=600).window == 150
    assert StatusParams.for_tracker(TRACKER, slots=8, frame_rows=1).window == 1
    top = TopParams()
    assert top_status_params(top).slots == top.solver.slots
    assert top_status_params(top).window == round(0.25 * top.camera.max_height)


def test_good_rows_track():
    status, drifted = both([GOOD] * 3 * W)
    assert set(status) == {T} and not any(drifted)


def test_lost_by_update_fraction():
    """Rows that stop stepping: degraded below 70 % of the window, lost below 20 %."""
    rows = [GOOD] * W + [(SAT, 10, 0, 0, 1)] * W
    status, drifted = both(rows)
    assert first(status, D) == W + 3       # 4th unsolved row: 6 of 10 stepped < 0.7
    assert first(status, L) == W + 8       # 9th: 1 of 10 < 0.2 (2 of 10 is not)
    assert drifted[first(status, L)] and not drifted[first(status, L) - 1]


def test_lost_by_outliers():
    """Stepped rows whose innovations are mostly outliers."""
    rows = [GOOD] * W + [(0, 10, 8, 10, 1)] * W
    status, _ = both(rows)
    assert first(status, D) == W + 3       # 4th bad row: 32 of 100 outliers > 25 %
    assert first(status, L) == W + 6       # 7th: 56 of 100 > 50 % (48 is not)


def test_degraded_by_condition_alone():
    """ILL rows (the solver's pivot check) beyond half the formed rows degrade; with
    the update-fraction bounds at 0 nothing else can."""
    tracker = replace(TRACKER, degraded_update_fraction=0.0, lost_update_fraction=0.0)
    params = DEFAULT.replace(degraded_update_fraction=0.0, lost_update_fraction=0.0)
    rows = [GOOD] * W + [(ILL, 10, 0, 0, 1)] * W
    status, _ = both(rows, params, tracker)
    assert first(status, D) == W + 5      # 6 of 10 formed rows ILL (5 of 10 is not more)
    assert L not in status


def test_degraded_by_measurements_and_no_system():
    rows = [GOOD] * W + [(0, 4, 0, 4, 1)] * W + [GOOD] * W + [(EMPTY, 0, 0, 0, 1)] * 3
    status, _ = both(rows)
    # the window mean of confident measurements per stepped row drops below 6
    assert D in status[W:2 * W] and L not in status
    assert status[3 * W - 1] == T


def test_readout_gap_is_no_loss():
    """Rows that could not have stepped (a readout gap) leave the update fraction alone:
    degraded (no system formed), never lost; marked determinable, the same rows lose."""
    rows = [GOOD] * W + [GAP] * 2 * W + [GOOD] * W
    status, drifted = both(rows)
    assert L not in status and D in status[W:3 * W] and not any(drifted)
    assert status[-1] == T
    status, _ = both([r[:4] + (1,) for r in rows])
    assert L in status


def test_update_fraction_counts_determinable_rows_only():
    """Unsolved rows between gap rows lose track after as many unsolved rows as without
    the gap rows in between: the window is one of determinable rows."""
    plain, _ = both([GOOD] * W + [(SAT, 10, 0, 0, 1)] * W)
    k = first(plain, L) - W                 # unsolved rows it takes
    status, _ = both([GOOD] * W + [(SAT, 10, 0, 0, 1), GAP] * W)
    assert first(status, L) == W + 2 * k


def test_no_formed_row_is_degraded():
    status, _ = both([(EMPTY, 0, 0, 0, 1)] * (W - 1))
    assert set(status) == {D}        # window not full: never lost, but nothing formed


def test_latch_and_recovery():
    """Lost stays until a whole window after the loss is not degraded; drifted stays."""
    rows = [GOOD] * W + [(SAT, 10, 0, 0, 1)] * W + [GOOD] * 3 * W
    status, drifted = both(rows)
    lost_at = first(status, L)
    back = lost_at + 1 + next(k for k, s in enumerate(status[lost_at + 1:]) if s != L)
    assert back - lost_at >= W and status[back] == T
    assert all(drifted[lost_at:]) and not any(drifted[:lost_at])


def test_clear_forgets_loss_and_drift():
    model = StatusUnitModel(DEFAULT)
    for row in [GOOD] * W + [(SAT, 10, 0, 0, 1)] * W:
        flags = model.update(*row)
    assert model.state["lost"] and model.state["drifted"] and model.state["losses"] == 1
    model.clear()
    assert model.state == {k: 0 for k in model.state}
    fresh = StatusUnitModel(DEFAULT)
    assert [model.update(*GOOD) for _ in range(2 * W)] == \
        [fresh.update(*GOOD) for _ in range(2 * W)] == [0] * (2 * W)


def test_random_regimes_agree_with_golden():
    rng = np.random.default_rng(SEED)
    print(f"SEED={SEED}")
    for window in (1, 2, 5, 10, 37):
        params = DEFAULT.replace(window=window, max_window=64)
        rows = regime_rows(rng, 2000, params)
        status, _ = both(rows, params)
        assert {T, D, L} <= set(status), f"window {window}: every status occurs"


def test_window_register_restarts_and_is_flagged():
    """A new window restarts the history; 0 and values above max_window are taken as
    1 and max_window and flagged."""
    params = DEFAULT.replace(max_window=16)
    model = StatusUnitModel(params)
    for _ in range(W):
        model.update(SAT, 10, 0, 0, 1)
    assert model.state["lost"]
    model.set_settings(window=4)
    model.update(*GOOD)
    assert model.sums()["n"] == 1 and model.state["window_error"] == 0
    for window, effective in ((0, 1), (17, 16), (2047, 16)):
        model.set_settings(window=window)
        model.update(*GOOD)
        assert model.state["window_error"] == 1 and model._window == effective


def test_golden_mapping_round_trip():
    """golden_to_hardware and hardware_to_golden invert each other on hardware rows."""
    flags = [0, EMPTY, ILL, SAT, 0]
    stepped, condition = hardware_to_golden(flags, 50.0)
    assert golden_to_hardware(stepped, condition, 50.0) == flags
    assert golden_to_hardware([True], [80.0], 50.0) == [0]     # stepped with condition 80


def test_fractions_compare_exactly_for_one_decimal():
    """0.2 and 0.7 in FRACTION_FMT give the golden's verdict for every count up to a
    window of 4096 rows."""
    for f in (0.2, 0.7):
        raw = int(FRACTION_FMT.quantize(f))
        n = np.arange(1, 4097)
        for count in (np.floor(f * n), np.ceil(f * n)):
            golden = count / n < f
            hardware = count * (1 << FRACTION_FMT.frac_bits) < raw * n
            assert np.array_equal(golden, hardware)


def test_status_source_widens_flags():
    solver = PoseSolverParams()
    assert status_source(solver).flag_bits == FLAG_BITS == 7
    with pytest.raises(TypeError, match="solver must be a PoseSolverParams"):
        status_source(1)


def test_model_rejects_bad_input():
    model = StatusUnitModel(DEFAULT)
    with pytest.raises(ValueError, match="flags must be an integer .* 15"):
        model.update(16, 0, 0, 0, 1)
    with pytest.raises(ValueError, match="outliers must be an integer"):
        model.update(0, 0, DEFAULT.slots + 1, 0, 1)
    with pytest.raises(ValueError, match="determinable must be an integer"):
        model.update(0, 0, 0, 0, 2)
    with pytest.raises(ValueError, match="unknown settings"):
        model.set_settings(windw=3)
    with pytest.raises(TypeError, match="params must be a StatusParams"):
        StatusUnitModel(None)


@pytest.mark.parametrize("changes, message", [
    ({"slots": 0}, "slots must be an integer"),
    ({"max_window": 24}, "max_window must be a power of two, not 24"),
    ({"max_window": 1}, "max_window must be an integer"),
    ({"window": 0}, "window must be an integer"),
    ({"window": 2048}, "window must be an integer"),
    ({"lost_update_fraction": 1.5}, "lost_update_fraction must be a number"),
    ({"lost_outlier_fraction": -0.1}, "lost_outlier_fraction must be a number"),
    ({"degraded_update_fraction": "a"}, "degraded_update_fraction must be a number"),
    ({"degraded_outlier_fraction": 2}, "degraded_outlier_fraction must be a number"),
    ({"degraded_ill_fraction": 1.1}, "degraded_ill_fraction must be a number"),
    ({"degraded_measurements": 300.0}, "degraded_measurements must be a number"),
    ({"count_bits": 4}, "count_bits must be an integer"),
])
def test_parameter_checks(changes, message):
    with pytest.raises((TypeError, ValueError), match=message):
        StatusParams(**changes)


def test_for_tracker_checks_frame_rows():
    with pytest.raises(ValueError, match="frame_rows must be a number greater than 0"):
        StatusParams.for_tracker(TRACKER, slots=8, frame_rows=0)


def test_regime_rows_are_reproducible():
    a = regime_rows(np.random.default_rng(3), 50, DEFAULT)
    b = regime_rows(np.random.default_rng(3), 50, DEFAULT)
    assert a == b and regime_row(np.random.default_rng(0), "empty", 8)[0] == EMPTY


def test_loss_before_acquisition_marks_no_drift():
    """Start-up rows (no reference yet: EMPTY) are LOST but leave no drift; a loss
    after the first TRACKING row does."""
    rows = [(EMPTY, 0, 0, 0, 1)] * 2 * W + [GOOD] * 3 * W + [(SAT, 10, 0, 0, 1)] * W
    status, drifted = both(rows)
    acquired = first(status, T)
    assert status[W - 1] == L and acquired > 2 * W
    assert not any(drifted[:acquired])
    assert drifted[-1] and status[-1] == L


def test_real_runs_agree_with_golden():
    """On the closed-loop emulator run (stereo20 cut, 3 frames; the hardware's own
    per-row quantities) the model and the golden monitor agree on every row; on the
    golden tracker's run (fed through golden_to_hardware) too, as no golden slot there
    stepped with a condition above degraded_condition (measured: 96 and 64 rows)."""
    from sim_tests.pose.status_runs import dataset, emulator_agreement, golden_agreement
    data = dataset()
    emulated = emulator_agreement(data)
    assert emulated["agree"] == emulated["drifted_agree"] == 1.0
    assert emulated["rows"] == 96 and all(emulated["model"])      # all three statuses
    golden = golden_agreement(data)
    assert golden["stepped_above_condition"] == 0
    assert golden["agree"] == golden["drifted_agree"] == 1.0

"""emulator.pose_solver against golden.pose_lsq: the fixed-point design is accurate
enough (level 2 of the three levels of truth), and its checks flag what they must."""

import os

import numpy as np
import pytest

from emulator import pose_solver as E
from emulator.pose import program
from hdl.pose.program import UPPER
from golden import pose_lsq as G
from hdl.pose.params import PoseFlag
from sim_tests.pose.pose_solver.stimulus import build_case, random_rows, sequence_rows

SEED = int(os.environ.get("SEED", "8"))


def _golden(params, coefficients, rows):
    """Golden float solution of the same quantized inputs and stored coefficients."""
    fmts = [params.coef_t_fmt] * 3 + [params.coef_c_fmt] * 3 + [params.coef_r_fmt] * 3
    table = np.stack([fmts[k].to_float(coefficients[..., k]) for k in range(9)], axis=-1)
    coef = G.ShiftCoefficients.from_table(table[np.where(rows.present, rows.slot, 0),
                                                rows.row[:, None]])
    return G.solve_step(coef, params.cue_fmt.to_float(rows.cue),
                        params.shift_fmt.to_float(rows.shift),
                        params.conf_fmt.to_float(rows.conf) * rows.present)


@pytest.fixture(scope="module")
def random_case():
    params, coefficients, _ = build_case("random")
    rows, kind = random_rows(params, np.random.default_rng(SEED), 1500)
    return params, coefficients, rows, kind, E.solve_rows(params, coefficients, rows), \
        _golden(params, coefficients, rows)


def test_scaled_diagonal_lies_in_a_quarter_to_one(random_case):
    params, coefficients, rows, kind, _, _ = random_case
    normal, rhs = E.accumulate(params, coefficients, rows)
    scaled, _, scales, empty, _ = E.scale_system(params, normal, rhs)
    for i in range(6):
        value = params.unit_fmt.to_float(np.asarray(scaled[UPPER.index((i, i))].raw,
                                                     dtype=float))[~empty]
        assert np.all((value >= 0.25) & (value <= 1.0)), i


def test_rsqrt_seed_and_newton_step_accuracy():
    """Seeds are good to 2**-17 over the pivot range; after the Newton step to 2**-34."""
    params, _, _ = build_case("random")
    rng = np.random.default_rng(SEED)
    pivots = np.concatenate([2.0 ** rng.uniform(-params.pivot_log2, 0.99, 4000),
                             [2.0 ** -params.pivot_log2, 0.25, 0.5, 1.0, 1.5]])
    raw = params.unit_fmt.quantize(pivots)
    value = params.unit_fmt.to_float(raw)
    seed = program.rsqrt_seed(params, program.Value(raw, params.unit_fmt))
    seed = params.seed_fmt.to_float(np.asarray(seed.raw, dtype=float))
    exact = 1 / np.sqrt(value)
    assert np.max(np.abs(seed / exact - 1)) < 2.0 ** -17
    newton = seed * (1.5 - value * seed * seed / 2)
    assert np.max(np.abs(newton / exact - 1)) < 2.0 ** -34


def test_steps_match_golden_within_the_error_budget(random_case):
    """Relative step error ≤ 1e-4 + 2e-8·condition on every row both solve (the budget
    of docs/pose/pose_solver.md; random rows have inconsistent shifts, the harder case)."""
    params, _, _, _, result, golden = random_case
    both = (result.flags == 0) & golden.ok
    step = params.step_fmt.to_float(result.step)
    error = np.linalg.norm(step - golden.step, axis=1)[both]
    bound = (1e-4 + 2e-8 * golden.condition[both]) * np.linalg.norm(golden.step[both], axis=1)
    assert both.sum() > 800
    assert np.all(error <= bound), np.max(error / bound)


@pytest.mark.parametrize("case", ["stereo8", "radial4"])
def test_sequence_steps_match_golden(case):
    params, coefficients, rig = build_case(case)
    rows, _ = sequence_rows(params, rig, np.random.default_rng(SEED), 600)
    result = E.solve_rows(params, coefficients, rows)
    golden = _golden(params, coefficients, rows)
    both = (result.flags == 0) & golden.ok
    assert both.mean() > 0.95
    step = params.step_fmt.to_float(result.step)
    relative = (np.linalg.norm(step - golden.step, axis=1)[both]
                / np.linalg.norm(golden.step[both], axis=1))
    assert np.median(relative) < 2e-5 and np.max(relative) < 1e-3


def test_flags_follow_the_checks(random_case):
    params, _, rows, kind, result, golden = random_case
    flags = result.flags
    assert np.all(flags[kind == "zero"] == PoseFlag.EMPTY)
    assert np.all(flags[kind == "overrun"] == PoseFlag.OVERRUN)
    # rank-deficient rows (fewer than six equations) are never solved
    few = rows.counts < 6
    assert np.all(flags[few] != 0)
    # a solved row is one the golden model solves, or one just past its cut
    assert np.all(golden.condition[flags == 0] < 1e7)
    # well-conditioned rows are solved unless their step leaves the step format
    fits = np.max(np.abs(golden.step), axis=1) < 0.9
    assert np.all(flags[golden.ok & (golden.condition < 1e4) & fits
                        & (kind != "extreme") & (kind != "overrun")] == 0)
    assert np.all(result.step[flags != 0] == 0)


def test_flagged_rows_leave_their_slot(random_case):
    """A flagged row emits the pose its slot had (the same row's last record, or the
    reset pose) and leaves it for the next frame."""
    params, _, rows, _, result, _ = random_case
    quats, positions = E.integrate_rows(params, result, rows.row)
    reset_q, reset_p = E.identity_pose(params)
    last = {}
    checked = 0
    for k, (y, flag) in enumerate(zip(rows.row.tolist(), result.flags)):
        if flag != 0:
            q, p = (quats[last[y]], positions[last[y]]) if y in last else (reset_q, reset_p)
            assert np.array_equal(quats[k], q) and np.array_equal(positions[k], p), k
            checked += 1
        last[y] = k
    assert checked > 50


def _frame_steps(params, rng, frames):
    """Raw steps of ``frames`` frames of every row slot (frame-major), about 1 cm and
    0.6° each, and 10 % of the rows flagged (step zero)."""
    count = frames * params.rows
    steps = np.concatenate([rng.normal(0, 0.01, (count, 3)), rng.normal(0, 0.01, (count, 3))], 1)
    flags = np.where(rng.random(count) < 0.1, int(PoseFlag.ILL), 0)
    raw = np.where((flags == 0)[:, None], params.step_fmt.quantize(steps), 0)
    return E.StepResult(step=raw, flags=flags), np.tile(np.arange(params.rows), frames)


def test_each_row_slot_chains_its_own_frames():
    """Frames of rows with known steps: row y's pose in frame i is the composition of
    row y's steps of frames 0..i alone (each from the reset pose), as the float
    integrator gives it (to the fixed point's rounding);
    composing onto the previous row's pose instead is centimetres off."""
    params, _, _ = build_case("random")
    frames = 4
    result, row = _frame_steps(params, np.random.default_rng(SEED), frames)
    quats, positions = E.integrate_rows(params, result, row)
    q = params.quat_fmt.to_float(quats).reshape(frames, params.rows, 4)
    p = params.position_fmt.to_float(positions).reshape(frames, params.rows, 3)
    steps = params.step_fmt.to_float(result.step).reshape(frames, params.rows, 6)
    for y in range(params.rows):
        q_float, p_float = G.integrate_steps([1.0, 0, 0, 0], np.zeros(3), steps[:, y])
        assert np.max(np.abs(q[:, y] - q_float)) < 1e-5, y
        assert np.max(np.abs(p[:, y] - p_float)) < 1e-6, y
    _, chained = G.integrate_steps([1.0, 0, 0, 0], np.zeros(3), steps.reshape(-1, 6))
    assert np.median(np.linalg.norm(p.reshape(-1, 3) - chained, axis=1)) > 0.05


def test_frame_chains_stay_within_the_drift_target():
    """The pose ring's per-slot chains of one-frame steps (~1° each) over 1 s of the
    papers' motion: within issue 8's 0.002° and 0.02 cm. The first-order
    δq = (1, θ/2) turned |θ|³/12 too little per step (0.00305° over the second)."""
    from emulator.benches.pose_solver import frame_chain_error
    chain = frame_chain_error()
    assert chain["step_angle_max_deg"] > 0.9  # one-frame steps, not one row's
    assert chain["traj_err_deg"] < 0.002 and chain["traj_err_cm"] < 0.02


def test_initial_poses_one_or_one_per_slot():
    """``pose``: one pose for every slot, or one per slot; anything else is rejected."""
    params, _, _ = build_case("random")
    rng = np.random.default_rng(SEED)
    result, row = _frame_steps(params, rng, 2)
    ring_q = params.quat_fmt.quantize(G.quat_multiply(
        [1.0, 0, 0, 0], np.c_[np.ones(params.rows), rng.normal(0, 0.1, (params.rows, 3))]))
    ring_q = params.quat_fmt.quantize(params.quat_fmt.to_float(ring_q) / np.linalg.norm(
        params.quat_fmt.to_float(ring_q), axis=1, keepdims=True))
    ring_p = params.position_fmt.quantize(rng.normal(0, 1, (params.rows, 3)))
    quats, positions = E.integrate_rows(params, result, row, (ring_q, ring_p))
    for y in (0, 17, params.rows - 1):
        alone = E.StepResult(step=result.step[row == y], flags=result.flags[row == y])
        q1, p1 = E.integrate_rows(params, alone, np.full(2, y), (ring_q[y], ring_p[y]))
        assert np.array_equal(quats[row == y], q1) and np.array_equal(positions[row == y], p1)
    with pytest.raises(ValueError, match="pose must be raw"):
        E.integrate_rows(params, result, row, (ring_q[:3], ring_p[:3]))
    with pytest.raises(ValueError, match="row must be"):
        E.integrate_rows(params, result, row + 1)


def test_integration_keeps_the_quaternion_normalized():
    """Small-motion steps (|θ| up to 0.1 rad per step), all composed in one slot: the
    quaternion stays unit and the pose follows the exact composition, far closer than the
    first-order δq = (1, θ/2)'s |θ|³/12 per step; the one Newton step of the
    normalization leaves (3/8)(|θ|²/4)² of norm error."""
    params, _, _ = build_case("random")
    rng = np.random.default_rng(SEED)
    steps = np.concatenate([rng.normal(0, 0.01, (400, 3)), rng.normal(0, 0.03, (400, 3))], 1)
    raw = params.step_fmt.quantize(np.clip(steps, -0.1, 0.1))
    result = E.StepResult(step=raw, flags=np.zeros(len(raw), dtype=np.int64))
    quats, positions = E.integrate_rows(params, result, np.zeros(len(raw), dtype=np.int64))
    q = params.quat_fmt.to_float(quats)
    theta = np.linalg.norm(params.step_fmt.to_float(raw)[:, 3:], axis=1)
    newton = 0.375 * (theta ** 2 / 4 + 1e-5) ** 2 + 1e-10
    assert np.all(np.abs(np.linalg.norm(q, axis=1) - 1) < newton)
    q_float, p_float = G.integrate_steps([1.0, 0, 0, 0], np.zeros(3), params.step_fmt.to_float(raw))
    relative = G.quat_multiply(q_float * [1, -1, -1, -1], q / np.linalg.norm(q, axis=1)[:, None])
    angle = 2 * np.arcsin(np.minimum(1, np.linalg.norm(relative[:, 1:], axis=1)))
    assert angle.max() < 1.5 * np.sum(theta ** 3) / 12
    assert np.max(np.linalg.norm(params.position_fmt.to_float(positions) - p_float, axis=1)) < 1e-3


def test_largest_steps_integrate_without_overflow():
    """The increment's values at the step format's extremes (|θ_k| → 1, |θ|² → 3, far
    outside the small-motion range) neither saturate nor wrap: the fixed-point result is
    the float64 evaluation of the same formula, q ⊗ (1 − |θ|²/12, θ/2) then one Newton
    step, to the rounding."""
    params, _, _ = build_case("random")
    qf, sf = params.quat_fmt, params.step_fmt
    rng = np.random.default_rng(SEED)
    q = rng.normal(0, 1, 4)
    for start in ([1.0, 0, 0, 0], q / np.linalg.norm(q)):
        raw_q = qf.quantize(start)
        for theta in (sf.max_raw, sf.min_raw):
            step = np.array([0, 0, 0, theta, theta, -theta], dtype=np.int64)
            result = E.StepResult(step=step[None], flags=np.zeros(1, dtype=np.int64))
            (quat,), _ = E.integrate_rows(params, result, np.zeros(1, dtype=np.int64),
                                          (raw_q, np.zeros(3, dtype=np.int64)))
            a = sf.to_float(step[3:])
            q0 = qf.to_float(raw_q)
            first = G.quat_multiply(q0, np.r_[1.0, a / 2])
            q1 = first - q0 * np.dot(a, a) / 12
            expected = q1 * (1.5 - np.dot(q1, q1) / 2)
            assert np.max(np.abs(qf.to_float(quat) - expected)) < 1e-10, (start, theta)


def test_trajectory_stays_on_the_float_trajectory():
    """0.05 s of the papers' motion on radial4, every row's step composed in one slot
    (2,880 compositions: a slot makes 120 per second): fixed-point pose within a
    twentieth of the 1 s budget (0.02 cm, 0.002°); the full second is in the benchmark."""
    params, coefficients, rig = build_case("radial4")
    rows, synthetic = sequence_rows(params, rig, np.random.default_rng(SEED), 2880)
    result = E.solve_rows(params, coefficients, rows)
    golden = _golden(params, coefficients, rows)
    start_q = params.quat_fmt.quantize(synthetic.start[0])
    start_p = params.position_fmt.quantize(synthetic.start[1])
    quats, positions = E.integrate_rows(params, result, np.zeros(len(rows), dtype=np.int64),
                                        (start_q, start_p))
    steps = np.where((result.flags == 0)[:, None], golden.step, 0.0)
    q_float, p_float = G.integrate_steps(params.quat_fmt.to_float(start_q),
                                         params.position_fmt.to_float(start_p), steps)
    centimetres = 100 * np.linalg.norm(params.position_fmt.to_float(positions) - p_float, axis=1)
    relative = G.quat_multiply(q_float * [1, -1, -1, -1], params.quat_fmt.to_float(quats))
    degrees = np.degrees(2 * np.arcsin(np.minimum(1, np.linalg.norm(relative[:, 1:], axis=1))))
    assert centimetres.max() < 0.02 / 20 and degrees.max() < 0.002 / 20


def test_rows_are_checked():
    params, coefficients, _ = build_case("random")
    rows, _ = random_rows(params, np.random.default_rng(SEED), 3)
    with pytest.raises(ValueError, match="at least one measurement in every row"):
        E.PoseRows(slot=rows.slot, shift=rows.shift, cue=rows.cue, conf=rows.conf,
                   present=np.zeros_like(rows.present), row=rows.row, time=rows.time)
    with pytest.raises(ValueError, match="row must be in"):
        E.solve_rows(params, coefficients, E.PoseRows(
            slot=rows.slot, shift=rows.shift, cue=rows.cue, conf=rows.conf,
            present=rows.present, row=rows.row + params.rows, time=rows.time))
    with pytest.raises(ValueError, match="coef_raw must have shape"):
        E.solve_rows(params, coefficients[:, :3], rows)

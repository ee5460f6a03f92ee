"""emulator.pose.information_gain (the motion filter's information gain in fixed point)
against golden's float :func:`golden.temporal_filter.information_gain`: the prior
information's running average, the gain solve on real solver systems, the filter's
level, the loop's fallback, parameter checks.

Systems come from the stereo20 rig cut to 32 rows (its solver and coefficient store);
set SEED to replay the randomized tests, the seed in use is printed.
"""

import os
from fractions import Fraction

import numpy as np
import pytest

from golden.temporal_filter import information_gain
from hdl.pose.program import UPPER, build_gain_program, build_row_program, schedule
from emulator.pose.forecast import MotionFilter
from emulator.pose.information_gain import PriorInformation, gain_step
from emulator.pose_solver import accumulate, solve_system

from sim_tests.pose.prior_stimulus import cut_stereo20, measurement_rows

SEED = int(os.environ.get("SEED", "5"))

#: |d_fixed − d_float| / |Y − p| per row, the largest allowed: the float gain is computed
#: from the same fixed-point N, Λ and p, so only the engine's rounding (30 fraction bits
#: of the scaled unknowns, D^-1/2 from a seed and one Newton step) and the step format
#: remain. Measured on the test's 39 solved rows (seed 5): 1.2e-9.
GAIN_TOLERANCE = 1e-7


@pytest.fixture(scope="module")
def config():
    return cut_stereo20()


@pytest.fixture(scope="module")
def params(config):
    return config.forecast(motion_gain="information")


def _float(values):
    return np.array([v.fmt.to_float(np.asarray(v.raw, dtype=object).astype(float))
                     for v in values]).T


def _matrix(upper):
    out = np.zeros(upper.shape[:-1] + (6, 6))
    for k, (i, j) in enumerate(UPPER):
        out[..., i, j] = out[..., j, i] = upper[..., k]
    return out


def test_the_row_program_is_unchanged_by_the_gain_program(config):
    """The shared Cholesky solve keeps the row program's ops and schedule (the engine's
    ROM and its 258-clock schedule at this size); the gain program is its own."""
    solver = config.top.solver
    row, gain = build_row_program(solver), build_gain_program(solver)
    assert not {op.dst.name for op in row.ops} & {op.dst.name for op in gain.ops
                                                   if op.dst.bank == "work"} - {"three_halves"}
    assert [f"N{i}{j}" for i, j in UPPER] == list(gain.inputs)[:21]
    assert len(gain.step) == 6 and all(op.checked for op in gain.ops if op.kind == "mac")
    print("row program", schedule(row).length, "clocks; gain program",
          schedule(gain).length, "clocks")


def test_prior_information_is_the_golden_running_average_of_solved_rows(config, params):
    """First solved row: ``Λ = c·N``; later rows ``Λ ← (1 − s) Λ + s c N``, computed
    exactly (rationals, the quantized c and s): each update rounds once by at most half
    an ulp and the average forgets old errors at the rate s, so the error stays within
    ``1/(2s) + 1`` ulp (200 rows of random systems)."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    solver = params.solver
    prior = PriorInformation(params)
    c = Fraction(params.prior_raw, 1 << params.prior_fmt.frac_bits)
    s = Fraction(params.smoothing_raw, 1 << params.gain_fmt.frac_bits)
    unit = Fraction(1, 1 << (params.information_fmt.frac_bits - solver.normal_fmt.frac_bits))
    bound = 1 / (2 * s) + 1
    expected, normals, worst = None, [], 0
    for _ in range(200):
        normal, _ = accumulate(solver, config.coef_raw, measurement_rows(params, rng, 1))
        raw = [int(v.raw[0]) for v in normal]
        normals.append(raw)
        prior.keep(prior.updated(raw))
        n = [c * v / unit for v in raw]          # c·N in information_fmt ulps, exactly
        expected = n if expected is None else [(1 - s) * e + s * v
                                               for e, v in zip(expected, n)]
        error = max(abs(int(g) - e) for g, e in zip(prior.prior, expected))
        worst = max(worst, error)
        assert error <= bound
    print(f"largest difference from the exact average: {float(worst):.2f} ulp "
          f"(bound {float(bound):.1f})")
    assert np.ptp(np.array(normals, dtype=float), axis=0).max() > 0   # the rows differed


def test_prior_information_cannot_overflow_at_the_extremes(params):
    """The largest prior weight of ``prior_fmt`` times the most negative and positive
    normal-matrix entries fits ``information_fmt`` (``Overflow.ERROR`` would raise)."""
    fmt = params.solver.normal_fmt
    extreme = params.replace(alpha=1 / (1 + params.prior_fmt.max_value))
    prior = PriorInformation(extreme)
    assert extreme.prior_raw == params.prior_fmt.max_raw
    for value, other in ((fmt.min_raw, fmt.max_raw), (fmt.max_raw, fmt.min_raw)):
        first = prior.updated([value] * 21)
        prior.keep(first)
        later = prior.updated([other] * 21)
        assert all(params.information_fmt.min_raw <= int(v) <= params.information_fmt.max_raw
                   for v in (*first, *later))


def test_gain_step_is_the_golden_information_gain_of_the_row(config, params):
    """40 rows with a prior of earlier random rows and a prediction near the solved step:
    ``d`` is golden's ``(N + Λ)⁻¹ N (Y − p)`` on the same fixed-point N, Λ and p within
    GAIN_TOLERANCE of |Y − p|; rows with only some cameras (weak directions) are among
    them, and there the gain differs from the scalar α."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    solver = params.solver
    coef = config.coef_raw
    prior = PriorInformation(params)
    for _ in range(30):
        normal, _ = accumulate(solver, coef, measurement_rows(params, rng, 1))
        prior.keep(prior.updated([int(v.raw[0]) for v in normal]))
    errors, departures = [], []
    for r in range(40):
        cameras = None if r % 2 else sorted(rng.choice(params.cameras, 4, replace=False))
        rows = measurement_rows(params, rng, 1, cameras)
        normal, rhs = accumulate(solver, coef, rows)
        result = solve_system(solver, normal, rhs, rows.counts > solver.slots)
        if result.flags[0]:
            continue
        y = solver.step_fmt.to_float(result.step[0].astype(float))
        predicted = params.motion_fmt.quantize(y + rng.normal(scale=1e-3, size=6))
        updated = prior.updated([int(v.raw[0]) for v in normal])
        d, flags = gain_step(params, normal, rhs, updated[None], predicted[None])
        assert flags[0] == 0
        n = _matrix(_float(normal)[0])
        lam = _matrix(params.information_fmt.to_float(np.array(updated, dtype=float)))
        p = params.motion_fmt.to_float(predicted.astype(float))
        y_exact = np.linalg.solve(n, _float(rhs)[0])
        expected = np.linalg.solve(n + lam, n @ (y_exact - p))
        got = solver.step_fmt.to_float(d[0].astype(float))
        errors.append(np.abs(got - expected).max() / np.abs(y_exact - p).max())
        alpha = params.gain_fmt.to_float(params.alpha_raw)
        departures.append(np.abs(expected - alpha * (y_exact - p)).max()
                          / np.abs(y_exact - p).max())
    print(f"{len(errors)} rows: max relative error {max(errors):.2e}, largest departure "
          f"from the scalar gain {max(departures):.2f}")
    assert len(errors) >= 30
    assert max(errors) < GAIN_TOLERANCE
    assert max(departures) > 0.05          # the gain is not the scalar α in disguise


def test_the_filter_moves_by_the_gain_when_given_and_by_alpha_without(params):
    zero = np.zeros(6, dtype=np.int64)
    step = params.solver.step_fmt.quantize(np.full(6, 0.01))
    d = params.solver.step_fmt.quantize(np.array([0.002, 0, 0, 0, 0, -0.001]))
    gained = MotionFilter(params, zero)
    level = gained.update(step, d)
    assert np.allclose(params.motion_fmt.to_float(level), [0.002, 0, 0, 0, 0, -0.001],
                       atol=1e-11)
    scalar = MotionFilter(params, zero)
    alpha = params.gain_fmt.to_float(params.alpha_raw)
    assert np.allclose(params.motion_fmt.to_float(scalar.update(step)), alpha * 0.01,
                       atol=1e-11)


@pytest.mark.parametrize("changes, name", [({"motion_gain": "matrix"}, "motion_gain"),
                                           ({"typical_smoothing": 0.0}, "typical_smoothing"),
                                           ({"typical_smoothing": 1e-9}, "typical_smoothing"),
                                           ({"alpha": 1e-3}, "alpha")])
def test_bad_parameters_are_named(params, changes, name):
    with pytest.raises(ValueError, match=name):
        params.replace(**changes)

"""The pose solver with the information gain (``PoseSolver(..., gain=...)``: prior store,
the normalizer's gain inputs, the merged engine program, the ``gains`` stream) in the
Amaranth simulator against the model (:func:`emulator.pose_solver.solve_system`,
:class:`emulator.pose.information_gain.PriorInformation`,
:func:`emulator.pose.information_gain.gain_step`): rows of measurements on the cut
stereo20 solver (all cameras, or three: weak directions), each with its own prediction;
every record's step and flags and every solved row's moves and ``ok`` bit for bit.
SEED replays it (printed)."""

import os

import numpy as np
import pytest
from amaranth.sim import Simulator

from hdl.pose_solver import PoseSolver
from emulator.pose.information_gain import PriorInformation, gain_step
from emulator.pose_solver import accumulate, solve_system

from sim_tests.pose.prior_stimulus import cut_stereo20, measurement_rows

SEED = int(os.environ.get("SEED", "6"))


@pytest.fixture(scope="module")
def setup():
    config = cut_stereo20()
    return config, config.forecast(motion_gain="information", alpha=0.07)


def stimulus(config, params, rng, count):
    """(PoseRows of one row, prediction raw (6,)) per row: every third row on three
    cameras, the prediction near the row's solved step."""
    out = []
    for r in range(count):
        cameras = sorted(rng.choice(params.cameras, 3, replace=False)) if r % 3 == 2 else None
        rows = measurement_rows(params, rng, 1, cameras)
        rows = type(rows)(**{**rows.__dict__, "time": np.array([r])})
        normal, rhs = accumulate(params.solver, config.coef_raw, rows)
        result = solve_system(params.solver, normal, rhs, rows.counts > params.solver.slots)
        y = params.solver.step_fmt.to_float(result.step[0].astype(float))
        out.append((rows, params.motion_fmt.quantize(y + rng.normal(scale=2e-3, size=6))))
    return out


def expected(config, params, rows):
    """Per row: (step, flags, moves or None, ok or None) of the model."""
    prior = PriorInformation(params)
    out = []
    for pose_rows, predicted in rows:
        normal, rhs = accumulate(params.solver, config.coef_raw, pose_rows)
        result = solve_system(params.solver, normal, rhs,
                              pose_rows.counts > params.solver.slots)
        moves = ok = None
        if result.flags[0] == 0:
            updated = prior.updated([int(v.raw[0]) for v in normal])
            d, flags = gain_step(params, normal, rhs, updated[None], predicted[None])
            prior.keep(updated)
            moves, ok = [int(v) for v in d[0]], int(flags[0] == 0)
        out.append(([int(v) for v in result.step[0]], int(result.flags[0]), moves, ok))
    return out


def run_solver(config, params, rows):
    dut = PoseSolver(params.solver, config.coef_store, gain=params)
    got = []

    async def bench(ctx):
        ctx.set(dut.o.ready, 1)
        ctx.set(dut.gains.ready, 1)
        for pose_rows, predicted in rows:
            ctx.set(dut.predicted, [int(v) for v in predicted])
            for t in pose_rows.transfers():
                for name, value in t.items():
                    ctx.set(getattr(dut.i.payload, name), value)
                ctx.set(dut.i.valid, 1)
                await ctx.tick().until(dut.i.ready)
            ctx.set(dut.i.valid, 0)
            # the record and the moves come out together; the prediction holds until then
            *_, step, flags, moves, ok = await ctx.tick().sample(
                dut.o.payload.step, dut.o.payload.flags, dut.gains.payload.move,
                dut.gains.payload.ok).until(dut.o.valid & dut.gains.valid)
            got.append(([int(v) for v in step], int(flags), [int(v) for v in moves], int(ok)))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return got


def test_records_and_moves_match_the_model(setup):
    print(f"SEED={SEED}")
    config, params = setup
    rows = stimulus(config, params, np.random.default_rng(SEED), 9)
    want = expected(config, params, rows)
    got = run_solver(config, params, rows)
    solved = 0
    for r, ((step, flags, moves, ok), (w_step, w_flags, w_moves, w_ok)) in enumerate(
            zip(got, want)):
        assert (step, flags) == (w_step, w_flags), f"row {r}: record"
        if w_flags == 0:
            solved += 1
            assert (ok, moves if w_ok else None) == (w_ok, w_moves if w_ok else None), \
                f"row {r}: moves"
    print(f"{len(got)} rows, {solved} solved, moves of the solved rows stood: "
          f"{sum(w[3] for w in want if w[1] == 0)}; largest move "
          f"{max(abs(v) for w in want if w[2] for v in w[2])}")
    assert solved >= 6 and sum(w[3] for w in want if w[1] == 0) >= 6

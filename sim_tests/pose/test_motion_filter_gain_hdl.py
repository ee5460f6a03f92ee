"""hdl.pose.forecast_filter.MotionFilter with ``motion_gain="information"`` in the Amaranth
simulator against the model (:class:`emulator.pose.forecast.ForecastModel`: the filter
and the loop delay): random solved and flagged records, each with a gain that stands or
was flagged (the level then moves by α), random idle clocks; every forecast Ŷ bit for
bit. SEED replays it (printed)."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from hdl.pose.forecast_filter import MotionFilter
from emulator.pose.forecast import ForecastModel

from sim_tests.pose.forecast.stimulus import small_params

SEED = int(os.environ.get("SEED", "4"))


def records(params, rng, count):
    """(step raw (6,), flags, move raw (6,), ok) per row: steps of about a centimetre,
    moves a fraction of them, a fifth of the rows flagged, a tenth of the gains."""
    fmt = params.solver.step_fmt
    out = []
    for _ in range(count):
        step = fmt.quantize(rng.normal(scale=0.01, size=6))
        move = fmt.quantize(rng.normal(scale=0.003, size=6))
        out.append((step, int(rng.random() < 0.2), move, int(rng.random() >= 0.1)))
    return out


def run_filter(params, rows, seed):
    """Per row slot: query, read Ŷ, then the record and its gain. Returns every Ŷ."""
    dut = MotionFilter(params)
    rng = random.Random(seed)
    motions = []

    async def bench(ctx):
        ctx.set(dut.restart, 1)
        await ctx.tick()
        ctx.set(dut.restart, 0)
        for slot, (step, flags, move, ok) in enumerate(rows):
            ctx.set(dut.query.payload, slot)
            ctx.set(dut.query.valid, 1)
            await ctx.tick().until(dut.query.ready)
            ctx.set(dut.query.valid, 0)
            await ctx.tick().until(dut.motion_valid)
            motions.append([ctx.get(dut.motion[i]) for i in range(6)])
            while rng.random() < 0.3:
                await ctx.tick()
            ctx.set(dut.records.payload.step, [int(v) for v in step])
            ctx.set(dut.records.payload.flags, flags)
            ctx.set(dut.records.valid, 1)
            if rng.random() < 0.5:          # the gain may come late: the record waits
                await ctx.tick().repeat(3)
                assert not ctx.get(dut.records.ready)
            ctx.set(dut.gains.payload.move, [int(v) for v in move])
            ctx.set(dut.gains.payload.ok, ok)
            ctx.set(dut.gains.valid, 1)
            await ctx.tick().until(dut.records.ready)
            ctx.set(dut.records.valid, 0)
            ctx.set(dut.gains.valid, 0)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return motions


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_forecasts_match_the_model(delay):
    print(f"SEED={SEED}")
    params = small_params(motion_gain="information", loop_delay_rows=delay)
    rows = records(params, np.random.default_rng(SEED), 60)
    model = ForecastModel(params, None, None, np.zeros(6, dtype=np.int64))
    want = []
    for slot, (step, flags, move, ok) in enumerate(rows):
        want.append([int(v) for v in model.motion(slot)])
        solved = not flags
        model.take(slot, step if solved else None, move if solved and ok else None)
    got = run_filter(params, rows, SEED)
    assert got == want
    # the moves and α both took part, and the forecast moved
    assert sum(1 for _, f, _, ok in rows if not f and ok) > 30
    assert sum(1 for _, f, _, ok in rows if not f and not ok) > 2
    assert np.ptp(np.array(want), axis=0).min() > 0

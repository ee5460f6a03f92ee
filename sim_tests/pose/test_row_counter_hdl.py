"""RowCounter gateware (hdl/pose/row_counter.py) in the Amaranth simulator against
:func:`emulator.pose.tracking_status.count_rows`: random rows of verdicts (some longer
than ``slots``: the counts stop there), with and without valid gaps and ready
backpressure (SEED, printed); the parameter check."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from emulator.hdl_sim.payload import pack
from emulator.pose.tracking_status import count_rows, measurement_verdicts
from hdl.pose.row_counter import RowCounter, verdict_layout
from hdl.pose.status_params import ROW_INPUTS

from sim_tests.common.sim_streams import drain
from sim_tests.pose.status_stimulus import SMALL, random_verdicts

SEED = int(os.environ.get("SEED", "1"))


def run_counter(params, verdicts, *, seed, gaps):
    dut = RowCounter(params)
    rng, sink_rng = random.Random(seed), random.Random(seed + 1)
    prob = 0.6 if gaps else 1.0
    rows = sum(v["last"] for v in verdicts)
    got = []

    async def source(ctx):
        for v in verdicts:
            while rng.random() >= prob:
                await ctx.tick()
            ctx.set(dut.i.payload.as_value(), pack(verdict_layout(), v))
            ctx.set(dut.i.valid, 1)
            await ctx.tick().until(dut.i.ready)
            ctx.set(dut.i.valid, 0)

    async def sink(ctx):
        await drain(ctx, dut.o, rows, rng=sink_rng, prob=prob, out=got,
                    convert=lambda payload: tuple(int(getattr(payload, n)) for n in ROW_INPUTS),
                    limit=10 * len(verdicts) + 100)
        await ctx.tick().repeat(4)
        assert not ctx.get(dut.o.valid)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source, background=True)
    sim.add_testbench(sink)
    sim.run()
    return got


@pytest.mark.parametrize("gaps", [False, True], ids=["full_rate", "gaps_and_backpressure"])
def test_counts_match_model(gaps):
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    verdicts = random_verdicts(rng, 300, SMALL.slots)
    want = count_rows(verdicts, SMALL.slots)
    assert run_counter(SMALL, verdicts, seed=SEED, gaps=gaps) == want
    assert max(max(w[:3]) for w in want) == SMALL.slots      # some counts stopped
    assert {w[3] for w in want} == {0, 1}                    # both determinable verdicts


def test_measurement_verdicts_of_a_consistency_row():
    verdict = {"outlier": np.array([False, True, False]), "conf": np.array([3, 0, 0]),
               "determinable": True}
    bits = measurement_verdicts(np.array([5, 7, 0]), verdict)
    assert [b["last"] for b in bits] == [0, 0, 1]
    assert [b["determinable"] for b in bits] == [0, 0, 1]
    assert count_rows(bits, 8) == [(2, 1, 1, 1)]
    bits = measurement_verdicts(np.array([5]), {**verdict, "determinable": False})
    assert count_rows(bits, 8) == [(1, 0, 1, 0)]


def test_parameter_check():
    with pytest.raises(TypeError, match="params must be a StatusParams"):
        RowCounter(None)

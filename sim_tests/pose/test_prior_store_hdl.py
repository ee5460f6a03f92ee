"""PriorStore gateware (hdl/pose/prior_store.py) in the Amaranth simulator against
:class:`emulator.pose.information_gain.PriorInformation`: the normal matrices of rows of
measurements accumulated with the stereo20 solver's coefficient store (and rows at the
extremes of ``normal_fmt``), random verdicts, valid gaps and ready backpressure, and
malformed rows (counted, never kept). SEED replays the randomized tests (printed)."""

import gc
import os
import random
import warnings

import numpy as np
import pytest
from amaranth.hdl import UnusedElaboratable
from amaranth.sim import Simulator

from hdl.pose.prior_store import PriorStore

from sim_tests.pose.prior_stimulus import (ENTRIES, cut_stereo20, expected_totals, framed,
                                           normals)

SEED = int(os.environ.get("SEED", "2"))


@pytest.fixture(scope="module")
def setup():
    config = cut_stereo20()
    return config, config.forecast(motion_gain="information")


def run_store(params, rows, *, seed, gaps):
    """Drive ``rows`` (each: (entries (value, last) list, keep)); returns the M values of
    every row and the final ``malformed`` and ``valid`` (a dict)."""
    dut = PriorStore(params)
    rng, sink_rng = random.Random(seed), random.Random(seed + 1)
    prob = 0.6 if gaps else 1.0
    got, status = [[] for _ in rows], {}

    async def source(ctx):
        for entries, keep in rows:
            for value, last in entries:
                while rng.random() >= prob:
                    await ctx.tick()
                ctx.set(dut.i.payload.value, value)
                ctx.set(dut.i.payload.last, last)
                ctx.set(dut.i.valid, 1)
                await ctx.tick().until(dut.i.ready)
                ctx.set(dut.i.valid, 0)
            ctx.set(dut.keep.payload, keep)
            ctx.set(dut.keep.valid, 1)
            await ctx.tick().until(dut.keep.ready)
            ctx.set(dut.keep.valid, 0)

    async def sink(ctx):
        row, cycles = 0, 0
        total = sum(len(entries) for entries, _ in rows)
        while sum(map(len, got)) < total:
            ready = sink_rng.random() < prob
            ctx.set(dut.o.ready, ready)
            *_, valid, value, last = await ctx.tick().sample(dut.o.valid, dut.o.payload.value,
                                                             dut.o.payload.last)
            if valid and ready:
                got[row].append(int(value))
                row += bool(last)
            cycles += 1
            assert cycles < 10 * total + 100, "prior store hung"
        await ctx.tick().repeat(8)
        assert not ctx.get(dut.o.valid)
        status.update(malformed=ctx.get(dut.malformed), valid=ctx.get(dut.valid))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source, background=True)
    sim.add_testbench(sink)
    sim.run()
    return got, status


@pytest.mark.parametrize("gaps", [False, True], ids=["full_rate", "gaps_and_backpressure"])
@pytest.mark.parametrize("alpha", [0.1, 0.07], ids=["alpha_0.1", "alpha_0.07"])
def test_m_and_the_prior_match_the_model(setup, gaps, alpha):
    """α = 0.1 gives the prior weight c = 9 (c·N exact); α = 0.07 a c with a fraction,
    so both of the update's roundings take part."""
    print(f"SEED={SEED}")
    config, params = setup
    params = params.replace(alpha=alpha, typical_smoothing=0.03)
    rng = np.random.default_rng(SEED)
    matrices = normals(config, params, rng, 40)
    keeps = [int(v) for v in rng.random(len(matrices)) < 0.8]
    keeps[0] = 0                          # the first row is not kept: Λ stays unset
    rows = framed(matrices, keeps)
    got, status = run_store(params, rows, seed=SEED, gaps=gaps)
    want, model = expected_totals(params, rows)
    for r, (g, w) in enumerate(zip(got, want)):
        assert g == w, f"row {r}"
    assert model.valid and sum(keeps) > 20
    assert status == {"malformed": 0, "valid": 1}


def test_malformed_rows_are_counted_and_never_kept(setup):
    """A row ending early (``last`` on entry 5) and one without ``last``: both counted,
    neither kept although their verdicts say keep; the rows after them match the model
    without them."""
    config, params = setup
    rng = np.random.default_rng(SEED + 1)
    a, b, c, d = normals(config, params, rng, 4)
    rows = [([(v, int(k == ENTRIES - 1)) for k, v in enumerate(a)], 1),
            ([(v, int(k == 5)) for k, v in enumerate(b[:6])], 1),
            ([(v, 0) for v in c], 1),
            ([(v, int(k == ENTRIES - 1)) for k, v in enumerate(d)], 1)]
    got, status = run_store(params, rows, seed=SEED, gaps=True)
    want, _ = expected_totals(params, [rows[0], rows[3]])
    assert got[0] == want[0] and got[3] == want[1]
    assert [len(g) for g in got] == [ENTRIES, 6, ENTRIES, ENTRIES]
    assert status == {"malformed": 2, "valid": 1}


def test_bad_parameters_are_named():
    with warnings.catch_warnings():      # the component that failed is unused
        warnings.simplefilter("ignore", UnusedElaboratable)
        with pytest.raises(TypeError, match="params must be a ForecastParams"):
            PriorStore("params")
        gc.collect()

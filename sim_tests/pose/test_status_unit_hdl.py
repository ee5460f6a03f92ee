"""Status unit gateware (hdl/pose/status_unit.py) in the Amaranth simulator, bit-exact
with :class:`emulator.pose.tracking_status.StatusUnitModel`: every output record (all
fields, the flags with status and drifted), the state register after the run; random
regime rows (SEED, printed) with and without valid gaps and ready backpressure, window
changes and clear strobes between records, records of a real closed-loop emulator run,
the latency and throughput, and the parameter checks."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from emulator.hdl_sim.payload import pack
from hdl.pose.params import PoseSolverParams, solver_source
from hdl.pose.status_params import ROW_INPUTS, StatusParams
from hdl.pose.status_unit import StatusUnit

from sim_tests.pose.status_stimulus import (SMALL, SOLVER, expected, packable, random_records,
                                            regime_rows)

SEED = int(os.environ.get("SEED", "1"))
STATE = ("status", "drifted", "lost", "acquired", "window_error", "losses",
         "degraded_rows", "lost_rows")


def run_unit(params, solver, records, rows, *, seed, gaps, events=None):
    """Records and rows through the gateware; ``events`` maps a record index to
    settings changes (dict) or ``"clear"``, applied once the record before it is out.
    Returns the output records (flags included), the state and the transfer clocks."""
    dut = StatusUnit(params, solver)
    rng, sink_rng = random.Random(seed), random.Random(seed + 1)
    prob = 0.6 if gaps else 1.0
    events = events or {}
    src_layout = solver_source(solver).layout()
    out = {"records": [], "in_cycles": [], "out_cycles": []}
    cycle = [0]

    async def source(ctx):
        for k, (record, row) in enumerate(zip(records, rows)):
            while len(out["records"]) < k and k in events:
                await ctx.tick()
            event = events.get(k)
            if event == "clear":
                ctx.set(dut.clear, 1)
                await ctx.tick()
                ctx.set(dut.clear, 0)
            elif event:
                for name, value in event.items():
                    ctx.set(getattr(dut.settings, name), value)
            while rng.random() >= prob:
                await ctx.tick()
            ctx.set(dut.i.payload.as_value(), pack(src_layout, packable({**record,
                                                                          "flags": row[0]})))
            ctx.set(dut.row.payload.as_value(), pack(dut.row.payload.shape(),
                                                     dict(zip(ROW_INPUTS, row[1:]))))
            ctx.set(dut.i.valid, 1)
            ctx.set(dut.row.valid, 1)
            await ctx.tick().until(dut.i.ready)
            out["in_cycles"].append(cycle[0])
            ctx.set(dut.i.valid, 0)
            ctx.set(dut.row.valid, 0)

    async def sink(ctx):
        while len(out["records"]) < len(records):
            ready = sink_rng.random() < prob
            ctx.set(dut.o.ready, ready)
            *_, valid, payload = await ctx.tick().sample(dut.o.valid, dut.o.payload)
            cycle[0] += 1
            if valid and ready:
                out["records"].append(_record(payload))
                out["out_cycles"].append(cycle[0] - 1)
            assert cycle[0] < 20 * len(records) + 100, "unit hung"
        await ctx.tick().repeat(8)
        assert not ctx.get(dut.o.valid)
        out["state"] = {name: ctx.get(getattr(dut.state, name)) for name in STATE}

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source, background=True)
    sim.add_testbench(sink)
    sim.run()
    return out


def _record(view):
    def value(v):
        return [int(x) for x in v] if hasattr(v, "__len__") and not isinstance(v, int) \
            else int(v)
    return {name: value(getattr(view, name))
            for name in ("row", "time", "flags", "q", "p", "step")}


def check(params, solver, records, rows, *, seed, gaps, events=None):
    got = run_unit(params, solver, records, rows, seed=seed, gaps=gaps, events=events)
    want, state = expected(params, records, rows, events)
    for k, (g, w) in enumerate(zip(got["records"], want)):
        assert g == w, f"record {k}: hardware {g}, model {w}; row {rows[k]}"
    assert len(got["records"]) == len(want)
    assert got["state"] == state
    return got


@pytest.mark.parametrize("gaps", [False, True], ids=["full_rate", "gaps_and_backpressure"])
def test_random_regimes_bit_exact(gaps):
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    rows = regime_rows(rng, 600, SMALL)
    records = random_records(SOLVER, rng, len(rows))
    got = check(SMALL, SOLVER, records, rows, seed=SEED, gaps=gaps)
    codes = {(r["flags"] >> 4) & 3 for r in got["records"]}
    assert codes == {0, 1, 2}


def test_window_changes_and_clear_between_records():
    """New windows (including 0 and too large, flagged) and clear strobes, and new
    thresholds, between records."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED + 1)
    rows = regime_rows(rng, 400, SMALL)
    records = random_records(SOLVER, rng, len(rows))
    events = {40: {"window": 3}, 90: "clear", 150: {"window": 0}, 170: {"window": 16},
              200: {"window": 31}, 230: {"window": 9, "degraded_measurements": 0},
              260: {"lost_outlier_fraction": 1 << 16, "degraded_ill_fraction": 0},
              300: "clear", 330: {"window": 1}}
    check(SMALL, SOLVER, records, rows, seed=SEED, gaps=True, events=events)


def test_real_closed_loop_records_bit_exact():
    """The records and per-row counts of the emulator's closed loop (stereo20 cut to 32
    rows, 3 frames; sim_tests/pose/status_runs.py) with the golden thresholds."""
    from sim_tests.pose.status_runs import dataset, emulator_run, frame_rows
    from golden.tracker_params import TrackerParams
    data = dataset()
    config, records, rows = emulator_run(data)
    solver = config.router.solver
    params = StatusParams.for_tracker(TrackerParams(), slots=solver.slots,
                                      frame_rows=frame_rows(data), max_window=64)
    fields = [{name: (records[name][k].tolist() if np.ndim(records[name][k]) else
                      int(records[name][k])) for name in ("row", "time", "q", "p", "step")}
              for k in range(len(rows))]
    got = check(params, solver, fields, rows, seed=SEED, gaps=True)
    assert {(r["flags"] >> 4) & 3 for r in got["records"]} == {0, 1, 2}


def test_latency_and_interval():
    rng = np.random.default_rng(SEED)
    rows = regime_rows(rng, 50, SMALL)
    got = run_unit(SMALL, SOLVER, random_records(SOLVER, rng, 50), rows, seed=SEED,
                   gaps=False)
    latency = np.array(got["out_cycles"]) - np.array(got["in_cycles"])
    assert set(latency.tolist()) == {StatusUnit.latency}
    assert set(np.diff(got["in_cycles"]).tolist()) == {StatusUnit.interval}


def test_parameter_checks():
    with pytest.raises(TypeError, match="params must be a StatusParams"):
        StatusUnit(None, SOLVER)
    with pytest.raises(TypeError, match="solver must be a PoseSolverParams"):
        StatusUnit(SMALL, None)
    with pytest.raises(ValueError, match=r"params.slots must be the solver's slots \(16\), "
                                         r"not 8"):
        StatusUnit(SMALL, PoseSolverParams(slots=16))

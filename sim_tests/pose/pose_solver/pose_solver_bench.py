"""cocotb bench for hdl.pose_solver.PoseSolver: every pose record against
emulator.pose_solver, in order and bit for bit, plus latency and throughput.

Environment: POSE_CASE (a stimulus case), POSE_ROWS (rows per test, default 300),
POSE_FRAMED=1 (``random`` case: table rows in frame order, so every row slot's pose is
read back once per frame; otherwise random order, with slots repeating back to back).
"""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, RisingEdge

from emulator.pose_solver import pose_solver_model
from hdl.pose_solver import PoseSolver, counters_layout, measurement_layout, record_layout
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.payload import unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource

from sim_tests.pose.pose_solver.stimulus import build_case, mixed_rows


def _expected(params, coefficients, rows):
    model = pose_solver_model(params, coefficients, rows)
    return [{"row": int(model["row"][k]), "time": int(model["time"][k]),
             "flags": int(model["flags"][k]), "q": [int(v) for v in model["q"][k]],
             "p": [int(v) for v in model["p"][k]], "step": [int(v) for v in model["step"][k]]}
            for k in range(len(rows))], model


def _record(payload):
    """An unpacked record with its arrays as lists (``unpack`` gives index dicts)."""
    return {name: [value[k] for k in range(len(value))] if isinstance(value, dict) else value
            for name, value in payload.items()}


def _first_difference(got, expected):
    for k, (g, e) in enumerate(zip(got, expected)):
        if g != e:
            return f"record {k} (row {e['row']}): hardware {g} != model {e}"
    return f"{len(got)} records received, {len(expected)} expected"


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def pose_records_match_model(dut, traffic):
    """Rows of the case's mix, with or without valid gaps and ready backpressure. At
    full rate the rows start once the pose ring is cleared after reset (the latency
    check needs an idle solver); with gaps they start at once and the first waits."""
    case = os.environ["POSE_CASE"]
    count = int(os.environ.get("POSE_ROWS", "300"))
    framed = bool(int(os.environ.get("POSE_FRAMED", "0")))
    params = load_params()
    _, coefficients, rig = build_case(case)
    solver = PoseSolver(params, coefficients)
    rng = random.Random(cocotb.RANDOM_SEED)
    rows = mixed_rows(case, params, rig, np.random.default_rng(cocotb.RANDOM_SEED), count,
                      framed=framed)
    expected, model = _expected(params, coefficients, rows)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    source = StreamSource(dut, "i", measurement_layout(params), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.7)
    sink = StreamSink(dut, "o", record_layout(params), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.3)
    _drive_side_inputs(dut, params)
    await reset(dut)
    if busy:
        await ClockCycles(dut.clk, solver.clear_clocks)
    await source.send(rows.transfers())
    sidecar = load_sidecar()
    await sink.wait_for(len(expected), timeout_cycles=len(expected) * 4 * sidecar["latency"])
    got = [_record(payload) for _, payload in sink.received]
    assert got == expected, _first_difference(got, expected)

    flags = np.bincount(model["flags"], minlength=9)
    counters = unpack(counters_layout(params), dut.counters.value)
    assert counters == {"solved": int(flags[0]), "empty": int(flags[1]), "ill": int(flags[2]),
                        "saturated": int(flags[4]), "overrun": int(flags[8])}, counters
    slots = np.bincount(rows.row, minlength=params.rows)
    dut._log.info(f"{case}/{traffic}: {len(got)} records bit-exact; flags {flags.tolist()}; "
                  f"row slots used {np.sum(slots > 0)}, up to {slots.max()} times")
    if busy:
        _check_timing(dut, source, sink, sidecar, solver.row_interval)


def _check_timing(dut, source, sink, sidecar, interval):
    """A record whose row found the solver idle comes exactly ``latency`` clocks after
    the row's last transfer; back to back, rows never take longer than ``row_interval``."""
    ends = [cycle for cycle, p in source.sent if p["last"]]
    outs = [cycle for cycle, _ in sink.received]
    latency = sidecar["latency"]
    idle = [k for k in range(len(ends)) if k == 0 or outs[k - 1] < ends[k]]
    assert idle, "no row found the solver idle"
    assert [outs[k] - ends[k] for k in idle] == [latency] * len(idle), \
        f"latency differs from {latency}: {[outs[k] - ends[k] for k in idle][:10]}"
    gaps = np.diff(outs)
    assert gaps.max() <= interval, f"rows {gaps.max()} clocks apart, row_interval {interval}"
    dut._log.info(f"latency {latency} clocks on {len(idle)} idle rows; row interval "
                  f"{gaps.min()}..{gaps.max()} clocks (bound {interval})")


def _drive_side_inputs(dut, params):
    """No coefficient write, no row gated, the conditioning gate at its reset value:
    every input driven (Icarus leaves an undriven one X, which reaches the records)."""
    dut.pivot_log2.value = params.pivot_log2
    dut.coef_write__en.value = 0
    dut.coef_write__addr.value = 0
    dut.coef_write__index.value = 0
    dut.coef_write__data.value = 0
    dut.gated.value = 0


@cocotb.test()
async def coefficients_rewritten_at_run_time(dut):
    """A coefficient written through coef_write changes the next solve as in the model."""
    case = os.environ["POSE_CASE"]
    params = load_params()
    _, coefficients, rig = build_case(case)
    rows = mixed_rows(case, params, rig, np.random.default_rng(cocotb.RANDOM_SEED), 4)
    coefficients = coefficients.copy()
    clock = start_clock(dut)
    source = StreamSource(dut, "i", measurement_layout(params), clock)
    sink = StreamSink(dut, "o", record_layout(params), clock)
    _drive_side_inputs(dut, params)
    await reset(dut)
    rng = np.random.default_rng(cocotb.RANDOM_SEED)
    fmts = [params.coef_t_fmt] * 3 + [params.coef_c_fmt] * 3 + [params.coef_r_fmt] * 3
    for r in range(len(rows)):
        for slot in rows.slot[r][rows.present[r]]:
            index = int(rng.integers(0, 9))
            value = int(rng.integers(fmts[index].min_raw, fmts[index].max_raw + 1))
            coefficients[slot, rows.row[r], index] = value
            dut.coef_write__addr.value = int(slot) * params.rows + int(rows.row[r])
            dut.coef_write__index.value = index
            dut.coef_write__data.value = value & ((1 << params.coef_store_width) - 1)
            dut.coef_write__en.value = 1
            await RisingEdge(dut.clk)
    dut.coef_write__en.value = 0
    expected, _ = _expected(params, coefficients, rows)
    await source.send(rows.transfers())
    await sink.wait_for(len(expected), timeout_cycles=len(expected) * 4 * load_sidecar()["latency"])
    got = [_record(payload) for _, payload in sink.received]
    assert got == expected, _first_difference(got, expected)

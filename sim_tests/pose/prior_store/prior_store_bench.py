"""cocotb bench for hdl.pose.prior_store.PriorStore: every row's ``M = N + Λ'`` against
:class:`emulator.pose.information_gain.PriorInformation` on normal matrices of the cut
stereo20 solver (:mod:`sim_tests.pose.prior_stimulus`), random verdicts. Environment:
PRIOR_ROWS (rows, seeded by cocotb's RANDOM_SEED)."""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.streams import StreamSink, StreamSource
from hdl.pose.prior_store import entry_layout, total_fmt

from sim_tests.pose.prior_stimulus import cut_stereo20, expected_totals, framed, normals


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def totals_match_model(dut, traffic):
    params = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    data_rng = np.random.default_rng(cocotb.RANDOM_SEED)
    count = int(os.environ.get("PRIOR_ROWS", "30"))
    matrices = normals(cut_stereo20(), params, data_rng, count)
    rows = framed(matrices, data_rng.random(count) < 0.8)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    dut.prior_weight.value = params.prior_raw
    dut.smoothing.value = params.smoothing_raw
    entries = StreamSource(dut, "i", entry_layout(params.solver.normal_fmt), clock, rng=rng,
                           valid_prob=1.0 if busy else 0.6)
    verdicts = StreamSource(dut, "keep", 1, clock, rng=rng, valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", entry_layout(total_fmt(params)), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    await reset(dut)
    for row, keep in rows:
        await entries.send([{"value": v, "last": last} for v, last in row])
        await verdicts.send([keep])
    want, model = expected_totals(params, rows)
    total = sum(len(w) for w in want)
    await sink.wait_for(total, timeout_cycles=10 * total + 100)
    await ClockCycles(dut.clk, 4)
    got = [payload["value"] for _, payload in sink.received]
    assert got == [v for w in want for v in w]
    assert int(dut.valid.value) == int(model.valid) and int(dut.malformed.value) == 0
    dut._log.info(f"{traffic}: {len(rows)} rows, {total} entries bit-exact")

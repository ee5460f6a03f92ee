"""cocotb bench for hdl.pose.row_counter.RowCounter: every row's counts against
:func:`emulator.pose.tracking_status.count_rows`. Environment: COUNTER_ROWS (random rows
of verdicts, seeded by cocotb's RANDOM_SEED)."""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.streams import StreamSink, StreamSource
from emulator.pose.tracking_status import count_rows
from hdl.pose.row_counter import verdict_layout
from hdl.pose.status_params import ROW_INPUTS

from sim_tests.pose.status_stimulus import random_verdicts


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def counts_match_model(dut, traffic):
    params = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    verdicts = random_verdicts(np.random.default_rng(cocotb.RANDOM_SEED),
                               int(os.environ.get("COUNTER_ROWS", "200")), params.slots)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    source = StreamSource(dut, "i", verdict_layout(), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", params.row_layout(), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    await reset(dut)
    await source.send(verdicts)
    want = count_rows(verdicts, params.slots)
    await sink.wait_for(len(want), timeout_cycles=10 * len(verdicts) + 100)
    await ClockCycles(dut.clk, 4)
    got = [tuple(payload[n] for n in ROW_INPUTS) for _, payload in sink.received]
    assert got == want
    dut._log.info(f"{traffic}: {len(want)} rows of {len(verdicts)} verdicts bit-exact")

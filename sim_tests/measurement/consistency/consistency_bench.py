"""cocotb bench for hdl.measurement.consistency.ConsistencyStage: every output transfer,
the rows' ``gated`` verdicts and the counters against
:class:`emulator.measurement.consistency.ConsistencyModel`, bit for bit.

Environment: CONS_CASE (``SMALL`` or ``LARGE``, sim_tests/measurement/consistency/
stimulus.py), CONS_ROWS (random rows per test).
"""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.payload import pack, unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource
from hdl.measurement.consistency import (COUNTS, counts_layout, judge_layout,
                                         settings_init, settings_layout)
from hdl.pose.accumulator import measurement_layout

from sim_tests.measurement.consistency.stimulus import (check_against_model, judge_inputs,
                                                       random_rows)


async def _watch_verdicts(dut, clock, gated, determinable):
    """The ``gated`` and ``determinable`` outputs of every transfer on ``o`` (read where
    the sink reads)."""
    while True:
        await ReadOnly()
        if int(dut.o__valid.value) and int(dut.o__ready.value):
            gated.append(int(dut.gated.value))
            determinable.append(int(dut.determinable.value))
        await RisingEdge(clock.clk)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def transfers_match_model(dut, traffic):
    params = load_params()
    count = int(os.environ.get("CONS_ROWS", "60"))
    rng = random.Random(cocotb.RANDOM_SEED)
    rows = random_rows(params, np.random.default_rng(cocotb.RANDOM_SEED), count)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    dut.settings.value = pack(settings_layout(params), settings_init(params))
    source = StreamSource(dut, "i", judge_layout(params), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", measurement_layout(params.solver), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    gated, determinable = [], []
    await reset(dut)
    cocotb.start_soon(_watch_verdicts(dut, clock, gated, determinable))
    await source.send(judge_inputs(params, rows))
    total = sum(len(t) for t, *_ in rows)
    await sink.wait_for(total, timeout_cycles=200 * total)
    await ClockCycles(dut.clk, 64)     # the last measurement's scale update is counted
    got = {"transfers": [payload for _, payload in sink.received], "gated": gated,
           "determinable": determinable, "counts": unpack(counts_layout(), dut.counts.value)}
    model = check_against_model(params, rows, got)
    assert set(got["counts"]) == set(COUNTS)
    dut._log.info(f"{traffic}: {total} transfers of {count} rows bit-exact; {model.counts}")

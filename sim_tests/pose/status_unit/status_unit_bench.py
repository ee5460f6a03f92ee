"""cocotb bench for hdl.pose.status_unit.StatusUnit: every output record (all fields,
flags with status and drifted) and the state register against
:class:`emulator.pose.tracking_status.StatusUnitModel`, bit for bit.

Environment: STATUS_CASE (``SMALL``: random regime rows of sim_tests/pose/status_stimulus.py,
STATUS_ROWS of them, seeded by cocotb's RANDOM_SEED; ``REAL``: the records and counts in
the pickle STATUS_RECORDS, from a closed-loop emulator run).
"""

import os
import pickle
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, RisingEdge

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.payload import pack, unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource
from hdl.pose.params import solver_source
from hdl.pose.status_params import ROW_INPUTS, status_source

from sim_tests.pose.status_stimulus import (SOLVER, expected, packable, random_records,
                                            regime_rows)

#: Settings changes and clears between records (SMALL case), by record index.
EVENTS = {40: {"window": 3}, 90: "clear", 150: {"window": 0}, 170: {"window": 16},
          200: {"window": 31}, 230: {"window": 9, "degraded_measurements": 0}}


def _stimulus(params):
    case = os.environ.get("STATUS_CASE", "SMALL")
    if case == "REAL":
        with open(os.environ["STATUS_RECORDS"], "rb") as f:
            run = pickle.load(f)
        return run["solver"], run["records"], run["rows"]
    rng = np.random.default_rng(cocotb.RANDOM_SEED)
    rows = regime_rows(rng, int(os.environ.get("STATUS_ROWS", "300")), params)
    return SOLVER, random_records(SOLVER, rng, len(rows)), rows


async def _events(dut, sink, events, settings_layout, settings):
    """Apply each event once the records before it are out (the unit idle)."""
    for index in sorted(events):
        while len(sink.received) < index:
            await RisingEdge(dut.clk)
        event = events[index]
        if event == "clear":
            dut.clear.value = 1
            await RisingEdge(dut.clk)
            dut.clear.value = 0
        else:
            settings.update(event)
            dut.settings.value = pack(settings_layout, settings)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def records_match_model(dut, traffic):
    params = load_params()
    solver, records, rows = _stimulus(params)
    small = os.environ.get("STATUS_CASE", "SMALL") == "SMALL"
    events = EVENTS if small and traffic != "full_rate" else {}
    rng = random.Random(cocotb.RANDOM_SEED)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    settings = params.raw_settings()
    layout = params.settings_layout()
    dut.settings.value = pack(layout, settings)
    dut.clear.value = 0
    source = StreamSource(dut, "i", solver_source(solver).layout(), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    counts = StreamSource(dut, "row", params.row_layout(), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", status_source(solver).layout(), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    await reset(dut)
    if events:
        # one record at a time around the events, so that each applies between records
        cocotb.start_soon(_events(dut, sink, events, layout, settings))
        for k, (record, row) in enumerate(zip(records, rows)):
            while k in events and len(sink.received) < k:
                await RisingEdge(dut.clk)
            if k in events:
                await ClockCycles(dut.clk, 2)
            cocotb.start_soon(counts.send([dict(zip(ROW_INPUTS, row[1:]))]))
            await source.send([packable({**record, "flags": row[0]})])
    else:
        cocotb.start_soon(counts.send([dict(zip(ROW_INPUTS, r[1:])) for r in rows]))
        await source.send([packable({**r, "flags": row[0]}) for r, row in zip(records, rows)])
    await sink.wait_for(len(records), timeout_cycles=20 * len(records) + 100)
    await ClockCycles(dut.clk, 8)
    want, state = expected(params, records, rows, events)
    for k, ((_, got), w) in enumerate(zip(sink.received, want)):
        assert got == packable(w), f"record {k}: hardware {got}, model {w}; row {rows[k]}"
    assert len(sink.received) == len(want)
    assert unpack(params.state_layout(), dut.state.value) == state
    codes = np.bincount([(w["flags"] >> 4) & 3 for w in want], minlength=3).tolist()
    dut._log.info(f"{traffic}: {len(want)} records bit-exact; tracking/degraded/lost "
                  f"{codes}; state {state}")

"""cocotb bench for hdl.pose.motion_track.MotionTrack: the segments of a case (a restart
with ``frame_rows`` and ``initial``, or none, then rows; :mod:`.stimulus`) driven into
the Verilog, every ``Y`` and the ``saturated``/``overrange`` status after each segment
against the model's, bit for bit; at full rate, and with random valid gaps and ready
backpressure.

Environment: TRACK_CASE (path of a pickled case: ``segments``, ``outputs``, ``counts``).
"""

import os
import pickle
import random

import cocotb
from amaranth.lib import data
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.payload import pack
from emulator.hdl_sim.streams import StreamSink, StreamSource
from hdl.pose.forecast_filter import DEFAULT_SLOT_BITS, track_layout


def _row(slot, level, trend, target):
    return {"slot": int(slot) % 2 ** DEFAULT_SLOT_BITS,
            "level": dict(enumerate(int(v) for v in level)),
            "trend": dict(enumerate(int(v) for v in trend)),
            "target": {k: 0 if target is None else int(target[k]) for k in range(6)},
            "solved": int(target is not None)}


async def _between_rows(dut):
    """Wait for a clock where the block takes a row (IDLE): a restart lands there."""
    while True:
        await ReadOnly()
        idle = int(dut.i__ready.value)
        await RisingEdge(dut.clk)
        if idle:
            return


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def track_matches_model(dut, traffic):
    with open(os.environ["TRACK_CASE"], "rb") as f:
        case = pickle.load(f)
    params = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    motion = data.ArrayLayout(params.motion_fmt.shape(), 6)
    dut.restart.value = 0
    dut.alpha.value = params.track_alpha_raw
    source = StreamSource(dut, "i", track_layout(params), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", motion, clock, rng=rng, ready_prob=1.0 if busy else 0.6)
    await reset(dut)
    status, total = [], 0
    for register, initial, rows in case["segments"]:
        if initial is not None:
            await _between_rows(dut)
            dut.frame_rows.value = int(register)
            dut.initial.value = pack(motion, dict(enumerate(int(v) for v in initial)))
            dut.restart.value = 1
            await RisingEdge(dut.clk)
            dut.restart.value = 0
        await source.send([_row(*row) for row in rows])
        total += len(rows)
        await sink.wait_for(total, timeout_cycles=4000 * (len(rows) + 10))
        await ClockCycles(dut.clk, 4)
        await ReadOnly()
        status.append((int(dut.saturated.value), int(dut.overrange.value)))
        await RisingEdge(dut.clk)
    got = [[y[k] for k in range(6)] for _, y in sink.received]
    assert len(got) == len(case["outputs"]), (len(got), len(case["outputs"]))
    for n, (g, e) in enumerate(zip(got, case["outputs"])):
        assert g == [int(v) for v in e], f"row {n}: hardware {g}, model {[int(v) for v in e]}"
    assert status == [tuple(c) for c in case["counts"]], (status, case["counts"])
    dut._log.info(f"{traffic}: {len(got)} rows of Y bit-exact over "
                  f"{len(case['segments'])} segments; status {status}")

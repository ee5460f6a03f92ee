"""MotionTrack gateware (hdl/pose/motion_track.py) in the Amaranth simulator against
:class:`emulator.pose.motion_track.MotionTrackModel`, bit for bit: the rows the
emulator's closed loop gives its track on stereo20 cut to 32 rows (3 frames), and a
randomized stream from reset with readout gaps (some longer than a frame), restarts at a run-time
``frame_rows`` below the ring's length, ``frame_rows`` out of range, values at the
format's ends (saturation counted), valid gaps and ready backpressure. SEED replays the
randomized test (printed)."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.rig import preset
from hdl.pipeline_config import PipelineConfig
from hdl.pose.motion_track import MotionTrack

from sim_tests.common.sim_streams import drain
from sim_tests.pose.motion_track.stimulus import RING, expected, loop_rows, random_segments

SEED = int(os.environ.get("SEED", "31"))
SLOT_BITS = 16


def simulate_track(params, depth, segments, *, seed, gaps):
    """Drive ``segments`` — each ``(frame_rows or None, initial or None, rows)``: a
    restart with that ``frame_rows`` register and ``initial`` (None: no restart), then the
    rows — through :class:`MotionTrack` of ring length ``depth``; returns the ``Y`` of
    every row, the ``saturated`` and ``overrange`` after each segment."""
    dut = MotionTrack(params, depth, slot_bits=SLOT_BITS)
    rng, sink_rng = random.Random(seed), random.Random(seed + 1)
    prob = 0.6 if gaps else 1.0
    total = sum(len(rows) for *_, rows in segments)
    got, status = [], []

    async def source(ctx):
        for register, initial, rows in segments:
            if initial is not None:
                await ctx.tick().until(dut.i.ready)          # between rows
                ctx.set(dut.frame_rows, int(register))
                for k in range(6):
                    ctx.set(dut.initial[k], int(initial[k]))
                ctx.set(dut.restart, 1)
                await ctx.tick()
                ctx.set(dut.restart, 0)
            for slot, level, trend, target in rows:
                while rng.random() >= prob:
                    await ctx.tick()
                ctx.set(dut.i.payload.slot, int(slot) % 2 ** SLOT_BITS)
                for k in range(6):
                    ctx.set(dut.i.payload.level[k], int(level[k]))
                    ctx.set(dut.i.payload.trend[k], int(trend[k]))
                    ctx.set(dut.i.payload.target[k], 0 if target is None else int(target[k]))
                ctx.set(dut.i.payload.solved, target is not None)
                ctx.set(dut.i.valid, 1)
                await ctx.tick().until(dut.i.ready)
                ctx.set(dut.i.valid, 0)
            await ctx.tick().until(dut.i.ready)              # the segment's last row out
            await ctx.tick().repeat(4)
            status.append((ctx.get(dut.saturated), ctx.get(dut.overrange)))

    async def sink(ctx):
        await drain(ctx, dut.o, total, rng=sink_rng, prob=prob, out=got,
                    convert=lambda value: [int(value[k]) for k in range(6)],
                    limit=4000 * (total + 10))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source)
    sim.add_testbench(sink, background=True)
    sim.run()
    return np.array(got), status


def test_the_closed_loop_s_rows_bit_exact():
    """The rows of a real closed loop (3 frames of stereo20 cut to 32 rows, P = 32): the
    gateware, restarted at the loop's initial motion, gives the model's Y row by row."""
    params, period, initial, rows, outputs = loop_rows()
    assert len(rows) >= 2 * period
    got, status = simulate_track(params, period, [(period, initial, rows)], seed=SEED,
                                 gaps=True)
    assert np.array_equal(got, np.array(outputs))
    assert status[-1] == (0, 0)


@pytest.mark.parametrize("gaps", [False, True], ids=["full_rate", "gaps_and_backpressure"])
def test_random_rows_gaps_restarts_and_saturation_bit_exact(gaps):
    """From reset (a ring of 12 at P = 12), then restarts at P = 8 and 5, gaps of 3, 12
    and 30 row periods, a restart with frame_rows 0 (overrange: the ring's 12), rows at
    the format's ends (saturated and counted): every Y and every count equal to the
    model's."""
    print(f"SEED={SEED}")
    params, segments = random_segments(SEED)
    outputs, counts = expected(params, RING, segments)
    got, status = simulate_track(params, RING, segments, seed=SEED, gaps=gaps)
    assert np.array_equal(got, np.array(outputs))
    assert status == counts
    assert counts[2][0] > 0 and counts[-1][1] == 1     # the stimulus reached both
    assert np.any(np.array(outputs[:len(segments[0][2])]) != 0)    # reset's rows moved


def test_bad_parameters_are_named():
    params = PipelineConfig.for_rig(preset("stereo8-board")).forecast()
    with pytest.raises(TypeError, match="params"):
        MotionTrack(object(), 8)
    with pytest.raises(ValueError, match="frame_rows"):
        MotionTrack(params, 0)
    with pytest.raises(ValueError, match="slot_bits"):
        MotionTrack(params, 8, slot_bits=1)

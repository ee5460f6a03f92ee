"""MotionTrack gateware (hdl/pose/motion_track.py) in the Amaranth simulator against
:class:`emulator.pose.motion_track.MotionTrackModel`, bit for bit: the rows the
emulator's closed loop gives its track on stereo20 cut to 32 rows (3 frames), and a
randomized stream with readout gaps (some longer than a frame), restarts at a run-time
``frame_rows`` below the ring's length, ``frame_rows`` out of range, values at the
format's ends (saturation counted), valid gaps and ready backpressure. SEED replays the
randomized test (printed)."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

import emulator.pipeline as pipeline
from emulator.pose.motion_track import MotionTrackModel
from golden.rig import preset
from hdl.pipeline_config import PipelineConfig
from hdl.pose.motion_track import MotionTrack

from sim_tests.common.sim_streams import drain
from sim_tests.pose.status_runs import dataset, frame_rows

SEED = int(os.environ.get("SEED", "31"))
SLOT_BITS = 16


def loop_rows():
    """The closed loop's track inputs and outputs on the cut stereo20 run: ``(params, P,
    initial, rows, outputs)``, ``rows`` the (slot, level, trend, step) the pipeline gave
    its :class:`MotionTrackModel`."""
    from emulator.e2e import true_steps
    from hdl.top_params import DEFAULT_SEGMENTS
    data = dataset(frames=3)
    config = PipelineConfig.for_rig(data.rig, stereo_segments=DEFAULT_SEGMENTS)
    rows, outputs, made = [], [], []
    update, init = MotionTrackModel.update, MotionTrackModel.__init__

    def recording_init(self, params, frame_rows, level):
        made.append((params, frame_rows, np.array(level)))
        init(self, params, frame_rows, level)

    def recording_update(self, slot, level, trend, target=None):
        rows.append((slot, np.array(level), np.array(trend),
                     None if target is None else np.array(target)))
        outputs.append(update(self, slot, level, trend, target))
        return outputs[-1]

    try:
        MotionTrackModel.__init__, MotionTrackModel.update = recording_init, recording_update
        pipeline.run(config, data, forecast=config.forecast(),
                     initial_motion=true_steps(data, [1], [0])[0],
                     consistency=config.consistency(), cue_fallback=True)
    finally:
        MotionTrackModel.__init__, MotionTrackModel.update = init, update
    (params, period, initial), = made
    assert period == round(frame_rows(data))
    return params, period, initial, rows, outputs


def random_rows(params, rng, count, gap_every, extreme=False, slot=0):
    """(slot, level, trend, target or None) raw rows after slot ``slot``, with a readout
    gap every ``gap_every`` rows (some longer than a frame of 8 row periods)."""
    fmt = params.motion_fmt
    rows = []
    base = rng.uniform(-0.02, 0.02, 6)
    for i in range(count):
        slot += rng.choice([3, 12, 30]) if i % gap_every == gap_every - 1 else 1
        if extreme:
            level = np.array([rng.choice([fmt.min_raw, fmt.max_raw]) for _ in range(6)])
            trend = np.array([rng.choice([fmt.min_raw, fmt.max_raw]) for _ in range(6)])
            target = np.array([rng.choice([fmt.min_raw, fmt.max_raw]) for _ in range(6)])
        else:
            level = fmt.quantize(base + rng.normal(0, 1e-3, 6))
            trend = fmt.quantize(rng.normal(0, 1e-5, 6))
            target = fmt.quantize(base + rng.normal(0, 2e-3, 6))
        rows.append((slot, level, trend, None if rng.random() < 0.2 else target))
    return rows


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
    """A ring of 12 run at P = 8 (then 5), gaps of 3, 12 and 30 row periods, a restart
    with frame_rows 0 (overrange: the ring's 12), rows at the format's ends (saturated
    and counted): every Y and every count equal to the model's."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    params = PipelineConfig.for_rig(preset("stereo8-board")).forecast()
    fmt = params.motion_fmt
    depth = 12
    first = random_rows(params, rng, 40, 7)
    segments = [
        (8, fmt.quantize(rng.uniform(-0.02, 0.02, 6)), first),
        (None, None, random_rows(params, rng, 6, 3, extreme=True, slot=first[-1][0])),
        (5, fmt.quantize(np.full(6, 0.95)), random_rows(params, rng, 20, 4)),
        (0, fmt.quantize(rng.uniform(-0.02, 0.02, 6)), random_rows(params, rng, 20, 5)),
    ]
    expected, counts, model = [], [], None
    for register, initial, rows in segments:
        if initial is not None:
            period = depth if register == 0 or register > depth else register
            saturated = 0 if model is None else model.saturated
            model = MotionTrackModel(params, period, initial)
            model.saturated += saturated
        expected += [model.update(*row) for row in rows]
        counts.append((model.saturated, int(register == 0) if initial is not None
                       else counts[-1][1]))
    got, status = simulate_track(params, depth, segments, seed=SEED, gaps=gaps)
    assert np.array_equal(got, np.array(expected))
    assert status == counts
    assert counts[1][0] > 0 and counts[-1][1] == 1     # the stimulus reached both


def test_bad_parameters_are_named():
    params = PipelineConfig.for_rig(preset("stereo8-board")).forecast()
    with pytest.raises(TypeError, match="params"):
        MotionTrack(object(), 8)
    with pytest.raises(ValueError, match="frame_rows"):
        MotionTrack(params, 0)
    with pytest.raises(ValueError, match="slot_bits"):
        MotionTrack(params, 8, slot_bits=1)

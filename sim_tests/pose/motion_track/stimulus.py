"""Stimulus of the motion track's tests (hdl/pose/motion_track.py) and what the model
gives for it: the rows a real closed loop hands its track, and seeded random segments
that run from reset, restart at run-time ``frame_rows`` (one out of range), skip row
periods (some gaps longer than a frame) and reach the format's ends.

A *segment* is ``(frame_rows or None, initial or None, rows)``: a restart with that
``frame_rows`` register and ``initial`` (None: no restart; a first segment without one
runs from reset), then the rows ``(slot, level, trend, target or None)`` (raw
``motion_fmt``; None: an unsolved row)."""

import numpy as np

import emulator.pipeline as pipeline
from emulator.pose.motion_track import MotionTrackModel
from golden.rig import preset
from hdl.pipeline_config import PipelineConfig

__all__ = ["loop_rows", "random_rows", "random_segments", "expected", "RING"]

#: The ring length of the random segments' block (run at P = 12, 8, 5 and 0 → 12).
RING = 12


def loop_rows():
    """The closed loop's track inputs and outputs on the cut stereo20 run: ``(params, P,
    initial, rows, outputs)``, ``rows`` the (slot, level, trend, target) the pipeline gave
    its :class:`MotionTrackModel`."""
    from emulator.e2e import true_steps
    from hdl.top_params import DEFAULT_SEGMENTS
    from sim_tests.pose.status_runs import dataset, frame_rows
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


def random_segments(seed):
    """``(params, segments)``: the board rig's formats; from reset (P = the ring's
    :data:`RING`, a ring of zeros) 10 rows, then restarts at P = 8 (40 rows, gaps), the
    format's ends without a restart (6 rows, saturating), P = 5 near the range's top and
    ``frame_rows`` 0 (overrange: the ring's length)."""
    rng = np.random.default_rng(seed)
    params = PipelineConfig.for_rig(preset("stereo8-board")).forecast()
    fmt = params.motion_fmt
    reset = random_rows(params, rng, 10, 4)
    first = random_rows(params, rng, 40, 7, slot=reset[-1][0])
    return params, [
        (None, None, reset),
        (8, fmt.quantize(rng.uniform(-0.02, 0.02, 6)), first),
        (None, None, random_rows(params, rng, 6, 3, extreme=True, slot=first[-1][0])),
        (5, fmt.quantize(np.full(6, 0.95)), random_rows(params, rng, 20, 4)),
        (0, fmt.quantize(rng.uniform(-0.02, 0.02, 6)), random_rows(params, rng, 20, 5)),
    ]


def expected(params, depth, segments):
    """The model's ``Y`` of every row of ``segments`` through a block of ring length
    ``depth`` (reset: P = ``depth`` from 0), and ``(saturated, overrange)`` after each."""
    outputs, counts = [], []
    model, overrange = MotionTrackModel(params, depth, np.zeros(6, dtype=np.int64)), 0
    for register, initial, rows in segments:
        if initial is not None:
            overrange = int(register == 0 or register > depth)
            saturated = model.saturated
            model = MotionTrackModel(params, depth if overrange else register, initial)
            model.saturated += saturated
        outputs += [model.update(*row) for row in rows]
        counts.append((model.saturated, overrange))
    return outputs, counts

"""cocotb bench for hdl.row_descriptor.StereoRowDescriptor: a stereo pair with a lost
row and bad rows, every measurement against emulator.row_descriptor.StereoLaneModel."""

import random

import cocotb
import numpy as np

from emulator.row_descriptor import StereoLaneModel
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar

from emulator.hdl_sim.row_driving import Lane, split_rows
from emulator.hdl_sim.row_stimulus import frame_beats, inject_faults, moving_rows


def pair_stimulus(params, rng, disparity, faults):
    """Rows of a left (``a``) and right (``b``) camera seeing the same texture
    ``disparity`` pixels apart; with ``faults``, camera ``b`` loses a row and both get
    bad rows."""
    frames, _ = moving_rows(rng, 2, params.height, params.width + disparity + 40)
    a = frame_beats(frames[:, :, 20:params.width + 20])
    b = frame_beats(frames[:, :, 20 + disparity:params.width + 20 + disparity])
    if faults:
        w = params.width
        b = b[:w] + b[2 * w:]
        a, b = inject_faults(rng, a, w, 2), inject_faults(rng, b, w, 2)
    return split_rows(a), split_rows(b)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"], faults=[False, True])
async def stereo_lane_matches_model(dut, traffic, faults):
    params = load_params()
    busy = traffic == "full_rate"
    rng = random.Random(cocotb.RANDOM_SEED)
    np_rng = np.random.default_rng(cocotb.RANDOM_SEED)
    lane = Lane(dut, params, ["a", "b"], rng, busy=busy)
    await lane.start()
    # The true disparity lies inside every row's window (the window moves with the row's
    # centre), so the model must find it wherever the texture allows.
    margin = params.centre_range + 2
    disparity = int(np_rng.integers(params.match.shift_min + margin,
                                    params.match.shift_max - margin + 1))
    rows_a, rows_b = pair_stimulus(params, np_rng, disparity, faults)
    centres = [int(c) for c in np_rng.integers(-params.centre_range, params.centre_range + 1,
                                               len(rows_a))]
    beats_a = [x for row in rows_a for x in row]
    beats_b = [x for row in rows_b for x in row]
    per_beat = [c for row, c in zip(rows_a, centres) for _ in row]
    expected = StereoLaneModel(params).run(beats_a, per_beat, beats_b)
    if not faults:
        assert all(abs(m["shift"] - disparity) <= 1 for m in expected if not m["textureless"])
    await lane.play_all({"a": rows_a, "b": rows_b}, centres)
    last_cycles = [c for c, x in lane.sources["a"].sent if x["last"]] if not faults else None
    await lane.check(expected, load_sidecar()["latency"], busy, last_cycles)

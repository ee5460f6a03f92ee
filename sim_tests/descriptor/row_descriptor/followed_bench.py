"""cocotb bench for hdl.row_descriptor.RowDescriptor(params, follow=True): the
following lane against emulator.row_descriptor.TemporalLaneModel(params, follow=True),
every measurement in order, bit for bit, and the out-of-range count.

Rows: one stereo20 camera's rows from a closed-loop emulator run (``closed_loop.py``),
cut to the lane, first with the centres and source rows the loop chose, then again with
random ones (some outside the served range and the centre range), and one row lost, so
that the next frame's request for it must be flagged. RUN_SLOW=1 plays more random
frames.
"""

import os
import random

import cocotb
import numpy as np

from emulator.descriptor.framer import frame_rows
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.row_stimulus import frame_beats
from emulator.hdl_sim.streams import StreamSink, StreamSource
from emulator.row_descriptor import TemporalLaneModel
from sim_tests.descriptor.test_ring_store import random_sources

#: One model for all tests of a simulation: reset does not clear the lane's memories,
#: so each test starts from the store the previous one left (the model is reset too).
_MODELS = {}


def stimulus(params, rng):
    """Beats (with ``centre`` and ``source``), the centre of each beat and the source of
    each row."""
    loop = np.load(os.environ["ROWTRACK_RD_LOOP"])
    pixels = loop["pixels"]
    n_loop, height = pixels.shape[0], params.height
    x0 = (pixels.shape[2] - params.width) // 2
    cut = pixels[:, :height, x0:x0 + params.width]
    n_random = 6 if os.environ.get("RUN_SLOW") else 2
    frames = np.concatenate([cut, cut[np.arange(n_random) % n_loop]])
    k = loop["source"].shape[-1]          # the loop's segments; every (k/K)-th for K < k
    sources = loop["source"].reshape(n_loop, -1, k)[:, :height, ::k // params.segments]
    sources = sources.reshape(-1, params.segments).tolist()
    centres = loop["centre"].reshape(n_loop, -1)[:, :height].ravel().tolist()
    sources += [[s % (1 << params.row_bits) for s in row] for row in random_sources(
        rng, params, list(range(height)) * n_random)]
    centres += rng.integers(-params.centre_range - 2, params.centre_range + 3,
                            n_random * height).tolist()
    lost_y = int(rng.integers(height))            # lost in the first random frame,
    sources[(n_loop + 1) * height + lost_y] = [lost_y] * params.segments  # asked for next
    beats = frame_beats(frames, camera=int(loop["camera"]) % (1 << params.camera_bits),
                        frame0=(1 << params.frame_bits) - 2, frame_bits=params.frame_bits)
    for k in range(len(frames) * height):
        for beat in beats[k * params.width:(k + 1) * params.width]:
            beat.update(centre=int(centres[k]), source=[int(r) for r in sources[k]])
    lost = n_loop * height + lost_y
    del beats[lost * params.width:(lost + 1) * params.width]
    del sources[lost], centres[lost]
    per_beat = [beat["centre"] for beat in beats]
    return beats, per_beat, sources


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def following_lane_matches_model(dut, traffic):
    params = load_params()
    busy = traffic == "full_rate"
    seed = cocotb.RANDOM_SEED
    print(f"SEED={seed}")
    clock = start_clock(dut)
    rng = random.Random(seed)
    source = StreamSource(dut, "i", params.input_layout(True), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.7)
    sink = StreamSink(dut, "o", params.measurement_layout(), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.4)
    dut.half_width.value = params.max_half_width      # the built window (driven: Icarus)
    await reset(dut)
    beats, per_beat, sources = stimulus(params, np.random.default_rng(seed))
    model = _MODELS.setdefault("lane", TemporalLaneModel(params, follow=True))
    model.store.reset()
    expected = model.process_rows(frame_rows(beats, per_beat, params), sources)
    served = sum(not m["no_reference"] for m in expected) // params.segments
    print(f"{len(expected) // params.segments} rows, {served} with a reference, "
          f"{model.store.out_of_range} requests out of range")
    await source.send(beats)
    await sink.wait_for(len(expected), timeout_cycles=40 * len(expected) + 5000)
    got = [payload for _, payload in sink.received]
    for i, (g, e) in enumerate(zip(got, expected)):
        assert g == e, f"measurement {i}: hardware {g} != model {e} (SEED={seed})"
    assert len(got) == len(expected)
    assert int(dut.out_of_range.value) == model.store.out_of_range > 0
    if busy:
        cycles = [c for c, _ in source.sent]
        assert cycles == list(range(cycles[0], cycles[0] + len(cycles))), "input bubbles"
        lasts = np.array([c for c, b in source.sent if b["last"]])
        segments = np.array([m["segment"] for m in expected])
        want = np.repeat(lasts, params.segments) + load_sidecar()["latency"] + segments
        assert np.array_equal([c for c, _ in sink.received], want), "latency"

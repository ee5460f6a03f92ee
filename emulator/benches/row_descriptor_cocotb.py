"""Full-size run for the benchmark (``emulator/benches/row_descriptor.py``): 640-pixel
rows at full rate through a temporal or stereo lane, every measurement checked against
the model; writes throughput and latency to ``$ROWTRACK_FIGURES``."""

import json
import os
import random

import cocotb
import numpy as np

from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.row_driving import Lane, split_rows
from emulator.hdl_sim.row_stimulus import frame_beats, moving_rows
from emulator.row_descriptor import StereoLaneModel, TemporalLaneModel

#: Rows per frame played (row indices 0 … ROWS − 1 of the lane's frame) and frames.
ROWS, FRAMES = 24, 3


@cocotb.test()
async def full_size_figures(dut):
    params = load_params()
    stereo = hasattr(dut, "a__valid")
    rng = np.random.default_rng(cocotb.RANDOM_SEED)
    lane = Lane(dut, params, ["a", "b"] if stereo else ["i"], random.Random(1), busy=True)
    await lane.start()
    frames, _ = moving_rows(rng, FRAMES, ROWS, params.width + 60)
    if stereo:
        streams = {"a": split_rows(frame_beats(frames[:, :, 20:params.width + 20])),
                   "b": split_rows(frame_beats(frames[:, :, 60:]))}
    else:
        streams = {"i": split_rows(frame_beats(frames[:, :, :params.width]))}
    centres = [0] * len(next(iter(streams.values())))
    beats = {port: [b for row in rows for b in row] for port, rows in streams.items()}
    if stereo:
        expected = StereoLaneModel(params).run(beats["a"], [0] * len(beats["a"]), beats["b"])
    else:
        expected = TemporalLaneModel(params).run(beats["i"], [0] * len(beats["i"]))
    await lane.play_all(streams, centres)
    await lane.sink.wait_for(len(expected), timeout_cycles=10000)
    got = [payload for _, payload in lane.sink.received]
    sent = lane.sources[next(iter(streams))].sent
    last_pixels = np.array([c for c, b in sent if b["last"]])
    out_cycles = np.array([c for c, _ in lane.sink.received]).reshape(-1, params.segments)
    figures = {
        "pixels": len(sent),
        "px_per_clock": len(sent) / (sent[-1][0] - sent[0][0] + 1),
        "latency_first_clocks": int((out_cycles[:, 0] - last_pixels).max()),
        "latency_clocks": int((out_cycles[:, -1] - last_pixels).max()),
        "latency_spread": int(np.ptp(out_cycles[:, -1] - last_pixels)),
        "sidecar_latency": load_sidecar()["latency"],
        "measurements": len(got),
        "mismatches": sum(g != e for g, e in zip(got, expected)) + abs(len(got) - len(expected)),
    }
    with open(os.environ["ROWTRACK_FIGURES"], "w") as f:
        json.dump(figures, f)
    assert figures["mismatches"] == 0

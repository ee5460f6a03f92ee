"""cocotb bench for hdl.dt.filter.DomainTransformFilter and DomainTransformRounds (``DT_ROUNDS``
rounds, default 1): every output against emulator.dt.filter.

Frames come from image files (``DT_IMAGE_PAIRS``: ``guide,value`` PNG pairs separated
by the path separator; the guide is converted to grey, a 16-bit value image is scaled to
the block's bits) and from the rolling-shutter simulator (``DT_DATASET``: a
``golden.dataset`` file whose camera images are both guide and value). Each frame is
cropped to the block's width and ``DT_ROWS`` rows and gets its own sigma registers (with
several rounds, once the previous frame has left the block: every round latches them).
"""

import os
import random

import cocotb
import cv2
import numpy as np
from cocotb.triggers import ClockCycles

from emulator.dt.filter import filter_rounds, sigma_register
from hdl.dt.filter import DomainTransformFilter
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.streams import StreamSink, StreamSource

#: (sigma_s in pixels, sigma_r in guide LSBs), used by the frames in turn.
SIGMAS = [(8.0, 24.0), (30.0, 60.0), (3.5, 12.0)]


def _fit(image, params, rows):
    return np.ascontiguousarray(image[:rows, :params.width])


def _to_bits(image, bits):
    image = np.asarray(image, dtype=np.int64)
    source_bits = 16 if image.max() > 255 else 8
    if bits == source_bits:
        return image
    return image >> 8 if bits < source_bits else image * 257


def load_frames(params):
    """(guide, value) pairs from the files named in the environment."""
    rows = int(os.environ.get("DT_ROWS", "12"))
    frames = []
    for pair in filter(None, os.environ.get("DT_IMAGE_PAIRS", "").split(os.pathsep)):
        guide_path, value_path = pair.split(",")
        guide = cv2.imread(guide_path, cv2.IMREAD_GRAYSCALE)
        value = cv2.imread(value_path, cv2.IMREAD_UNCHANGED)
        assert guide is not None and value is not None, f"cannot read {pair}"
        frames.append((_fit(guide, params, rows), _fit(_to_bits(value, params.value_bits),
                                                       params, rows)))
    if os.environ.get("DT_DATASET"):
        from golden.dataset import Dataset
        dataset = Dataset.load(os.environ["DT_DATASET"])
        for camera in dataset.cameras[:2]:
            image = _fit(camera.rows[0], params, rows)
            frames.append((image, _to_bits(image, params.value_bits)))
    assert frames, "no frames: set DT_IMAGE_PAIRS and/or DT_DATASET"
    return frames


def _pixels(guide, value):
    height, width = guide.shape
    return [{"guide": int(guide[y, x]), "value": int(value[y, x]), "last": int(y == height - 1)}
            for y in range(height) for x in range(width)]


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def dt_filter_matches_model(dut, traffic):
    """Image-file and simulator frames, sigmas changed between frames."""
    params = load_params()
    sidecar = load_sidecar()
    rounds = int(os.environ.get("DT_ROUNDS", "1"))
    rng = random.Random(cocotb.RANDOM_SEED)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    source = StreamSource(dut, "i", params.input_layout(), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.7)
    sink = StreamSink(dut, "o", params.output_layout(), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.6)
    dut.sigma_s.value = 0
    dut.sigma_r.value = 0
    await reset(dut)

    expected = []
    for n, (guide, value) in enumerate(load_frames(params)):
        if rounds > 1 and expected:
            done = sum(e.size for e in expected)
            await sink.wait_for(done, timeout_cycles=20 * done + 20 * sidecar["latency"])
        sigma_s, sigma_r = (sigma_register(name, v) for name, v in
                            zip(("sigma_s", "sigma_r"), SIGMAS[n % len(SIGMAS)]))
        dut.sigma_s.value = sigma_s
        dut.sigma_r.value = sigma_r
        await ClockCycles(dut.clk, DomainTransformFilter.coefficient_settle_clocks)
        expected.append(filter_rounds(params, guide, value, sigma_s, sigma_r, rounds))
        await source.send(_pixels(guide, value))
    total = sum(e.size for e in expected)
    await sink.wait_for(total, timeout_cycles=20 * total + 20 * sidecar["latency"])

    flat = np.concatenate([e.ravel() for e in expected]).tolist()
    got = [p["value"] for _, p in sink.received]
    bad = [i for i, (a, b) in enumerate(zip(got, flat)) if a != b]
    assert len(got) == total and not bad, (
        f"{len(bad)} of {total} pixels differ from emulator.dt.filter, first at {bad[:1]}")
    ends = np.cumsum([e.size for e in expected]) - 1
    assert [i for i, (_, p) in enumerate(sink.received) if p["last"]] == ends.tolist()
    if busy:
        delays = {out[0] - sent[0] for out, sent in zip(sink.received, source.sent)}
        assert delays == {sidecar["latency"]}, f"latency {delays} != {sidecar['latency']}"
        first = expected[0].size
        span = sink.received[first - 1][0] - sink.received[0][0] + 1
        assert span == first, f"{first} pixels took {span} clocks"

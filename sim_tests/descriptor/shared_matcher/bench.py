"""cocotb bench for hdl.descriptor.matcher.ShiftMatcher(params, ports=P): P cameras of
the golden simulator's dataset on the matcher's ports at once, each port's
measurements (on its own output) against the model's of that camera alone
(emulator.descriptor.matcher.measure_rows), bit for bit, with every port offering a
column in each of its slots and with gaps and backpressure."""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import Combine

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.streams import StreamSink, StreamSource
from golden.dataset import Dataset
from hdl.descriptor.layouts import pair_layout
from sim_tests.descriptor.shared_matcher.stimulus import camera_columns


def dataset_pixels(params, camera):
    """The middle ``height × width`` of one camera's frames in the dataset."""
    rows = Dataset.load(os.environ["ROWTRACK_RD_DATASET"]).cameras[camera].rows
    y0, x0 = (rows.shape[1] - params.height) // 2, (rows.shape[2] - params.width) // 2
    return rows[:, y0:y0 + params.height, x0:x0 + params.width]


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def shared_matcher_matches_model(dut, traffic):
    params, ports = load_params(), int(os.environ["ROWTRACK_PORTS"])
    full = traffic == "full_rate"
    rng = random.Random(cocotb.RANDOM_SEED)
    np_rng = np.random.default_rng(cocotb.RANDOM_SEED)
    clock = start_clock(dut)
    sources = [StreamSource(dut, f"i__{k}", pair_layout(params), clock, rng=rng,
                            valid_prob=1.0 if full else 0.6) for k in range(ports)]
    sinks = [StreamSink(dut, f"o__{k}", params.measurement_layout(), clock, rng=rng,
                        ready_prob=1.0 if full else 0.5) for k in range(ports)]
    await reset(dut)
    cameras = [camera_columns(params, np_rng, k, dataset_pixels(params, k))
               for k in range(ports)]
    expected = [e for _, e in cameras]
    sends = [cocotb.start_soon(src.send(columns)) for src, (columns, _) in zip(sources, cameras)]
    await Combine(*sends)
    total = sum(map(len, expected))
    for sink, mine in zip(sinks, expected):
        await sink.wait_for(len(mine), timeout_cycles=20 * total + 2000)
    for k, (sink, mine) in enumerate(zip(sinks, expected)):
        got = [m for _, m in sink.received]
        assert len(got) == len(mine), (k, len(got), len(mine))
        for i, (g, e) in enumerate(zip(got, mine)):
            assert g == e, f"port {k}, measurement {i}: hardware {g} != model {e}"
    if full:
        # the segments of the ports end together, and queue for the engine without
        # stalling anything: every port gives a column in each of its slots
        for k, src in enumerate(sources):
            cycles = [c for c, _ in src.sent]
            gaps = {b - a for a, b in zip(cycles, cycles[1:])}
            assert gaps == {ports}, f"port {k} stalled: gaps {sorted(gaps)}"
        # a row's results leave the matcher's latency after its last column, plus one
        # engine job (and the clock to start it) per other port's segment queued ahead
        latency, job = load_sidecar()["latency"], params.engine_result_step + 1
        waits = []
        for src, sink in zip(sources, sinks):
            lasts = [c for c, beat in src.sent if beat["last"]]
            firsts = [c for c, m in sink.received if m["segment"] == 0]
            waits += [first - last - latency for last, first in zip(lasts, firsts)]
        print(f"waits behind other ports' jobs: {sorted(set(waits))} clocks")
        assert min(waits) == 0 and max(waits) <= (ports - 1) * job, waits

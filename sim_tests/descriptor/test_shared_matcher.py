"""One shift matcher serving several cameras' column streams in turn
(``ShiftMatcher(ports=P)``, issue 17 item 3), in the Amaranth simulator: every camera's
measurements equal the bit-accurate model's of that camera alone
(:func:`emulator.descriptor.matcher.measure_rows`), whatever the streams' gaps and the
output's backpressure. Rows are seeded textures moving between frames, each camera's
own, at per-row centres and half-widths, with bad rows and rows without a reference;
the cocotb bench plays three cameras of the golden simulator's dataset on Verilator."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from emulator.hdl_sim.payload import pack, unpack
from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb
from emulator.hdl_sim.row_stimulus import moving_rows, simulator_dataset
from golden.descriptor import MatchParams
from hdl.descriptor.matcher import ShiftMatcher
from hdl.descriptor.params import RowDescriptorParams
from sim_tests.descriptor.shared_matcher.stimulus import camera_columns

SEED = int(os.environ.get("SEED", "20261208"))

#: 160-pixel rows, 2 segments, centre ±4, run-time half-widths.
SMALL = RowDescriptorParams(width=160, height=3, centre_range=4, match=MatchParams(segments=2))


def camera_rows(params, rng, camera, frames=2):
    """One camera's seeded moving texture as matcher columns, with the model's
    measurements (:func:`camera_columns`)."""
    pixels, _ = moving_rows(rng, frames + 1, params.height, params.width)
    return camera_columns(params, rng, camera, pixels)


def run_matcher(dut, streams, n_expected, *, seed, valid_prob, ready_prob):
    """Offer each stream on its port (``dut.i`` or ``dut.i[k]``), idle at random
    between beats, with random backpressure on every output; return each output's
    measurements in order."""
    rng = random.Random(seed)
    ports = [dut.i] if dut.ports == 1 else [dut.i[k] for k in range(dut.ports)]
    outs = [dut.o] if dut.ports == 1 else [dut.o[k] for k in range(dut.ports)]
    layout, out_layout = ports[0].payload.shape(), outs[0].payload.shape()
    outputs = [[] for _ in outs]

    async def testbench(ctx):
        sent = [0] * len(ports)
        offering = [False] * len(ports)
        limit = 8 * sum(len(s) for s in streams) + 4000
        for _ in range(limit):
            if sum(map(len, outputs)) >= n_expected and all(
                    sent[k] == len(s) for k, s in enumerate(streams)):
                return
            for k, (port, beats) in enumerate(zip(ports, streams)):
                if not offering[k] and sent[k] < len(beats):
                    offering[k] = rng.random() < valid_prob
                ctx.set(port.valid, offering[k])
                if sent[k] < len(beats):
                    ctx.set(port.payload.as_value(), pack(layout, beats[sent[k]]))
            ready = [rng.random() < ready_prob for _ in outs]
            for out, r in zip(outs, ready):
                ctx.set(out.ready, r)
            taken = [ctx.get(port.valid) and ctx.get(port.ready) for port in ports]
            given = [ctx.get(out.valid) and r for out, r in zip(outs, ready)]
            payloads = [ctx.get(out.payload.as_value()) for out in outs]
            await ctx.tick()
            for k, t in enumerate(taken):
                if t:
                    sent[k] += 1
                    offering[k] = False
            for k, g in enumerate(given):
                if g:
                    outputs[k].append(unpack(out_layout, payloads[k]))
        raise AssertionError(f"timeout: {sum(map(len, outputs))} of {n_expected} "
                             f"measurements (SEED={seed})")

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return outputs


def test_the_stimulus_is_the_lanes():
    """One camera on one port: the model's measurements, so the columns are built as
    the lane's store hands them on (the shared cases below rest on this)."""
    rng = np.random.default_rng(SEED)
    beats, expected = camera_rows(SMALL, rng, 0)
    got = run_matcher(ShiftMatcher(SMALL), [beats], len(expected), seed=SEED,
                      valid_prob=0.7, ready_prob=0.7)
    assert got == [expected], f"SEED={SEED}"


@pytest.mark.parametrize("ports, valid_prob, ready_prob", [
    (3, 1.0, 1.0),        # every port offers a column in its slot: no bubbles
    (3, 0.6, 0.5),        # bubbles and backpressure
    (2, 0.8, 0.3),
])
def test_shared_matcher_gives_each_camera_its_own_measurements(ports, valid_prob,
                                                                ready_prob):
    seed = SEED + ports + int(10 * valid_prob)
    print(f"SEED={seed}")
    rng = np.random.default_rng(seed)
    cameras = [camera_rows(SMALL, rng, c) for c in range(ports)]
    expected = [e for _, e in cameras]
    got = run_matcher(ShiftMatcher(SMALL, ports=ports), [b for b, _ in cameras],
                      sum(map(len, expected)), seed=seed, valid_prob=valid_prob,
                      ready_prob=ready_prob)
    assert got == expected, f"SEED={seed}"


def test_an_idle_port_costs_the_others_nothing():
    """Port 1 never offers a column: ports 0 and 2 still get their own measurements
    (the idle slot is a bubble that keeps nothing of theirs)."""
    rng = np.random.default_rng(SEED + 7)
    cameras = [camera_rows(SMALL, rng, c) for c in (0, 2)]
    streams = [cameras[0][0], [], cameras[1][0]]
    got = run_matcher(ShiftMatcher(SMALL, ports=3), streams,
                      sum(len(e) for _, e in cameras), seed=SEED, valid_prob=0.9,
                      ready_prob=0.9)
    assert got == [cameras[0][1], [], cameras[1][1]]


@pytest.mark.parametrize("ports", [0, 17, 2.0, True])
def test_ports_must_be_a_small_integer(ports):
    with pytest.raises(ValueError, match="ports must be an integer between 1 and 16"):
        ShiftMatcher(SMALL, ports=ports)


def test_shared_matcher_cocotb():
    """Three cameras of the dataset on one matcher, in the generated Verilog."""
    dataset = simulator_dataset(BUILD_ROOT / "row_descriptor-yaw-dataset.npz")
    run_cocotb(ShiftMatcher(SMALL.replace(height=4), ports=3), name="shared_matcher",
               sim="verilator", test_module="sim_tests.descriptor.shared_matcher.bench",
               extra_env={"ROWTRACK_RD_DATASET": str(dataset), "ROWTRACK_PORTS": "3"})

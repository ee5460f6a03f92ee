"""Framer and PoseOutput in the Amaranth simulator against emulator/output/packets.py."""

import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from emulator.output import packets
from hdl.fixed import SQ
from hdl.output.packet import Framer, PoseOutput
from hdl.output.params import PacketParams, PoseOutputParams, PoseSource
from emulator.hdl_sim.payload import unpack
from sim_tests.output.test_packets import random_record

P = PacketParams()
SEED = 77


def random_pose(rng, source=PoseSource()):
    """A pose in ``source`` formats, every field over its full range."""
    def value(bits, signed):
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
        return int(rng.choice([lo, hi, 0, int(rng.integers(lo, hi, endpoint=True))]))
    return {"time": value(source.time_bits, False), "row": value(source.row_bits, False),
            "flags": value(source.flag_bits, False),
            "p": [value(source.position_fmt.width, True) for _ in range(3)],
            "q": [value(source.quaternion_fmt.width, True) for _ in range(4)],
            "step": [value(source.step_fmt.width, True) for _ in range(6)]}


def as_fields(layout, value):
    """A struct value read from the simulator as a dict, arrays as lists of ints."""
    fields = unpack(layout, value.as_value().value)
    return {name: [v[k] for k in sorted(v)] if isinstance(v, dict) else v
            for name, v in fields.items()}


def run_framer(records, *, ready_prob, seed=SEED):
    dut = Framer(P)
    rng = random.Random(seed)
    out = []

    async def testbench(ctx):
        queue = list(records)
        idle = 0
        while queue or idle < 3 * P.packet_bytes:
            ctx.set(dut.i.valid, bool(queue))
            if queue:
                ctx.set(dut.i.payload, queue[0])
            ready = rng.random() < ready_prob
            ctx.set(dut.o.ready, ready)
            if queue and ctx.get(dut.i.ready):
                queue.pop(0)
            if ready and ctx.get(dut.o.valid):
                out.append(ctx.get(dut.o.payload))
                idle = 0
            else:
                idle += 1
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return bytes(out)


@pytest.mark.parametrize("ready_prob", [1.0, 0.4])
def test_framer_bytes_equal_the_model(ready_prob):
    rng = np.random.default_rng(SEED)
    records = [random_record(rng) for _ in range(12)]
    got = run_framer(records, ready_prob=ready_prob)
    assert got == b"".join(packets.encode_packet(P, r) for r in records)


def run_pose_output(poses, *, spacing, cfg, params=PoseOutputParams(), uart_ready=1.0,
                    pops=False, seed=SEED):
    """Feed ``poses`` one every ``spacing`` clocks (a list, or an int); returns the UART
    bytes, the records popped from the FIFO and the final status."""
    dut = PoseOutput(params)
    rng = random.Random(seed)
    uart, fifo, status = bytearray(), [], {}
    gaps = spacing if isinstance(spacing, list) else [spacing] * len(poses)

    async def testbench(ctx):
        ctx.set(dut.cfg, cfg)
        queue = list(zip(poses, gaps))
        wait, idle = 0, 0
        while queue or idle < 100:
            valid = bool(queue) and wait == 0
            ctx.set(dut.pose.valid, valid)
            if valid:
                ctx.set(dut.pose.payload, queue[0][0])
                assert ctx.get(dut.pose.ready), "PoseOutput stalled the tracker"
                wait = queue.pop(0)[1] - 1
            else:
                wait = max(wait - 1, 0)
            ready = rng.random() < uart_ready
            ctx.set(dut.uart.ready, ready)
            if ready and ctx.get(dut.uart.valid):
                uart.append(ctx.get(dut.uart.payload))
                idle = 0
            else:
                idle += 1
            pop = pops and ctx.get(dut.fifo.valid)
            ctx.set(dut.fifo.ready, pop)
            if pop:
                fifo.append(as_fields(P.record_layout(), ctx.get(dut.fifo.payload)))
            await ctx.tick()
        ctx.set(dut.fifo.ready, 0)
        await ctx.tick()
        status.update(as_fields(params.status_layout(), ctx.get(dut.status)))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return bytes(uart), fifo, status


def decode_all(data):
    size = P.packet_bytes
    assert len(data) % size == 0
    return [packets.decode_payload(P, data[k + 3:k + size - 2]) for k in range(0, len(data), size)]


CFG = {"uart_enable": 1, "fifo_enable": 1, "decimation": 1, "rate_window": 0}


@pytest.mark.parametrize("decimation", [0, 1, 3])
def test_paced_poses_all_reach_both_sinks(decimation):
    """Poses slower than a packet: every kept pose is sent and queued, nothing dropped."""
    rng = np.random.default_rng(SEED + decimation)
    poses = [random_pose(rng) for _ in range(10)]
    cfg = {**CFG, "decimation": decimation}
    data, fifo, status = run_pose_output(poses, spacing=P.packet_bytes + 3, cfg=cfg, pops=True)
    expected = [record for _, record in packets.keep_poses(PoseOutputParams(), poses,
                                                           decimation)]
    assert data == b"".join(packets.encode_packet(P, r) for r in expected)
    assert fifo == expected
    kept = len(expected)
    assert status["poses"] == 10 and status["records"] == kept
    assert status["decimated"] == 10 - kept and status["packets"] == kept
    assert status["uart_dropped"] == status["fifo_dropped"] == status["fifo_level"] == 0


def test_tracker_formats_are_narrowed_like_the_model():
    """Poses in the pose solver's formats: rounded half-even and saturated into the
    packet, bit for bit as emulator.output.packets.narrow_pose does."""
    source = PoseSource(position_fmt=SQ(10, 32), quaternion_fmt=SQ(2, 40), row_bits=10,
                        time_bits=32, flag_bits=4)
    params = PoseOutputParams(source=source)
    rng = np.random.default_rng(SEED)
    poses = [random_pose(rng, source) for _ in range(12)]
    data, fifo, _ = run_pose_output(poses, spacing=P.packet_bytes + 3, cfg=CFG, params=params,
                                    pops=True)
    expected = [record for _, record in packets.keep_poses(params, poses, 1)]
    assert fifo == expected
    assert data == b"".join(packets.encode_packet(P, r) for r in expected)


def test_fast_poses_are_dropped_and_counted_never_silently():
    """Poses every clock into a UART sink with backpressure and a small unread FIFO."""
    rng = np.random.default_rng(SEED)
    poses = [random_pose(rng) for _ in range(150)]
    params = PoseOutputParams(fifo_depth=8)
    data, _, status = run_pose_output(poses, spacing=1, cfg=CFG, params=params, uart_ready=0.5)
    sent = decode_all(data)
    kept = dict(packets.keep_poses(params, poses, 1))
    assert status["records"] == 150 and status["packets"] == len(sent)
    assert status["packets"] + status["uart_dropped"] == status["records"]
    assert 1 < len(sent) < 150
    assert sum(r["skipped"] for r in sent) + len(sent) == sent[-1]["seq"] + 1
    for previous, record in zip(sent, sent[1:]):
        assert record["seq"] == previous["seq"] + 1 + record["skipped"]
    for record in sent:
        expected = {**kept[record["seq"]], "skipped": record["skipped"]}
        assert record == expected
    assert status["fifo_level"] == 8 and status["fifo_dropped"] == 150 - 8


def test_disabled_sinks_take_and_drop_nothing():
    rng = np.random.default_rng(SEED)
    poses = [random_pose(rng) for _ in range(10)]
    cfg = {**CFG, "uart_enable": 0, "fifo_enable": 0}
    data, _, status = run_pose_output(poses, spacing=1, cfg=cfg)
    assert data == b""
    assert status["records"] == 10 and status["packets"] == 0
    assert status["uart_dropped"] == status["fifo_dropped"] == status["fifo_level"] == 0


def test_pose_rate_counts_poses_per_window():
    """One pose every 10 clocks in windows of 100: 10 per window; then idle: 0."""
    dut = PoseOutput()
    rates = []

    async def testbench(ctx):
        ctx.set(dut.cfg, {**CFG, "rate_window": 100})
        for cycle in range(800):
            ctx.set(dut.pose.valid, cycle < 500 and cycle % 10 == 0)
            await ctx.tick()
            if cycle in (250, 450, 799):
                rates.append(ctx.get(dut.status.pose_rate))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    assert rates == [10, 10, 0]


def test_bad_params():
    with pytest.raises(TypeError, match="params must be a PoseOutputParams, not 1"):
        PoseOutput(1)
    with pytest.raises(TypeError, match="params must be a PacketParams, not 1"):
        Framer(1)

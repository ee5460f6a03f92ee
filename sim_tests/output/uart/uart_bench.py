"""cocotb bench for the pose link (PoseOutput + UartTx): a UART monitor decodes the
``tx`` line and every byte is compared with the emulator's packets; the PS FIFO is
drained the way the PS does it, reading ``fifo_head`` and pulsing ``fifo_pop``."""

import random

import cocotb
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge

from emulator.output import packets
from emulator.hdl_sim.uart_line import UartMonitor, wait_idle
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.payload import pack, unpack

#: Small divisors keep the simulation short; the timing model is the same at any value.
DIVISORS = {"fast": 16, "fractional": 16 * 3 + 5}


def random_pose(rng, source):
    def value(bits, signed):
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
        return rng.choice([lo, hi, 0, rng.randint(lo, hi)])
    return {"time": value(source.time_bits, False), "row": value(source.row_bits, False),
            "flags": value(source.flag_bits, False),
            "p": [value(source.position_fmt.width, True) for _ in range(3)],
            "q": [value(source.quaternion_fmt.width, True) for _ in range(4)],
            "step": [value(source.step_fmt.width, True) for _ in range(6)]}


def _as_payload(pose):
    return {k: ({i: x for i, x in enumerate(v)} if isinstance(v, list) else v)
            for k, v in pose.items()}


class FifoReader:
    """Drains the PS FIFO through the register interface: while ``status.fifo_level`` is
    not zero, read ``fifo_head``, then write 1 to ``fifo_pop`` (a one-clock strobe, as
    the register file makes it). ``received`` holds the records in order."""

    def __init__(self, dut, params):
        self.dut, self.params, self.received = dut, params, []
        dut.fifo_pop__stb.value = 0
        dut.fifo_pop__data.value = 0
        cocotb.start_soon(self._run())

    async def _run(self):
        po, dut = self.params.pose_output, self.dut
        while True:
            await RisingEdge(dut.clk)
            await ReadOnly()
            if unpack(po.status_layout(), dut.status.value)["fifo_level"]:
                self.received.append(unpack(po.packet.record_layout(), dut.fifo_head.value))
                await RisingEdge(dut.clk)
                dut.fifo_pop__stb.value = 1
                dut.fifo_pop__data.value = 1
                await RisingEdge(dut.clk)
                dut.fifo_pop__stb.value = 0
                dut.fifo_pop__data.value = 0


async def _setup(dut, cfg, divisor, *, drain_fifo=False):
    params = load_params()
    po = params.pose_output
    start_clock(dut)
    dut.pose__valid.value = 0
    dut.cfg.value = pack(po.config_layout(), cfg)
    dut.divisor.value = divisor
    monitor = UartMonitor(dut, params.uart, divisor)
    fifo = FifoReader(dut, params) if drain_fifo else None
    if fifo is None:
        dut.fifo_pop__stb.value = 0
        dut.fifo_pop__data.value = 0
    await reset(dut)
    return params, monitor, fifo


async def _send(dut, layout, pose):
    dut.pose__payload.value = pack(layout, _as_payload(pose))
    dut.pose__valid.value = 1
    await RisingEdge(dut.clk)
    dut.pose__valid.value = 0


def _status(dut, params):
    return unpack(params.pose_output.status_layout(), dut.status.value)


@cocotb.parametrize(divisor=sorted(DIVISORS), decimation=[1, 3])
async def paced_poses_match_the_model_byte_for_byte(dut, divisor, decimation):
    """Poses slower than the link: every kept pose is on the line, exactly as modelled."""
    raw = DIVISORS[divisor]
    cfg = {"uart_enable": 1, "fifo_enable": 1, "decimation": decimation, "rate_window": 0}
    params, monitor, _ = await _setup(dut, cfg, raw)
    po = params.pose_output
    rng = random.Random(cocotb.RANDOM_SEED)
    poses = [random_pose(rng, po.source) for _ in range(12)]
    packet_clocks = po.packet.packet_bytes * packets.uart_byte_clocks(params.uart, raw)
    for pose in poses:
        await _send(dut, po.source.layout(), pose)
        await ClockCycles(dut.clk, packet_clocks + rng.randint(0, 40))
    await wait_idle(dut, monitor, 3 * max(packets.uart_bit_clocks(params.uart, raw)) * 10)
    expected = [r for _, r in packets.keep_poses(po, poses, decimation)]
    assert bytes(monitor.received) == b"".join(packets.encode_packet(po.packet, r)
                                               for r in expected)
    assert monitor.framing_errors == 0
    status = _status(dut, params)
    assert (status["poses"], status["records"], status["packets"], status["uart_dropped"]) == \
        (12, len(expected), len(expected), 0)


@cocotb.test()
async def fast_poses_drop_whole_records_and_say_so(dut):
    """One pose every 25 clocks, far faster than the link: whole packets only, each the
    model's record, with ``skipped`` accounting for every dropped one; the FIFO keeps
    every record while it is drained."""
    raw = DIVISORS["fast"]
    cfg = {"uart_enable": 1, "fifo_enable": 1, "decimation": 1, "rate_window": 0}
    params, monitor, fifo = await _setup(dut, cfg, raw, drain_fifo=True)
    po = params.pose_output
    rng = random.Random(cocotb.RANDOM_SEED)
    poses = [random_pose(rng, po.source) for _ in range(80)]
    for pose in poses:
        await _send(dut, po.source.layout(), pose)
        await ClockCycles(dut.clk, 24)
    await wait_idle(dut, monitor, 200)
    data = bytes(monitor.received)
    size = po.packet.packet_bytes
    assert len(data) % size == 0 and monitor.framing_errors == 0
    sent = [packets.decode_payload(po.packet, data[k + 3:k + size - 2])
            for k in range(0, len(data), size)]
    kept = dict((r["seq"], r) for _, r in packets.keep_poses(po, poses, 1))
    assert 2 < len(sent) < len(poses)
    for record in sent:
        assert packets.encode_packet(po.packet, record) == \
            packets.encode_packet(po.packet, {**kept[record["seq"]], "skipped": record["skipped"]})
    for previous, record in zip(sent, sent[1:]):
        assert record["seq"] == previous["seq"] + 1 + record["skipped"]
    status = _status(dut, params)
    assert status["records"] == len(poses)
    assert status["packets"] == len(sent)
    assert status["packets"] + status["uart_dropped"] == status["records"]
    assert [r["seq"] for r in fifo.received] == list(range(len(poses)))
    assert status["fifo_dropped"] == 0

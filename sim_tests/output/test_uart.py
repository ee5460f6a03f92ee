"""UartTx in the Amaranth simulator: every bit's value and exact duration, back-to-back
frames, the divisor clamp."""

import random

import pytest
from amaranth.sim import Simulator

from emulator.output.packets import uart_bit_clocks
from hdl.output.params import FRAME_BITS, UartParams
from hdl.output.uart import UartTx

SEED = 1234


def run_uart(payloads, divisor, *, gap_prob=0.0, seed=SEED, params=UartParams()):
    """Send ``payloads``; returns (tx per cycle, cycles at which a byte was taken)."""
    dut = UartTx(params)
    rng = random.Random(seed)
    trace, taken = [], []
    clocks = sum(uart_bit_clocks(params, divisor)) * (len(payloads) + 2) * 3 + 50

    async def testbench(ctx):
        ctx.set(dut.divisor, divisor)
        queue = list(payloads)
        for cycle in range(clocks):
            offer = bool(queue) and rng.random() >= gap_prob
            ctx.set(dut.i.valid, offer)
            if offer:
                ctx.set(dut.i.payload, queue[0])
            trace.append(ctx.get(dut.tx))
            if offer and ctx.get(dut.i.ready):
                taken.append(cycle)
                queue.pop(0)
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return trace, taken


def expected_line(payload, durations):
    bits = [0] + [(payload >> k) & 1 for k in range(8)] + [1]
    return [bit for bit, clocks in zip(bits, durations) for _ in range(clocks)]


@pytest.mark.parametrize("divisor", [16, 17, 40, 533, 16 * 7 + 15])
def test_back_to_back_frames_are_exact(divisor):
    """Bytes waiting are sent with no idle time; each bit lasts exactly as modelled."""
    rng = random.Random(SEED + divisor)
    payloads = [0x00, 0xFF, 0x55, 0xAA] + [rng.randrange(256) for _ in range(8)]
    trace, taken = run_uart(payloads, divisor)
    durations = uart_bit_clocks(UartParams(), divisor)
    frame = sum(durations)
    assert taken[0] == 0
    assert [b - a for a, b in zip(taken, taken[1:])] == [frame] * (len(payloads) - 1)
    expected = [1] + [v for p in payloads for v in expected_line(p, durations)]
    assert trace[:len(expected)] == expected
    assert set(trace[len(expected):]) == {1}                  # idle high afterwards


def test_gaps_between_bytes_keep_the_line_idle():
    payloads = list(range(0, 256, 17))
    trace, taken = run_uart(payloads, 40, gap_prob=0.9)
    durations = uart_bit_clocks(UartParams(), 40)
    for payload, cycle in zip(payloads, taken):
        line = expected_line(payload, durations)
        assert trace[cycle + 1:cycle + 1 + len(line)] == line
    frame = sum(durations)
    assert all(b - a >= frame for a, b in zip(taken, taken[1:]))
    gaps = [b - a - frame for a, b in zip(taken, taken[1:])]
    assert max(gaps) > 0, "the random gaps never left the line idle (seed too kind)"
    for a, b in zip(taken, taken[1:]):
        assert set(trace[a + 1 + frame:b + 1]) <= {1}


def test_divisor_below_one_clock_per_bit_runs_at_one():
    trace, taken = run_uart([0b10110010], 5)
    assert trace[1:1 + FRAME_BITS] == expected_line(0b10110010, [1] * FRAME_BITS)


def test_bad_params():
    with pytest.raises(TypeError, match="params must be a UartParams, not 3"):
        UartTx(3)

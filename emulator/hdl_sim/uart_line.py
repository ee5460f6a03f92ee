"""A UART line watched from cocotb: 8N1 frames decoded at the bit timing of the
hardware's fractional divisor, and waiting for the line to go quiet."""

import cocotb
from cocotb.triggers import ReadOnly, RisingEdge

from emulator.output import packets

__all__ = ["UartMonitor", "wait_idle"]


class UartMonitor:
    """Decodes 8N1 frames on the ``line`` port: a falling edge starts a frame; each
    later bit is sampled in the middle of its duration
    (:func:`emulator.output.packets.uart_bit_clocks`); a frame whose stop bit is not high is a
    framing error."""

    def __init__(self, dut, uart, divisor, *, line="tx"):
        self.dut = dut
        self.line = getattr(dut, line)
        self.bits = packets.uart_bit_clocks(uart, divisor)
        self.received = bytearray()
        self.framing_errors = 0
        cocotb.start_soon(self._run())

    async def _run(self):
        clk, tx = self.dut.clk, self.line
        starts = [sum(self.bits[:k]) for k in range(len(self.bits))]
        while True:
            await RisingEdge(clk)
            await ReadOnly()
            if int(tx.value):
                continue
            elapsed, samples = 0, [0]         # this clock is the start bit's first
            for start, clocks in zip(starts[1:], self.bits[1:]):
                while elapsed < start + clocks // 2:
                    await RisingEdge(clk)
                    elapsed += 1
                await ReadOnly()
                samples.append(int(tx.value))
            while elapsed < sum(self.bits) - 1:
                await RisingEdge(clk)
                elapsed += 1
            if samples[-1] != 1:
                self.framing_errors += 1
            self.received.append(sum(bit << k for k, bit in enumerate(samples[1:9])))


async def wait_idle(dut, monitor, clocks):
    """Wait until the monitored line has been idle for ``clocks``."""
    idle = 0
    while idle < clocks:
        await RisingEdge(dut.clk)
        await ReadOnly()
        idle = idle + 1 if int(monitor.line.value) else 0

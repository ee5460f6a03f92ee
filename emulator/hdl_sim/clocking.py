"""Clock and reset for cocotb benches of Amaranth designs (ports ``clk`` and ``rst``)."""

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, RisingEdge

from emulator.hdl_sim.streams import CycleCounter

__all__ = ["start_clock", "reset"]

#: Nominal system clock period in the benches; cycle counts, not times, are what we check.
CLOCK_PERIOD_NS = 10


def start_clock(dut, period_ns=CLOCK_PERIOD_NS):
    """Start ``dut.clk`` and return a :class:`CycleCounter`; hold ``rst`` high.

    Build the stream drivers after this (so every input is driven) and then call
    :func:`reset`.
    """
    dut.rst.value = 1
    cocotb.start_soon(Clock(dut.clk, period_ns, unit="ns").start())
    return CycleCounter(dut.clk)


async def reset(dut, cycles=3):
    """Hold ``rst`` for ``cycles`` clocks, release it, and return after the next edge."""
    dut.rst.value = 1
    await ClockCycles(dut.clk, cycles)
    dut.rst.value = 0
    await RisingEdge(dut.clk)

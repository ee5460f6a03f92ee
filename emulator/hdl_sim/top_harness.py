"""Bench helpers for :class:`hdl.top.RowtrackTop` in cocotb: start it (clock, quiet
camera pins, reset, an AXI4-Lite master on its register window) and watch the row sets
its front end hands to the measurement engine."""

import random

import cocotb
from cocotb.triggers import ReadOnly, RisingEdge

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.registers import Registers

__all__ = ["child", "ColumnMonitor", "engine_input", "stream_monitor", "start_top"]


def child(parent, name):
    """Sub-instance ``name`` (escaped in the Verilog when it is a keyword, e.g. fork)."""
    try:
        return getattr(parent, name)
    except AttributeError:
        return parent._id(f"\\{name} ", extended=False)


class ColumnMonitor:
    """Every column taken on a stream (its ``valid``/``ready``/``payload`` handles), raw,
    with the clock it was taken; ``stalls``: the clocks it was offered and not taken."""

    def __init__(self, dut, valid, ready, payload, clock):
        self.handles = (valid, ready, payload)
        self.clock = clock
        self.dut = dut
        self.columns, self.stalls = [], []
        cocotb.start_soon(self._run())

    async def _run(self):
        valid, ready, payload = self.handles
        while True:
            await RisingEdge(self.dut.clk)
            await ReadOnly()
            if int(valid.value):
                if int(ready.value):
                    self.columns.append((self.clock.cycle, int(payload.value)))
                else:
                    self.stalls.append(self.clock.cycle)


def engine_input(dut, clock):
    """A :class:`ColumnMonitor` of the row sets entering the measurement engine."""
    fork = child(dut.engine, "fork")
    return ColumnMonitor(dut, fork.i__valid, fork.i__ready, fork.i__payload, clock)


def stream_monitor(dut, instance, port, clock):
    """A :class:`ColumnMonitor` of stream ``port`` of sub-instance ``instance``."""
    return ColumnMonitor(dut, getattr(instance, f"{port}__valid"),
                         getattr(instance, f"{port}__ready"),
                         getattr(instance, f"{port}__payload"), clock)


async def start_top(dut):
    """Clock, quiet inputs, reset; returns (params, regmap, registers, clock)."""
    params = load_params()
    regmap = params.regmap()
    clock = start_clock(dut)
    for k in range(params.camera.n_cameras):
        getattr(dut, f"pclk{k}_rst").value = 1
        getattr(dut, f"pclk{k}_clk").value = 0
        for pin in ("vsync", "href", "data"):
            getattr(dut, f"dvp__{k}__{pin}").value = 0
    regs = Registers(dut, regmap, rng=random.Random(cocotb.RANDOM_SEED))
    await reset(dut)
    for k in range(params.camera.n_cameras):
        getattr(dut, f"pclk{k}_rst").value = 0
    return params, regmap, regs, clock

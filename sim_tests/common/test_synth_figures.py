"""How ``emulator.synth`` counts a netlist: LUTs as a device's capacity counts them
(logic and distributed memory), and figures from cached cell counts."""

import json

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from emulator.synth import _cell_counts, synth_verilog
from hdl.verilog import write_verilog


def test_slice_luts_are_logic_and_memory():
    """Distributed RAM and shift registers occupy LUTs of the device (UG474): a RAM64M
    four, a RAM32X1D two, an SRL one; ``lut`` is their sum with the logic LUTs."""
    cells = {"LUT2": 5, "LUT6": 3, "RAM64M": 2, "RAM32X1D": 1, "SRLC32E": 3, "FDRE": 7,
             "INV": 4}
    figures = _cell_counts(cells)
    assert figures["lut_logic"] == 8
    assert figures["lut_memory"] == 4 * 2 + 2 + 3
    assert figures["lut"] == 8 + 13
    assert figures["lutram"] == 3 and figures["ff"] == 7


class _SmallRam(wiring.Component):
    """A 32-word, 8-bit RAM with an asynchronous read: distributed RAM on the xc7."""

    def __init__(self):
        super().__init__({"addr": In(5), "wdata": In(8), "we": In(1), "rdata": Out(8)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.mem = mem = Memory(shape=8, depth=32, init=[])
        write, read = mem.write_port(), mem.read_port(domain="comb")
        total = Signal(8)
        m.d.sync += total.eq(total + read.data)
        m.d.comb += [write.addr.eq(self.addr), write.data.eq(self.wdata),
                     write.en.eq(self.we), read.addr.eq(self.addr + 1),
                     self.rdata.eq(total)]
        return m


def test_a_distributed_ram_counts_in_the_luts(tmp_path):
    """Synthesized: the RAM's cells are counted into ``lut``, and a second call reads
    the cached cell counts (same figures, no synthesis: the cache holds cells)."""
    path = write_verilog(_SmallRam(), "small_ram", tmp_path)
    figures = synth_verilog(path, "small_ram", tmp_path)
    assert figures["lutram"] > 0 and figures["lut_memory"] >= 2 * figures["lutram"]
    assert figures["lut"] == figures["lut_logic"] + figures["lut_memory"]
    cached = json.loads((tmp_path / "figures.json").read_text())
    assert "cells" in cached
    (tmp_path / "stat.json").unlink()
    assert synth_verilog(path, "small_ram", tmp_path) == figures


def test_a_cache_without_cell_counts_is_not_trusted(tmp_path):
    """A cache written before the figures were counted from cells synthesizes again."""
    path = write_verilog(_SmallRam(), "small_ram", tmp_path)
    figures = synth_verilog(path, "small_ram", tmp_path)
    cached = json.loads((tmp_path / "figures.json").read_text())
    stale = {"key": cached["key"], "figures": {**figures, "lut": 0}}
    (tmp_path / "figures.json").write_text(json.dumps(stale))
    assert synth_verilog(path, "small_ram", tmp_path) == figures

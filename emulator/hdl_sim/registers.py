"""Register access from cocotb benches: an AXI4-Lite master (cocotbext-axi) and the
bit bookkeeping of a :class:`hdl.bus.register_map.RegisterMap` (which bits of a register's port a
word shows, where)."""

import itertools
import logging

from cocotbext.axi import AxiLiteBus, AxiLiteMaster, AxiResp

from emulator.hdl_sim.payload import pack

__all__ = ["Registers", "port_name", "element_bits", "word_bits", "piece_mask", "with_word"]


def port_name(word, suffix=""):
    """The Verilog port of ``word``'s register (``<group>__<register>[__data|__stb]``)."""
    return f"{word.group.name}__{word.register.name}" + (f"__{suffix}" if suffix else "")


def element_bits(word, flat):
    """Element ``word.index`` of a register's flat port value."""
    width = word.register.width
    return (int(flat) >> (word.index * width)) & ((1 << width) - 1)


def word_bits(word, element):
    """The 32-bit word ``word`` shows for an element value."""
    value = 0
    for piece in word.pieces():
        value |= ((element >> piece.src) & ((1 << piece.width) - 1)) << piece.dst
    return value


def piece_mask(word):
    """Bits of the word that hold register bits."""
    return word_bits(word, (1 << word.register.width) - 1)


def with_word(word, element, value):
    """``element`` after writing 32-bit ``value`` to ``word``."""
    for piece in word.pieces():
        mask = ((1 << piece.width) - 1) << piece.src
        element = (element & ~mask) | (((value >> piece.dst) & ((1 << piece.width) - 1))
                                       << piece.src)
    return element


def _pauses(rng, probability):
    return (rng.random() < probability for _ in itertools.count())


class Registers:
    """cocotbext-axi AXI4-Lite master on port ``prefix`` with the map's base address.

    ``backpressure`` pauses every channel at random (valid gaps on AW/W/AR, ready
    low on B/R) from the seeded ``rng``.
    """

    def __init__(self, dut, regmap, *, prefix="axi", rng=None, backpressure=0.0):
        bus = AxiLiteBus.from_prefix(dut, prefix, bus_separator="__")
        self.master = AxiLiteMaster(bus, dut.clk, dut.rst)
        # cocotbext-axi logs every transfer at INFO: thousands of lines for a
        # coefficient load, which drown the bench's own messages.
        for interface in (self.master.write_if, self.master.read_if):
            interface.log.setLevel(logging.WARNING)
        self.regmap = regmap
        if backpressure:
            for channel in (self.master.write_if.aw_channel, self.master.write_if.w_channel,
                            self.master.write_if.b_channel, self.master.read_if.ar_channel,
                            self.master.read_if.r_channel):
                channel.set_pause_generator(_pauses(rng, backpressure))

    def address(self, word):
        return self.regmap.base + word.offset

    async def read(self, address):
        """``(value, ok)`` of a 32-bit read."""
        resp = await self.master.read(address, 4)
        return int.from_bytes(resp.data, "little"), resp.resp == AxiResp.OKAY

    async def write(self, address, value, length=4):
        """True if the write answered OKAY (``length`` < 4: a byte-strobed write)."""
        resp = await self.master.write(address, int(value).to_bytes(4, "little")[:length])
        return resp.resp == AxiResp.OKAY

    async def read_register(self, group, name, index=0):
        """The whole element of a register, read word by word from word 0 (which samples
        a read-only element whole, :class:`hdl.bus.register_file.RegisterFile`)."""
        value = 0
        for word in self.regmap.words():
            if (word.group.name, word.register.name, word.index) == (group, name, index):
                data, ok = await self.read(self.address(word))
                assert ok, f"reading {group}.{name}[{index}] failed"
                for piece in word.pieces():
                    value |= ((data >> piece.dst) & ((1 << piece.width) - 1)) << piece.src
        return value

    async def write_register(self, group, name, element, index=0):
        """Write a whole element, word by word (the last word delivers a command);
        ``element`` is an integer or a field dict of the register's layout."""
        if isinstance(element, dict):
            element = pack(self.regmap.find(group, name).register.shape, element)
        for word in self.regmap.words():
            if (word.group.name, word.register.name, word.index) == (group, name, index):
                assert await self.write(self.address(word), word_bits(word, element)), \
                    f"writing {group}.{name}[{index}] failed"

"""cocotb bench for the register file of rowtrack's map, walked from the declaration:
every word read and written through cocotbext-axi, every port checked, every illegal
access answered SLVERR."""

import random

import cocotb
from cocotb.triggers import ReadOnly, RisingEdge

from hdl.bus.register_map import Access, WORD_BYTES
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params

from emulator.hdl_sim.registers import Registers, element_bits, piece_mask, port_name, with_word, word_bits


def _by_access(regmap, access):
    return [w for w in regmap.words() if w.register.access is access]


async def _setup(dut, backpressure):
    regmap = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    start_clock(dut)
    for word in _by_access(regmap, Access.RO):
        getattr(dut, port_name(word)).value = 0
    regs = Registers(dut, regmap, rng=rng, backpressure=backpressure)
    await reset(dut)
    return regmap, rng, regs


@cocotb.parametrize(backpressure=[0.0, 0.4])
async def control_registers_store_and_drive(dut, backpressure):
    """RW words: reset values, random writes read back, and the ports follow."""
    regmap, rng, regs = await _setup(dut, backpressure)
    words = _by_access(regmap, Access.RW)
    model = {(w.group.name, w.register.name, w.index): w.register.reset_raw for w in words}
    for word in words:
        key = (word.group.name, word.register.name, word.index)
        value, ok = await regs.read(regs.address(word))
        assert ok and value == word_bits(word, model[key]), f"reset value of {key}"
    for word in rng.sample(words, len(words)) * 2:
        key = (word.group.name, word.register.name, word.index)
        value = rng.getrandbits(32)
        assert await regs.write(regs.address(word), value)
        model[key] = with_word(word, model[key], value)
    for word in words:
        key = (word.group.name, word.register.name, word.index)
        value, ok = await regs.read(regs.address(word))
        assert ok and value == word_bits(word, model[key]), f"read back of {key}"
        assert element_bits(word, getattr(dut, port_name(word)).value) == model[key], \
            f"port of {key}"


@cocotb.parametrize(backpressure=[0.0, 0.4])
async def status_and_constants_read(dut, backpressure):
    """RO words show their port; CONST words their value; both refuse writes."""
    regmap, rng, regs = await _setup(dut, backpressure)
    ports = {}
    for word in _by_access(regmap, Access.RO):
        name = port_name(word)
        if name not in ports:
            handle = getattr(dut, name)
            ports[name] = rng.getrandbits(len(handle))
            handle.value = ports[name]
    await RisingEdge(dut.clk)
    for word in _by_access(regmap, Access.RO) + _by_access(regmap, Access.CONST):
        if word.register.access is Access.RO:
            expected = word_bits(word, element_bits(word, ports[port_name(word)]))
        else:
            expected = word_bits(word, word.register.value)
        value, ok = await regs.read(regs.address(word))
        assert ok and value == expected, f"{word.group.name}.{word.register.name}"
        assert not await regs.write(regs.address(word), rng.getrandbits(32))


@cocotb.parametrize(backpressure=[0.0, 0.4])
async def multi_word_status_reads_one_sample(dut, backpressure):
    """Every RO element of several words: reading word 0 samples it whole, and the other
    words answer from that sample after the block has changed the port."""
    regmap, rng, regs = await _setup(dut, backpressure)
    elements = {}
    for word in _by_access(regmap, Access.RO):
        if word.register.words > 1:
            elements.setdefault((port_name(word), word.index), []).append(word)
    assert elements, "the map has no multi-word status register to test"
    for (name, _), words in elements.items():
        handle = getattr(dut, name)
        sampled = rng.getrandbits(len(handle))
        handle.value = sampled
        await RisingEdge(dut.clk)
        first, *rest = words
        value, ok = await regs.read(regs.address(first))
        assert ok and value == word_bits(first, element_bits(first, sampled)), name
        handle.value = sampled ^ ((1 << len(handle)) - 1)
        for word in rest:
            value, ok = await regs.read(regs.address(word))
            assert ok and value == word_bits(word, element_bits(word, sampled)), \
                f"{name}[{word.index}] word {word.word} is not word 0's sample"


async def _watch_strobes(dut, words, seen):
    names = sorted({port_name(w) for w in words})
    while True:
        await RisingEdge(dut.clk)
        await ReadOnly()
        for name in names:
            stb = int(getattr(dut, f"{name}__stb").value)
            if stb:
                seen.append((name, stb, int(getattr(dut, f"{name}__data").value)))


@cocotb.parametrize(backpressure=[0.0, 0.4])
async def commands_strobe_once(dut, backpressure):
    """WO registers deliver the written value with a one-clock strobe on the last word;
    reads and partial writes are errors."""
    regmap, rng, regs = await _setup(dut, backpressure)
    words = _by_access(regmap, Access.WO)
    assert words, "the map has no command register to test"
    seen = []
    cocotb.start_soon(_watch_strobes(dut, words, seen))
    for word in words:
        assert not (await regs.read(regs.address(word)))[1]
    elements = {}
    for word in words:
        key = (word.group.name, word.register.name, word.index)
        elements.setdefault(key, []).append(word)
    for key, element_words in elements.items():
        value = rng.getrandbits(element_words[0].register.width)
        del seen[:]
        for word in element_words:
            assert await regs.write(regs.address(word), word_bits(word, value))
        for _ in range(3):
            await RisingEdge(dut.clk)
        word = element_words[-1]
        assert len(seen) == 1, f"{key}: {len(seen)} strobes"
        name, stb, data = seen[0]
        assert stb == 1 << word.index and element_bits(word, data) == value, key
        del seen[:]
        assert not await regs.write(regs.address(word), 1, length=1)
        await RisingEdge(dut.clk)
        assert not seen, f"{key}: a refused partial write strobed"


@cocotb.test()
async def whole_window_and_beyond(dut):
    """Every word of the window answers OKAY exactly when the map says it is readable;
    addresses outside it, or misaligned, answer SLVERR; the bus keeps working."""
    regmap, rng, regs = await _setup(dut, 0.0)
    readable = {w.offset for w in regmap.words() if w.register.access is not Access.WO}
    for offset in range(0, regmap.size, WORD_BYTES):
        value, ok = await regs.read(regmap.base + offset)
        assert ok == (offset in readable), f"read at offset {offset:#x}"
        if not ok:
            assert value == 0
    mapped = {w.offset for w in regmap.words()}
    for offset in rng.sample([o for o in range(0, regmap.size, WORD_BYTES) if o not in mapped],
                             20):
        assert not await regs.write(regmap.base + offset, rng.getrandbits(32))
    for address in (regmap.base - WORD_BYTES, regmap.base + regmap.size, 0, 0xFFFF_FFFC,
                    regmap.base + 1, regmap.base + 2):
        assert not (await regs.read(address))[1], hex(address)
        assert not await regs.write(address, 0x5A5A_5A5A, length=4 - address % 4), hex(address)
    magic = regmap.find("ident", "magic")
    assert await regs.read(regs.address(magic)) == (magic.register.value, True)
    control = [w for w in regmap.words() if w.register.access is Access.RW][0]
    assert element_bits(control, getattr(dut, port_name(control)).value) == \
        control.register.reset_raw, "an erroring write changed a control register"
    assert piece_mask(control)

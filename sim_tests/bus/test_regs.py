"""The register map declaration and the AXI4-Lite register file (Amaranth simulator)."""

from pathlib import Path

import pytest
from amaranth.lib import data
from amaranth.sim import Simulator

from hdl.bus.register_map import Access, Register, RegisterGroup, RegisterMap
from hdl.bus.axi4lite import RESP_OKAY, RESP_SLVERR
from hdl.bus.register_file import RegisterFile
from hdl.top_params import TopParams

DOCS = Path(__file__).resolve().parents[2] / "docs"
BASE = 0x4000_0000
LAYOUT = data.StructLayout({"a": 4, "b": 30, "c": 3})


def small_map():
    return RegisterMap(groups=[
        RegisterGroup("ident", 0x0, "ids", [Register("magic", 32, Access.CONST, "m",
                                                     value=0x1234_5678)]),
        RegisterGroup("blk", 0x10, "a block", [
            Register("ctl", LAYOUT, Access.RW, "control", reset={"a": 3, "c": 5}),
            Register("wide", 40, Access.RW, "wide", count=2),
            Register("st", 16, Access.RO, "status", count=3),
            Register("cmd", 40, Access.WO, "command"),
        ]),
    ], base=BASE, size=0x100)


class AxiLite:
    """A minimal AXI4-Lite master for Amaranth testbenches."""

    def __init__(self, ctx, axi):
        self.ctx, self.axi = ctx, axi

    async def write(self, addr, value, strobe=0xF, *, w_delay=0):
        ctx, axi = self.ctx, self.axi
        ctx.set(axi.awaddr, addr)
        ctx.set(axi.awvalid, 1)
        ctx.set(axi.bready, 1)
        for _ in range(w_delay):          # address alone must not be taken
            await ctx.tick()
            assert not ctx.get(axi.awready)
        ctx.set(axi.wdata, value)
        ctx.set(axi.wstrb, strobe)
        ctx.set(axi.wvalid, 1)
        await ctx.tick().until(axi.awready)
        ctx.set(axi.awvalid, 0)
        ctx.set(axi.wvalid, 0)
        resp, = await ctx.tick().sample(axi.bresp).until(axi.bvalid)
        return resp

    async def read(self, addr, *, r_delay=0):
        ctx, axi = self.ctx, self.axi
        ctx.set(axi.araddr, addr)
        ctx.set(axi.arvalid, 1)
        ctx.set(axi.rready, 0)
        await ctx.tick().until(axi.arready)
        ctx.set(axi.arvalid, 0)
        for _ in range(r_delay):          # the response holds while rready is low
            await ctx.tick()
        ctx.set(axi.rready, 1)
        value, resp = await ctx.tick().sample(axi.rdata, axi.rresp).until(axi.rvalid)
        ctx.set(axi.rready, 0)
        return value, resp


def simulate(dut, bench):
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()


def test_pieces_never_straddle_words():
    reg = Register("ctl", LAYOUT, Access.RW, "x")
    assert [(p.name, p.word, p.dst, p.width) for p in reg.pieces()] == [
        ("a", 0, 0, 4), ("b", 1, 0, 30), ("c", 2, 0, 3)]
    wide = Register("w", data.StructLayout({"x": 3, "y": 70, "z": 2}), Access.RO, "x")
    assert [(p.name, p.word, p.dst, p.width, p.part) for p in wide.pieces()] == [
        ("x", 0, 0, 3, None), ("y", 1, 0, 32, (0, 32)), ("y", 2, 0, 32, (32, 64)),
        ("y", 3, 0, 6, (64, 70)), ("z", 3, 6, 2, None)]
    assert wide.words == 4
    array = Register("s", data.StructLayout({"n": data.ArrayLayout(16, 3)}), Access.RO, "x")
    assert [(p.name, p.word, p.dst) for p in array.pieces()] == [
        ("n[0]", 0, 0), ("n[1]", 0, 16), ("n[2]", 1, 0)]


def test_words_and_lookup():
    regmap = small_map()
    offsets = [(w.offset, w.register.name, w.index, w.word) for w in regmap.words()]
    assert offsets[:4] == [(0, "magic", 0, 0), (0x10, "ctl", 0, 0), (0x14, "ctl", 0, 1),
                           (0x18, "ctl", 0, 2)]
    assert regmap.find("blk", "st").offset == 0x2C
    assert regmap.group("blk").size == 4 * (3 + 4 + 3 + 2)
    with pytest.raises(KeyError, match="no register blk.nope"):
        regmap.find("blk", "nope")


def test_layout_crc_ignores_constant_values():
    regmap = small_map()
    assert regmap.with_value("ident", "magic", 7).layout_crc() == regmap.layout_crc()
    moved = regmap.replace(groups=(regmap.groups[0],
                                   RegisterGroup("blk", 0x20, "x", regmap.groups[1].registers)))
    assert moved.layout_crc() != regmap.layout_crc()


@pytest.mark.parametrize("build, error, message", [
    (lambda: Register("1x", 8, Access.RW, ""), ValueError, "name must be an identifier"),
    (lambda: Register("a__b", 8, Access.RW, ""), ValueError, "without leading or double"),
    (lambda: Register("a", 0, Access.RW, ""), ValueError, "shape of a must be at least one bit"),
    (lambda: Register("a", "8", Access.RW, ""), TypeError, "shape of a must be a width or a Layout"),
    (lambda: Register("a", 8, "rw", ""), TypeError, "access of a must be an Access"),
    (lambda: Register("a", 8, Access.RW, "", count=0), ValueError, "count of a must be an integer at least 1"),
    (lambda: Register("a", 8, Access.RO, "", reset=1), ValueError, "reset of a applies to RW"),
    (lambda: Register("a", 8, Access.RW, "", value=1), ValueError, "value of a applies to CONST"),
    (lambda: Register("a", 8, Access.CONST, "", value=256), ValueError, "value of a must fit 8"),
    (lambda: Register("a", 8, Access.RW, "", reset=256), ValueError, "reset of a must fit 8"),
    (lambda: Register("a", 8, Access.RW, "", reset={"x": 1}), TypeError, "reset of a is a dict"),
    (lambda: RegisterGroup("g", 2, ""), ValueError, "offset of group g must be a non-negative "
                                                   "multiple of 4"),
    (lambda: RegisterGroup("g", 0, "", [1]), TypeError, "group g must hold Registers"),
    (lambda: RegisterGroup("g", 0, "", [Register("a", 1, Access.RO, "")] * 2), ValueError,
     "group g declares 'a' twice"),
    (lambda: RegisterMap(groups=[], size=100), ValueError, "size must be a power of two"),
    (lambda: RegisterMap(groups=[], base=0x10, size=0x100), ValueError,
     "base must be a non-negative multiple of size"),
    (lambda: RegisterMap(groups=[RegisterGroup("g", 0, "", [Register("a", 64, Access.RO, "")]),
                                 RegisterGroup("h", 4, "", [])]), ValueError,
     "group h at 0x4 overlaps group g"),
    (lambda: RegisterMap(groups=[RegisterGroup("g", 0xFFC, "", [Register("a", 64, Access.RO,
                                                                         "")])]),
     ValueError, "group g ends at 0x1004, beyond the window"),
    (lambda: RegisterMap(groups=[RegisterGroup("g", 0, ""), RegisterGroup("g", 4, "")]),
     ValueError, "group 'g' is declared twice"),
    (lambda: RegisterFile(3), TypeError, "regmap must be a RegisterMap"),
    (lambda: RegisterFile(small_map(), addr_width=4), ValueError, "addr_width must be an integer "
                                                                  "between 8 and 64"),
    (lambda: RegisterFile(small_map(), addr_width=16), ValueError, "base 0x40000000 does not fit"),
    (lambda: RegisterFile(RegisterMap(groups=[RegisterGroup("axi", 0, "")])), ValueError,
     "group name 'axi' is reserved"),
])
def test_bad_declarations(build, error, message):
    with pytest.raises(error, match=message):
        build()


def test_register_file_reads_writes_and_errors():
    dut = RegisterFile(small_map())
    seen = {}

    async def bench(ctx):
        bus = AxiLite(ctx, dut.axi)
        assert await bus.read(BASE) == (0x1234_5678, RESP_OKAY)
        # Reset values, field by field in their own words.
        assert [await bus.read(BASE + a) for a in (0x10, 0x14, 0x18)] == [
            (3, RESP_OKAY), (0, RESP_OKAY), (5, RESP_OKAY)]
        # A byte-strobed write changes only the strobed bytes.
        assert await bus.write(BASE + 0x14, 0x3BCD_EF01, strobe=0b0101) == RESP_OKAY
        assert await bus.read(BASE + 0x14) == (0x00CD_0001, RESP_OKAY)
        assert ctx.get(dut.blk.ctl.b) == 0x00CD_0001
        # Array elements and multi-word values; bits beyond the width read as zero.
        assert await bus.write(BASE + 0x28, 0xFFFF_FFFF) == RESP_OKAY
        assert await bus.read(BASE + 0x28) == (0xFF, RESP_OKAY)
        assert ctx.get(dut.blk.wide[1]) == 0xFF_0000_0000
        ctx.set(dut.blk.st[2], 0xBEEF)
        assert await bus.read(BASE + 0x34) == (0xBEEF, RESP_OKAY)
        # A command is delivered when its highest word is written, with a strobe.
        assert await bus.write(BASE + 0x38, 0x1111_2222) == RESP_OKAY
        assert not seen
        assert await bus.write(BASE + 0x3C, 0x33, w_delay=3) == RESP_OKAY
        assert seen == {"cmd": 0x33_1111_2222}
        # Errors: RO/CONST writes, WO reads, partial WO writes, unmapped, misaligned,
        # outside the window; none of them changes anything.
        for addr in (BASE + 0x2C, BASE, BASE + 0x40, BASE + 0x100, 0x5000_0010):
            assert await bus.write(addr, 1) == RESP_SLVERR, hex(addr)
        assert await bus.write(BASE + 0x3C, 0x44, strobe=0b0001) == RESP_SLVERR
        for addr in (BASE + 0x38, BASE + 0x40, BASE + 0x12, 0x5000_0010, BASE + 0x0FF0):
            assert await bus.read(addr, r_delay=2) == (0, RESP_SLVERR), hex(addr)
        assert await bus.read(BASE + 0x10) == (3, RESP_OKAY)
        assert seen == {"cmd": 0x33_1111_2222}

    async def watch_commands(ctx):
        async for _, _, stb, value in ctx.tick().sample(dut.blk.cmd.stb, dut.blk.cmd.data):
            if stb:
                assert "cmd" not in seen, "the command strobe lasted more than one clock"
                seen["cmd"] = value

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.add_process(watch_commands)
    sim.run()


def test_a_multi_word_status_element_reads_as_one_sample():
    """Reading word 0 of a read-only element of several words samples the element whole;
    its other words answer from that sample even when the block changes it between the
    reads (a torn read would mix two values), and each element has its own sample."""
    regmap = RegisterMap(groups=[RegisterGroup("blk", 0x0, "a block", [
        Register("live", 40, Access.RO, "a wide counter", count=2)])], base=BASE, size=0x100)
    dut = RegisterFile(regmap)
    first, second, other = 0xAA_1111_2222, 0xBB_3333_4444, 0xCC_5555_6666

    async def bench(ctx):
        bus = AxiLite(ctx, dut.axi)
        ctx.set(dut.blk.live[1], first)
        ctx.set(dut.blk.live[0], other)
        assert await bus.read(BASE + 0x8) == (0x1111_2222, RESP_OKAY)
        ctx.set(dut.blk.live[1], second)
        assert await bus.read(BASE + 0xC) == (0xAA, RESP_OKAY)
        assert await bus.read(BASE + 0x4) == (0, RESP_OKAY)   # element 0 not sampled yet
        assert await bus.read(BASE + 0x0) == (0x5555_6666, RESP_OKAY)
        assert await bus.read(BASE + 0x4) == (0xCC, RESP_OKAY)
        assert await bus.read(BASE + 0xC) == (0xAA, RESP_OKAY)
        assert await bus.read(BASE + 0x8) == (0x3333_4444, RESP_OKAY)
        assert await bus.read(BASE + 0xC) == (0xBB, RESP_OKAY)

    simulate(dut, bench)


def test_register_map_doc_is_generated_from_the_declaration():
    """docs/register_map.md is the markdown of the map `rowtrack build` uses."""
    from emulator.commands.build import docs_params
    regmap = docs_params().regmap()
    text = (DOCS / "register_map.md").read_text()
    assert regmap.markdown() in text, \
        "docs/register_map.md is stale: run `rowtrack build --write-docs docs`"
    assert f"`{regmap.layout_crc():#010x}`" in text


def test_rowtrack_map_binds_every_block():
    regmap = TopParams().regmap()
    assert [g.name for g in regmap.groups] == ["ident", "pose_out", "camera", "solver",
                                               "engine", "status"]
    assert regmap.find("ident", "map_crc").register.value == regmap.layout_crc()
    for group, name in (("pose_out", "control"), ("pose_out", "uart_divisor"),
                        ("camera", "sync"), ("camera", "inputs"), ("solver", "coef"),
                        ("solver", "counters"), ("engine", "control"), ("engine", "status")):
        regmap.find(group, name)


def test_engine_group_binds_the_engine_layouts():
    """Control is the engine's cfg (enabled after reset, centres 0, the temporal window's
    half-width the built maximum), status its counters; the group says that the lanes
    have no run-time thresholds."""
    from amaranth.lib import data

    from hdl.measurement.engine_params import engine_config_layout, engine_status_layout
    params = TopParams()
    engine = params.regmap().group("engine")
    control, status = (next(r for r in engine.registers if r.name == name)
                       for name in ("control", "status"))
    assert control.shape == engine_config_layout(params.engine)
    assert status.shape == engine_status_layout(params.engine)
    assert data.Const(control.shape, control.reset_raw).enable == 1
    w = params.engine.temporal.max_half_width
    assert data.Const(control.shape, control.reset_raw).half_width == w == 20
    assert control.reset_raw == (1 << control.shape["enable"].offset
                                 | w << control.shape["half_width"].offset)
    geometry = next(r for r in engine.registers if r.name == "geometry")
    assert geometry.value == params.segments | len(params.pairs) << 8 | params.solver.slots << 16
    assert "no run-time thresholds" in engine.doc


def test_stereo20_closed_loop_map_fits_the_window():
    """20 cameras' registers fit beside every other group (they overlapped the solver's at
    0x400 when the camera group had 0x200 bytes)."""
    from golden.rig import load_rig
    from hdl.pipeline_config import PipelineConfig
    regmap = PipelineConfig.for_rig(load_rig("stereo20"), closed_loop=True).top.regmap()
    assert regmap.find("camera", "inputs").register.count == 20
    assert "loop" in [g.name for g in regmap.groups]


def test_the_most_cameras_a_front_end_takes_fit_the_camera_group():
    """The front end takes at most 32 cameras; their group must still end in the window
    (RegisterMap raises naming the group otherwise)."""
    from dataclasses import replace
    params = TopParams()
    with pytest.raises(ValueError, match="n_cameras"):
        replace(params.camera, n_cameras=33)
    widest = TopParams.for_pairs([(2 * i, 2 * i + 1) for i in range(16)]).regmap()
    assert widest.find("camera", "inputs").register.count == 32

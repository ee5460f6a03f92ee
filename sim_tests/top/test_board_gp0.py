"""The GP0 (AXI3) to AXI4-Lite bridge in front of a register file: IDs, bursts, narrow
transfers and errors, in the Amaranth simulator."""

from amaranth.hdl import Elaboratable, Module
from amaranth.lib import wiring
from amaranth.sim import Simulator

from hdl.board.gp0 import BURST_FIXED, BURST_INCR, BURST_WRAP, GP0ToAXI4Lite
from hdl.bus.axi4lite import RESP_OKAY, RESP_SLVERR
from hdl.bus.register_file import RegisterFile
from sim_tests.bus.test_regs import BASE, small_map


class BridgedRegisters(Elaboratable):
    def __init__(self):
        self.bridge = GP0ToAXI4Lite()
        self.regs = RegisterFile(small_map())

    def elaborate(self, platform):
        m = Module()
        m.submodules.bridge = self.bridge
        m.submodules.regs = self.regs
        wiring.connect(m, self.bridge.lite, self.regs.axi)
        return m


class GP0Master:
    """Drives AXI3 transactions the way the PS7's GP0 port does (one at a time)."""

    def __init__(self, ctx, port):
        self.ctx, self.port = ctx, port

    async def read(self, addr, *, ident=0, length=1, burst=BURST_INCR, size=2):
        ctx, p = self.ctx, self.port
        for name, value in (("araddr", addr), ("arid", ident), ("arlen", length - 1),
                            ("arburst", burst), ("arsize", size), ("arvalid", 1)):
            ctx.set(getattr(p, name), value)
        await ctx.tick().until(p.arready)
        ctx.set(p.arvalid, 0)
        ctx.set(p.rready, 1)
        beats = []
        while not beats or not beats[-1][2]:
            beats.append(tuple(await ctx.tick().sample(p.rdata, p.rresp, p.rlast, p.rid)
                               .until(p.rvalid)))
            assert len(beats) <= length, "more read beats than the burst length"
        ctx.set(p.rready, 0)
        return beats

    async def write(self, addr, words, *, ident=0, burst=BURST_INCR, size=2, strobe=0xF,
                    last_at=None):
        ctx, p = self.ctx, self.port
        last_at = len(words) - 1 if last_at is None else last_at
        for name, value in (("awaddr", addr), ("awid", ident), ("awlen", len(words) - 1),
                            ("awburst", burst), ("awsize", size), ("awvalid", 1)):
            ctx.set(getattr(p, name), value)
        await ctx.tick().until(p.awready)
        ctx.set(p.awvalid, 0)
        for k, word in enumerate(words):
            ctx.set(p.wdata, word)
            ctx.set(p.wstrb, strobe)
            ctx.set(p.wid, ident)
            ctx.set(p.wlast, k == last_at)
            ctx.set(p.wvalid, 1)
            await ctx.tick().until(p.wready)
        ctx.set(p.wvalid, 0)
        ctx.set(p.bready, 1)
        resp, bid = await ctx.tick().sample(p.bresp, p.bid).until(p.bvalid)
        ctx.set(p.bready, 0)
        return resp, bid


def run(bench):
    dut = BridgedRegisters()

    async def testbench(ctx):
        await bench(ctx, GP0Master(ctx, dut.bridge.gp0), dut.regs)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()


def test_single_transfers_echo_ids():
    async def bench(ctx, gp0, regs):
        assert await gp0.read(BASE, ident=0x5A3) == [(0x1234_5678, RESP_OKAY, 1, 0x5A3)]
        assert await gp0.write(BASE + 0x1C, [0xCAFE], ident=0xFFF) == (RESP_OKAY, 0xFFF)
        assert ctx.get(regs.blk.wide[0]) == 0xCAFE
        assert await gp0.write(BASE + 0x40, [1], ident=7) == (RESP_SLVERR, 7)
        assert await gp0.read(BASE + 0x40, ident=9) == [(0, RESP_SLVERR, 1, 9)]
    run(bench)


def test_incr_and_fixed_bursts():
    async def bench(ctx, gp0, regs):
        ctx.set(regs.blk.st[2], 0x7777)
        beats = await gp0.read(BASE + 0x10, ident=3, length=4)
        assert beats == [(3, 0, 0, 3), (0, 0, 0, 3), (5, 0, 0, 3), (0, 0, 1, 3)]
        assert await gp0.read(BASE + 0x34, length=3, burst=BURST_FIXED) == \
            [(0x7777, 0, 0, 0), (0x7777, 0, 0, 0), (0x7777, 0, 1, 0)]
        assert await gp0.write(BASE + 0x1C, [0x1111, 0x22, 0x3333, 0x44]) == (RESP_OKAY, 0)
        assert ctx.get(regs.blk.wide[0]) == 0x22_0000_1111
        assert ctx.get(regs.blk.wide[1]) == 0x44_0000_3333
        # A burst running into an unmapped word answers SLVERR for that beat only.
        beats = await gp0.read(BASE + 0x34, length=4)
        assert [resp for _, resp, _, _ in beats] == [RESP_OKAY, RESP_SLVERR, RESP_SLVERR,
                                                    RESP_SLVERR]
    run(bench)


def test_narrow_transfers_use_their_word():
    async def bench(ctx, gp0, regs):
        assert await gp0.write(BASE + 0x15, [0x0000_AB00], size=0, strobe=0b0010) == (0, 0)
        assert ctx.get(regs.blk.ctl.b) == 0xAB00
        # A byte read returns the whole word; the CPU picks its lane.
        assert await gp0.read(BASE + 0x15, size=0) == [(0xAB00, RESP_OKAY, 1, 0)]
    run(bench)


def test_malformed_bursts_are_answered_never_hang():
    async def bench(ctx, gp0, regs):
        assert await gp0.read(BASE + 0x10, length=2, burst=BURST_WRAP) == \
            [(0, RESP_SLVERR, 0, 0), (0, RESP_SLVERR, 1, 0)]
        assert await gp0.write(BASE + 0x1C, [5, 6], burst=BURST_WRAP) == (RESP_SLVERR, 0)
        assert ctx.get(regs.blk.wide[0]) == 0
        # WLAST on the wrong beat: the data is written, the response is an error.
        assert await gp0.write(BASE + 0x1C, [8, 9], last_at=0) == (RESP_SLVERR, 0)
        assert await gp0.read(BASE + 0x10) == [(3, RESP_OKAY, 1, 0)]
    run(bench)

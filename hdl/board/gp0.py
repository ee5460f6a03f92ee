"""The PS7's M_AXI_GP0 port (AXI3) and a bridge to the AXI4-Lite register file.

GP0 is a full AXI3 master: transaction IDs that must be echoed, bursts of up to 16
beats, narrow (byte, half-word) transfers. The register file speaks AXI4-Lite. The
bridge serves one read and one write transaction at a time (independently), splits a
burst into single-word accesses (INCR and FIXED; a WRAP burst answers SLVERR on every
beat without touching a register), aligns narrow addresses to their word (the byte
strobes select the bytes) and echoes the IDs. Every request is answered, so a stray
access from the PS never hangs the bus.
"""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from hdl.bus.axi4lite import AXI4LiteSignature, RESP_SLVERR

__all__ = ["GP0Signature", "GP0ToAXI4Lite", "BURST_FIXED", "BURST_INCR", "BURST_WRAP"]

BURST_FIXED, BURST_INCR, BURST_WRAP = 0b00, 0b01, 0b10


class GP0Signature(wiring.Signature):
    """The M_AXI_GP0 port as the PS7 drives it (AXI3: 12-bit IDs, 4-bit lengths,
    32-bit address and data), seen from the master. Member names are the PS7
    primitive's port names without the ``MAXIGP0`` prefix, lower case."""

    ID_BITS = 12

    def __init__(self):
        i = self.ID_BITS
        super().__init__({
            "araddr": Out(32), "arburst": Out(2), "arcache": Out(4), "arid": Out(i),
            "arlen": Out(4), "arlock": Out(2), "arprot": Out(3), "arqos": Out(4),
            "arsize": Out(2), "arvalid": Out(1), "arready": In(1),
            "awaddr": Out(32), "awburst": Out(2), "awcache": Out(4), "awid": Out(i),
            "awlen": Out(4), "awlock": Out(2), "awprot": Out(3), "awqos": Out(4),
            "awsize": Out(2), "awvalid": Out(1), "awready": In(1),
            "wdata": Out(32), "wid": Out(i), "wlast": Out(1), "wstrb": Out(4),
            "wvalid": Out(1), "wready": In(1),
            "bid": In(i), "bresp": In(2), "bvalid": In(1), "bready": Out(1),
            "rdata": In(32), "rid": In(i), "rlast": In(1), "rresp": In(2), "rvalid": In(1),
            "rready": Out(1),
        })

    def __eq__(self, other):
        return isinstance(other, GP0Signature)

    def __repr__(self):
        return "GP0Signature()"


def _next_address(addr, burst, size):
    """Address of the next beat: unchanged for FIXED, plus the beat size otherwise."""
    return Mux(burst == BURST_FIXED, addr, addr + (1 << size))


class GP0ToAXI4Lite(wiring.Component):
    """Serves AXI3 transactions from GP0 as AXI4-Lite single-word accesses.

    Members
    -------
    gp0 : In(GP0Signature())
        From the PS7.
    lite : Out(AXI4LiteSignature(32))
        To the register file.

    Latency: a single read takes the register file's latency plus two clocks; a
    single write plus three. Throughput: one beat per three to four clocks (the PS
    issues register accesses far more slowly). Reset: drops transactions in flight.
    """

    def __init__(self):
        super().__init__({"gp0": In(GP0Signature()), "lite": Out(AXI4LiteSignature(32))})

    def elaborate(self, platform):
        m = Module()
        self._read_engine(m)
        self._write_engine(m)
        return m

    def _read_engine(self, m):
        gp0, lite = self.gp0, self.lite
        rid = Signal(GP0Signature.ID_BITS)
        addr = Signal(32)
        beats_left = Signal(4)
        burst = Signal(2)
        size = Signal(2)
        rdata = Signal(32)
        rresp = Signal(2)
        m.d.comb += [gp0.rid.eq(rid), gp0.rdata.eq(rdata), gp0.rresp.eq(rresp),
                     gp0.rlast.eq(beats_left == 0), lite.araddr.eq(addr & ~3),
                     lite.arprot.eq(0)]
        with m.FSM(name="read"):
            with m.State("IDLE"):
                m.d.comb += gp0.arready.eq(1)
                with m.If(gp0.arvalid):
                    m.d.sync += [rid.eq(gp0.arid), addr.eq(gp0.araddr), burst.eq(gp0.arburst),
                                 size.eq(gp0.arsize), beats_left.eq(gp0.arlen)]
                    m.next = "ADDRESS"
            with m.State("ADDRESS"):
                with m.If(burst == BURST_WRAP):
                    m.d.sync += [rdata.eq(0), rresp.eq(RESP_SLVERR)]
                    m.next = "REPLY"
                with m.Else():
                    m.d.comb += lite.arvalid.eq(1)
                    with m.If(lite.arready):
                        m.next = "DATA"
            with m.State("DATA"):
                m.d.comb += lite.rready.eq(1)
                with m.If(lite.rvalid):
                    m.d.sync += [rdata.eq(lite.rdata), rresp.eq(lite.rresp)]
                    m.next = "REPLY"
            with m.State("REPLY"):
                m.d.comb += gp0.rvalid.eq(1)
                with m.If(gp0.rready):
                    m.d.sync += [beats_left.eq(beats_left - 1),
                                 addr.eq(_next_address(addr, burst, size))]
                    m.next = "ADDRESS"
                    with m.If(beats_left == 0):
                        m.next = "IDLE"

    def _write_engine(self, m):
        gp0, lite = self.gp0, self.lite
        bid = Signal(GP0Signature.ID_BITS)
        addr = Signal(32)
        beats_left = Signal(4)
        burst = Signal(2)
        size = Signal(2)
        wdata = Signal(32)
        wstrb = Signal(4)
        bad = Signal()                                   # a beat failed or the burst was malformed
        aw_done = Signal()
        w_done = Signal()
        m.d.comb += [gp0.bid.eq(bid), gp0.bresp.eq(Mux(bad, RESP_SLVERR, 0)),
                     lite.awaddr.eq(addr & ~3), lite.awprot.eq(0),
                     lite.wdata.eq(wdata), lite.wstrb.eq(wstrb)]
        with m.FSM(name="write"):
            with m.State("IDLE"):
                m.d.comb += gp0.awready.eq(1)
                with m.If(gp0.awvalid):
                    m.d.sync += [bid.eq(gp0.awid), addr.eq(gp0.awaddr), burst.eq(gp0.awburst),
                                 size.eq(gp0.awsize), beats_left.eq(gp0.awlen), bad.eq(0)]
                    m.next = "BEAT"
            with m.State("BEAT"):
                m.d.comb += gp0.wready.eq(1)
                with m.If(gp0.wvalid):
                    m.d.sync += [wdata.eq(gp0.wdata), wstrb.eq(gp0.wstrb),
                                 aw_done.eq(0), w_done.eq(0)]
                    with m.If(gp0.wlast != (beats_left == 0)):
                        m.d.sync += bad.eq(1)
                    with m.If(burst == BURST_WRAP):
                        m.d.sync += bad.eq(1)
                        m.next = "STEP"
                    with m.Else():
                        m.next = "WRITE"
            with m.State("WRITE"):
                m.d.comb += [lite.awvalid.eq(~aw_done), lite.wvalid.eq(~w_done)]
                with m.If(lite.awvalid & lite.awready):
                    m.d.sync += aw_done.eq(1)
                with m.If(lite.wvalid & lite.wready):
                    m.d.sync += w_done.eq(1)
                with m.If((aw_done | lite.awready) & (w_done | lite.wready)):
                    m.next = "RESPONSE"
            with m.State("RESPONSE"):
                m.d.comb += lite.bready.eq(1)
                with m.If(lite.bvalid):
                    with m.If(lite.bresp != 0):
                        m.d.sync += bad.eq(1)
                    m.next = "STEP"
            with m.State("STEP"):
                m.d.sync += [beats_left.eq(beats_left - 1),
                             addr.eq(_next_address(addr, burst, size))]
                with m.If(beats_left == 0):
                    m.next = "REPLY"
                with m.Else():
                    m.next = "BEAT"
            with m.State("REPLY"):
                m.d.comb += gp0.bvalid.eq(1)
                with m.If(gp0.bready):
                    m.next = "IDLE"

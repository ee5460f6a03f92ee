"""The AXI4-Lite interface of the register file (the PS7's M_AXI_GP0 after the bridge)."""

from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from golden.checks import check_int

__all__ = ["AXI4LiteSignature", "RESP_OKAY", "RESP_SLVERR"]

#: AXI response codes.
RESP_OKAY = 0b00
RESP_SLVERR = 0b10


class AXI4LiteSignature(wiring.Signature):
    """AXI4-Lite with 32-bit data, seen from the master (``In`` members are driven by the
    slave). Ports flatten to ``<name>__awaddr`` etc. (cocotbext-axi:
    ``AxiLiteBus.from_prefix(dut, name, bus_separator="__")``)."""

    def __init__(self, addr_width):
        check_int("addr_width", addr_width, 3, 64)
        self.addr_width = addr_width
        super().__init__({
            "awaddr": Out(addr_width), "awprot": Out(3), "awvalid": Out(1), "awready": In(1),
            "wdata": Out(32), "wstrb": Out(4), "wvalid": Out(1), "wready": In(1),
            "bresp": In(2), "bvalid": In(1), "bready": Out(1),
            "araddr": Out(addr_width), "arprot": Out(3), "arvalid": Out(1), "arready": In(1),
            "rdata": In(32), "rresp": In(2), "rvalid": In(1), "rready": Out(1),
        })

    def __eq__(self, other):
        return isinstance(other, AXI4LiteSignature) and other.addr_width == self.addr_width

    def __repr__(self):
        return f"AXI4LiteSignature({self.addr_width})"

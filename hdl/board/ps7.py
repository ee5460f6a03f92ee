"""The Zynq-7000 processing system (PS7) as a black box: the one place it is created.

amaranth-boards describes the Zynq boards' programmable-logic pins but never
instantiates the PS7 primitive, which Vivado needs to connect the fabric to the ARM
cores. :class:`PS7` instantiates it with what the design uses:

* ``FCLK_CLK0`` through a global buffer, the clock of the ``sync`` domain (its
  frequency is set by the PS software — FSBL ``ps7_init`` or Linux's fclk driver — and
  declared here for the timing constraints),
* ``FCLK_RESET0_N``, the domain's reset once synchronized, and
* the ``M_AXI_GP0`` master port (its clock is the same ``FCLK_CLK0``).

Everything else of the PS (DDR, MIO, the other AXI ports) is left to the PS
configuration; the bitstream is meant to be loaded into a running PS (Linux
``fpga_manager`` or JTAG after the FSBL). Only :mod:`hdl.board` touches this primitive;
the pipeline top takes AXI4-Lite through a port so a bench can stand in for the PS7.
"""

from amaranth.hdl import ClockSignal, Instance, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import Out

from hdl.board.gp0 import GP0Signature

__all__ = ["PS7", "FCLK0_NET"]

#: Name of the buffered FCLK_CLK0 net, and of its clock in the constraints.
FCLK0_NET = "fclk0"


class PS7(wiring.Component):
    """The PS7 primitive: FCLK_CLK0, its reset, and M_AXI_GP0 clocked by ``domain``.

    The parent creates ``domain`` from :attr:`fclk0` and :attr:`reset` (through a reset
    synchronizer); GP0's clock input is that domain's clock.

    Parameters
    ----------
    fclk_hz : float
        The FCLK_CLK0 frequency the PS is configured for (used for the clock
        constraint, not to configure the PS).
    domain : str
        The clock domain of the GP0 port.

    Members
    -------
    gp0 : Out(GP0Signature())
        The M_AXI_GP0 master, in ``domain``.
    fclk0 : Out(1)
        FCLK_CLK0 through a global clock buffer.
    reset : Out(1)
        High while FCLK_RESET0_N is low (asynchronous to FCLK_CLK0).
    """

    def __init__(self, *, fclk_hz=100e6, domain="sync"):
        if not isinstance(fclk_hz, (int, float)) or not 10e6 <= fclk_hz <= 250e6:
            raise ValueError(f"fclk_hz must be between 10 MHz and 250 MHz, not {fclk_hz!r}")
        if not isinstance(domain, str) or not domain:
            raise TypeError(f"domain must be a non-empty string, not {domain!r}")
        self.fclk_hz = fclk_hz
        self.domain = domain
        super().__init__({"gp0": Out(GP0Signature()), FCLK0_NET: Out(1), "reset": Out(1)})

    def _gp0_ports(self):
        """Instance keyword arguments connecting every GP0 member to ``MAXIGP0<NAME>``."""
        ports = {}
        for name, member in self.gp0.signature.members.items():
            direction = "o" if member.flow is Out else "i"
            ports[f"{direction}_MAXIGP0{name.upper()}"] = getattr(self.gp0, name)
        return ports

    def elaborate(self, platform):
        m = Module()
        fclk = Signal(4)
        fclk_resetn = Signal(4)
        clk = getattr(self, FCLK0_NET)
        m.submodules.ps7 = Instance(
            "PS7",
            o_FCLKCLK=fclk, o_FCLKRESETN=fclk_resetn,
            i_MAXIGP0ACLK=ClockSignal(self.domain),
            **self._gp0_ports())
        m.submodules.fclk0_bufg = Instance("BUFG", i_I=fclk[0], o_O=clk)
        m.d.comb += self.reset.eq(~fclk_resetn[0])
        if platform is not None:
            platform.add_clock_constraint(clk, self.fclk_hz)
        return m

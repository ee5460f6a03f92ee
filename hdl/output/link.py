"""The pose link: pose output and UART transmitter wired together, with the PS FIFO
read through the register file (head register and write-1-to-pop strobe)."""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.bus.register_file import command_signature
from hdl.output.packet import PoseOutput
from hdl.top_params import TopParams
from hdl.output.uart import UartTx

__all__ = ["PoseLink"]


class PoseLink(wiring.Component):
    """Pose output and UART transmitter wired together.

    Parameters
    ----------
    params : TopParams
        Uses ``pose_output`` and ``uart``.

    Members
    -------
    pose : In(stream.Signature(pose_output.source.layout()))
    cfg : In(pose_output.config_layout())
    divisor : In(uart.divisor_fmt.shape())
    fifo_head : Out(packet.record_layout())
        The oldest record in the PS FIFO (valid while ``status.fifo_level`` is not 0).
    fifo_pop : In(command_signature(1))
        The ``fifo_pop`` register's write strobe: a write of 1 drops ``fifo_head``.
    status : Out(pose_output.status_layout())
    tx : Out(1)
    """

    def __init__(self, params=TopParams()):
        if not isinstance(params, TopParams):
            raise TypeError(f"params must be a TopParams, not {params!r}")
        self.params = params
        po = params.pose_output
        super().__init__({
            "pose": In(stream.Signature(po.source.layout())),
            "cfg": In(po.config_layout()),
            "divisor": In(params.uart.divisor_fmt.shape()),
            "fifo_head": Out(po.packet.record_layout()),
            "fifo_pop": In(command_signature(1)),
            "status": Out(po.status_layout()),
            "tx": Out(1, init=1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.output = output = PoseOutput(self.params.pose_output)
        m.submodules.uart = uart = UartTx(self.params.uart)
        wiring.connect(m, wiring.flipped(self.pose), output.pose)
        wiring.connect(m, output.uart, uart.i)
        m.d.comb += [output.cfg.eq(self.cfg), uart.divisor.eq(self.divisor),
                     self.fifo_head.eq(output.fifo.payload),
                     output.fifo.ready.eq(self.fifo_pop.stb & self.fifo_pop.data),
                     self.status.eq(output.status), self.tx.eq(uart.tx)]
        return m

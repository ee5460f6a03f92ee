"""The pipeline top: the blocks wired together, with AXI4-Lite in and the UART line out.

:class:`RowtrackTop` contains no logic of its own; it connects

* the camera front end (:class:`hdl.camera_sync.CameraFrontEnd`: one DVP input per
  camera in its pixel-clock domain, the trigger/sync monitor and the row aligner),
* the pose output (:class:`PoseLink`: decimation, framing, UART, PS FIFO), and
* the register file (:class:`hdl.regs.RegisterFile` of :func:`hdl.regmap.rowtrack_map`)
  to every block's configuration and status.

The PS7 is not in here: the top takes AXI4-Lite through a port, so a cocotb bench can
stand in for the PS, and the board tops (:mod:`hdl.board`) add the PS7 and pins.
"""

from dataclasses import dataclass, replace

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .camera_input import CameraParams
from .camera_sync import CameraFrontEnd
from .pose_packet import PoseOutput, PoseOutputParams
from .regmap import rowtrack_map
from .regs import AXI4LiteSignature, RegisterFile
from .streams import dvp_signature
from .uart import UartParams, UartTx

__all__ = ["TopParams", "PoseLink", "RowtrackTop", "register_file"]


@dataclass(frozen=True, kw_only=True)
class TopParams:
    """Parameters of :class:`RowtrackTop` (no Amaranth here).

    Parameters
    ----------
    camera : CameraParams
    pose_output : PoseOutputParams
    uart : UartParams
    clk_hz : int
        System clock (FCLK_CLK0) frequency; sets the reset values of the time-based
        registers and the UART divisor.
    baud : int
        UART baud rate after reset.
    reg_base, reg_size : int
        Register window on the AXI bus (GP0 spans ``0x4000_0000``–``0x7FFF_FFFF``).
    """
    camera: CameraParams = CameraParams(n_cameras=4)
    pose_output: PoseOutputParams = PoseOutputParams()
    uart: UartParams = UartParams()
    clk_hz: int = 100_000_000
    baud: int = 3_000_000
    reg_base: int = 0x4000_0000
    reg_size: int = 0x1000

    def __post_init__(self):
        for name, cls in (("camera", CameraParams), ("pose_output", PoseOutputParams),
                          ("uart", UartParams)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"{name} must be a {cls.__name__}, not {getattr(self, name)!r}")
        for name in ("clk_hz", "baud", "reg_base", "reg_size"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool):
                raise TypeError(f"{name} must be an integer, not {value!r}")
        if not 1_000_000 <= self.clk_hz <= 500_000_000:
            raise ValueError(f"clk_hz must be between 1 MHz and 500 MHz, not {self.clk_hz}")
        self.uart.divisor_raw(self.clk_hz, self.baud)       # raises if the baud is unreachable

    replace = replace

    def regmap(self):
        return rowtrack_map(self)


def register_file(params=TopParams()):
    """The register file of the top built with ``params`` (a catalog entry of its own)."""
    return RegisterFile(params.regmap())


class PoseLink(wiring.Component):
    """Pose output and UART transmitter wired together.

    Parameters
    ----------
    params : TopParams
        Uses ``pose_output`` and ``uart``.

    Members
    -------
    pose : In(stream.Signature(packet.pose_layout()))
    cfg : In(pose_output.config_layout())
    divisor : In(uart.divisor_fmt.shape())
    fifo : Out(stream.Signature(packet.record_layout()))
    status : Out(pose_output.status_layout())
    tx : Out(1)
    """

    def __init__(self, params=TopParams()):
        if not isinstance(params, TopParams):
            raise TypeError(f"params must be a TopParams, not {params!r}")
        self.params = params
        po = params.pose_output
        super().__init__({
            "pose": In(stream.Signature(po.packet.pose_layout())),
            "cfg": In(po.config_layout()),
            "divisor": In(params.uart.divisor_fmt.shape()),
            "fifo": Out(stream.Signature(po.packet.record_layout())),
            "status": Out(po.status_layout()),
            "tx": Out(1, init=1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.output = output = PoseOutput(self.params.pose_output)
        m.submodules.uart = uart = UartTx(self.params.uart)
        wiring.connect(m, wiring.flipped(self.pose), output.pose)
        wiring.connect(m, output.uart, uart.i)
        wiring.connect(m, output.fifo, wiring.flipped(self.fifo))
        m.d.comb += [output.cfg.eq(self.cfg), uart.divisor.eq(self.divisor),
                     self.status.eq(output.status), self.tx.eq(uart.tx)]
        return m


class RowtrackTop(wiring.Component):
    """The tracker with its register file, for a board top or a cocotb bench.

    Parameters
    ----------
    params : TopParams
    domains : sequence of str, optional
        Camera ``k``'s pixel clock domain (default ``pclk0``, ``pclk1``, ...).

    Members
    -------
    axi : In(AXI4LiteSignature(32))
        Registers (:func:`hdl.regmap.rowtrack_map`), from the PS7's GP0 port.
    dvp : In(dvp_signature(pixel_bits)).array(n_cameras)
        Camera ports, each in its pixel clock domain.
    trigger, expose : Out(1)
    fsin : Out(n_cameras)
        Trigger outputs of the camera sync.
    uart_tx : Out(1)
        Pose packets.
    """

    def __init__(self, params=TopParams(), *, domains=None):
        if not isinstance(params, TopParams):
            raise TypeError(f"params must be a TopParams, not {params!r}")
        self.params = params
        n = params.camera.n_cameras
        self.domains = tuple(domains) if domains is not None else \
            tuple(f"pclk{k}" for k in range(n))
        super().__init__({
            "axi": In(AXI4LiteSignature(32)),
            "dvp": In(dvp_signature(params.camera.pixel_bits)).array(n),
            "trigger": Out(1), "expose": Out(1), "fsin": Out(n),
            "uart_tx": Out(1, init=1),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        m.submodules.regs = regs = RegisterFile(p.regmap())
        m.submodules.front = front = CameraFrontEnd(p.camera, domains=self.domains)
        m.submodules.pose_link = link = PoseLink(p)
        wiring.connect(m, wiring.flipped(self.axi), regs.axi)

        for k in range(p.camera.n_cameras):
            wiring.connect(m, wiring.flipped(self.dvp[k]), front.dvp[k])
        cam = regs.camera
        m.d.comb += [
            front.cfg.input.eq(cam.input), front.cfg.sync.eq(cam.sync),
            front.cfg.align.eq(cam.align),
            cam.time.now.eq(front.status.now), cam.time.frame.eq(front.status.frame),
            cam.sync_status.eq(front.status.sync), cam.align_status.eq(front.status.align),
            cam.inputs.eq(front.status.inputs),
            self.trigger.eq(front.trigger), self.expose.eq(front.expose),
            self.fsin.eq(front.fsin),
        ]

        out = regs.pose_out
        m.d.comb += [
            link.cfg.eq(out.control), link.divisor.eq(out.uart_divisor),
            out.status.eq(link.status), out.fifo_head.eq(link.fifo.payload),
            link.fifo.ready.eq(out.fifo_pop.stb & out.fifo_pop.data),
            self.uart_tx.eq(link.tx),
        ]
        return m

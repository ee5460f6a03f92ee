"""The pipeline top: the blocks wired together, with AXI4-Lite in and the UART line out.

:class:`RowtrackTop` contains no logic of its own; it connects

* the camera front end (:class:`hdl.camera_sync.CameraFrontEnd`: one DVP input per
  camera in its pixel-clock domain, the trigger/sync monitor and the row aligner),
* the measurement engine (:class:`hdl.measurement_engine.MeasurementEngine`: a temporal
  row-descriptor lane per camera, a stereo lane per pair, and the router that turns
  their segment measurements into the solver's slots with their depth cues),
* the pose solver (:class:`hdl.pose_solver.PoseSolver`: coefficient store, normal
  equations, LDLᵀ solve, pose integration),
* the pose output (:class:`PoseLink`: decimation, framing, UART, PS FIFO), and
* the register file (:class:`hdl.regs.RegisterFile` of :func:`hdl.regmap.rowtrack_map`)
  to every block's configuration, status and the solver's coefficient load.

The PS7 is not in here: the top takes AXI4-Lite through a port, so a cocotb bench can
stand in for the PS, and the board tops (:mod:`hdl.board`) add the PS7 and pins.
"""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .camera_sync import CameraFrontEnd
from .measurement_engine import MeasurementEngine
from .pose_packet import PoseOutput
from .pose_solver import PoseSolver
from .regs import AXI4LiteSignature, RegisterFile
from .streams import dvp_signature
from .top_params import TopParams
from .uart import UartTx

__all__ = ["PoseLink", "RowtrackTop", "register_file"]


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
    pose : In(stream.Signature(pose_output.source.layout()))
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
            "pose": In(stream.Signature(po.source.layout())),
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
        #: The clock domains it uses without defining them, in port order
        #: (:func:`hdl.verilog.to_verilog`).
        self.clock_domains = ("sync", *self.domains)
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
        m.submodules.engine = engine = MeasurementEngine(p.engine)
        m.submodules.solver = solver = PoseSolver(p.solver)
        m.submodules.pose_link = link = PoseLink(p)
        wiring.connect(m, wiring.flipped(self.axi), regs.axi)
        wiring.connect(m, front.o, engine.rows)
        wiring.connect(m, engine.o, solver.i)
        m.d.comb += [engine.cfg.eq(regs.engine.control), regs.engine.status.eq(engine.status)]

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

        pose, record = link.pose, solver.o
        coef = regs.solver.coef
        m.d.comb += [
            pose.valid.eq(record.valid), record.ready.eq(pose.ready),
            pose.payload.t_row.eq(record.payload.time), pose.payload.row.eq(record.payload.row),
            pose.payload.position.eq(record.payload.p),
            pose.payload.quaternion.eq(record.payload.q),
            pose.payload.flags.eq(record.payload.flags),
            solver.coef_write.addr.eq(coef.data.addr), solver.coef_write.index.eq(coef.data.index),
            solver.coef_write.data.eq(coef.data.data), solver.coef_write.en.eq(coef.stb),
            regs.solver.counters.eq(solver.counters),
        ]

        out = regs.pose_out
        m.d.comb += [
            link.cfg.eq(out.control), link.divisor.eq(out.uart_divisor),
            out.status.eq(link.status), out.fifo_head.eq(link.fifo.payload),
            link.fifo.ready.eq(out.fifo_pop.stb & out.fifo_pop.data),
            self.uart_tx.eq(link.tx),
        ]
        return m

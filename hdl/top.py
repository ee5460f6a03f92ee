"""The pipeline top: the blocks wired together, with AXI4-Lite in and the UART line out.

:class:`RowtrackTop` contains no logic of its own; it connects

* the camera front end (:class:`hdl.front_end.camera_sync.CameraFrontEnd`: one DVP input per
  camera in its pixel-clock domain, the trigger/sync monitor and the row aligner),
* the measurement engine (:class:`hdl.measurement.engine.MeasurementEngine`: a temporal
  row-descriptor lane per camera, a stereo lane per pair, and the router that turns
  their segment measurements into the solver's slots with their depth cues),
* the pose solver (:class:`hdl.pose_solver.PoseSolver`: coefficient store, normal
  equations, LDLᵀ solve, pose integration),
* the pose output (:class:`hdl.output.link.PoseLink`: decimation, framing, UART, PS
  FIFO), and
* the register file (:class:`hdl.bus.register_file.RegisterFile` of :func:`hdl.bus.regmap.rowtrack_map`)
  to every block's configuration, status and the solver's coefficient load.

The PS7 is not in here: the top takes AXI4-Lite through a port, so a cocotb bench can
stand in for the PS, and the board tops (:mod:`hdl.board`) add the PS7 and pins.
"""

from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from hdl.front_end.camera_sync import CameraFrontEnd
from hdl.measurement.engine import MeasurementEngine
from hdl.output.link import PoseLink
from hdl.pose_solver import PoseSolver
from hdl.bus.axi4lite import AXI4LiteSignature
from hdl.bus.register_file import RegisterFile
from hdl.streams import dvp_signature
from hdl.top_params import TopParams

__all__ = ["RowtrackTop", "register_file"]


def register_file(params=TopParams()):
    """The register file of the top built with ``params`` (a catalog entry of its own)."""
    return RegisterFile(params.regmap())


class RowtrackTop(wiring.Component):
    """The tracker with its register file, for a board top or a cocotb bench.

    Parameters
    ----------
    params : TopParams
    domains : sequence of str, optional
        Camera ``k``'s pixel clock domain (default ``pclk0``, ``pclk1``, ...).
    coefficients : ndarray (slots, rows, 9), optional
        Initial contents of the solver's coefficient store (raw; default zeros, loaded
        through the registers), e.g. a rig's ``PipelineConfig.coef_raw``.

    Members
    -------
    axi : In(AXI4LiteSignature(32))
        Registers (:func:`hdl.bus.regmap.rowtrack_map`), from the PS7's GP0 port.
    dvp : In(dvp_signature(pixel_bits)).array(n_cameras)
        Camera ports, each in its pixel clock domain.
    trigger, expose : Out(1)
    fsin : Out(n_cameras)
        Trigger outputs of the camera sync.
    uart_tx : Out(1)
        Pose packets.
    """

    def __init__(self, params=TopParams(), *, domains=None, coefficients=None):
        if not isinstance(params, TopParams):
            raise TypeError(f"params must be a TopParams, not {params!r}")
        self.params = params
        self.coefficients = coefficients
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
        m.submodules.solver = solver = PoseSolver(p.solver, self.coefficients)
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

        wiring.connect(m, solver.o, link.pose)
        coef = regs.solver.coef
        m.d.comb += [
            solver.coef_write.addr.eq(coef.data.addr), solver.coef_write.index.eq(coef.data.index),
            solver.coef_write.data.eq(coef.data.data), solver.coef_write.en.eq(coef.stb),
            regs.solver.counters.eq(solver.counters),
        ]

        out = regs.pose_out
        wiring.connect(m, out.fifo_pop, link.fifo_pop)
        m.d.comb += [
            link.cfg.eq(out.control), link.divisor.eq(out.uart_divisor),
            out.status.eq(link.status), out.fifo_head.eq(link.fifo_head),
            self.uart_tx.eq(link.tx),
        ]
        return m

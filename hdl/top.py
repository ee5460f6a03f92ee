"""The pipeline top: the blocks wired together, with AXI4-Lite in and the UART line out.

:class:`RowtrackTop` contains no logic of its own; it connects

* the camera front end (:class:`hdl.front_end.camera_sync.CameraFrontEnd`: one DVP input per
  camera in its pixel-clock domain, the trigger/sync monitor and the row aligner),
* the measurement engine (:class:`hdl.measurement.engine.MeasurementEngine`: a temporal
  row-descriptor lane per camera, a stereo lane per pair, and the router that turns
  their segment measurements into the solver's slots with their depth cues),
* the pose solver (:class:`hdl.pose_solver.PoseSolver`: coefficient store, normal
  equations, LDLᵀ solve, pose integration), or, in a closed-loop top
  (``TopParams.closed_loop``), the tracking loop around it
  (:class:`hdl.pose.tracking_loop.TrackingLoop`: consistency stage, solver, tracking
  status and the forecast that gives the engine's following lanes each row's window
  centre and reference row),
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
from hdl.pose.row_counter import RowCounter
from hdl.pose.status_params import top_status_params
from hdl.pose.status_unit import StatusUnit
from hdl.pose.tracking_loop import TrackingLoop, information_settings
from hdl.pose_solver import PoseSolver
from hdl.bus.axi4lite import AXI4LiteSignature
from hdl.bus.register_file import RegisterFile
from hdl.streams import dvp_signature
from hdl.top_params import DEFAULT_SEGMENTS, TopParams

__all__ = ["RowtrackTop", "register_file", "board_config", "closed_loop_top"]


def register_file(params=TopParams()):
    """The register file of the top built with ``params`` (a catalog entry of its own)."""
    return RegisterFile(params.regmap())


#: Lanes per shift matcher in the top of a rig a supported board carries (issue 17 item
#: 3). Two: a 640-column row then takes 2 × 640 clocks at the 100 MHz design clock,
#: within the 1,390 clocks of the board cameras' row period during readout (120 fps,
#: 80 % readout); three would take 1,920, i.e. need the 150 MHz clock.
BOARD_MATCHER_PORTS = 2


def matcher_ports(rig):
    """Lanes per shift matcher for ``rig``: :data:`BOARD_MATCHER_PORTS` when a supported
    board carries its cameras (the board top needs the LUTs), one otherwise. stereo20
    (20 cameras, no board; it fits its xc7z045 with a matcher per lane) overflowed its
    camera buffers in the co-simulation with two: its cameras, at the bench's 80.6 MHz
    pixel clock and with up to 15 rows of skew for the aligner to wait out, outran an
    engine taking a column every second clock."""
    from hdl.board import board, names
    carried = len(rig.cameras) <= max(board(name).n_cameras for name in names())
    return BOARD_MATCHER_PORTS if carried else 1


def board_config(rig, **changes):
    """The closed-loop pipeline a board carries for ``rig`` (a :class:`golden.rig.Rig`):
    its cameras, pairs and coefficient stores, K = K_s = :data:`DEFAULT_SEGMENTS`,
    :func:`matcher_ports` lanes per shift matcher; ``changes`` go to
    :meth:`PipelineConfig.for_rig` (e.g. ``clk_hz``, ``baud``, ``matcher_ports``)."""
    from hdl.pipeline_config import PipelineConfig
    changes.setdefault("matcher_ports", matcher_ports(rig))
    return PipelineConfig.for_rig(rig, closed_loop=True, stereo_segments=DEFAULT_SEGMENTS,
                                  **changes)


def closed_loop_top(rig_name="stereo8-board"):
    """The closed-loop top of preset rig ``rig_name`` (:func:`board_config`): the
    catalog's ``top_closed``, the build a board user loads."""
    from golden.rig import preset
    config = board_config(preset(rig_name))
    return RowtrackTop(config.top, coefficients=config.coef_store,
                       forecast_stores=config.forecast_stores)


class RowtrackTop(wiring.Component):
    """The tracker with its register file, for a board top or a cocotb bench.

    Parameters
    ----------
    params : TopParams
    domains : sequence of str, optional
        Camera ``k``'s pixel clock domain (default ``pclk0``, ``pclk1``, ...).
    coefficients : ndarray (slots, rows, 9), optional
        Initial contents of the solver's coefficient store (raw; default zeros, loaded
        through the registers), e.g. a rig's ``PipelineConfig.coef_store``.
    forecast_stores : (ndarray, ndarray), closed loop only
        The contents of the forecast's two stores in their layouts (raw,
        (slots, entries_per_slot, 9)): its copy of the solver's store and the across-rows
        store, ``PipelineConfig.forecast_stores`` (``.coef_store`` and
        ``.row_coef_store``: polynomial terms); fixed at build time (no register load
        yet).

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

    def __init__(self, params=TopParams(), *, domains=None, coefficients=None,
                 forecast_stores=None):
        if not isinstance(params, TopParams):
            raise TypeError(f"params must be a TopParams, not {params!r}")
        if params.closed_loop and forecast_stores is None:
            raise ValueError("forecast_stores must be given for a closed-loop top")
        if not params.closed_loop and forecast_stores is not None:
            raise ValueError("forecast_stores is for a closed-loop top only")
        self.params = params
        self.coefficients = coefficients
        self.forecast_stores = forecast_stores
        #: The blocks between the engine and the pose output, by the kind of top.
        self._wire_back_end = self._wire_loop if params.closed_loop else self._wire_solver
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
        m.submodules.pose_link = link = PoseLink(p)
        wiring.connect(m, wiring.flipped(self.axi), regs.axi)
        wiring.connect(m, front.o, engine.rows)
        m.d.comb += [engine.cfg.eq(regs.engine.control), regs.engine.status.eq(engine.status)]
        self._wire_back_end(m, regs, engine, link)

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
        wiring.connect(m, out.fifo_pop, link.fifo_pop)
        m.d.comb += [
            link.cfg.eq(out.control), link.divisor.eq(out.uart_divisor),
            out.status.eq(link.status), out.fifo_head.eq(link.fifo_head),
            self.uart_tx.eq(link.tx),
        ]
        return m

    @staticmethod
    def _wire_solver_registers(m, regs, solver):
        """The solver's coefficient load and conditioning gate (a PoseSolver, or the
        tracking loop holding one)."""
        coef, write, group = regs.solver.coef, solver.coef_write, regs.solver
        m.d.comb += [write.addr.eq(coef.data.addr), write.index.eq(coef.data.index),
                     write.data.eq(coef.data.data), write.en.eq(coef.stb),
                     solver.pivot_log2.eq(group.pivot_log2),
                     group.status.pivot_log2_error.eq(solver.pivot_log2_error)]

    def _wire_solver(self, m, regs, engine, link):
        """Open loop: the engine's measurements straight into the solver."""
        m.submodules.solver = solver = PoseSolver(self.params.solver, self.coefficients)
        wiring.connect(m, engine.o, solver.i)
        wiring.connect(m, solver.o, link.pose)
        self._wire_solver_registers(m, regs, solver)
        m.d.comb += regs.solver.counters.eq(solver.counters)

    def _wire_loop(self, m, regs, engine, link):
        """Closed loop: the engine's measurements into the tracking loop, its forecast
        back into the engine, its records through the tracking-status unit (with the
        per-row counts of the loop's verdicts) to the pose output."""
        p = self.params
        status_params = top_status_params(p)
        m.submodules.loop = loop = TrackingLoop(p.forecast, p.consistency,
                                                *self.forecast_stores, self.coefficients)
        m.submodules.row_counter = counter = RowCounter(status_params)
        m.submodules.status = status = StatusUnit(status_params, p.solver)
        wiring.connect(m, engine.o, loop.i)
        wiring.connect(m, loop.verdicts, counter.i)
        wiring.connect(m, counter.o, status.row)
        wiring.connect(m, loop.records, status.i)
        wiring.connect(m, status.o, link.pose)
        ahead, fed = loop.o, engine.forecast
        m.d.comb += [fed.valid.eq(ahead.valid), ahead.ready.eq(fed.ready),
                     fed.payload.camera.eq(ahead.payload.camera),
                     fed.payload.centre.eq(ahead.payload.centre),
                     fed.payload.segment_rows.eq(ahead.payload.segment_rows),
                     fed.payload.row.eq(ahead.payload.row),
                     fed.payload.last.eq(ahead.payload.last)]
        self._wire_solver_registers(m, regs, loop)
        settings, state = regs.loop, regs.status
        m.d.comb += [
            loop.alpha.eq(settings.alpha), loop.beta.eq(settings.beta),
            loop.track_alpha.eq(settings.track_alpha), settings.track.eq(loop.track_y),
            loop.initial.eq(settings.initial), loop.restart.eq(settings.restart.stb),
            loop.frame_rows.eq(settings.frame_rows), loop.settings.eq(settings.consistency),
            settings.counts.eq(loop.counts), settings.forecast_counters.eq(loop.forecast_counters),
            settings.counters.eq(loop.counters), regs.solver.counters.eq(loop.solver_counters),
            status.settings.eq(state.settings), status.clear.eq(state.clear.stb),
            state.state.eq(status.state),
        ]
        m.d.comb += information_settings(loop, settings)

"""Parameters of the pipeline top (:class:`hdl.top.RowtrackTop`), without gateware.

A top is fixed by its cameras, their stereo pairs, the temporal segments per row (K),
the solver's formats, the pose output, the UART and the system clock; the measurement
engine's parameters follow from those (:meth:`hdl.measurement.engine_params.EngineParams.for_cameras`).
:class:`hdl.pipeline_config.PipelineConfig` builds one from a rig.
"""

from dataclasses import dataclass, field, replace

from golden.checks import check_int

from hdl.front_end.params import CameraParams
from hdl.measurement.consistency_params import ConsistencyParams
from hdl.measurement.engine_params import EngineParams
from hdl.measurement.router_params import StereoWindow
from hdl.output.params import PoseOutputParams
from hdl.pose.forecast_params import ForecastParams
from hdl.pose.params import PoseSolverParams, solver_source
from hdl.pose.status_params import status_source
from hdl.descriptor.params import DEFAULT_SEGMENTS
from hdl.output.params import UartParams

__all__ = ["TopParams", "solver_source", "DEFAULT_CAMERAS", "DEFAULT_SEGMENTS"]


#: Default camera ports (every supported board has four).
DEFAULT_CAMERAS = 4


@dataclass(frozen=True, kw_only=True)
class TopParams:
    """Parameters of :class:`RowtrackTop` (no Amaranth here).

    Parameters
    ----------
    camera : CameraParams
    pairs : tuple of (int, int)
        Stereo pairs ``(A, B)`` of the measurement engine, one stereo lane each; every
        camera belongs to exactly one pair (the stereo disparity is the solver's only
        depth cue).
    segments : int
        Temporal-lane segments per row (K): the solver's ``slots`` must be
        ``camera.n_cameras × segments``.
    stereo_segments : int
        Stereo-lane segments per row (K_s, each its own disparity; temporal segment k
        takes stereo segment ``k·K_s // K``).
    matcher_ports : int
        Lanes per shift matcher in the measurement engine
        (:class:`hdl.measurement.engine_params.EngineParams`; default 1, a matcher per
        lane).
    stereo_window : StereoWindow
        The stereo lanes' disparity window and which of their results give a depth
        (default the fixed [10, 70]; ``PipelineConfig.for_rig`` derives it from the rig).
    solver : PoseSolverParams
        ``rows`` must be the cameras' ``max_height``, ``time_bits`` their
        ``timestamp_bits`` and ``slots`` ``n_cameras × segments``.
    pose_output : PoseOutputParams
        ``source`` must be :func:`solver_source` of ``solver``.
    uart : UartParams
    clk_hz : int
        System clock (FCLK_CLK0) frequency; sets the reset values of the time-based
        registers and the UART divisor.
    baud : int
        UART baud rate after reset.
    reg_base, reg_size : int
        Register window on the AXI bus (GP0 spans ``0x4000_0000``–``0x7FFF_FFFF``).
    forecast : ForecastParams or None
    consistency : ConsistencyParams or None
        Both or neither. Both: the closed measurement loop (issue 16; built from a rig by
        ``PipelineConfig.for_rig(..., closed_loop=True)``): following temporal lanes with
        the router's cue fallback, and :class:`hdl.pose.tracking_loop.TrackingLoop`
        (consistency stage, solver, forecast) between the engine and the pose output;
        their ``solver`` must be ``solver``, their ``segments`` ``segments``, the
        forecast's ``height`` the cameras' ``max_height``. Neither: the open-loop top
        (each row against the same row of the previous frame, centres from registers).

    Members
    -------
    engine : EngineParams
        The measurement engine's parameters, derived from the above.
    """
    camera: CameraParams = CameraParams(n_cameras=DEFAULT_CAMERAS)
    pairs: tuple = ((0, 1), (2, 3))
    segments: int = DEFAULT_SEGMENTS
    stereo_segments: int = 1
    stereo_window: StereoWindow = StereoWindow()
    matcher_ports: int = 1
    solver: PoseSolverParams = PoseSolverParams(slots=DEFAULT_CAMERAS * DEFAULT_SEGMENTS)
    pose_output: PoseOutputParams = PoseOutputParams(source=solver_source(PoseSolverParams()))
    uart: UartParams = UartParams()
    clk_hz: int = 100_000_000
    baud: int = 3_000_000
    reg_base: int = 0x4000_0000
    reg_size: int = 0x1000
    forecast: ForecastParams = None
    consistency: ConsistencyParams = None
    engine: EngineParams = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        for name, cls in (("camera", CameraParams), ("solver", PoseSolverParams),
                          ("pose_output", PoseOutputParams), ("uart", UartParams)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"{name} must be a {cls.__name__}, not {getattr(self, name)!r}")
        if self.solver.rows != self.camera.max_height:
            raise ValueError(f"solver.rows must be camera.max_height ({self.camera.max_height}), "
                             f"not {self.solver.rows}")
        if self.solver.time_bits != self.camera.timestamp_bits:
            raise ValueError(f"solver.time_bits must be camera.timestamp_bits "
                             f"({self.camera.timestamp_bits}), not {self.solver.time_bits}")
        self._check_loop()
        source, name = ((status_source(self.solver), "status_source") if self.closed_loop
                        else (solver_source(self.solver), "solver_source"))
        if self.pose_output.source != source:
            raise ValueError(f"pose_output.source must be {name}(solver), not "
                             f"{self.pose_output.source!r}")
        for name in ("clk_hz", "baud", "reg_base", "reg_size"):
            check_int(name, getattr(self, name))
        if not 1_000_000 <= self.clk_hz <= 500_000_000:
            raise ValueError(f"clk_hz must be between 1 MHz and 500 MHz, not {self.clk_hz}")
        self.uart.divisor_raw(self.clk_hz, self.baud)       # raises if the baud is unreachable
        # The engine checks pairs (every camera in one pair), segments and solver.slots.
        object.__setattr__(self, "engine", EngineParams.for_cameras(
            self.camera, self.solver, self.pairs, segments=self.segments,
            stereo_segments=self.stereo_segments, stereo_window=self.stereo_window,
            follow=self.closed_loop,
            cue_fallback=self.closed_loop, matcher_ports=self.matcher_ports))

    def _check_loop(self):
        for name, cls in (("forecast", ForecastParams), ("consistency", ConsistencyParams)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, cls):
                raise TypeError(f"{name} must be a {cls.__name__} or None, not {value!r}")
        if (self.forecast is None) != (self.consistency is None):
            raise ValueError("forecast and consistency must be given together (the closed "
                             "loop) or not at all")
        for name in ("forecast", "consistency") if self.closed_loop else ():
            part = getattr(self, name)
            if part.solver != self.solver:
                raise ValueError(f"{name}.solver must be the top's solver")
            if part.segments != self.segments:
                raise ValueError(f"{name}.segments must be segments ({self.segments}), not "
                                 f"{part.segments}")
        if self.closed_loop and self.forecast.height != self.camera.max_height:
            raise ValueError(f"forecast.height must be camera.max_height "
                             f"({self.camera.max_height}), not {self.forecast.height}")

    @property
    def closed_loop(self):
        """The top closes the measurement loop (``forecast`` and ``consistency`` given)."""
        return self.forecast is not None

    @classmethod
    def for_pairs(cls, pairs, *, segments=DEFAULT_SEGMENTS, camera=CameraParams(),
                  solver=PoseSolverParams(), pose_output=PoseOutputParams(), **changes):
        """Parameters for ``len(pairs) · 2`` cameras: ``camera``, ``solver`` and
        ``pose_output`` adjusted to them (camera count, solver slots, rows, row bits
        at least the camera's, time bits, the output's source formats)."""
        n = 2 * len(pairs)
        camera = replace(camera, n_cameras=n)
        solver = replace(solver, slots=n * segments, rows=camera.max_height,
                         row_bits=max(solver.row_bits, camera.row_bits),
                         time_bits=camera.timestamp_bits)
        closed = changes.get("forecast") is not None
        pose_output = replace(pose_output, source=(status_source if closed
                                                   else solver_source)(solver))
        return cls(camera=camera, pairs=tuple(tuple(p) for p in pairs), segments=segments,
                   solver=solver, pose_output=pose_output, **changes)

    replace = replace

    def closing(self, forecast, consistency):
        """These parameters with the measurement loop closed by ``forecast`` and
        ``consistency`` (the pose output then carries the tracking status)."""
        return replace(self, forecast=forecast, consistency=consistency,
                       pose_output=replace(self.pose_output,
                                           source=status_source(self.solver)))

    def regmap(self):
        """The register map of the top built with these parameters."""
        from hdl.bus.regmap import rowtrack_map
        return rowtrack_map(self)

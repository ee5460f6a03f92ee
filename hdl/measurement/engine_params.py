"""Parameters and port layouts of the measurement engine (``hdl/measurement/engine.py``).

No Amaranth at import time: the engine's bit-accurate model
(``emulator/measurement/engine.py``) and the benches read the same object as the
gateware. The engine is the row-descriptor lanes of a camera cluster plus the
measurement router, so its parameters are the router's (lane and solver parameters,
stereo pairing) and the width of its own counters; :meth:`EngineParams.for_cameras`
sizes the lanes so that a camera beat of the front end *is* a lane's input beat.
"""

from dataclasses import dataclass, replace

from golden.checks import check_int
from golden.descriptor import MatchParams

from hdl.front_end.params import CameraParams
from hdl.measurement.router_params import RouterParams, StereoWindow
from hdl.pose.params import PoseSolverParams
from hdl.descriptor.params import DEFAULT_SEGMENTS, RowDescriptorParams

__all__ = ["EngineParams", "engine_config_layout", "fork_status_layout",
           "engine_status_layout"]

#: Width of a temporal lane's saturating ``out_of_range`` count
#: (``hdl.descriptor.store.COUNT_BITS``; that module imports Amaranth).
OUT_OF_RANGE_BITS = 32

#: Lane parameters a camera beat fixes, by their CameraParams name.
_BEAT_FIELDS = {"width": "max_width", "height": "max_height", "pixel_bits": "pixel_bits",
                "camera_bits": "camera_bits", "frame_bits": "frame_bits",
                "row_bits": "row_bits", "timestamp_bits": "timestamp_bits"}

#: Lane parameters that, with the beat's, fix a row's descriptor bits (the framer's and
#: the FIR's): the stereo lanes take the temporal lanes' bits, so they must agree.
_DESCRIPTOR_FIELDS = ("descriptor", "coeff_frac_bits")


@dataclass(frozen=True, kw_only=True)
class EngineParams:
    """One temporal lane per camera, one stereo lane per pair, and the router.

    Parameters
    ----------
    router : RouterParams
        Cameras, stereo pairs, the temporal and stereo lanes' parameters and the pose
        solver's. Both lane parameter sets must take the same camera beat and have the
        same ``descriptor`` and ``coeff_frac_bits``: each stereo lane matches the bits
        its pair's temporal lanes compute (``StereoRowDescriptor(shared=True)``).
    count_bits : int
        Width of the engine's own wrapping counters (row sets in, dropped, stereo rows
        skipped, forecast mismatches).
    follow : bool
        Closed loop (issue 16): the temporal lanes follow rows
        (``RowDescriptor(follow=True)``, a ring reference store), and each row set is
        joined with one forecast row (``forecast`` input, :meth:`forecast_layout`) that
        gives every temporal lane its window centre and source row. Default off: the
        open-loop engine, bit for bit.
    matcher_ports : int
        Lanes one shift matcher serves (issue 17 item 3,
        ``hdl.descriptor.matcher.ShiftMatcher(ports=P)``): temporal lanes of consecutive
        cameras, and stereo lanes of consecutive pairs, share a matcher ``P`` at a time.
        The measurements are the same bit for bit; the engine then takes a column of
        each row set at most every ``P`` clocks (the clock must be at least ``P`` times
        the cameras' pixel rate, with room for the matchers' stalls when segments of
        several lanes end together), and a row's results may wait up to ``P − 1`` more
        matcher jobs. Default 1: a matcher per lane.

    Raises
    ------
    TypeError, ValueError
        Naming the parameter.
    """
    router: RouterParams
    count_bits: int = 16
    follow: bool = False
    matcher_ports: int = 1

    def __post_init__(self):
        if not isinstance(self.router, RouterParams):
            raise TypeError(f"router must be a RouterParams, not {self.router!r}")
        check_int("count_bits", self.count_bits, 1, 32)
        check_int("matcher_ports", self.matcher_ports, 1, 16)
        if not isinstance(self.follow, bool):
            raise TypeError(f"follow must be a bool, not {self.follow!r}")
        if self.follow and self.router.temporal.radius < 3:
            raise ValueError(f"follow needs router.temporal.radius at least 3 (the ring "
                             f"store computes its addresses meanwhile), not "
                             f"{self.router.temporal.radius}")
        t, s = self.router.temporal, self.router.stereo
        for name in (*_BEAT_FIELDS, *_DESCRIPTOR_FIELDS):
            if getattr(t, name) != getattr(s, name):
                raise ValueError(f"router.stereo.{name} must be router.temporal.{name} "
                                 f"({getattr(t, name)}), not {getattr(s, name)}")
        if self.cameras > 1 << t.camera_bits:
            raise ValueError(f"router.temporal.camera_bits {t.camera_bits} cannot number "
                             f"{self.cameras} cameras")

    replace = replace

    @classmethod
    def for_cameras(cls, camera, solver, pairs, *, segments=DEFAULT_SEGMENTS,
                    stereo_segments=1, stereo_window=StereoWindow(), follow=False,
                    cue_fallback=False, matcher_ports=1):
        """The engine behind a camera front end with parameters ``camera``.

        Lanes are ``camera.max_width × camera.max_height`` with the camera beat's widths;
        temporal lanes have ``segments`` segments (the solver needs ``n_cameras ×
        segments`` slots and ``max_height`` rows), stereo lanes ``stereo_segments``
        (``golden.descriptor.STEREO_MATCH``'s disparity range). ``pairs``: ``(A, B)``
        camera indices per rectified pair, every camera in exactly one. ``follow``: the
        closed-loop engine; ``cue_fallback``: the router's cue store
        (:class:`~hdl.measurement.router_params.RouterParams`); ``matcher_ports``: lanes
        per shift matcher.

        Raises
        ------
        TypeError, ValueError
            Naming the parameter that cannot be met.
        """
        if not isinstance(camera, CameraParams):
            raise TypeError(f"camera must be a CameraParams, not {camera!r}")
        if not isinstance(solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {solver!r}")
        if not isinstance(stereo_window, StereoWindow):
            raise TypeError(f"stereo_window must be a StereoWindow, not {stereo_window!r}")
        check_int("segments", segments, 1)
        check_int("stereo_segments", stereo_segments, 1)
        if solver.rows != camera.max_height:
            raise ValueError(f"solver.rows must be camera.max_height ({camera.max_height}), "
                             f"not {solver.rows}")
        beat = {name: getattr(camera, source) for name, source in _BEAT_FIELDS.items()}
        lanes = {}
        for kind, match in (("temporal", MatchParams(segments=segments)),
                            ("stereo", stereo_window.match(stereo_segments))):
            try:
                lanes[kind] = RowDescriptorParams(**beat, match=match)
            except ValueError as err:
                raise ValueError(f"camera (max_width {camera.max_width}, max_height "
                                 f"{camera.max_height}) cannot size a {kind} lane with "
                                 f"segments={match.segments} and shifts [{match.shift_min}, "
                                 f"{match.shift_max}]: {err}") from err
        try:
            pairs = tuple(tuple(pair) for pair in pairs)
        except TypeError as err:
            raise TypeError(f"pairs must be a sequence of (A, B) camera pairs, not "
                            f"{pairs!r}") from err
        router = RouterParams(cameras=camera.n_cameras, pairs=pairs, solver=solver,
                              cue_fallback=cue_fallback, stereo_window=stereo_window,
                              **lanes)
        return cls(router=router, count_bits=camera.count_bits, follow=follow,
                   matcher_ports=matcher_ports)

    # --- shortcuts -----------------------------------------------------------------------

    @property
    def cameras(self):
        return self.router.cameras

    @property
    def pairs(self):
        return self.router.pairs

    @property
    def temporal(self):
        return self.router.temporal

    @property
    def stereo(self):
        return self.router.stereo

    def matcher_groups(self, lanes):
        """Indices of ``lanes`` lanes (cameras or pairs) grouped by the matcher that
        serves them: consecutive, ``matcher_ports`` at a time (the last group may be
        smaller)."""
        p = self.matcher_ports
        return [list(range(k, min(k + p, lanes))) for k in range(0, lanes, p)]

    # --- stream layouts (Amaranth imported only when asked for) -------------------------

    def pixel_layout(self):
        """One camera beat (``hdl.streams.camera_pixel_layout``), a lane's input."""
        return self.temporal.input_layout()

    def aligned_layout(self):
        """A column of a row set (``hdl.streams.aligned_row_layout``), the engine's input;
        equal to the front end's ``CameraParams.aligned_layout()`` it was sized from."""
        from hdl.streams import aligned_row_layout
        return aligned_row_layout(self.pixel_layout(), self.cameras)

    def forecast_layout(self):
        """One camera's forecast for a camera row, the ``forecast`` input (``follow``):
        a row is ``cameras`` transfers, camera 0 first, ``last`` on the final one. The
        fields the engine reads of ``hdl.pose.forecast_predictor.output_layout`` (same
        names and widths) plus ``row``, the camera row it is for (the join's key).

        Fields
        ------
        camera : range(cameras)
        centre : temporal.centre_fmt
            Window centre (pixels); the lane saturates it to ``±centre_range``.
        segment_rows : ArrayLayout(unsigned(solver.row_bits), K)
            The previous frame's row each of the camera's segments reads.
        row : unsigned(solver.row_bits)
        last : 1
        """
        from amaranth.lib import data
        row = self.router.solver.row_bits
        return data.StructLayout({"camera": range(self.cameras),
                                  "centre": self.temporal.centre_fmt.shape(),
                                  "segment_rows": data.ArrayLayout(row, self.temporal.segments),
                                  "row": row, "last": 1})

    def forecast_row_layout(self):
        """A whole forecast row (:class:`hdl.measurement.forecast_rows.ForecastRows`'
        output): ``centre`` and ``source`` (K rows of the lane's ``row_bits``, one per
        segment) per camera, and the ``row`` key."""
        from amaranth.lib import data
        segments = data.ArrayLayout(self.temporal.row_bits, self.temporal.segments)
        return data.StructLayout({
            "centre": data.ArrayLayout(self.temporal.centre_fmt.shape(), self.cameras),
            "source": data.ArrayLayout(segments, self.cameras),
            "row": self.router.solver.row_bits})


def engine_config_layout(params):
    """Run-time configuration of the engine (``cfg`` port).

    Fields
    ------
    temporal : ArrayLayout(temporal.centre_fmt, cameras)
        Shift-window centre of each camera's temporal lane, integer pixels.
    stereo : ArrayLayout(stereo.centre_fmt, pairs)
        Disparity-window centre of each pair's stereo lane, integer pixels.
    enable : 1
        0: row sets are consumed, counted as dropped, and reach no lane. Sampled at
        the first column of each row set.
    half_width : temporal.half_width_fmt
        Run-time half-width ``w`` of every temporal lane's shift window (``centre ± w``
        within the built window), integer pixels, sampled with each row's first pixel;
        outside ``temporal.min_half_width … max_half_width`` the lanes use the built
        maximum and ``status.half_width_error`` is set. The stereo lanes always search
        their built window.

    With ``follow`` there is no ``temporal`` field: the forecast gives those centres.
    """
    from amaranth.lib import data
    fields = {} if params.follow else {
        "temporal": data.ArrayLayout(params.temporal.centre_fmt.shape(), params.cameras)}
    return data.StructLayout({
        **fields,
        "stereo": data.ArrayLayout(params.stereo.centre_fmt.shape(), len(params.pairs)),
        "enable": 1,
        "half_width": params.temporal.half_width_fmt.shape(),
    })


def fork_status_layout(params):
    """Counters of the row-set fork (all ``count_bits`` wide, wrapping).

    Fields
    ------
    row_sets : row sets received (dropped ones included)
    dropped : row sets dropped because ``enable`` was 0
    stereo_skipped : ArrayLayout(count, pairs)
        Row sets handed to the lanes in which pair ``j`` was incomplete (a camera of
        the pair missing), so its stereo lane got no row.
    forecast_skipped, unforecast : with ``follow`` only
        Forecast rows discarded because they were older than the row set waiting for
        one (or for a row ``≥ height``); enabled row sets dropped because the forecast
        row waiting was newer (theirs was lost) or their row was ``≥ height``.
    """
    from amaranth.lib import data
    count = params.count_bits
    follow = {"forecast_skipped": count, "unforecast": count} if params.follow else {}
    return data.StructLayout({"row_sets": count, "dropped": count,
                              "stereo_skipped": data.ArrayLayout(count, len(params.pairs)),
                              **follow})


def engine_status_layout(params):
    """The fork's counters (:func:`fork_status_layout`), the router's (``router``) and
    ``half_width_error`` (1 while ``cfg.half_width`` is out of range and the lanes use
    the built maximum; last, so that the counters keep their addresses); with
    ``follow`` also ``malformed`` (forecast rows discarded by
    :class:`hdl.measurement.forecast_rows.ForecastRows`, ``count_bits``, wrapping)
    and ``out_of_range[k]`` (camera ``k``'s lane: rows whose source row the ring
    could not serve, saturating at ``OUT_OF_RANGE_BITS``)."""
    from amaranth.lib import data

    from hdl.measurement.router import router_status_layout
    fields = {name: field.shape for name, field in fork_status_layout(params)}
    if params.follow:
        fields["malformed"] = params.count_bits
        fields["out_of_range"] = data.ArrayLayout(OUT_OF_RANGE_BITS, params.cameras)
    return data.StructLayout({**fields, "router": router_status_layout(params.router),
                              "half_width_error": 1})

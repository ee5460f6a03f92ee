"""rowtrack's register map, declared once as data (see :mod:`hdl.bus.register_map`).

Each block's group binds the block's own ``config``/``status`` layouts, so a field added
to a block's layout appears in the decoder, the documentation (``docs/register_map.md``,
written by ``rowtrack build --write-docs docs``) and the register tests without another
edit. Groups sit at fixed offsets so that one block growing never moves another's
registers.
"""

from importlib.metadata import PackageNotFoundError, version

from amaranth.hdl import signed
from amaranth.lib import data

from hdl.front_end.camera_sync import sync_config_layout, sync_status_layout
from hdl.measurement.consistency import counts_layout, settings_init, settings_layout
from hdl.measurement.engine_params import engine_config_layout, engine_status_layout
from hdl.pose.params import MIN_PIVOT_LOG2
from hdl.pose.status_params import FRACTION_FMT, MEASUREMENTS_FMT, top_status_params
from hdl.pose_solver import counters_layout
from hdl.bus.register_map import Access, Register, RegisterGroup, RegisterMap

__all__ = ["rowtrack_map", "MAGIC", "GROUP_OFFSETS"]

#: ``ident.magic``: ASCII "RWTK".
MAGIC = 0x5257544B

#: Byte offset of each block's group in the window. The camera group grows with the
#: number of cameras (about 25 bytes each), so it has the window's upper half
#: (0x800..0xFFF, room for about 75 cameras; stereo20 uses 0x214 bytes); every other
#: group has 0x100 bytes.
GROUP_OFFSETS = {"ident": 0x000, "pose_out": 0x100, "solver": 0x400, "engine": 0x500,
                 "status": 0x600, "loop": 0x700, "camera": 0x800}


def _package_version():
    try:
        parts = version("rowtrack").split(".")[:3]
        return [int(p) if p.isdigit() else 0 for p in parts] + [0] * (3 - len(parts))
    except PackageNotFoundError:
        return [0, 0, 0]


def _fit(name, value, bits):
    """A default that must fit its field: an error here names the field, not a silent cut."""
    value = int(value)
    if not 0 <= value < (1 << bits):
        raise ValueError(f"default {name} = {value} does not fit {bits} bits")
    return value


def _ident(params):
    cam = params.camera
    major, minor, patch = _package_version()
    return RegisterGroup("ident", GROUP_OFFSETS["ident"], "Identification: read these "
                         "first to check that the bitstream matches the software.", [
        Register("magic", 32, Access.CONST, "`0x5257544B` (ASCII \"RWTK\")", value=MAGIC),
        Register("version", data.StructLayout({"patch": 8, "minor": 8, "major": 8}),
                 Access.CONST, "rowtrack package version the bitstream was built from",
                 value=patch | minor << 8 | major << 16),
        Register("map_crc", 32, Access.CONST, "CRC-32 of this register map's layout "
                 "(`RegisterMap.layout_crc`)"),
        Register("cameras", data.StructLayout({"n_cameras": 8, "pixel_bits": 8}),
                 Access.CONST, "camera ports built in",
                 value=cam.n_cameras | cam.pixel_bits << 8),
        Register("frame_size", data.StructLayout({"max_width": 16, "max_height": 16}),
                 Access.CONST, "largest frame the front end accepts",
                 value=cam.max_width | cam.max_height << 16),
        Register("clk_khz", 32, Access.CONST, "system clock (FCLK_CLK0) the build assumes, "
                 "kHz: the unit of every time stamp and interval register",
                 value=round(params.clk_hz / 1000)),
    ])


def _pose_out(params):
    po = params.pose_output
    packet = po.packet
    divisor = params.uart.divisor_raw(params.clk_hz, params.baud)
    return RegisterGroup("pose_out", GROUP_OFFSETS["pose_out"], "Pose output "
                         "(`hdl/output/packet.py`, `hdl/output/uart.py`): decimation, UART, the PS "
                         "FIFO of pose records and the output counters; see "
                         "[the packet format](packet_format.md).", [
        Register("control", po.config_layout(), Access.RW, "sinks, decimation and the "
                 "pose-rate window (reset: both sinks on, every pose, a one-second window)",
                 reset={"uart_enable": 1, "fifo_enable": 1, "decimation": 1,
                        "rate_window": _fit("rate_window", params.clk_hz, po.count_bits)}),
        Register("uart_divisor", params.uart.divisor_fmt.width, Access.RW,
                 f"system clocks per UART bit, raw {params.uart.divisor_fmt} "
                 f"(reset: {params.baud} baud at {params.clk_hz / 1e6:g} MHz)",
                 reset=divisor),
        Register("status", po.status_layout(), Access.RO, "output counters (wrap) and the "
                 "pose rate (poses in the last complete window)"),
        Register("fifo_head", packet.record_layout(), Access.RO, "the oldest record in the "
                 "PS FIFO (valid while `status.fifo_level` is not zero)"),
        Register("fifo_pop", 1, Access.WO, "write 1 to drop `fifo_head` and show the next "
                 "record"),
    ])


def _camera(params):
    cam = params.camera
    clk = params.clk_hz
    t = cam.timer_bits
    period = _fit("period", round(clk / 120), t)
    return RegisterGroup("camera", GROUP_OFFSETS["camera"], "Camera front end "
                         "(`hdl/front_end/camera_input.py`, `hdl/front_end/camera_sync.py`, "
                         "`hdl/front_end/row_aligner.py`). Times in system clocks.", [
        Register("input", cam.input_config_layout(), Access.RW, "every camera input's row "
                 "geometry and PCLK stall timeout (change only while the cameras are idle)",
                 reset={"width": cam.max_width, "height": cam.max_height,
                        "pclk_timeout": _fit("pclk_timeout", clk // 10_000, t)}),
        Register("sync", sync_config_layout(cam), Access.RW, "trigger generator and sync "
                 "monitor (reset: trigger off, 120 fps period, 10 µs pulse, 1 ms exposure)",
                 reset={"trigger_enable": 0, "period": period,
                        "pulse": _fit("pulse", clk // 100_000, t),
                        "exposure": _fit("exposure", clk // 1000, t),
                        "skew_threshold": _fit("skew_threshold", clk // 100_000,
                                               cam.skew_bits - 1),
                        "lost_timeout": _fit("lost_timeout", 2 * period, t)}),
        Register("align", cam.align_config_layout(), Access.RW, "cameras taking part and "
                 "the wait for late rows (reset: all cameras, 100 µs)",
                 reset={"enable": (1 << cam.n_cameras) - 1,
                        "timeout": _fit("timeout", clk // 10_000, t)}),
        Register("time", data.StructLayout({"now": cam.timestamp_bits,
                                            "frame": cam.frame_bits}),
                 Access.RO, "time base and current frame number"),
        Register("sync_status", sync_status_layout(cam), Access.RO, "desync and lost flags "
                 "and counters, latest frame and row skews against the master camera"),
        Register("align_status", cam.align_status_layout(), Access.RO, "rows each camera "
                 "was missing from or sent too late"),
        Register("inputs", cam.input_status_layout(), Access.RO, "per camera: bad, dropped "
                 "and glitch counters and sticky reason bits", count=cam.n_cameras),
    ])


def _solver(params):
    solver = params.solver
    return RegisterGroup("solver", GROUP_OFFSETS["solver"], "Pose solver "
                         "(`hdl/pose_solver.py`): coefficient load, row counters and the "
                         "conditioning gate.", [
        Register("geometry", data.StructLayout({"slots": 16, "rows": 16}), Access.CONST,
                 "coefficient store size: measurement slots and rows per frame",
                 value=solver.slots | solver.rows << 16),
        Register("counters", counters_layout(solver), Access.RO, "rows solved and rows "
                 "flagged per reason (`PoseFlag`)"),
        Register("coef", data.StructLayout({
            "addr": solver.entry_bits, "index": 4, "data": signed(solver.coef_store_width)}),
                 Access.WO, "write one stored entry: entry `slot · entries + row` "
                 "(or `+ term` when `coef_terms` > 0; entries = rows or terms), "
                 "coefficient 0–8 (a_T x y z, a_C x y z, a_R x y z), raw value"),
        Register("coef_terms", 4, Access.CONST, "polynomial terms per coefficient in "
                 "the row (0: the store holds every row)", value=solver.coef_terms),
        Register("pivot_log2", solver.pivot_log2_bits, Access.RW, "the conditioning "
                 "gate: a pivot of the scaled Cholesky factorization below "
                 "2^-`pivot_log2` flags the row ILL; from "
                 f"{MIN_PIVOT_LOG2} (strictest) to the build's {solver.pivot_log2} (the "
                 "loosest its formats hold, the reset); any other value: the build's, and "
                 "`status.pivot_log2_error` is set. Change it between rows",
                 reset=solver.pivot_log2),
        Register("status", data.StructLayout({"pivot_log2_error": 1}), Access.RO,
                 "`pivot_log2_error`: `pivot_log2` is out of range (live)"),
    ])


def _engine(params):
    engine = params.engine
    temporal, stereo = engine.temporal, engine.stereo
    return RegisterGroup("engine", GROUP_OFFSETS["engine"], "Measurement engine "
                         "(`hdl/measurement/engine.py`: a temporal row-descriptor lane per "
                         "camera, a stereo lane per pair, the router into the solver's "
                         "slots). The lanes have no run-time thresholds: the "
                         "strong-response threshold "
                         f"({temporal.descriptor.strong_response:g}), the textureless limit "
                         f"(`min_strong` = {temporal.match.min_strong} columns per segment), "
                         "the bit-transition limit and the peak-ratio cap and offset are "
                         "quantized into the lanes at build time "
                         "(`hdl/descriptor/params.py`); the search-window centres and the "
                         "temporal window's half-width are set at run time.", [
        Register("geometry", data.StructLayout({"segments": 8, "pairs": 8, "slots": 16}),
                 Access.CONST, "temporal segments per row, stereo pairs and the solver "
                 "slots they fill",
                 value=params.segments | len(params.pairs) << 8
                 | params.solver.slots << 16),
        Register("control", engine_config_layout(engine), Access.RW, "pipeline enable, "
                 "the search-window centres, integer pixels, saturated to "
                 f"±{temporal.centre_range} (temporal) and ±{stereo.centre_range} (stereo), "
                 "and `half_width` w, the temporal lanes' search window `centre ± w` within "
                 f"the built one ({temporal.min_half_width}…{temporal.max_half_width}; "
                 "outside: the built maximum, and `status.half_width_error` is set; the "
                 "stereo lanes search their whole window) "
                 "(reset: enabled, every centre 0, w the built maximum: temporal shifts "
                 f"{temporal.match.shift_min}…{temporal.match.shift_max}, disparities "
                 f"{stereo.match.shift_min}…{stereo.match.shift_max})",
                 reset={"enable": 1, "half_width": temporal.max_half_width}),
        Register("status", engine_status_layout(engine), Access.RO, "wrapping counters: "
                 "row sets received, dropped (`enable` 0), skipped per stereo pair (a "
                 "camera of the pair missing); the router's rows sent to the solver, rows "
                 "without a weighted measurement, misaligned measurements and stereo lanes "
                 "that had no measurement of their row; `half_width_error`: "
                 "`control.half_width` is out of range (live)"),
    ])


def _status(params):
    status = top_status_params(params)
    return RegisterGroup("status", GROUP_OFFSETS["status"], "Tracking status "
                         "(`hdl/pose/status_unit.py`, [docs/pose/tracking_status.md]"
                         "(pose/tracking_status.md)): the rule that sets bits 6:4 of every "
                         "pose record's flags (see [the packet format](packet_format.md)) "
                         f"over the last `window` rows (at most {status.max_window}). "
                         f"Fractions are raw {FRACTION_FMT} (0x10000 = 1), "
                         f"`degraded_measurements` raw {MEASUREMENTS_FMT}; change them "
                         "between rows (a new `window` restarts the history). The "
                         "closed-loop top places the unit between the tracking loop and "
                         "the pose output; in the open-loop top these registers are not "
                         "connected (`state` reads 0).", [
        Register("settings", status.settings_layout(), Access.RW, "window (rows) and "
                 "thresholds: lost below `lost_update_fraction` of rows solved or above "
                 "`lost_outlier_fraction` of outlier measurements over a full window; "
                 "degraded below `degraded_update_fraction`, above "
                 "`degraded_outlier_fraction`, above `degraded_ill_fraction` of formed "
                 "rows ILL, no row formed, or below `degraded_measurements` confident "
                 "measurements per solved row (reset: the golden tracker's, a window of "
                 f"{status.window} rows)", reset=status.raw_settings()),
        Register("clear", 1, Access.WO, "write 1 to forget the history, the loss latch, "
                 "drifted and the counters (before the next row)"),
        Register("state", status.state_layout(), Access.RO, "the latest row's status and "
                 "drifted, the loss latch, `acquired` (a row was tracking since reset or "
                 "clear), `window_error` (`window` 0 or above the largest, taken as 1 or "
                 "the largest), entries into lost and rows degraded and lost"),
    ])


def rowtrack_map(params):
    """The register map of :class:`hdl.top.RowtrackTop` built with ``params``."""
    loop = (_loop(params),) if params.closed_loop else ()
    regmap = RegisterMap(groups=(_ident(params), _pose_out(params), _camera(params),
                                 _solver(params), _engine(params), _status(params), *loop),
                         base=params.reg_base, size=params.reg_size)
    return regmap.with_value("ident", "map_crc", regmap.layout_crc())


def _loop(params):
    """The closed loop's run-time settings (closed-loop tops only)."""
    from hdl.pose.forecast_filter import DEFAULT_SLOT_BITS
    from hdl.pose.forecast_predictor import counters_layout as forecast_counters_layout
    from hdl.pose.tracking_loop import loop_counters_layout
    forecast, stage = params.forecast, params.consistency
    motion = forecast.motion_fmt
    information = forecast.motion_gain == "information"
    return RegisterGroup("loop", GROUP_OFFSETS["loop"], "Closed measurement loop "
                         "(`hdl/pose/tracking_loop.py`, [docs/pose/tracking_loop.md]"
                         "(pose/tracking_loop.md)): the forecast's filter gains and start, "
                         "the consistency stage's settings (raw in the formats of "
                         "[docs/measurement/consistency.md](measurement/consistency.md)) "
                         "and the loop's counters. Change the settings between rows; "
                         "`restart` starts the filter again at `initial` and the row "
                         "slots at row 0, at the next frame boundary.", [
        Register("alpha", forecast.gain_fmt.width, Access.RW, f"level gain α, raw "
                 f"{forecast.gain_fmt} (reset {forecast.alpha:g})",
                 reset=forecast.alpha_raw),
        Register("beta", forecast.gain_fmt.width, Access.RW, f"trend gain β, raw "
                 f"{forecast.gain_fmt} (reset {forecast.beta:g})", reset=forecast.beta_raw),
        Register("initial", data.ArrayLayout(motion.shape(), 6), Access.RW,
                 f"the motion Y = [T θ] the filter starts from at `restart`, raw {motion} "
                 f"(metres, radians per frame period)"),
        Register("restart", 1, Access.WO, "write to restart the filter at `initial` "
                 "(read then) and the row slots at row 0 of slot 0, at the next frame "
                 "boundary of the forecast: the rows already forecast finish as before "
                 "(nothing dropped), the loop waits for their records (the engine's row "
                 "0 waits too), then forecasts row 0 from `initial`. Written after "
                 "reset, before the cameras run, it applies from frame 1 (the first with "
                 "a previous frame)"),
        Register("frame_rows", DEFAULT_SLOT_BITS, Access.RW, "row periods per frame period, blanking "
                 "included: the row slots' count per frame", reset=int(stage.frame_rows)),
        Register("consistency", settings_layout(stage), Access.RW, "the consistency "
                 "stage's frame period, row-offset bound, Huber k, scale start, floor and "
                 "gains, and the row gates (reset: the build's parameters)",
                 reset=settings_init(stage)),
        Register("counts", counts_layout(), Access.RO, "consistency counters (wrap): rows "
                 "whose source was too far, saturations, outliers replaced, rows gated"),
        Register("forecast_counters", forecast_counters_layout(forecast), Access.RO,
                 "forecast saturations (centres, rows, displacements; `motion`: filter "
                 "updates and forecasts saturated into the motion format, a diverging "
                 "loop)"),
        Register("track_alpha", forecast.gain_fmt.width, Access.RW, f"the motion track's "
                 f"pull towards the filter's level, raw {forecast.gain_fmt} (reset "
                 f"{forecast.track_alpha:g}; [docs/pose/motion_track.md]"
                 f"(pose/motion_track.md))", reset=forecast.track_alpha_raw),
        Register("track", data.ArrayLayout(motion.shape(), 6), Access.RO,
                 f"the motion track's Y = [T θ] after the last row, raw {motion} (metres, "
                 f"radians per frame period; it changes once per row: reading word 0 "
                 f"samples all six, read it first)"),
        Register("counters", loop_counters_layout(forecast), Access.RO, "measurements of "
                 "another row than the forecast's, predicted shifts saturated, motion "
                 "track rows with a value saturated (wrap); `restart_pending`: a "
                 "`restart` was written and has not taken effect (set from the write "
                 "until the frame boundary it applies at; live); `track_overrange`: "
                 "`frame_rows` at the last restart was 0 or beyond the track's ring, "
                 "which runs with its built length"
                 + ("; `gain_flagged`: solved rows whose information gain was flagged "
                    "(the filter moved by α)" if information else "")),
        *_information_registers(forecast),
    ])


def _information_registers(forecast):
    """The information gain's run-time settings (a top built with it only)."""
    if forecast.motion_gain != "information":
        return []
    return [Register("prior_weight", forecast.prior_fmt.width, Access.RW,
                     f"the information gain's prior weight (1 − α)/α, raw "
                     f"{forecast.prior_fmt} (reset {(1 - forecast.alpha) / forecast.alpha:g})",
                     reset=forecast.prior_raw),
            Register("typical_smoothing", forecast.gain_fmt.width, Access.RW,
                     f"weight of each solved row in the typical information, raw "
                     f"{forecast.gain_fmt} (reset {forecast.typical_smoothing:g})",
                     reset=forecast.smoothing_raw)]

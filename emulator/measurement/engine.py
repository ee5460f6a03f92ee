"""Bit-accurate model of the measurement engine (``hdl/measurement/engine.py``).

Row sets in; tickets, lane measurements and the pose solver's transfers out. Composed of
the per-block models, called, not copied: the row-set fork (modelled here: which lane
gets which row, the tickets, the counters), :class:`emulator.row_descriptor.TemporalLaneModel`
per camera, :class:`emulator.row_descriptor.StereoLaneModel` per pair and
:func:`emulator.measurement.router.route_tickets`.

A *row set* is what the row aligner hands on for one row key: ``{camera: beats}`` with
each present camera's beats (dicts of ``hdl.streams.camera_pixel_layout`` fields) from
its ``first`` to its ``last`` beat. A *configuration* is a dict of the engine's ``cfg``
port fields (:func:`hdl.measurement.engine_params.engine_config_layout`): ``temporal``
and ``stereo`` window centres, ``enable`` and the temporal lanes' ``half_width``, as they
stand when the set's first column enters (the hardware samples them there);
``half_width`` may be left out: its register's reset, the built maximum.

In the closed loop (``EngineParams.follow``) the temporal lanes follow rows and the
engine also takes the forecast's transfers (``hdl.measurement.engine_params.
EngineParams.forecast_layout`` fields as dicts): :func:`forecast_rows` gathers them
into rows as :class:`hdl.measurement.forecast_rows.ForecastRows` does,
:func:`join_forecasts` joins one with each row set as the fork does (key check and
resynchronization, :mod:`hdl.measurement.row_set_fork`), and each temporal lane takes
its camera's centre and source row with the row's first beat. The configurations then
have no ``temporal`` field. This is what :func:`emulator.pipeline.run`'s closed loop
does to its rows, without the loop's feedback: the forecast rows are an input here.
"""

from dataclasses import dataclass

from emulator.descriptor.framer import frame_rows
from emulator.measurement.router import route_tickets
from emulator.row_descriptor import StereoLaneModel, TemporalLaneModel

__all__ = ["ForkResult", "EngineResult", "fork_row_sets", "run_engine", "row_set_columns",
           "forecast_rows", "join_forecasts"]


@dataclass(frozen=True)
class ForkResult:
    """What the row-set fork hands on.

    Members
    -------
    tickets : list of dict
        ``cameras``, ``pairs`` (bit masks), ``frame``, ``row``; one per set handed on.
    temporal : list of (beats, centres) or, with ``follow``, (beats, centres, sources)
        Per camera: its temporal lane's beat stream, the centre (and source row) its
        lane takes at each beat.
    stereo : list of (beats_a, centres, beats_b)
        Per pair: its stereo lane's two beat streams and the centre at each ``a`` beat.
    half_widths : list of list of int
        Per camera: the ``cfg.half_width`` its temporal lane takes at each beat.
    status : dict
        ``row_sets``, ``dropped``, ``stereo_skipped`` (list per pair); with ``follow``
        also ``forecast_skipped``, ``unforecast``; unwrapped counts.
    """
    tickets: list
    temporal: list
    stereo: list
    status: dict
    half_widths: list


def _half_width(params, cfg):
    """A configuration's temporal half-width (absent: the built maximum, the register's
    reset)."""
    return cfg.get("half_width", params.temporal.max_half_width)


@dataclass(frozen=True)
class EngineResult:
    """The engine's output: the fork's, every lane's measurements, the solver stream.

    Members
    -------
    fork : ForkResult
    temporal, stereo : list of list of dict
        Each temporal and stereo lane's measurements in output order.
    transfers : list of dict
        The solver's input stream (``hdl.pose_solver.measurement_layout`` fields).
    status : dict
        The ``status`` port's fields (unwrapped): the fork's counters, ``router`` and
        ``half_width_error`` (of the last configuration: the hardware's bit is live).
    """
    fork: ForkResult
    temporal: list
    stereo: list
    transfers: list
    status: dict


def _key(beats):
    return beats[0]["frame"], beats[0]["row"]


def forecast_rows(params, transfers):
    """The forecast transfers gathered into rows, as
    :class:`hdl.measurement.forecast_rows.ForecastRows`: ``(rows, malformed)``, each row
    a dict ``row``, ``centre`` (a list per camera) and ``source`` (per camera, a list of
    its segments' rows); a row that is not ``cameras`` transfers in camera order with
    ``last`` on the final one, or names a source row wider than the lanes' ``row_bits``,
    is discarded and counted."""
    cameras, row_bits, k = params.cameras, params.temporal.row_bits, params.temporal.segments
    rows, malformed = [], 0
    centre, source = [0] * cameras, [[0] * k] * cameras
    position, damaged = 0, False
    for t in transfers:
        segment_rows = [t["segment_rows"][n] for n in range(k)]     # a list or a dict
        wrong = (t["camera"] != position or bool(t["last"]) != (position == cameras - 1)
                 or any(r >> row_bits for r in segment_rows))
        centre[position], source[position] = t["centre"], segment_rows
        if t["last"]:
            if damaged or wrong:
                malformed += 1
            else:
                rows.append({"row": t["row"], "centre": list(centre), "source": list(source)})
            position, damaged = 0, False
        else:
            damaged |= wrong
            position = min(position + 1, cameras - 1)
    return rows, malformed


def _ahead(params, key, row):
    """The forecast row ``key`` is newer than the set's ``row`` (its set was lost)."""
    height = params.temporal.height
    gap = (key - row) % height
    return key < height and 0 < 2 * gap < height


def join_forecasts(params, row_sets, configs, rows):
    """The fork's join: per row set the forecast row it is handed on with (None: the set
    is dropped, by ``enable`` 0 or for want of its forecast), and the counts
    ``forecast_skipped`` and ``unforecast`` (:mod:`hdl.measurement.row_set_fork`).

    Raises
    ------
    ValueError
        If an enabled set waits for a forecast row that ``rows`` does not have (the
        hardware would wait).
    """
    joined, status = [], {"forecast_skipped": 0, "unforecast": 0}
    queue = list(rows)
    for row_set, cfg in zip(row_sets, configs, strict=True):
        _, row = _key(row_set[min(row_set)])
        found = None
        while cfg["enable"] and row < params.temporal.height:
            if not queue:
                raise ValueError(f"row set of row {row} waits for a forecast row")
            if queue[0]["row"] == row:
                found = queue.pop(0)
            elif not _ahead(params, queue[0]["row"], row):
                queue.pop(0)
                status["forecast_skipped"] += 1
                continue
            break
        status["unforecast"] += bool(cfg["enable"]) and found is None
        joined.append(found)
    return joined, status


def fork_row_sets(params, row_sets, configs, joined=None):
    """The fork: each set's beats to the lanes it addresses, one ticket per set handed
    on (see :class:`hdl.measurement.row_set_fork.RowSetFork`). ``configs[i]`` applies to
    ``row_sets[i]``; with ``follow``, ``joined[i]`` is its forecast row
    (:func:`join_forecasts`; None drops an enabled set as ``unforecast``)."""
    follow = params.follow
    if follow != (joined is not None):
        raise ValueError("joined must be given exactly when params.follow")
    temporal = [([], [], []) if follow else ([], []) for _ in range(params.cameras)]
    stereo = [([], [], []) for _ in params.pairs]
    half_widths = [[] for _ in range(params.cameras)]
    tickets = []
    status = {"row_sets": 0, "dropped": 0, "stereo_skipped": [0] * len(params.pairs)}
    for n, (row_set, cfg) in enumerate(zip(row_sets, configs, strict=True)):
        status["row_sets"] += 1
        if not cfg["enable"]:
            status["dropped"] += 1
            continue
        if follow and joined[n] is None:
            continue
        cameras = sorted(row_set)
        complete = [a in row_set and b in row_set for a, b in params.pairs]
        for k in cameras:
            beats, centres, *sources = temporal[k]
            beats += row_set[k]
            half_widths[k] += [_half_width(params, cfg)] * len(row_set[k])
            if follow:
                centres += [joined[n]["centre"][k]] * len(row_set[k])
                sources[0].extend([joined[n]["source"][k]] * len(row_set[k]))
            else:
                centres += [cfg["temporal"][k]] * len(row_set[k])
        for j, (a, b) in enumerate(params.pairs):
            if not complete[j]:
                status["stereo_skipped"][j] += 1
                continue
            beats_a, centres, beats_b = stereo[j]
            beats_a += row_set[a]
            centres += [cfg["stereo"][j]] * len(row_set[a])
            beats_b += row_set[b]
        frame, row = _key(row_set[cameras[0]])
        tickets.append({"cameras": sum(1 << k for k in cameras),
                        "pairs": sum(1 << j for j, ok in enumerate(complete) if ok),
                        "frame": frame, "row": row})
    return ForkResult(tickets=tickets, temporal=temporal, stereo=stereo, status=status,
                      half_widths=half_widths)


def _followed_lane(params, beats, centres, sources, half_widths):
    """A following temporal lane on its beats: ``(measurements, out_of_range)``; each
    row takes the centre, source row and half-width of its ``first`` beat."""
    lane = TemporalLaneModel(params, follow=True)
    rows = frame_rows(beats, centres, params, half_widths)
    firsts = [source for beat, source in zip(beats, sources) if beat["first"]]
    return lane.process_rows(rows, firsts[:len(rows)]), lane.store.out_of_range


def run_engine(params, row_sets, configs, forecast=None):
    """The whole engine on ``row_sets`` (with ``configs``; with ``follow``, the
    ``forecast`` transfers): an :class:`EngineResult`."""
    if params.follow != (forecast is not None):
        raise ValueError("forecast must be given exactly when params.follow")
    extra = {}
    if params.follow:
        rows, extra["malformed"] = forecast_rows(params, forecast)
        joined, join_status = join_forecasts(params, row_sets, configs, rows)
        fork = fork_row_sets(params, row_sets, configs, joined)
        fork.status.update(join_status)
        lanes = [_followed_lane(params.temporal, *lane, widths)
                 for lane, widths in zip(fork.temporal, fork.half_widths)]
        temporal = [measurements for measurements, _ in lanes]
        extra["out_of_range"] = [count for _, count in lanes]
    else:
        fork = fork_row_sets(params, row_sets, configs)
        temporal = [TemporalLaneModel(params.temporal).run(beats, centres, widths)
                    for (beats, centres), widths in zip(fork.temporal, fork.half_widths)]
    stereo = [StereoLaneModel(params.stereo).run(beats_a, centres, beats_b)
              for beats_a, centres, beats_b in fork.stereo]
    transfers, router = route_tickets(params.router, fork.tickets, temporal, stereo)
    last = configs[-1] if configs else {}
    extra["half_width_error"] = int(params.temporal.saturate_half_width(
        _half_width(params, last))[1])
    return EngineResult(fork=fork, temporal=temporal, stereo=stereo, transfers=transfers,
                        status={**fork.status, **extra, "router": router})


def row_set_columns(params, row_set, missing=None):
    """The set as the aligner streams it: one ``aligned_row_layout`` dict per column.

    Lane ``k`` carries beat ``x`` of camera ``k`` while it has one (zeros after its
    ``last``, and for cameras not in the set); ``missing`` defaults to every camera not
    in the set.
    """
    absent = sum(1 << k for k in range(params.cameras) if k not in row_set)
    zero = dict.fromkeys(next(iter(row_set.values()))[0], 0)
    columns = []
    for x in range(max(len(beats) for beats in row_set.values())):
        live = [k in row_set and x < len(row_set[k]) for k in range(params.cameras)]
        columns.append({
            "lanes": [row_set[k][x] if ok else zero for k, ok in enumerate(live)],
            "lane_valid": sum(1 << k for k, ok in enumerate(live) if ok),
            "missing": absent if missing is None else missing,
        })
    return columns

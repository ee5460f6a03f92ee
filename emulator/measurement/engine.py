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
and ``stereo`` window centres and ``enable``, as they stand when the set's first column
enters (the hardware samples them there).
"""

from dataclasses import dataclass

from emulator.measurement.router import route_tickets
from emulator.row_descriptor import StereoLaneModel, TemporalLaneModel

__all__ = ["ForkResult", "EngineResult", "fork_row_sets", "run_engine", "row_set_columns"]


@dataclass(frozen=True)
class ForkResult:
    """What the row-set fork hands on.

    Members
    -------
    tickets : list of dict
        ``cameras``, ``pairs`` (bit masks), ``frame``, ``row``; one per set handed on.
    temporal : list of (beats, centres)
        Per camera: its temporal lane's beat stream and the centre port at each beat.
    stereo : list of (beats_a, centres, beats_b)
        Per pair: its stereo lane's two beat streams and the centre at each ``a`` beat.
    status : dict
        ``row_sets``, ``dropped``, ``stereo_skipped`` (list per pair); unwrapped counts.
    """
    tickets: list
    temporal: list
    stereo: list
    status: dict


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
        The ``status`` port's fields (unwrapped): the fork's counters and ``router``.
    """
    fork: ForkResult
    temporal: list
    stereo: list
    transfers: list
    status: dict


def _key(beats):
    return beats[0]["frame"], beats[0]["row"]


def fork_row_sets(params, row_sets, configs):
    """The fork: each set's beats to the lanes it addresses, one ticket per set handed
    on (see :class:`hdl.measurement.row_set_fork.RowSetFork`). ``configs[i]`` applies to
    ``row_sets[i]``."""
    temporal = [([], []) for _ in range(params.cameras)]
    stereo = [([], [], []) for _ in params.pairs]
    tickets = []
    status = {"row_sets": 0, "dropped": 0, "stereo_skipped": [0] * len(params.pairs)}
    for row_set, cfg in zip(row_sets, configs, strict=True):
        status["row_sets"] += 1
        if not cfg["enable"]:
            status["dropped"] += 1
            continue
        cameras = sorted(row_set)
        complete = [a in row_set and b in row_set for a, b in params.pairs]
        for k in cameras:
            beats, centres = temporal[k]
            beats += row_set[k]
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
    return ForkResult(tickets=tickets, temporal=temporal, stereo=stereo, status=status)


def run_engine(params, row_sets, configs):
    """The whole engine on ``row_sets`` (with ``configs``): an :class:`EngineResult`."""
    fork = fork_row_sets(params, row_sets, configs)
    temporal = [TemporalLaneModel(params.temporal).run(beats, centres)
                for beats, centres in fork.temporal]
    stereo = [StereoLaneModel(params.stereo).run(beats_a, centres, beats_b)
              for beats_a, centres, beats_b in fork.stereo]
    transfers, router = route_tickets(params.router, fork.tickets, temporal, stereo)
    return EngineResult(fork=fork, temporal=temporal, stereo=stereo, transfers=transfers,
                        status={**fork.status, "router": router})


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

"""Co-simulated slice: the HDL top (cocotb) against the bit-accurate models.

:func:`cosim_slice` builds a :class:`hdl.top.RowtrackTop` for a sub-rig of whole stereo
pairs, plays the dataset's rows on its DVP pins, reads the pose records back from the PS
FIFO registers and the UART line, and compares them with the emulator fed with exactly
the row sets the HDL front end produced (their time stamps are the HDL clock's). The
cocotb side lives in ``emulator/hdl_sim/cosim_bench.py``; this module prepares its
input, runs it through :func:`emulator.hdl_sim.runner.run_cocotb` and judges the
result with :func:`compare_records`.
"""

import os
import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hdl.descriptor.params import DEFAULT_SEGMENTS

__all__ = ["RECORD_FIELDS", "CosimResult", "compare_records", "slice_rig", "slice_params",
           "NoSolvingWindow", "solving_window", "checked_input", "camera_stimulus",
           "run_bench", "pin_latencies", "latency_clocks", "cosim_slice"]

#: Fields of the PS FIFO's records compared, element by element (``quaternion`` and
#: ``position`` are arrays): what a record says of its pose (``seq`` counts records and
#: ``skipped`` depends on the sinks' timing).
RECORD_FIELDS = ("row", "t_row", "flags", "quaternion", "position")
#: UART divisor of the slice (raw ``UartParams.divisor_fmt``: one clock per bit), so a
#: packet leaves before the next row's record and the UART carries every record.
DIVISOR = 16
#: Camera timing of the slice: camera k's PCLK period is ``PCLK_PS + k · PCLK_STEP_PS``
#: (slower than the 10 ns system clock, each camera its own), horizontal blanking
#: ``HBLANK`` PCLKs.
PCLK_PS, PCLK_STEP_PS, HBLANK = 10_400, 400, 16


@dataclass(frozen=True)
class CosimResult:
    """What a co-simulated slice produced and how it compares.

    Members
    -------
    records : dict
        The HDL's pose records as read from the PS FIFO registers, raw integer arrays in
        the packet formats (``emulator.output.packets``), one entry per field of
        :data:`RECORD_FIELDS`: ``row``, ``t_row``, ``flags``, ``quaternion`` (n, 4),
        ``position`` (n, 3).
    expected : dict
        The emulator's records for the same row sets, narrowed the same way.
    mismatches : int
        Record fields that differ (0: bit-exact; see :func:`compare_records`).
    first_mismatch : str or None
        Where the first difference is.
    clocks : int
        System clocks simulated (set-up over AXI, cameras, drain, read-back).
    wall_s : float
        Wall time of the simulation (not of the Verilog build).
    row_sets : int
        Row sets the front end delivered to the measurement engine.
    clocks_per_row_set : float
        Clocks from the first to the last column of a row set entering the measurement
        engine, mean over the sets. The aligner streams columns as the slowest camera
        delivers them, so the slice's PCLKs bound it (``width`` pixels at the slowest
        PCLK); the engine itself takes a column every ``matcher_ports`` clocks.
    latency_clocks : int
        Largest time, over the records, from the last pixel of a row set at the DVP pins
        to its pose record in the PS FIFO, in system clocks; -1 when the HDL did not
        give one record per row set (``mismatches`` then counts the difference).
    clk_hz : float
    uart_packets_match : bool
        The bytes on the UART line decode to exactly the emulator's packets.
    cameras : tuple of int
        The dataset cameras of the slice (:func:`slice_rig`).
    first_row : int
        The first dataset row of the played window (:func:`solving_window`); the HDL
        numbers the window's rows from 0.
    timings : dict
        Wall seconds of ``elaborate`` (Verilog), ``build`` (the simulator's model) and
        ``simulate`` (:func:`emulator.hdl_sim.runner.run_cocotb`).
    """
    records: dict
    expected: dict
    mismatches: int
    first_mismatch: str | None
    clocks: int
    wall_s: float
    row_sets: int
    clocks_per_row_set: float
    latency_clocks: int
    clk_hz: float
    uart_packets_match: bool
    cameras: tuple
    first_row: int
    timings: dict

    @property
    def cycles_per_s(self):
        """Simulator speed: system clocks per second of wall time."""
        return self.clocks / self.wall_s


def _record_values(records, k, fields=RECORD_FIELDS):
    """``(label, value)`` of every compared element of record ``k``."""
    out = []
    for name in fields:
        value = np.asarray(records[name])[k]
        if np.ndim(value):
            out += [(f"{name}[{', '.join(map(str, i))}]", int(value[i]))
                    for i in np.ndindex(value.shape)]
        else:
            out.append((name, int(value)))
    return out


def compare_records(records, expected, frames=None, fields=RECORD_FIELDS):
    """Count the record fields in which the HDL's ``records`` differ from ``expected``.

    Records are compared in order, element by element (``quaternion`` and ``position``
    per component), over ``fields`` (default the PS FIFO's :data:`RECORD_FIELDS`);
    a record present on one side only counts all of its elements. ``frames`` (optional,
    one per expected record) names the frame in the message.

    Returns
    -------
    mismatches : int
    first : str or None
        e.g. ``"record 5 (frame 1, row 3): quaternion[2] HDL 12 ≠ emulator 13"``.
    """
    counts = []
    for name, side in (("records", records), ("expected", expected)):
        missing = [f for f in fields if f not in side]
        if missing:
            raise ValueError(f"{name} lacks the fields {missing}")
        counts.append(len(np.asarray(side["row"])))
    n_hdl, n_model = counts
    mismatches, first = 0, None
    for k in range(max(n_hdl, n_model)):
        side = expected if k < n_model else records
        where = f"record {k} (" + (f"frame {int(frames[k])}, " if frames is not None
                                   and k < len(frames) else "") + \
            f"row {int(np.asarray(side['row'])[k])})"
        if k >= n_hdl or k >= n_model:
            values = _record_values(side, k, fields)
            mismatches += len(values)
            if first is None:
                first = f"{where}: only the {'emulator' if k >= n_hdl else 'HDL'} has it " \
                        f"({n_hdl} HDL records, {n_model} emulator records)"
            continue
        for (label, got), (_, want) in zip(_record_values(records, k, fields),
                                           _record_values(expected, k, fields)):
            if got != want:
                mismatches += 1
                if first is None:
                    first = f"{where}: {label} HDL {got} ≠ emulator {want}"
    return mismatches, first


# --- the slice -------------------------------------------------------------------------

def slice_rig(rig, cameras, segments=DEFAULT_SEGMENTS):
    """The ``cameras / 2`` rectified pairs of ``rig`` that observe the motion best (the
    smallest condition number of :attr:`golden.rig.Rig.observability` with ``segments``
    points per row; the first such set in pair order on a tie) as a rig of their own, and the
    dataset camera behind each of its cameras (pairs become (0, 1), (2, 3), ...). On
    stereo20 no two pairs observe all six degrees of freedom: the smallest slice that
    can solve rows has three pairs."""
    from itertools import combinations

    from golden.depth import stereo_pairs
    from golden.rig import Rig
    pairs = stereo_pairs(rig)
    if isinstance(cameras, bool) or not isinstance(cameras, int) or cameras < 2 \
            or cameras % 2 or cameras // 2 > len(pairs):
        raise ValueError(f"cameras must be an even number from 2 to {2 * len(pairs)} (whole "
                         f"stereo pairs of rig {rig.name!r}), not {cameras!r}")

    def sub_rig(combo):
        chosen = [k for j in combo for k in pairs[j][:2]]
        return Rig(name=f"{rig.name}-slice", cameras=tuple(rig.cameras[k] for k in chosen),
                   row_points=segments, nominal_depth=rig.nominal_depth,
                   allow_unobservable=True), chosen

    candidates = [sub_rig(combo) for combo in combinations(range(len(pairs)), cameras // 2)]
    return min(candidates, key=lambda c: c[0].observability.condition)


def slice_params(rig, cameras, rows, records, segments=DEFAULT_SEGMENTS):
    """:class:`hdl.top_params.TopParams` of the slice and the pipeline of its sub-rig.

    The top has ``cameras`` ports (whole pairs of ``rig``, :func:`slice_rig`) and is
    built for cameras of the rig's width and ``rows`` rows, the window it plays
    (:meth:`hdl.pipeline_config.PipelineConfig.window`): the lanes, the router and the
    solver's arithmetic are the full design's, the memories indexed by row (reference
    rows, coefficient store, pose ring) hold the window's rows. Its formats and
    coefficients are the sub-rig's :class:`~hdl.pipeline_config.PipelineConfig` with
    ``segments`` temporal segments at full height, and its PS FIFO is deep enough for
    ``records`` pose records. Returns ``(params, config, chosen dataset cameras)``.
    """
    from hdl.pipeline_config import PipelineConfig
    from hdl.output.params import PoseOutputParams
    sub, chosen = slice_rig(rig, cameras, segments)
    config = PipelineConfig.for_rig(sub, segments=segments)
    depth = 1 << max(records, 2).bit_length()
    params = config.window(rows, pose_output=PoseOutputParams(fifo_depth=depth))
    return params, config, chosen


class NoSolvingWindow(ValueError):
    """No window of the slice's rows solves a row set in the emulator, so a
    co-simulation would not compare the solver's arithmetic."""


def solving_window(config, dataset, chosen, frames, rows):
    """First row of the ``rows`` consecutive rows that the emulator, run on the slice's
    cameras (``chosen``) over the first ``frames`` frames at full height, solves most
    often, and how many row sets it solves there; the first such window on a tie.

    Raises
    ------
    NoSolvingWindow
        When no window solves a row set (the message says which slice and why).
    """
    from types import SimpleNamespace

    from emulator.pipeline import run
    result = run(config, SimpleNamespace(cameras=[dataset.cameras[k] for k in chosen]),
                 frames)
    records = result.records
    solved = np.bincount(np.asarray(records["row"])[np.asarray(records["flags"]) == 0],
                         minlength=config.router.temporal.height)
    per_window = np.convolve(solved, np.ones(rows, dtype=int), mode="valid")
    first = int(np.argmax(per_window))
    if per_window[first] == 0:
        raise NoSolvingWindow(
            f"the emulator solves no row set of cameras {list(chosen)} in frames 0–"
            f"{frames - 1} (too few confident measurements or an ill-conditioned system "
            f"on every row), so a co-simulated slice would not check the solver; try more "
            f"--cosim-frames or --cosim-cameras")
    return first, int(per_window[first])


def row_sets_from_columns(layout, columns):
    """The row sets in the aligned columns the engine took: ``[{camera: beats}]`` and
    the clock each set's first and last column was taken (the fork's rule: a set ends
    with the column on which every lane still in it carries ``last``)."""
    from emulator.hdl_sim.payload import unpack
    sets, spans, current, first = [], [], {}, None
    for clock, raw in columns:
        column = unpack(layout, raw)
        lanes = [k for k in range(len(column["lanes"])) if column["lane_valid"] >> k & 1]
        first = clock if first is None else first
        for k in lanes:
            current.setdefault(k, []).append(column["lanes"][k])
        if all(column["lanes"][k]["last"] for k in lanes):
            sets.append(current)
            spans.append((first, clock))
            current, first = {}, None
    return sets, spans


def expected_records(params, coef_raw, row_sets):
    """The emulator on the row sets the HDL front end produced: the engine model, the
    solver model, and the PS FIFO's narrowing (``emulator.output.packets.keep_poses``), as
    record arrays; plus the pose records' packets (UART bytes)."""
    from emulator.output import packets
    from emulator.measurement.engine import run_engine
    from emulator.measurement.router import pose_rows
    from emulator.pose_solver import pose_solver_model
    engine = params.engine
    config = {"temporal": [0] * engine.cameras, "stereo": [0] * len(engine.pairs),
              "enable": 1}
    transfers = run_engine(engine, row_sets, [config] * len(row_sets)).transfers
    model = pose_solver_model(params.solver, coef_raw, pose_rows(engine.router, transfers))
    poses = [{name: value[k] for name, value in model.items()}
             for k in range(len(model["row"]))]
    kept = [record for _, record in packets.keep_poses(params.pose_output, poses, 1)]
    packet = params.pose_output.packet
    uart = b"".join(packets.encode_packet(packet, r) for r in kept)
    return record_arrays(packet, kept), uart


def record_arrays(packet, records):
    """PS FIFO records (dicts of ``packet``'s record layout) as arrays of
    :data:`RECORD_FIELDS`: (n,) for a field of one element, (n, count) otherwise."""
    counts = {field.name: field.count for field in packet.fields()}
    return {name: np.array([r[name] for r in records], dtype=np.int64).reshape(
        (len(records),) + ((counts[name],) if counts[name] > 1 else ()))
        for name in RECORD_FIELDS}


def pin_latencies(out, sets, frames_of_sets, clocks):
    """Per row set ``k`` (of the first ``len(clocks)``): clocks from its last pixel at the
    pins (the latest of its cameras) to ``clocks[k]``."""
    latencies = []
    for k, (row_set, clock) in enumerate(zip(sets, clocks)):
        frame = frames_of_sets[k]
        row = next(iter(row_set.values()))[0]["row"]
        latencies.append(clock - max(out["row_end_clocks"][cam][frame, row]
                                     for cam in row_set))
    return latencies


def latency_clocks(out, sets, frames_of_sets, fifo_clocks):
    """Largest clocks from a row set's last pixel at the pins to its record in the FIFO
    (record ``k`` is set ``k``'s: the router emits one row per set handed on)."""
    return int(max(pin_latencies(out, sets, frames_of_sets, fifo_clocks), default=0))


def _benchmark_times():
    """The default slice's Verilog and simulation times as the e2e benchmark measured them
    (``docs/results/figures.json``): the progress bars' estimate before a first run."""
    from emulator.report import benchmark_figures
    figures = benchmark_figures()
    return {phase: figures[f"e2e.wall_s.cosim_{phase}"] for phase in ("elaborate", "simulate")
            if f"e2e.wall_s.cosim_{phase}" in figures}


def checked_input(dataset, sim):
    """``dataset`` (a :class:`golden.dataset.Dataset` or its path) loaded, after checking
    ``sim`` names a simulator."""
    from golden.dataset import Dataset
    from emulator.hdl_sim.runner import SIMULATORS
    if sim not in SIMULATORS:
        raise ValueError(f"sim must be one of {', '.join(SIMULATORS)}, not {sim!r}")
    return Dataset.load(dataset) if isinstance(dataset, (str, os.PathLike)) else dataset


def camera_stimulus(images, clk_hz, row_period_s=None):
    """The bench's camera stimulus for ``images`` (cameras, frames, rows, width): the
    slice's DVP timing (:data:`PCLK_PS`, :data:`PCLK_STEP_PS`, :data:`HBLANK`; ``hblank``
    per camera), the UART :data:`DIVISOR` and a trigger period a quarter longer than the
    longest camera frame (system clocks of ``clk_hz``).

    With ``row_period_s`` every camera's horizontal blanking is stretched so that its rows
    last that long (within a PCLK), as the cameras of one rig read their rows at one rate
    (without it, a faster camera gains ``PCLK_STEP_PS`` per pixel on the slower ones).

    Raises
    ------
    ValueError
        When ``row_period_s`` leaves a camera less than :data:`HBLANK` PCLKs of blanking.
    """
    from emulator.hdl_sim.dvp import DvpTiming
    cameras, _, rows, width = images.shape
    pclk_ps = [PCLK_PS + k * PCLK_STEP_PS for k in range(cameras)]
    hblank = [HBLANK] * cameras
    if row_period_s is not None:
        row_ps = round(row_period_s * 1e12)
        hblank = [-(-row_ps // p) - width for p in pclk_ps]
        if min(hblank) < HBLANK:
            raise ValueError(f"row_period_s must leave every camera {HBLANK} PCLKs of "
                             f"blanking after its {width} pixels (at least "
                             f"{(width + HBLANK) * max(pclk_ps) * 1e-12:.3g} s), not "
                             f"{row_period_s!r}")
    frame_ps = max(DvpTiming(width=width, height=rows, hblank=h).frame_pclks * p
                   for h, p in zip(hblank, pclk_ps))
    period = frame_ps // round(1e12 / clk_hz) * 5 // 4 + 2_000
    return {"images": images, "divisor": DIVISOR, "hblank": hblank, "pclk_ps": pclk_ps,
            "period": period}


def run_bench(top, stim, build_dir, **cocotb_args):
    """``top`` through :mod:`emulator.hdl_sim.cosim_bench` with stimulus ``stim`` (saved
    under ``build_dir``); the bench's record. ``cocotb_args`` go to
    :func:`emulator.hdl_sim.runner.run_cocotb` (``name``, ``sim``, ``seed``, ...)."""
    from emulator.hdl_sim.runner import run_cocotb
    build_dir = Path(build_dir)
    build_dir.mkdir(parents=True, exist_ok=True)
    paths = {"in": build_dir / "stimulus.pkl", "out": build_dir / "record.pkl"}
    with open(paths["in"], "wb") as f:
        pickle.dump(stim, f)
    paths["out"].unlink(missing_ok=True)
    run_cocotb(top, test_module="emulator.hdl_sim.cosim_bench",
               extra_env={"ROWTRACK_COSIM_IN": str(paths["in"].resolve()),
                          "ROWTRACK_COSIM_OUT": str(paths["out"].resolve())}, **cocotb_args)
    with open(paths["out"], "rb") as f:
        return pickle.load(f)


def cosim_slice(dataset, *, cameras=6, frames=3, rows=8, segments=DEFAULT_SEGMENTS,
                sim="verilator", waves=False, seed=None, build_dir="build/cosim",
                progress=None):
    """Co-simulate ``rows`` rows of ``frames`` frames of ``cameras`` cameras of
    ``dataset`` (a :class:`golden.dataset.Dataset` or its path) through the HDL top and
    compare with the emulator; a :class:`CosimResult`.

    ``cameras`` is whole stereo pairs, those that observe the motion best
    (:func:`slice_rig`); the default three pairs are the fewest of stereo20 that solve
    rows (with two, every row is flagged). ``rows`` consecutive rows of each frame, at
    full width, where the emulator solves most row sets on the slice's cameras
    (:func:`solving_window`), are played as frames of ``rows`` rows (the top is built for
    them, :func:`slice_params`), with ``segments`` temporal segments per row.
    ``sim``: ``verilator`` or ``icarus``; ``waves`` records waveforms; ``seed`` fixes
    cocotb's seed (camera phases, bus pauses); ``build_dir`` receives the stimulus and
    the simulation's record (the HDL build itself goes under ``build/cocotb/``);
    ``progress`` (bool) prints the steps.

    Raises
    ------
    TypeError, ValueError
        Naming the parameter (``cameras`` not whole stereo pairs, ``frames`` or ``rows``
        beyond the dataset).
    NoSolvingWindow
        When the slice's cameras solve no row set in the emulator.
    """
    from golden.checks import check_int
    from hdl.top import RowtrackTop
    dataset = checked_input(dataset, sim)
    n_frames, height, width = dataset.cameras[0].rows.shape
    check_int("frames", frames, 1, n_frames)
    check_int("rows", rows, 1, height)
    params, config, chosen = slice_params(dataset.rig, cameras, rows, frames * rows,
                                          segments)
    say = print if progress else (lambda *_: None)
    first_row, solvable = solving_window(config, dataset, chosen, frames, rows)
    coef_raw = config.coef_raw[:, first_row:first_row + rows]
    window = slice(first_row, first_row + rows)
    images = np.stack([dataset.cameras[k].rows[:frames, window] for k in chosen])
    stim = {**camera_stimulus(images, params.clk_hz),
            "coef": config.store_window(first_row, rows)}
    say(f"[cosim] cameras {list(chosen)} × {frames} frames × rows {first_row}–"
        f"{first_row + rows - 1} of {width} pixels on {sim} (the emulator solves "
        f"{solvable} of these row sets)")
    timings = {}
    out = run_bench(RowtrackTop(params), stim, build_dir, name="rowtrack_cosim", sim=sim,
                    waves=waves, seed=seed, tag=f"{cameras}x{width}", timings=timings,
                    progress=progress, cache_key=repr(params), estimates=_benchmark_times())

    sets, spans = row_sets_from_columns(params.camera.aligned_layout(), out["columns"])
    order = {}
    frames_of_sets = [order.setdefault(next(iter(s.values()))[0]["frame"], len(order))
                      for s in sets]
    expected, uart = expected_records(params, coef_raw, sets)
    records = record_arrays(params.pose_output.packet, out["fifo_records"])
    mismatches, first = compare_records(records, expected, frames_of_sets)
    latency = latency_clocks(out, sets, frames_of_sets, out["fifo_clocks"]) \
        if len(sets) == len(out["fifo_clocks"]) else -1
    say(f"[cosim] {len(sets)} row sets, {len(out['fifo_records'])} records, "
        f"{mismatches} mismatches; counters {out['status']}")
    return CosimResult(
        records=records, expected=expected, mismatches=mismatches, first_mismatch=first,
        clocks=out["clocks"], wall_s=out["wall_s"], row_sets=len(sets),
        clocks_per_row_set=float(np.mean([b - a + 1 for a, b in spans])) if spans else 0.0,
        latency_clocks=latency, clk_hz=float(params.clk_hz),
        uart_packets_match=out["uart"] == uart and not out["uart_framing_errors"],
        cameras=tuple(chosen), first_row=first_row, timings=timings)

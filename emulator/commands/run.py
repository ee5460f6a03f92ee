"""``rowtrack run``: the main job (what ``make run`` calls).

Simulate a rig and trajectory (or load a dataset), run the hardware path's closed
measurement loop in the bit-accurate emulator
(:func:`emulator.hardware_path.closed_loop`, the first frame given), track the same
rows with the golden tracker's reference (b) with the same loop delay and with its
default parameters, judge the hardware path against truth
and golden (b) (:func:`emulator.e2e.check_closed_loop`), co-simulate the closed-loop HDL
top on a slice of the same rows against the emulator's closed loop on that slice
(:func:`emulator.cosim_loop.closed_loop_cosim`), and write ``build/report/`` (report.md,
PNG plots, metrics.json). Every input is
checked before the long work starts; the exit status is 1 when the hardware path misses
its accuracy tolerance or a comparison fails, with one line per failure saying where
(the axis, measured against bound).
"""

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path

from emulator.errors import UsageError

NAME = "run"
HELP = "the main job: simulate, run the hardware path's closed loop (bit-accurate " \
       "emulator) and the golden tracker, judge against truth, co-simulate a slice of " \
       "the HDL, and write build/report/"

#: Default scenario: the full stereo20 rig (640×480), four frames of the papers' motion
#: (1,440 scored rows; the closed loop takes about 75 s of the run, docs/e2e.md).
DEFAULT_FRAMES = 4
DEFAULT_TRAJECTORY = "paper"
#: Co-simulated slice of the closed-loop top: the middle rows of frames 0 and 1 (frame 1
#: has its reference) of three stereo pairs picked for observability (the smallest
#: stereo20 slice whose rows solve, so that the solver's arithmetic is compared too), cut
#: as a rig of their own (:func:`emulator.cosim_loop.slice_dataset`).
DEFAULT_COSIM = {"rows": 4, "cameras": 6, "frames": 2}


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, not {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be non-negative, not {value}")
    return value


def add_arguments(parser):
    from golden.rig import PRESETS
    from golden.trajectory import MOTIONS
    from golden.tracker_params import DEFAULT_MOTION_GAIN, MOTION_GAINS
    source = parser.add_argument_group("input (simulated unless --dataset)")
    source.add_argument("--rig", help=f"preset ({', '.join(PRESETS)}) or a .yaml/.toml rig "
                                      f"file (default: stereo20)")
    source.add_argument("--dataset", type=Path,
                        help="use this dataset (.npz from `rowtrack simulate`) instead of "
                             "simulating")
    source.add_argument("--trajectory", choices=MOTIONS,
                        help=f"motion to simulate (default: {DEFAULT_TRAJECTORY})")
    length = source.add_mutually_exclusive_group()
    length.add_argument("--frames", type=_positive_int,
                        help=f"frames to simulate or to use (default: {DEFAULT_FRAMES})")
    length.add_argument("--duration", type=float,
                        help="seconds to simulate, instead of --frames")
    source.add_argument("--rows", type=_positive_int,
                        help="cut the simulated rig to its middle ROWS rows, read out over "
                             "the same frame period (default: the full height)")
    source.add_argument("--seed", type=int, default=1,
                        help="seed of the room, the motion and the co-simulation "
                             "(default: %(default)s)")
    cosim = parser.add_argument_group("co-simulation of the HDL top")
    cosim.add_argument("--cosim-rows", type=_positive_int, default=DEFAULT_COSIM["rows"],
                       help="middle rows per frame of the co-simulated slice of the "
                            "closed-loop top; 0 skips the co-simulation (default: "
                            "%(default)s)")
    cosim.add_argument("--cosim-cameras", type=_positive_int,
                       default=DEFAULT_COSIM["cameras"],
                       help="cameras of the slice, whole stereo pairs chosen for observability "
                            "(at least 6 on stereo20 for rows that solve; default: %(default)s)")
    cosim.add_argument("--cosim-frames", type=_positive_int, default=DEFAULT_COSIM["frames"],
                       help="frames of the slice (default: %(default)s)")
    cosim.add_argument("--sim", choices=("verilator", "icarus"), default="verilator",
                       help="HDL simulator (default: %(default)s)")
    cosim.add_argument("--waves", action="store_true", help="record waveforms")
    parser.add_argument("--motion-gain", choices=MOTION_GAINS, default=DEFAULT_MOTION_GAIN,
                        help="the forecast filter's gain law: scalar, or information (the "
                             "per-direction gain 8-camera rigs such as the board rig need "
                             "to track; default: %(default)s)")
    parser.add_argument("-o", "--out", type=Path, default=Path("build/report"),
                        help="report directory (default: %(default)s)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


@dataclass(frozen=True)
class Job:
    """Checked inputs of one run: a loaded dataset or what to simulate."""
    rig: object
    config: object
    frames: int
    dataset: object = None
    dataset_path: Path = None
    trajectory: str = DEFAULT_TRAJECTORY
    seed: int = 1
    cosim: dict = None
    sim: str = "verilator"
    waves: bool = False
    out: Path = Path("build/report")
    #: Changes to the hardware path's forecast parameters
    #: (:meth:`hdl.pipeline_config.PipelineConfig.forecast`): ``motion_gain`` from the
    #: command line; a test breaks the forecast with them to see the run fail.
    forecast_changes: dict = None
    #: How long each row of the co-simulated slice lasts on the pins (default: the rig's
    #: ``t_r``, as its cameras read rows); a test of a rig cut to a few rows, whose
    #: stretched ``t_r`` would make the simulation long, plays them faster.
    cosim_row_period_s: float = None


def _cut_rows(rig, rows):
    """``rig`` with its middle ``rows`` rows, read out over the same time (frame period,
    blanking and exposure unchanged, so a rig with vertical blanking cuts too)."""
    if rows is None:
        return rig
    height = {cam.height for cam in rig.cameras}
    if len(height) != 1:
        raise UsageError("--rows needs cameras of one height")
    height, = height
    if not 3 <= rows <= height:
        raise UsageError(f"--rows must be between 3 and the rig's height {height}, not {rows}")
    readouts = {cam.t_r * height for cam in rig.cameras}
    if max(readouts) - min(readouts) > 1e-12:
        raise UsageError("--rows needs cameras of one readout time")
    try:
        return rig.replace_cameras(height=rows, cy=(rows - 1) / 2,
                                   t_r=max(readouts) / rows)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"--rows {rows}: {exc}") from None


def _frames(args, rig, available=None):
    """Frames to use, checked against what the dataset holds."""
    fps = rig.cameras[0].fps
    if args.duration is not None:
        if not (math.isfinite(args.duration) and args.duration > 0):
            raise UsageError(f"--duration must be a positive number of seconds, not "
                             f"{args.duration}")
        frames = rig.cameras[0].frame_count(args.duration)
    else:
        frames = available if args.frames is None and available else \
            (args.frames if args.frames is not None else DEFAULT_FRAMES)
    if frames < 2:
        raise UsageError(f"the run needs at least 2 frames (the first has no reference "
                         f"row), not {frames} (--frames/--duration at {fps:g} fps)")
    if available is not None and frames > available:
        raise UsageError(f"--frames {frames}: the dataset holds {available} frames")
    return frames


def _configure(rig):
    from emulator.hardware_path import hardware_config
    try:
        return hardware_config(rig)
    except ValueError as exc:
        raise UsageError(f"rig {rig.name!r} cannot run on the hardware pipeline: {exc}") \
            from None


def _simulation_inputs(args, rig, frames):
    """Fail now on a trajectory that takes a camera into a wall."""
    from golden.scene import default_scene_spec
    from golden.simulator import check_clearance, schedule
    from golden.trajectory import make_trajectory
    trajectory = make_trajectory(args.trajectory or DEFAULT_TRAJECTORY, seed=args.seed)
    try:
        check_clearance(rig, default_scene_spec(args.seed), trajectory,
                        schedule(rig, frames / rig.cameras[0].fps, args.seed))
    except ValueError as exc:
        raise UsageError(f"--trajectory {args.trajectory or DEFAULT_TRAJECTORY}: {exc}") \
            from None


def _cosim_slice(args, rig, config, frames):
    """The co-simulated slice, checked against the run: whole stereo pairs of the rig
    and its middle rows, cut as a rig of their own
    (:func:`emulator.cosim_loop.cut_slice`) whose closed-loop top can be built; None for
    --cosim-rows 0."""
    if args.cosim_rows == 0:
        return None
    router = config.router
    checks = (("--cosim-rows", args.cosim_rows, 1, router.temporal.height, "rows per frame"),
              ("--cosim-cameras", args.cosim_cameras, 1, router.cameras, "cameras"),
              ("--cosim-frames", args.cosim_frames, 2, frames, "frames in the run"))
    for flag, value, low, limit, what in checks:
        if not low <= value <= limit:
            raise UsageError(f"{flag} must be between {low} and the {limit} {what}, not "
                             f"{value}")
    from emulator.cosim_loop import cut_slice
    from hdl.top import board_config
    try:
        cut, chosen, first = cut_slice(rig, args.cosim_cameras, args.cosim_rows,
                                       config.segments)
    except (TypeError, ValueError) as exc:
        flag, value = ("--cosim-rows", args.cosim_rows) if str(exc).startswith("rows") \
            else ("--cosim-cameras", args.cosim_cameras)
        raise UsageError(f"{flag} {value}: {exc}") from None
    try:
        board_config(cut)
    except ValueError as exc:
        raise UsageError(f"--cosim-rows {args.cosim_rows}: no closed-loop top for "
                         f"{args.cosim_cameras} cameras × {args.cosim_rows} rows: {exc}") \
            from None
    return {"rows": args.cosim_rows, "cameras": args.cosim_cameras,
            "frames": args.cosim_frames, "segments": config.segments,
            "dataset_cameras": tuple(chosen), "first_row": first}


def _first_frame_given(dataset, path):
    """The hardware path starts from the dataset's true motion of its first tracked row."""
    from emulator.hardware_path import first_frame_motion
    try:
        first_frame_motion(dataset)
    except ValueError as exc:
        raise UsageError(f"--dataset {str(path)!r}: {exc}") from None


def _output(path):
    if path.exists() and not path.is_dir():
        raise UsageError(f"--out {str(path)!r} exists and is not a directory")
    return path


def check_inputs(args):
    """Every input checked, nothing long done yet: a :class:`Job`."""
    from golden.rig import load_rig
    from emulator.commands.track import _load
    out = _output(args.out)
    if args.dataset is not None:
        for flag in ("rig", "trajectory", "rows", "duration"):
            if getattr(args, flag) is not None:
                raise UsageError(f"--{flag} applies to a simulated run, not to --dataset")
        dataset = _load(args.dataset)
        rig = dataset.rig
        frames = _frames(args, rig, min(len(c.rows) for c in dataset.cameras))
        _first_frame_given(dataset, args.dataset)
    else:
        dataset = None
        try:
            rig = load_rig(args.rig or "stereo20")
        except (OSError, TypeError, ValueError) as exc:
            raise UsageError(f"--rig {args.rig}: {exc}") from None
        rig = _cut_rows(rig, args.rows)
        frames = _frames(args, rig)
    config = _configure(rig)
    if dataset is None:
        _simulation_inputs(args, rig, frames)
    return Job(rig=rig, config=config, frames=frames, dataset=dataset,
               dataset_path=args.dataset,
               trajectory=args.trajectory or DEFAULT_TRAJECTORY, seed=args.seed,
               cosim=_cosim_slice(args, rig, config, frames), sim=args.sim, waves=args.waves,
               out=out, forecast_changes={"motion_gain": args.motion_gain})


def run_job(job, progress=True):
    """The long work of a checked :class:`Job`: simulate, run the hardware path's closed
    loop, track with golden (b) (same loop delay) and the default golden tracker, judge,
    co-simulate. Returns :class:`emulator.report.Outcome`."""
    from emulator import e2e, hardware_path
    from emulator.report import Outcome
    from golden.metrics import evaluate
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.tracker import track
    from golden.trajectory import make_trajectory
    walls = {}
    started = start = time.perf_counter()
    dataset = job.dataset
    if dataset is None:
        dataset = simulate(job.rig, default_scene_spec(job.seed),
                           make_trajectory(job.trajectory, seed=job.seed),
                           job.frames / job.rig.cameras[0].fps, seed=job.seed,
                           progress=progress)
    walls["simulate"] = time.perf_counter() - start
    hardware = hardware_path.closed_loop(dataset, job.frames, config=job.config,
                               forecast_changes=job.forecast_changes, progress=progress)
    walls["emulator"] = hardware.result.seconds
    start = time.perf_counter()
    golden_b = track(dataset, hardware_path.golden_b_params(hardware.loop_delay_rows,
                                                            hardware.forecast.motion_gain),
                     progress=progress)
    walls["golden_b"] = time.perf_counter() - start
    start = time.perf_counter()
    golden = track(dataset, progress=progress)
    accuracy = evaluate(golden, dataset)
    walls["golden"] = time.perf_counter() - start
    start = time.perf_counter()
    comparison = e2e.compare_closed_loop(hardware, dataset, golden_b, golden)
    failures = e2e.check_closed_loop(comparison)
    walls["compare"] = time.perf_counter() - start
    cosim, cosim_failures, cosim_walls = cosimulate(job, dataset, progress)
    failures += cosim_failures
    walls.update(cosim_walls)
    walls["total"] = time.perf_counter() - started
    return Outcome(job=job, dataset=dataset, golden=golden, accuracy=accuracy,
                   golden_b=golden_b, hardware=hardware, comparison=comparison,
                   failures=failures, cosim=cosim, walls=walls)


def cosimulate(job, dataset, progress):
    """The co-simulated slice of a run, the closed-loop top against the emulator's closed
    loop on the same slice, both given the slice's true motion of frame 1 as the run's
    hardware path is given the first frame: ``(LoopCosimResult or None, failure lines,
    wall seconds by phase)``; none of it for ``--cosim-rows 0``."""
    if job.cosim is None:
        return None, [], {}
    from emulator.cosim_loop import closed_loop_cosim, slice_dataset
    from emulator.hardware_path import first_frame_motion
    from golden.tracker_params import DEFAULT_MOTION_GAIN
    start = time.perf_counter()
    cosim, failures = None, []
    part, _, _ = slice_dataset(dataset, job.cosim["cameras"], job.cosim["rows"],
                               job.cosim["segments"])
    try:
        period = job.cosim_row_period_s or dataset.rig.cameras[0].t_r
        cosim = closed_loop_cosim(part, row_period_s=period,
                                  frames=job.cosim["frames"],
                                  initial_motion=first_frame_motion(part),
                                  sim=job.sim, waves=job.waves,
                                  seed=job.seed, build_dir=Path("build/cosim_loop"),
                                  progress=progress,
                                  motion_gain=(job.forecast_changes or {}).get(
                                      "motion_gain", DEFAULT_MOTION_GAIN))
    except AssertionError as exc:      # the cocotb bench itself failed
        failures.append(f"HDL co-simulation: {exc}")
    walls = {"cosim": time.perf_counter() - start}
    if cosim is not None:
        walls.update({f"cosim_{k}": v for k, v in cosim.timings.items()})
    return cosim, failures, walls


def run(args):
    from emulator.report import write_report
    job = check_inputs(args)
    outcome = run_job(job, progress=not args.no_progress)
    paths = write_report(outcome, job.out)
    print(outcome.summary())
    print(f"wrote {', '.join(str(p) for p in paths)}")
    for failure in outcome.all_failures():
        print(f"rowtrack run: FAILED: {failure}")
    return 1 if outcome.all_failures() else 0

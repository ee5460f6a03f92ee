"""``rowtrack track``: run the golden per-row tracker on a simulated dataset.

Exit status 1 (with one line on stderr saying when) if tracking was lost: the trajectory
is still written, with each row's status and the rows after the loss marked, and the
table says so first (:mod:`golden.tracking_status`)."""

import json
import math
from pathlib import Path

from emulator.errors import UsageError

NAME = "track"
HELP = "track a dataset with the golden per-row tracker; print the accuracy, write the " \
       "trajectory and a plot"


def add_arguments(parser):
    from golden.tracker import DEPTHS, MOTION_GAINS, REFERENCES, SOLVERS
    from golden.tracker_params import DEFAULT_MOTION_GAIN
    parser.add_argument("data", type=Path, help="dataset .npz written by `rowtrack simulate`")
    parser.add_argument("--reference", choices=REFERENCES, default="homography",
                        help="reference rows: (a) the rotation-compensated previous frame or "
                             "(b) the previous frame's stored rows (default: %(default)s)")
    parser.add_argument("--no-parallax", action="store_true",
                        help="(a) compensate rotation only, as the papers do")
    parser.add_argument("--depth", choices=DEPTHS, default="auto",
                        help="depth source; 'oracle' is the simulator's true depth, for "
                             "ablations only (default: %(default)s)")
    parser.add_argument("--solver", choices=SOLVERS, default="linear",
                        help="per-row solve; 'nonlinear' refines every row on the exact "
                             "model (slow; default: %(default)s)")
    parser.add_argument("--segments", type=int, help="segments per camera row (default: 8)")
    parser.add_argument("--motion-gain", choices=MOTION_GAINS, default=DEFAULT_MOTION_GAIN,
                        help="motion filter gain: the information-weighted matrix or the "
                             "hardware forecast's scalar α (default: %(default)s)")
    parser.add_argument("--loop-delay-rows", type=int, default=0,
                        help="row periods between a slot's solve and the first slot whose "
                             "forecast includes it, as in hardware (default: %(default)s)")
    parser.add_argument("-o", "--out", type=Path,
                        help="trajectory file (default: DATA with suffix .track.npz)")
    parser.add_argument("--plot", type=Path,
                        help="plot file (default: DATA with suffix .track.png)")
    parser.add_argument("--no-plot", action="store_true", help="write no plot")
    parser.add_argument("--json", action="store_true", help="print the metrics as JSON")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _params(args):
    from golden.tracker import TrackerParams
    changes = {"reference": args.reference, "depth": args.depth, "solver": args.solver,
               "parallax": not args.no_parallax, "loop_delay_rows": args.loop_delay_rows,
               "motion_gain": args.motion_gain}
    if args.segments is not None:
        changes["segments"] = args.segments
    try:
        return TrackerParams(**changes)
    except (TypeError, ValueError) as exc:
        raise UsageError(str(exc)) from None


def _load(path):
    from golden.dataset import Dataset
    if not path.is_file():
        raise UsageError(f"dataset {str(path)!r} does not exist")
    try:
        return Dataset.load(path)
    except (OSError, ValueError, KeyError) as exc:
        raise UsageError(f"cannot read dataset {str(path)!r}: {exc}") from None


def _output(path, data, suffix):
    path = path or data.with_suffix(suffix)
    if not path.parent.is_dir():
        raise UsageError(f"output directory {str(path.parent)!r} does not exist")
    return path


def _check(dataset, params):
    """Reject what the tracker cannot do before it starts."""
    from golden.depth import stereo_pairs
    from golden.tracker_slots import RowSlots
    try:
        RowSlots(dataset)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if params.depth == "stereo" and not stereo_pairs(dataset.rig):
        raise UsageError(f"--depth stereo needs rectified stereo pairs; rig "
                         f"{dataset.rig.name!r} has none (use overlap or auto)")
    if params.depth == "oracle" and "scene" not in dataset.info:
        raise UsageError("--depth oracle needs the dataset's scene description")


def save_trajectory(path, result, dataset, metrics):
    """The tracker's output, the ground truth at the same times, and the metrics."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from golden.tracker_motion import ground_truth_track
    true_rot, true_pos = ground_truth_track(dataset).at(result.times)

    def quat(rotations):
        return Rotation.from_matrix(rotations).as_quat(scalar_first=True)

    np.savez(path, time=result.times, quaternion=quat(result.rotations),
             position=result.positions, true_quaternion=quat(true_rot),
             true_position=true_pos, tracked=result.tracked, updated=result.updated,
             condition=result.condition, equations=result.equations,
             camera_confidence=result.camera_confidence, motion=result.motion,
             status=result.status, drifted=result.drifted,
             params=np.array(json.dumps(result.params)),
             metrics=np.array(json.dumps(_json_safe(metrics))))


def plot_trajectory(path, result, dataset, metrics):
    """Estimated against true trajectory and the per-axis errors over time (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from golden.pose_lsq import body_step
    from golden.tracker_motion import ground_truth_track
    from golden.tracking_status import TrackingStatus
    true_rot, true_pos = ground_truth_track(dataset).at(result.times)
    ms = 1000 * (result.times - result.times[0])
    start = (true_rot[0], true_pos[0])
    est = body_step(*start, result.rotations, result.positions)
    true = body_step(*start, true_rot, true_pos)
    error = body_step(true_rot, true_pos, result.rotations, result.positions)
    fig, axes = plt.subplots(2, 2, figsize=(13, 8), sharex=True)
    colours = ("tab:red", "tab:green", "tab:blue")
    for k, axis in enumerate("xyz"):
        c = colours[k]
        axes[0, 0].plot(ms, 100 * true[:, k], color=c, lw=2, alpha=0.35)
        axes[0, 0].plot(ms, 100 * est[:, k], color=c, lw=0.8, label=f"T{axis}")
        axes[0, 1].plot(ms, np.degrees(true[:, 3 + k]), color=c, lw=2, alpha=0.35)
        axes[0, 1].plot(ms, np.degrees(est[:, 3 + k]), color=c, lw=0.8, label=f"θ{axis}")
        axes[1, 0].plot(ms, 100 * (result.positions - true_pos)[:, k], color=c, lw=0.8,
                        label=f"{axis}")
        axes[1, 1].plot(ms, np.degrees(error[:, 3 + k]), color=c, lw=0.8, label=f"θ{axis}")
    axes[0, 0].set_ylabel("motion since the start, cm (rig frame)")
    axes[0, 1].set_ylabel("rotation since the start, deg")
    axes[1, 0].set_ylabel("position error, cm (world)")
    axes[1, 1].set_ylabel("rotation error, deg (rig frame)")
    first = ms[np.argmax(result.tracked)]
    lost = result.status == TrackingStatus.LOST
    for ax in axes.ravel():
        ax.axvspan(0, first, color="0.9", lw=0)        # initialisation: poses given
        ax.fill_between(ms, 0, 1, where=lost, color="tab:red", alpha=0.15, lw=0,
                        transform=ax.get_xaxis_transform())
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel("time since the first row, ms")
    from golden.tracking_status import lost_time
    lost = lost_time(result)        # from the result: callers pass accuracy metrics only
    lost_note = "" if lost is None else f"TRACKING LOST at {1000 * lost:.1f} ms (red: lost); "
    fig.suptitle(f"{lost_note}{dataset.rig.name}: estimate (thin) vs ground truth (wide); per-row Y "
                 f"RMS {_triple(metrics['rms_t_cm'])} cm, {_triple(metrics['rms_r_deg'])}°; "
                 f"render {metrics['render_px']:.2f} px", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _triple(values, digits=3):
    return "/".join(f"{v:.{digits}f}" for v in values)


def _json_safe(metrics):
    """Metrics with non-finite numbers as None (JSON has no inf or NaN)."""
    def clean(value):
        if isinstance(value, list):
            return [clean(v) for v in value]
        return None if isinstance(value, float) and not math.isfinite(value) else value
    return {key: clean(value) for key, value in metrics.items()}


def lost_line(metrics):
    """The one line of a lost run (None if tracking was never lost)."""
    if metrics["lost_at_ms"] is None:
        return None
    return (f"tracking lost at {metrics['lost_at_ms']:.1f} ms; final status "
            f"{metrics['final_status']}; rows after it are marked drifted in the trajectory, "
            f"their accuracy is not a tracking result")


def format_metrics(metrics):
    """The metrics as a short human-readable table (a lost run says so first)."""
    lost = lost_line(metrics)
    return "\n".join(([f"TRACKING LOST: {lost}"] if lost else []) + [
        f"rows tracked          {metrics['rows']} ({metrics['seconds'] * 1000:.1f} ms)",
        f"per-row Y RMS (x/y/z) T {_triple(metrics['rms_t_cm'], 4)} cm   "
        f"θ {_triple(metrics['rms_r_rad'], 6)} rad = {_triple(metrics['rms_r_deg'], 4)}°",
        f"trajectory RMS        T {_triple(metrics['abs_t_cm'], 4)} cm   "
        f"θ {_triple(metrics['abs_r_deg'], 4)}°",
        f"final drift           T {_triple(metrics['final_t_cm'], 4)} cm   "
        f"θ {_triple(metrics['final_r_deg'], 4)}°",
        f"render error (1 m)    RMS {metrics['render_px']:.2f} px, max "
        f"{metrics['render_px_max']:.2f} px (1080×1200 per eye, 100° horizontal FoV)",
        f"rows with an update   {metrics['update_fraction']:.1%}",
        f"condition number      median {metrics['cond_median']:.3g}, max "
        f"{metrics['cond_max']:.3g}",
        f"status                {metrics['status']} (tracking "
        f"{metrics['tracking_fraction']:.1%}, degraded {metrics['degraded_fraction']:.1%}, "
        f"lost {metrics['lost_fraction']:.1%} of rows)"])


def run(args):
    import sys

    from golden.metrics import evaluate
    from golden.tracker import track
    from golden.tracking_status import status_summary
    params = _params(args)
    dataset = _load(args.data)
    _check(dataset, params)
    out = _output(args.out, args.data, ".track.npz")
    plot = None if args.no_plot else _output(args.plot, args.data, ".track.png")
    result = track(dataset, params, progress=not args.no_progress)
    metrics = {**evaluate(result, dataset), **status_summary(result)}
    save_trajectory(out, result, dataset, metrics)
    if plot is not None:
        plot_trajectory(plot, result, dataset, metrics)
    if args.json:
        print(json.dumps(_json_safe(metrics), sort_keys=True))
    else:
        print(format_metrics(metrics))
        print(f"wrote {out}" + (f" and {plot}" if plot else ""))
    lost = lost_line(metrics)
    if lost:
        print(f"rowtrack track: {lost}", file=sys.stderr)
        return 1
    return 0

"""Real runs for the tracking-status checks: the emulator's closed loop (as
emulator/benches/hw_tracking.py runs it) and the golden tracker on the stereo20 rig cut to
its 32 middle rows (as sim_tests/pose/test_closed_loop.py),
and the agreement of the status unit's model with the golden StatusMonitor on them.

:func:`emulator_run` takes each record's row counts from the pipeline's loop history
(``row_counts``, the consistency stage's verdicts). Run as a script for the figures::

    .venv/bin/python -m sim_tests.pose.status_runs [--frames 3] [--motion paper] [--seed 1]
    .venv/bin/python -m sim_tests.pose.status_runs --rig8 [--height 480] [--duration 0.1]
        [--seed 1] [--params '{"consistency_always": true}']

(the second: the golden tracker on issue 18's 8-camera rig, sim_tests/golden/rig8.py,
``head`` motion, oracle depth).
"""

import argparse
import json

import numpy as np

import emulator.pipeline as pipeline
from emulator.pose.tracking_status import golden_to_hardware
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.tracker import TrackerParams, track
from golden.trajectory import make_trajectory
from hdl.pipeline_config import PipelineConfig
from hdl.pose.status_params import StatusParams

from sim_tests.pose.status_stimulus import golden_statuses, model_statuses

ROWS = 32


def dataset(frames=3, motion="paper", seed=1):
    """The hw_tracking benchmark's sequence (sensor noise, ``motion`` of ``seed``) on the
    stereo20 rig cut to 32 rows."""
    from emulator.benches.tracker import NOISE
    rig = preset("stereo20").replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                             t_r=1 / (120 * ROWS), noise_sigma=NOISE)
    return simulate(rig, default_scene_spec(seed), make_trajectory(motion, seed=seed),
                    frames / 120, seed=seed)


def emulator_run(data):
    """The closed loop as emulator/benches/hw_tracking.py runs it (the configuration's
    forecast with the hardware's loop delay, the consistency stage, a disparity per
    temporal segment, the cue fallback, started at the true one-frame motion of the
    first tracked row): ``(config, records, rows)`` with ``rows`` the status unit's
    inputs ``(flags, judged, outliers, confident, determinable)`` of every record."""
    from emulator.e2e import true_steps
    from hdl.top_params import DEFAULT_SEGMENTS
    config = PipelineConfig.for_rig(data.rig, stereo_segments=DEFAULT_SEGMENTS)
    result = pipeline.run(config, data, forecast=config.forecast(),
                          initial_motion=true_steps(data, [1], [0])[0],
                          consistency=config.consistency(), cue_fallback=True)
    flags, counts = result.records["flags"], result.loop["row_counts"]
    if len(counts) != len(flags):
        raise AssertionError(f"{len(counts)} judged rows for {len(flags)} records")
    return config, result.records, [(int(f), *map(int, c)) for f, c in zip(flags, counts)]


def frame_rows(data):
    """Row periods per frame period (blanking included), as golden.tracker counts them."""
    cam = data.rig.cameras[0]
    return 1.0 / (cam.fps * cam.t_r)


def emulator_agreement(data, tracker=TrackerParams()):
    """Model against golden StatusMonitor on the emulator run's own per-row quantities."""
    config, _, rows = emulator_run(data)
    params = StatusParams.for_tracker(tracker, slots=config.router.solver.slots,
                                      frame_rows=frame_rows(data))
    status, drifted, _ = model_statuses(params, rows)
    g_status, g_drifted = golden_statuses(params, rows, tracker)
    return _figures(status, g_status, drifted, g_drifted)


def golden_agreement(data, tracker=TrackerParams()):
    """Model against the golden tracker's own status, fed the golden run's quantities
    (:func:`emulator.pose.tracking_status.golden_to_hardware`)."""
    result = track(data, tracker)
    t = result.tracked
    window = max(round(tracker.status_window * frame_rows(data)), 1)
    slots = int(max(result.equations.max(), result.judged.max(), 1))
    params = StatusParams.for_tracker(tracker, slots=slots, frame_rows=frame_rows(data),
                                      max_window=1 << max(1, (window - 1).bit_length()))
    flags = golden_to_hardware(result.updated[t], result.condition[t],
                               tracker.degraded_condition)
    rows = list(zip(flags, result.judged[t].tolist(), result.outliers[t].tolist(),
                    result.equations[t].tolist(), result.determinable[t].astype(int).tolist()))
    status, drifted, _ = model_statuses(params, rows)
    figures = _figures(status, result.status[t].tolist(), drifted,
                       result.drifted[t].astype(int).tolist())
    # golden slots the hardware cannot reproduce: stepped with a condition above the bound
    figures["stepped_above_condition"] = int(np.count_nonzero(
        result.updated[t] & (result.condition[t] > tracker.degraded_condition)))
    return figures


def _figures(status, golden, drifted, golden_drifted):
    status, golden = np.array(status), np.array(golden)
    return {"rows": len(status), "agree": float(np.mean(status == golden)),
            "drifted_agree": float(np.mean(np.array(drifted) == np.array(golden_drifted))),
            "model": np.bincount(status, minlength=3).tolist(),
            "golden": np.bincount(golden, minlength=3).tolist()}


def rig8_dataset(height, duration, seed):
    from sim_tests.golden.rig8 import eight_camera_rig, issue_room
    rig = eight_camera_rig(width=height * 4 // 3, height=height)
    return simulate(rig, issue_room(seed), make_trajectory("head", seed=seed), duration,
                    seed=seed)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--motion", default="paper")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--rig8", action="store_true")
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--duration", type=float, default=0.1)
    parser.add_argument("--params", default="{}", help="TrackerParams (rig8) as JSON")
    args = parser.parse_args(argv)
    print(f"SEED={args.seed}")
    if args.rig8:
        data = rig8_dataset(args.height, args.duration, args.seed)
        tracker = TrackerParams(**{"depth": "oracle", **json.loads(args.params)})
        runs = (("golden track(), rig8", golden_agreement(data, tracker)),)
    else:
        data = dataset(args.frames, args.motion, args.seed)
        runs = (("emulator closed loop", emulator_agreement(data)),
                ("golden track()", golden_agreement(data)))
    for name, figures in runs:
        extra = "" if "stepped_above_condition" not in figures else \
            f"; golden rows stepped above degraded_condition: " \
            f"{figures['stepped_above_condition']}"
        print(f"{name}: {figures['rows']} rows, status agreement {figures['agree']:.2%}, "
              f"drifted agreement {figures['drifted_agree']:.2%}; rows tracking/degraded/"
              f"lost: model {figures['model']}, golden {figures['golden']}{extra}")


if __name__ == "__main__":
    main()

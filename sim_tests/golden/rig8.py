"""The 8-camera stereo rig and room of issue 18, built from golden.rig primitives (the
preset comes with the stress-suite work; until then tests and the boundary study build
it here), and a script that reproduces the issue's frame-boundary drift.

    .venv/bin/python -m sim_tests.golden.rig8 [--seed S] [--duration 0.1] [--height 480]
                                              [--params '{"boundary": "none"}']

simulates the rig with ``head`` motion (noise σ = 2), tracks it with the oracle depth
(and any other TrackerParams given as JSON) and prints the position error at 30/60/90
ms, where it first exceeds 1 cm, and the tracking status the tracker reports. Heights
must make the 0.5-ms trigger offsets whole row periods (480, 240; not 120).
"""

import argparse
import json
import math

import numpy as np

from golden.camera import Camera
from golden.rig import Rig
from golden.rotations import orientation_ypr
from golden.scene import Box, SceneSpec

#: (yaw, pitch, roll) in degrees of the pairs facing front, right, back and left: the
#: side pairs rolled 90° about their optical axes, the front pair tilted up 30°, the back
#: pair down 30°.
RIG8_PAIRS = ((0, 30, 0), (90, 0, 90), (180, -30, 0), (270, 0, 90))


def eight_camera_rig(*, width=640, height=480, fps=100.0, noise_sigma=2.0):
    """4 stereo pairs, 8 cm baseline along each camera's x axis, pair centres 10 cm from
    the rig origin; 60° vertical FoV, 80 % readout, trigger offset 0.5 ms × pair index."""
    cameras = []
    for k, ypr in enumerate(RIG8_PAIRS):
        rotation = orientation_ypr(*ypr)
        centre = 0.10 * rotation[:, 2]
        for side, sign in (("L", -1), ("R", 1)):
            cameras.append(Camera.from_fov(
                name=f"pair{k}{side}", width=width, height=height, fps=fps,
                t_f=0.2 / fps, rotation=rotation, position=centre + sign * 0.04 * rotation[:, 0],
                trigger_offset=0.0005 * k, noise_sigma=noise_sigma))
    return Rig(name="rig8", cameras=tuple(cameras), row_points=8)


def issue_room(seed):
    """A 7 × 5 × 3 m room with 3–5 boxes (0.3–1 m wide, up to 2.2 m tall) kept at least
    1.2 m from the room centre, where the rig starts."""
    rng = np.random.default_rng([seed, 18])
    boxes = []
    while len(boxes) < rng.integers(3, 6):
        size = rng.uniform(0.3, 1.0, 2)
        centre = rng.uniform([-3.5 + size[0] / 2, -2.5 + size[1] / 2],
                             [3.5 - size[0] / 2, 2.5 - size[1] / 2])
        if np.hypot(*centre) - size.max() < 1.2:
            continue
        height = rng.uniform(0.3, 2.2)
        boxes.append(Box(lo=(*(centre - size / 2), 0.0), hi=(*(centre + size / 2), height)))
    return SceneSpec(room=(7.0, 5.0, 3.0), boxes=tuple(boxes), seed=seed)


def first_exceeding(times, error, bound):
    """Time (ms since the first row) at which ``error`` first exceeds ``bound`` (NaN: never)."""
    above = np.flatnonzero(error > bound)
    return math.nan if not len(above) else 1000 * (times[above[0]] - times[0])


def main(argv=None):
    from golden.simulator import simulate
    from golden.tracker import TrackerParams, track
    from golden.tracker_motion import ground_truth_track
    from golden.trajectory import make_trajectory

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--duration", type=float, default=0.1)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--params", default="{}", help="TrackerParams as JSON")
    args = parser.parse_args(argv)
    width = args.height * 4 // 3
    rig = eight_camera_rig(width=width, height=args.height)
    print(f"SEED={args.seed}")
    dataset = simulate(rig, issue_room(args.seed), make_trajectory("head", seed=args.seed),
                       args.duration, seed=args.seed)
    result = track(dataset, TrackerParams(**{"depth": "oracle", **json.loads(args.params)}))
    _, true_pos = ground_truth_track(dataset).at(result.times)
    error = 100 * np.linalg.norm(result.positions - true_pos, axis=1)
    ms = 1000 * (result.times - result.times[0])
    for t in (30, 60, 90):
        k = np.searchsorted(ms, t)
        if k < len(ms):
            print(f"|p error| at {t} ms: {error[k]:.3f} cm")
    print(f"max |p error| {error.max():.3f} cm; first > 1 cm at "
          f"{first_exceeding(result.times, error, 1.0):.1f} ms")
    tracked = result.tracked
    print(f"updated {result.updated[tracked].mean():.1%} of tracked slots")
    from golden.tracking_status import describe_status
    print(describe_status(result))


if __name__ == "__main__":
    main()

"""``rowtrack simulate``: render a rolling-shutter camera-cluster dataset (golden model)."""

import math
from pathlib import Path

from emulator.errors import UsageError

NAME = "simulate"
HELP = "simulate a rolling-shutter camera cluster moving through a textured room"


def add_arguments(parser):
    from golden.lens import LENS_PRESETS
    from golden.rig import PRESETS
    from golden.trajectory import MOTIONS
    parser.add_argument("--rig", default="stereo20",
                        help=f"preset ({', '.join(PRESETS)}) or a .yaml/.toml rig file "
                             f"(default: %(default)s)")
    parser.add_argument("--lens", choices=sorted(LENS_PRESETS),
                        help="lens preset for a preset rig (default: the preset's own)")
    parser.add_argument("--allow-unobservable", action="store_true",
                        help="accept a rig that cannot observe every degree of freedom")
    parser.add_argument("--duration", type=float, default=0.1,
                        help="seconds of frames to simulate (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the default room's textures, the head motion, trigger "
                             "jitter and sensor noise (default: %(default)s)")
    parser.add_argument("--motion", choices=MOTIONS, default="head",
                        help="trajectory: random head motion, the papers' test case, or a "
                             "static / pure-rotation / pure-translation case (default: %(default)s)")
    parser.add_argument("--speed", default="1.4", metavar="PROFILE",
                        help="linear speed in m/s: a number or time:speed knots such as "
                             "0:0,0.05:1.4 (RMS for head motion; default: %(default)s)")
    parser.add_argument("--angular-speed", default="120", metavar="PROFILE",
                        help="angular speed in deg/s, same forms (default: %(default)s)")
    parser.add_argument("--noise", type=float, metavar="SIGMA",
                        help="sensor noise std in gray levels for every camera "
                             "(default: the rig's own, 0 for presets)")
    parser.add_argument("--scene", type=Path, help="scene .yaml/.toml file (default: the "
                                                   "furnished 7×6×3 m room)")
    parser.add_argument("--texture", type=Path, action="append", default=[], metavar="IMAGE",
                        help="texture image for the room, then each box in turn (repeatable)")
    parser.add_argument("--compress", action="store_true", help="write a compressed .npz")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-o", "--out", type=Path, required=True, help="output .npz file")


def _inputs(args):
    """Rig, scene spec and trajectory from the arguments, checked (nothing rendered)."""
    from golden.rig import load_rig
    from golden.scene import default_scene_spec, load_scene_spec
    from golden.simulator import check_clearance, schedule
    from golden.textures import image_texture
    from golden.trajectory import SpeedProfile, make_trajectory
    if args.out.suffix != ".npz":
        raise UsageError(f"--out must end in .npz, not {str(args.out)!r}")
    if not args.out.parent.is_dir():
        raise UsageError(f"--out directory {str(args.out.parent)!r} does not exist")
    if not args.duration > 0:
        raise UsageError(f"--duration must be positive, not {args.duration}")
    if args.noise is not None and not args.noise >= 0:
        raise UsageError(f"--noise must be non-negative, not {args.noise}")
    try:
        rig = load_rig(args.rig, lens=args.lens,
                       allow_unobservable=args.allow_unobservable or None)
        if args.noise is not None:
            rig = rig.replace_cameras(noise_sigma=args.noise)
        spec = load_scene_spec(args.scene) if args.scene else default_scene_spec(args.seed)
        for path in args.texture:
            image_texture(path, (1, 1))  # unreadable images fail now, not mid-render
        spec = spec.with_textures(args.texture)
        linear = SpeedProfile.parse(args.speed, "--speed")
        angular = SpeedProfile.parse(args.angular_speed, "--angular-speed").scaled(math.pi / 180)
        trajectory = make_trajectory(args.motion, seed=args.seed, linear_speed=linear,
                                     angular_speed=angular)
        check_clearance(rig, spec, trajectory, schedule(rig, args.duration, args.seed))
    except (TypeError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    return rig, spec, trajectory


def run(args):
    from golden.simulator import simulate
    rig, spec, trajectory = _inputs(args)
    dataset = simulate(rig, spec, trajectory, args.duration, seed=args.seed,
                       progress=not args.no_progress)
    dataset.save(args.out, compress=args.compress)
    rows = sum(rec.time.size for rec in dataset.cameras)
    verdict = rig.observability
    print(f"wrote {args.out}: {len(rig.cameras)} cameras, {rows} rows over {args.duration} s "
          f"({args.motion} motion, seed {args.seed}); rig rank {verdict.rank}/6, "
          f"condition {verdict.condition:.3g}"
          + (f", UNOBSERVABLE: {', '.join(verdict.unobservable)}" if verdict.unobservable else ""))
    return 0

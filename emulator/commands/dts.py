"""``rowtrack dts``: depth super-resolution with the domain transform solver (golden model)."""

import time
from pathlib import Path

from emulator.errors import UsageError

NAME = "dts"
HELP = ("edge-aware refinement of an upsampled depth/disparity map along a colour guide "
        "(domain transform solver)")


def add_arguments(parser):
    from golden.dts import DtsParams
    d = DtsParams()
    parser.add_argument("--guide", type=Path, required=True,
                        help="colour or grey guide image at the output resolution (8/16-bit)")
    parser.add_argument("--target", type=Path, required=True,
                        help="upsampled, noisy depth or disparity map at the guide's resolution "
                             "(8- or 16-bit; the output keeps its bit depth and scale)")
    parser.add_argument("--confidence", type=Path,
                        help="confidence map (8- or 16-bit, scaled to [0, 1]); default: trust "
                             "the target less where it has steep gradients")
    parser.add_argument("-o", "--out", type=Path, required=True, help="output image")
    parser.add_argument("--factor", type=float, default=4.0,
                        help="upsampling factor of the target; sets --sigma-s and --lam by the "
                             "per-factor rule (default: %(default)s)")
    parser.add_argument("--sigma-s", type=float,
                        help="spatial extent in pixels (default: from --factor)")
    parser.add_argument("--sigma-r", type=float, default=d.sigma_r,
                        help="edge scale of the guide, guide in [0, 1] (default: %(default)s)")
    parser.add_argument("--lam", type=float,
                        help="smoothness weight lambda (default: from --factor)")
    parser.add_argument("--iterations", type=int, default=d.iterations,
                        help="x/y iterations (default: %(default)s)")
    parser.add_argument("--norm", choices=("l1", "l2"), default=d.norm,
                        help="norm of the guide's colour change (default: %(default)s)")
    parser.add_argument("--depth-sigma", type=float, default=d.depth_sigma,
                        help="the target is a guide channel too: a change of this fraction of "
                             "its range weighs like --sigma-r (default: %(default)s)")
    parser.add_argument("--depth-smoothing", type=float, default=d.depth_smoothing,
                        help="range std (target units) of the bilateral filter that smooths the "
                             "target channel; 0 uses the raw target (default: %(default)s)")
    parser.add_argument("--disparity-power", type=float, default=d.disparity_power,
                        help="data weight x (target / its median) ** P: inverse noise variance "
                             "of a disparity map; 0 for other targets (default: %(default)s)")
    parser.add_argument("--colour-only", action="store_true",
                        help="edges from the guide only (no target channel)")
    parser.add_argument("--robust", type=float, metavar="EPS",
                        help="Charbonnier data term with scale EPS in target units (default: L2)")
    parser.add_argument("--hard", type=float, metavar="THRESHOLD",
                        help="pin pixels whose confidence reaches THRESHOLD to the target")


#: Parameter names in the models' messages -> the options that set them.
OPTIONS = {"factor": "--factor", "sigma_s": "--sigma-s", "sigma_r": "--sigma-r", "lam": "--lam",
           "depth_sigma": "--depth-sigma", "depth_smoothing": "--depth-smoothing",
           "disparity_power": "--disparity-power",
           "iterations": "--iterations", "robust": "--robust", "hard_threshold": "--hard",
           "window": "--window"}


def option_error(exc):
    """A model's "name must be ..." error as a UsageError naming the command-line option."""
    name, _, rest = str(exc).partition(" ")
    return UsageError(f"{OPTIONS.get(name, name)} {rest}")


def _inputs(args):
    """Parameters and images, all checked before the solver starts."""
    from golden.dt_io import check_writable, read_image, unit_scale
    from golden.dts import DtsParams
    try:
        given = {"sigma_s": args.sigma_s, "lam": args.lam}
        params = DtsParams.for_factor(
            args.factor, **{k: v for k, v in given.items() if v is not None},
            sigma_r=args.sigma_r, iterations=args.iterations, norm=args.norm,
            depth_sigma=None if args.colour_only else args.depth_sigma,
            depth_smoothing=args.depth_smoothing or None,
            disparity_power=args.disparity_power,
            robust=args.robust, hard_threshold=args.hard)
        check_writable(args.out, "--out")
        guide = read_image(args.guide, "--guide")
        target = read_image(args.target, "--target")
        confidence = None
        if args.confidence is not None:
            confidence = read_image(args.confidence, "--confidence")
            if confidence.ndim != 2:
                raise ValueError("--confidence must be a single-channel image")
    except (TypeError, ValueError) as exc:
        raise option_error(exc) from None
    for name, image in (("--target", target), ("--confidence", confidence)):
        if image is not None and image.shape[:2] != guide.shape[:2]:
            raise UsageError(f"{name} must have the guide's size {guide.shape[1]}x{guide.shape[0]}, "
                             f"not {image.shape[1]}x{image.shape[0]}")
    return params, unit_scale(guide), target, (None if confidence is None
                                               else unit_scale(confidence))


def run(args):
    from golden.dt_io import write_like
    from golden.dts import dts, target_confidence
    params, guide, target, confidence = _inputs(args)
    start = time.perf_counter()
    values = target.astype(float)
    if confidence is None:
        confidence = target_confidence(values)
    out = dts(values, guide, confidence, params)
    seconds = time.perf_counter() - start
    write_like(args.out, out, target.dtype)
    megapixels = target.shape[0] * target.shape[1] / 1e6
    print(f"dts: {target.shape[1]}x{target.shape[0]} ({megapixels:.2f} MP, "
          f"{target.dtype.itemsize * 8}-bit) in {seconds:.2f} s -> {args.out}")
    return 0

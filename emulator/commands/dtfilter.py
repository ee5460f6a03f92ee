"""``rowtrack dtfilter``: edge-aware smoothing with the domain transform (golden or hardware)."""

import time
from pathlib import Path

from emulator.commands.dts import option_error
from emulator.errors import UsageError

NAME = "dtfilter"
HELP = ("edge-aware smoothing of an image with the domain-transform filter (float RF/NC, "
        "or the bit-accurate model of the hardware block)")


def add_arguments(parser):
    parser.add_argument("input", type=Path, help="image to smooth (8- or 16-bit)")
    parser.add_argument("-o", "--out", type=Path, required=True,
                        help="output image (same bit depth as the input)")
    parser.add_argument("--guide", type=Path,
                        help="edges come from this image (default: the input itself)")
    parser.add_argument("--sigma-s", type=float, default=60.0,
                        help="spatial standard deviation in pixels (default: %(default)s)")
    parser.add_argument("--sigma-r", type=float, default=0.4,
                        help="range standard deviation, guide in [0, 1] (default: %(default)s)")
    parser.add_argument("--iterations", type=int, default=3,
                        help="horizontal+vertical rounds (default: %(default)s)")
    parser.add_argument("--method", choices=("rf", "nc"), default="rf",
                        help="recursive filter or normalized convolution (default: %(default)s)")
    parser.add_argument("--norm", choices=("l1", "l2"), default="l1",
                        help="norm of the guide's colour change (default: %(default)s)")
    parser.add_argument("--hardware", action="store_true",
                        help="run the bit-accurate model of hdl.dt.filter instead: one RF "
                             "round, grey 8-bit guide, single-channel input, --window lines")
    parser.add_argument("--window", type=int, default=8,
                        help="vertical anti-causal window of --hardware (default: %(default)s)")


def _grey8(image):
    """The hardware's guide: one channel, 8 bits."""
    import cv2
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    return grey >> 8 if grey.dtype.itemsize == 2 else grey


def _hardware(args, image, guide):
    from emulator.dt.filter import filter_frame, sigma_register
    from hdl.dt.params import DtFilterParams
    if image.ndim != 2:
        raise UsageError("--hardware filters single-channel images only")
    try:
        params = DtFilterParams(width=image.shape[1], value_bits=8 * image.dtype.itemsize,
                                window=args.window)
        sigma_s = sigma_register("sigma_s", args.sigma_s)
        sigma_r = sigma_register("sigma_r", args.sigma_r * 255.0)
    except (TypeError, ValueError) as exc:
        raise option_error(exc) from None
    return lambda: filter_frame(params, _grey8(guide), image, sigma_s, sigma_r)


def _golden(args, image, guide):
    from golden.dt import check_parameters, normalized_convolution, recursive_filter
    from golden.dt_io import unit_scale
    method = recursive_filter if args.method == "rf" else normalized_convolution
    kwargs = dict(sigma_s=args.sigma_s, sigma_r=args.sigma_r, iterations=args.iterations,
                  norm=args.norm)
    try:
        check_parameters(**kwargs)
    except (TypeError, ValueError) as exc:
        raise option_error(exc) from None
    return lambda: method(image.astype(float), unit_scale(guide), **kwargs)


def run(args):
    from golden.dt_io import check_writable, read_image, write_like
    try:
        check_writable(args.out, "--out")
        image = read_image(args.input, "input")
        guide = image if args.guide is None else read_image(args.guide, "--guide")
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if guide.shape[:2] != image.shape[:2]:
        raise UsageError(f"--guide must have the input's size {image.shape[1]}x{image.shape[0]}, "
                         f"not {guide.shape[1]}x{guide.shape[0]}")
    work = (_hardware if args.hardware else _golden)(args, image, guide)
    start = time.perf_counter()
    out = work()
    seconds = time.perf_counter() - start
    write_like(args.out, out, image.dtype)
    what = "hardware model" if args.hardware else args.method.upper()
    print(f"dtfilter ({what}): {image.shape[1]}x{image.shape[0]} "
          f"({image.shape[0] * image.shape[1] / 1e6:.2f} MP) in {seconds:.2f} s -> {args.out}")
    return 0

"""``rowtrack host``: receive the pose packets from the board's UART."""

import json
import sys
from dataclasses import asdict
from pathlib import Path

from emulator.cli import UsageError

NAME = "host"
HELP = ("read pose packets from a serial port: CRC and sequence checks, resync, lost "
        "packets, live pose and rate, CSV log")


def add_arguments(parser):
    parser.add_argument("--port", required=True, help="serial device, e.g. /dev/ttyUSB0")
    parser.add_argument("--baud", type=int, default=3_000_000,
                        help="baud rate (default: %(default)s)")
    parser.add_argument("--csv", type=Path, metavar="FILE", help="log every record to FILE")
    parser.add_argument("--count", type=int, metavar="N", help="stop after N good packets")
    parser.add_argument("--seconds", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument("--clk-mhz", type=float, default=100.0, metavar="MHZ",
                        help="the board's system clock, for the record rate from time "
                             "stamps (default: %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="no live status line")
    parser.add_argument("--json", action="store_true",
                        help="print the final counts as one JSON object")


def run(args):
    import serial
    from emulator.output.host import run_host
    if args.baud <= 0:
        raise UsageError(f"--baud must be positive, not {args.baud}")
    for name in ("count", "seconds"):
        value = getattr(args, name)
        if value is not None and value <= 0:
            raise UsageError(f"--{name} must be positive, not {value}")
    if args.clk_mhz <= 0:
        raise UsageError(f"--clk-mhz must be positive, not {args.clk_mhz:g}")
    if args.csv is not None and not args.csv.parent.is_dir():
        raise UsageError(f"--csv: directory {args.csv.parent} does not exist")
    try:
        link = serial.Serial(args.port, args.baud, timeout=0.05)
    except (serial.SerialException, ValueError) as exc:
        raise UsageError(f"cannot open --port {args.port}: {exc}") from None
    try:
        stats = run_host(link, baud=args.baud, csv_path=args.csv, count=args.count,
                         seconds=args.seconds, clk_hz=args.clk_mhz * 1e6,
                         live=not args.quiet)
    finally:
        link.close()
    if args.json:
        print(json.dumps(asdict(stats), sort_keys=True))
    else:
        print(", ".join(f"{key} {value}" for key, value in asdict(stats).items()),
              file=sys.stderr)
    return 0

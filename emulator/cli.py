"""``rowtrack``: the command-line entry point.

Each subcommand lives in its own module under :mod:`emulator.commands` and provides
``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``. To add one, write
the module and list it in :data:`COMMANDS`.
"""

import argparse
import importlib
import sys
from importlib.metadata import PackageNotFoundError, version

from emulator.errors import UsageError  # re-exported: commands raise it

__all__ = ["main", "build_parser", "UsageError"]

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS = (
    "emulator.commands.run",
    "emulator.commands.verilog",
    "emulator.commands.bench",
    "emulator.commands.build",
    "emulator.commands.synth_report",
    "emulator.commands.host",
    "emulator.commands.simulate",
    "emulator.commands.dts",
    "emulator.commands.dtfilter",
    "emulator.commands.track",
)


def _version():
    try:
        return version("rowtrack")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


def build_parser():
    parser = argparse.ArgumentParser(
        prog="rowtrack",
        description="Row-rate 6-DoF tracking with rolling-shutter camera clusters: "
                    "golden model, bit-accurate emulator and Amaranth hardware.")
    parser.add_argument("--version", action="version", version=f"rowtrack {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module_name in COMMANDS:
        module = importlib.import_module(module_name)
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return args._run(args) or 0
    except UsageError as exc:
        print(f"rowtrack {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

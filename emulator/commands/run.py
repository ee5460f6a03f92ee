"""``rowtrack run``: the main job (what ``make run`` calls).

Until the end-to-end pipeline exists this writes the Verilog of every block.
"""

from pathlib import Path

NAME = "run"
HELP = "the main job: build every block's Verilog (the end-to-end run comes with the pipeline)"


def add_arguments(parser):
    parser.add_argument("-o", "--out", default="build/verilog", type=Path,
                        help="output directory (default: %(default)s)")


def run(args):
    from hdl import catalog
    from emulator.commands.verilog import write_blocks
    paths = write_blocks(catalog.names(), args.out)
    for path in paths:
        print(f"wrote {path}")
    print(f"{len(paths)} block(s) written to {args.out}/")
    return 0

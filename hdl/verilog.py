"""Writing a component's Verilog plus the JSON sidecar that benches and docs read."""

import json
from pathlib import Path

from amaranth.back import verilog
from amaranth.hdl import Shape
from amaranth.lib import wiring

__all__ = ["write_verilog", "sidecar"]


def sidecar(component, name):
    """Parameters, latency and ports of ``component`` as plain data."""
    ports = []
    for path, member in component.signature.members.flatten():
        if member.is_port:
            ports.append({"name": "__".join(str(p) for p in path),
                          "direction": "in" if member.flow is wiring.In else "out",
                          "width": Shape.cast(member.shape).width})
    params = getattr(component, "params", None)
    return {
        "name": name,
        "class": f"{type(component).__module__}.{type(component).__qualname__}",
        "params": repr(params) if params is not None else None,
        "latency": getattr(component, "latency", None),
        "ports": ports,
    }


def write_verilog(component, name, out_dir):
    """Elaborate ``component`` to ``out_dir/name.v`` and ``out_dir/name.json``.

    Returns the path of the Verilog file. A file whose content would not change is left
    untouched, so that its time stamp stays older than what was built from it (Verilator
    and make then skip rebuilding an unchanged design).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    v_path = out_dir / f"{name}.v"
    _write_if_changed(v_path, verilog.convert(component, name=name, emit_src=False))
    _write_if_changed(out_dir / f"{name}.json",
                      json.dumps(sidecar(component, name), indent=2) + "\n")
    return v_path


def _write_if_changed(path, text):
    if not path.exists() or path.read_text() != text:
        path.write_text(text)

"""Writing a component's Verilog plus the JSON sidecar that benches and docs read."""

import hashlib
import json
from pathlib import Path

from amaranth.back import verilog
from amaranth.hdl import ClockDomain, ClockSignal, Module, ResetSignal, Shape, Value
from amaranth.lib import wiring

__all__ = ["write_verilog", "to_verilog", "sidecar"]


def sidecar(component, name):
    """Parameters, latency and ports of ``component`` as plain data."""
    ports = []
    # The signature flattened on the component itself, so that an array member gives
    # one port per element (``dvp__0__vsync``), as in the Verilog.
    for path, member, value in component.signature.flatten(component):
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


def to_verilog(component, name):
    """``component``'s Verilog text, the same in every Python process.

    Amaranth creates the clock domains a design uses without defining them in set
    order, which depends on the string hash seed; with several such domains (the camera
    pixel clocks) every process would write the ports in another order, and a simulator
    would rebuild an unchanged design. A component with several domains lists them in a
    ``clock_domains`` attribute (port order); they are created here in that order, with
    the ports Amaranth would give them (``clk``/``rst`` for ``sync``, ``<name>_clk`` and
    ``<name>_rst`` otherwise).

    Raises
    ------
    ValueError
        The design uses a clock domain that it neither defines nor lists.
    """
    domains = tuple(getattr(component, "clock_domains", ()))
    if not domains:
        return verilog.convert(component, name=name, emit_src=False)
    # Ports as plain signals: Amaranth names them after the signals (a signature's
    # members are named by their path, a domain's clock and reset as stated above) and
    # gives their direction from the design.
    ports = [Value.cast(value) for _, _, value in component.signature.flatten(component)]
    ports += [signal(domain) for domain in domains for signal in (ClockSignal, ResetSignal)]

    def define(domain):
        if domain not in domains:
            raise ValueError(f"{type(component).__name__} uses the clock domain {domain!r}, "
                             f"which its clock_domains {domains!r} does not list")
        m = Module()
        m.domains += ClockDomain(domain)
        return m

    return verilog.convert(component, name=name, emit_src=False, ports=ports,
                           missing_domain=define)


def write_verilog(component, name, out_dir, *, cache_key=None):
    """Elaborate ``component`` to ``out_dir/name.v`` and ``out_dir/name.json``
    (:func:`to_verilog`).

    Returns the path of the Verilog file. A file whose content would not change is left
    untouched, so that its time stamp stays older than what was built from it (Verilator
    and make then skip rebuilding an unchanged design). ``cache_key``, a string that
    determines the design (such as the repr of the parameters the component is built
    from), skips the elaboration when the files were written for the same key, the same
    source of ``hdl/`` and ``golden/`` and the same Amaranth version.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    v_path = out_dir / f"{name}.v"
    key_path = out_dir / f"{name}.key"
    key = _design_key(component, name, cache_key) if cache_key is not None else None
    if key is None or not v_path.exists() or not key_path.exists() \
            or key_path.read_text() != key:
        key_path.unlink(missing_ok=True)
        _write_if_changed(v_path, to_verilog(component, name))
        if key is not None:
            key_path.write_text(key)
    _write_if_changed(out_dir / f"{name}.json",
                      json.dumps(sidecar(component, name), indent=2) + "\n")
    return v_path


def _design_key(component, name, cache_key):
    """A digest of what a component's Verilog depends on: its class and name, the
    caller's ``cache_key``, its clock domains, the Python source of the gateware and of
    the reference maths it takes constants from, and the Amaranth version."""
    import amaranth

    import golden
    digest = hashlib.sha256()
    for part in (type(component).__module__, type(component).__qualname__, name,
                 cache_key, repr(getattr(component, "clock_domains", ())),
                 amaranth.__version__):
        digest.update(part.encode() + b"\0")
    for package in (Path(__file__).parent, Path(golden.__file__).parent):
        for source in sorted(package.rglob("*.py")):
            digest.update(str(source.relative_to(package.parent)).encode() + b"\0")
            digest.update(source.read_bytes())
    return digest.hexdigest()


def _write_if_changed(path, text):
    if not path.exists() or path.read_text() != text:
        path.write_text(text)

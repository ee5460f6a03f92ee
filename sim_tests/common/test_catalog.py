"""Every block of ``hdl/catalog.py`` elaborates to Verilog with its default parameters,
and the Verilog module has the ports its sidecar (and so every bench) expects."""

import re

import pytest

from hdl import catalog
from hdl.verilog import sidecar, to_verilog


@pytest.mark.parametrize("name", catalog.names())
def test_catalog_block_elaborates_to_verilog(name):
    component = catalog.build(name)
    text = to_verilog(component, name)
    header = re.search(rf"^module {re.escape(name)}\((.*?)\);", text, re.M | re.S)
    assert header, f"no module {name} in the Verilog"
    ports = {p.strip().lstrip("\\") for p in header.group(1).split(",")}
    for port in sidecar(component, name)["ports"]:
        assert port["name"] in ports, f"{name}: port {port['name']} is not in the Verilog"
        width = port["width"]
        kind = "input" if port["direction"] == "in" else "output"
        declared = rf"^\s*{kind} (\[{width - 1}:0\] )?\\?{re.escape(port['name'])}\s*;"
        assert re.search(declared, text, re.M), \
            f"{name}: {kind} {port['name']} of width {width} is not declared so"


def test_an_unknown_block_is_named():
    with pytest.raises(ValueError, match="block must be one of .*, not 'nope'"):
        catalog.build("nope")

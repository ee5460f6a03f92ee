"""Issue 17's targets (emulator/top_targets.py): each names a preset rig, a known device
and, where it has one, a board whose rig it is; bad names are refused by name."""

import pytest

from emulator.benches.top import _io_pins
from emulator.synth import XC7Z020
from emulator.top_targets import DEVICES, FIT_PCT, TARGETS, target
from golden.rig import preset
from hdl import board


def test_targets_name_rigs_devices_and_boards():
    assert [t.rig for t in TARGETS] == ["stereo8-board", "stereo20"]
    for t in TARGETS:
        preset(t.rig)                       # raises for an unknown rig
        assert t.device in DEVICES
        if t.board is not None:
            assert board.board(t.board).rig == t.rig
    assert DEVICES["xc7z020"] is XC7Z020
    # The larger device is larger in every resource.
    assert all(DEVICES["xc7z045"][k] > XC7Z020[k] for k in XC7Z020)
    assert FIT_PCT == 80.0


def test_target_lookup_refuses_unknown_rigs():
    assert target("stereo20").device == "xc7z045"
    with pytest.raises(ValueError, match="rig must be one of stereo8-board, stereo20, not 'x'"):
        target("x")


def test_io_pins_on_a_board_and_without_one():
    board_pins = _io_pins(target("stereo8-board"), 8)
    spec = board.board("microzed-7020")
    assert board_pins == {"io_pins": len(spec.pins_used()),
                          "io_pins_left": len(spec.pins_left())}
    # 20 DVP cameras: PCLK, VSYNC, HREF, 8 data bits and FSIN each, and the UART's TXD.
    assert _io_pins(target("stereo20"), 20) == {"io_pins": 20 * 12 + 1}

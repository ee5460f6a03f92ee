"""The tracking-status group of the register map (hdl/bus/regmap.py): it binds the status
unit's own layouts, resets to the golden thresholds, and the window register holds the
largest window."""

from amaranth.lib import data

from hdl.bus.regmap import GROUP_OFFSETS
from hdl.pose.status_params import StatusParams, top_status_params
from hdl.top_params import TopParams


def _registers(params):
    group = params.regmap().group("status")
    return group, {r.name: r for r in group.registers}


def test_status_group_binds_the_unit_layouts():
    params = TopParams()
    status = top_status_params(params)
    group, regs = _registers(params)
    assert group.offset == GROUP_OFFSETS["status"] == 0x600
    assert regs["settings"].shape == status.settings_layout()
    assert regs["state"].shape == status.state_layout()
    assert regs["clear"].width == 1
    reset = data.Const(regs["settings"].shape, regs["settings"].reset_raw)
    for name, value in status.raw_settings().items():
        assert getattr(reset, name) == value, name
    assert reset.window == 120 and reset.lost_outlier_fraction == 1 << 15


def test_window_register_holds_the_largest_window_and_more():
    """``window`` is wide enough to write a value above max_window (flagged, not cut)."""
    status = StatusParams()
    assert (1 << status.window_bits) - 1 > status.max_window
    assert status.settings_layout().size <= 32 * 5

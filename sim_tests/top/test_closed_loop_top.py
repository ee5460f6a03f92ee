"""The closed-loop top's parameters and register map (issue 16): the measurement loop
closed in the gateware top (TopParams.forecast/.consistency).

Bit-exactness of its parts against the emulator is in the blocks' own benches
(sim_tests/measurement/follow_engine, sim_tests/pose/tracking_loop,
sim_tests/pose/status_unit), of the whole top in its co-simulations
(sim_tests/top/test_run.py's end-to-end job on Icarus, test_closed_loop_cosim.py); its
Verilog is the catalog's ``top_closed`` (sim_tests/common/test_catalog.py).
"""

from dataclasses import replace

import pytest

from golden.rig import preset
from hdl.pipeline_config import PipelineConfig
from hdl.pose.status_params import status_source
from hdl.top import RowtrackTop

ROWS = 32


@pytest.fixture(scope="module")
def config():
    """stereo8 (four pairs, all six axes observable) cut to its middle 32 rows, read out
    over the same time per row, the loop closed."""
    rig = preset("stereo8")
    cam = rig.cameras[0]
    rig = rig.replace_cameras(height=ROWS, cy=(ROWS - 1) / 2, t_r=cam.t_r * cam.height / ROWS)
    return PipelineConfig.for_rig(rig, closed_loop=True, stereo_segments=4)


def test_the_closed_loop_top_follows_and_carries_the_status(config):
    top = config.top
    assert top.closed_loop and top.engine.follow and top.engine.router.cue_fallback
    assert top.pose_output.source == status_source(top.solver)
    assert config.forecast() == top.forecast and config.consistency() == top.consistency


@pytest.mark.parametrize("change, message", [
    (lambda t: {"consistency": None}, "forecast and consistency must be given together"),
    (lambda t: {"forecast": replace(t.forecast, segments=2)},
     "forecast.segments must be segments"),
    (lambda t: {"forecast": replace(t.forecast, height=16)},
     "forecast.height must be camera.max_height"),
    (lambda t: {"consistency": "x"}, "consistency must be a ConsistencyParams or None"),
])
def test_bad_loop_parameters_name_the_parameter(config, change, message):
    with pytest.raises((TypeError, ValueError), match=message):
        config.top.replace(**change(config.top))


def test_the_open_top_keeps_the_solver_source(config):
    with pytest.raises(ValueError, match="pose_output.source must be solver_source"):
        config.top.replace(forecast=None, consistency=None)


def test_forecast_stores_go_with_the_closed_loop_only(config):
    with pytest.raises(ValueError, match="forecast_stores must be given"):
        RowtrackTop(config.top)
    open_top = PipelineConfig.for_rig(preset("stereo8")).top
    with pytest.raises(ValueError, match="forecast_stores is for a closed-loop top only"):
        RowtrackTop(open_top, forecast_stores=config.forecast_stores)


def test_the_loop_registers_are_in_the_map(config):
    """The default (information gain) build adds the prior's two settings to the scalar
    build's loop registers."""
    scalar = ["alpha", "beta", "initial", "restart", "frame_rows", "consistency", "counts",
              "forecast_counters", "track_alpha", "track", "counters"]
    groups = {g.name: g for g in config.top.regmap().groups}
    assert [r.name for r in groups["loop"].registers] == scalar + [
        "prior_weight", "typical_smoothing"]
    scalar_top = replace(config.top, forecast=replace(config.top.forecast,
                                                      motion_gain="scalar"))
    assert [r.name for r in {g.name: g for g in scalar_top.regmap().groups}["loop"]
            .registers] == scalar
    frame_rows = next(r for r in groups["loop"].registers if r.name == "frame_rows")
    assert frame_rows.reset == int(config.frame_rows)
    assert "loop" not in {g.name for g in PipelineConfig.for_rig(preset("stereo8"))
                          .top.regmap().groups}

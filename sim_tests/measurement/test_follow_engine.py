"""The closed-loop ("follow") measurement engine's model
(emulator/measurement/engine.py with EngineParams.follow) against the emulator's closed
loop (emulator/pipeline.py), its forecast join under faults, and the parameter checks.
The gateware runs in the cocotb bench (sim_tests/measurement/follow_engine/).

SEED replays a run (printed).
"""

import os
from dataclasses import replace

import numpy as np
import pytest

from emulator.e2e import true_steps
from emulator.measurement.engine import forecast_rows, run_engine
from emulator.pipeline import run
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory
from hdl.pipeline_config import PipelineConfig
from hdl.measurement.engine import MeasurementEngine
from hdl.measurement.engine_params import engine_config_layout
from hdl.measurement.forecast_rows import ForecastRows
from sim_tests.measurement.follow_engine.stimulus import (closed_loop, configs,
                                                          damage_forecast, follow_config,
                                                          forecast_transfers, priming,
                                                          row_sets)
from sim_tests.measurement.measurement_engine.stimulus import simulated_dataset, small_rig

SEED = int(os.environ.get("SEED", "1"))
FRAMES = 3


@pytest.fixture(scope="module")
def loop():
    print(f"SEED={SEED}")
    return closed_loop(simulated_dataset(small_rig(), SEED), FRAMES)


def _rows(transfers):
    """The transfers split after each ``last``."""
    ends = [n + 1 for n, t in enumerate(transfers) if t["last"]]
    return [transfers[a:b] for a, b in zip([0] + ends, ends)]


def test_model_equals_the_closed_loop(loop):
    """Same rows, the loop's forecasts as input: the engine model's transfers are the
    pipeline's (before any consistency stage), transfer by transfer."""
    params, result = loop.params, loop.result
    history = result.loop
    assert history["centre"].any(), "the forecast never moved a window"
    rows = history["segment_rows"]
    assert (rows != history["row"][:, None, None]).any(), "no row was followed"
    assert (rows != rows[..., :1]).any(), "no camera row read its segments from two rows"
    got = run_engine(params, loop.row_sets, configs(params, len(loop.row_sets)), loop.forecast)
    assert len(got.transfers) == len(result.transfers) == FRAMES * 6 * params.router.solver.slots
    for n, (g, e) in enumerate(zip(got.transfers, result.transfers)):
        assert g == e, f"transfer {n}: engine model {g}, pipeline {e}"
    assert got.status["forecast_skipped"] == got.status["unforecast"] == 0
    assert got.status["malformed"] == 0
    weighted = sum(t["conf"] > 0 for t in got.transfers)
    print(f"{weighted} of {len(got.transfers)} transfers carry weight")
    assert weighted > len(got.transfers) // 3
    # the cue fallback and the followed rows both matter on this slice
    no_fallback = params.replace(router=replace(params.router, cue_fallback=False))
    other = run_engine(no_fallback, loop.row_sets, configs(params, len(loop.row_sets)),
                       loop.forecast)
    assert other.transfers != got.transfers
    fixed = [{**t, "centre": 0, "segment_rows": [t["row"]] * params.temporal.segments}
             for t in loop.forecast]
    other = run_engine(params, loop.row_sets, configs(params, len(loop.row_sets)), fixed)
    assert other.transfers != got.transfers


def test_model_equals_the_closed_loop_on_stereo20():
    """The whole stereo20 rig (20 cameras, 10 pairs, 640-pixel rows) cut to 32 rows, three
    frames, K = K_s = 4 as the hw_tracking bench: the model's transfers are the closed
    loop's (no consistency stage), transfer by transfer."""
    print(f"SEED={SEED}")
    rows, frames = 32, 3
    rig = preset("stereo20").replace_cameras(height=rows, cy=(rows - 1) / 2,
                                             t_r=1 / (120 * rows))
    dataset = simulate(rig, default_scene_spec(SEED), make_trajectory("paper"), frames / 120,
                       seed=SEED)
    config = PipelineConfig.for_rig(rig, segments=4, stereo_segments=4)
    params = config.top.engine.replace(
        follow=True, router=replace(config.router, cue_fallback=True))
    result = run(config, dataset, frames, forecast=config.forecast(loop_delay_rows=1),
                 initial_motion=true_steps(dataset, [1], [0])[0], consistency=None,
                 cue_fallback=True)
    sets = row_sets(config, dataset, frames)
    got = run_engine(params, sets, configs(params, len(sets)), forecast_transfers(result.loop))
    assert len(got.transfers) == len(result.transfers) == frames * rows * 80
    for n, (g, e) in enumerate(zip(got.transfers, result.transfers)):
        assert g == e, f"transfer {n}: engine model {g}, pipeline {e}"
    print(f"{sum(t['conf'] > 0 for t in got.transfers)} of {len(got.transfers)} weighted")


def test_damaged_forecasts_are_counted_and_never_misapplied(loop):
    """A forecast row with an older key, a lost one, a stale extra one and one out of
    camera order: counted, the sets without their forecast dropped, every routed row
    equal to the clean run's or without weight (a reference the dropped sets left
    stale), and the join back in step."""
    params = loop.params
    rng = np.random.default_rng(SEED)
    damaged = damage_forecast(params, loop.forecast, rng)
    cfg = configs(params, len(loop.row_sets))
    clean = run_engine(params, loop.row_sets, cfg, loop.forecast)
    got = run_engine(params, loop.row_sets, cfg, damaged)
    status = got.status
    print(status)
    assert (status["forecast_skipped"], status["unforecast"], status["malformed"]) == (2, 3, 1)
    assert status["router"]["rows"] == len(loop.row_sets) - 3
    by_key = {(t["frame"], t["row"]): row
              for t, row in zip(clean.fork.tickets, _rows(clean.transfers))}
    for ticket, row in zip(got.fork.tickets, _rows(got.transfers)):
        reference = by_key[ticket["frame"], ticket["row"]]
        for g, e in zip(row, reference, strict=True):
            assert g == e or g["conf"] == 0, f"{ticket}: {g} against {e}"
    assert _rows(got.transfers)[-1] == _rows(clean.transfers)[-1]


def test_forecast_rows_gathers_and_discards():
    params = closed_loop_params()
    k = params.temporal.segments
    sources = [[c + n for n in range(k)] for c in range(4)]     # row_bits = 3
    good = forecast_transfers({"row": [3], "centre": [[1, -2, 3, -4]],
                               "segment_rows": [sources]})
    rows, malformed = forecast_rows(params, good)
    assert rows == [{"row": 3, "centre": [1, -2, 3, -4], "source": sources}]
    assert malformed == 0
    early = [dict(t) for t in good]
    early[1]["last"] = 1                       # a row cut short, then a stray rest
    rows, malformed = forecast_rows(params, early + good)
    assert (rows, malformed) == ([{"row": 3, "centre": [1, -2, 3, -4],
                                   "source": sources}], 2)
    wide = [dict(t) for t in good]             # a segment's row beyond the lanes' row_bits
    wide[2]["segment_rows"] = sources[2][:-1] + [1 << params.temporal.row_bits]
    assert forecast_rows(params, wide) == ([], 1)
    long = good[:3] + [dict(good[2], last=0)] + good[3:]
    assert forecast_rows(params, long) == ([], 1)


def closed_loop_params():
    return follow_config()[1]


def test_parameter_checks():
    params = closed_loop_params()
    with pytest.raises(TypeError, match="follow must be a bool, not 1"):
        params.replace(follow=1)
    narrow = replace(params.temporal, descriptor=replace(params.temporal.descriptor, sigma=0.6))
    with pytest.raises(ValueError, match="follow needs router.temporal.radius at least 3 "
                                         r"\(the ring store computes its addresses "
                                         r"meanwhile\), not 2"):
        params.replace(router=replace(params.router, temporal=narrow))
    with pytest.raises(ValueError, match="params.follow must be True for a forecast input"):
        ForecastRows(params.replace(follow=False))
    with pytest.raises(ValueError, match="forecast must be given exactly when params.follow"):
        run_engine(params, [], [])
    with pytest.raises(ValueError, match="row set of row 0 waits for a forecast row"):
        run_engine(params, closed_loop_row_sets(params), configs(params, 1), [])


def closed_loop_row_sets(params):
    return priming(params, 8)[0][:1]


def test_ports_follow_the_option():
    params = closed_loop_params()
    assert "temporal" not in dict(engine_config_layout(params).members)
    assert "temporal" in dict(engine_config_layout(params.replace(follow=False)).members)
    engine = MeasurementEngine(params)
    assert dict(params.forecast_layout().members).keys() == {
        "camera", "centre", "segment_rows", "row", "last"}
    assert "forecast" in engine.signature.members
    assert "forecast" not in MeasurementEngine(params.replace(follow=False)).signature.members

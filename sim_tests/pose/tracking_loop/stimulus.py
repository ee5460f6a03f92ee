"""Stimulus and expected outputs of the tracking loop's tests (hdl/pose/tracking_loop.py):
a real closed loop of ``emulator.pipeline.run`` (forecast at delay 1, consistency stage,
a disparity per segment, cue fallback) on stereo20 cut to a few pairs and rows, its
measurement stream (the router's transfers, before the consistency stage) as the
gateware's input, and what the loop's model gave: per row the forecast transfers and the
solver's records.

A case is a dict: ``params`` (ForecastParams), ``stage`` (ConsistencyParams),
``coefficients``, ``row_coefficients`` (the forecast's stores' contents: polynomial
terms), ``solver_store``, ``initial`` (raw
``motion_fmt``), ``inputs`` (the measurement transfers, in order), ``expected`` (per row
the forecast's per-camera transfers), ``records`` (per row the pose record), ``track``
(per row the motion track's ``Y``, raw ``motion_fmt``) and ``track_saturated``, ``slots``
and ``rows`` (the model's row slot and camera row of each row), ``counts`` (the stage's
counters at the end), ``restart`` (None, or the frame before whose first row the loop
restarted and the raw ``motion_fmt`` motion it restarted at).
"""

from functools import lru_cache
from pathlib import Path
from unittest import mock

import numpy as np

from emulator.measurement.consistency import ConsistencyModel
from emulator.pose.forecast import output_transfers
from emulator.pose.tracking_loop import TrackingLoopModel
from sim_tests.pose.forecast.stimulus import VERSION, cached

__all__ = ["closed_loop_case", "restart_after", "PAIRS", "CACHE"]

CACHE = Path(__file__).resolve().parents[3] / "build" / "tracking_loop_stimulus"
#: stereo20's pairs kept: the front pair, the one beside it rolled 90°, a tilted one
#: (with K = 4 segments per row the six cameras observe all six axes, condition 19).
PAIRS = (0, 1, 4)


def cut_rig(rows, pairs=PAIRS):
    """stereo20 with only ``pairs`` and ``rows`` rows, the frame period ``rows`` row
    periods (120 fps)."""
    from golden.rig import Rig, preset
    rig = preset("stereo20")
    cameras = tuple(c for k in pairs for c in rig.cameras[2 * k:2 * k + 2])
    return Rig(name="stereo20", cameras=cameras, row_points=4).replace_cameras(
        height=rows, cy=(rows - 1) / 2, t_r=1 / (120 * rows))


@lru_cache(maxsize=None)
def closed_loop_case(rows=32, frames=3, seed=1, pairs=PAIRS, delay=1, restart=None,
                     gain="scalar"):
    """The closed loop on ``cut_rig(rows, pairs)``, ``frames`` frames of the papers'
    motion (seed ``seed``), loop delay ``delay`` rows, the filter's ``gain`` law
    (``ForecastParams.motion_gain``), started at the true motion of frame 1's first row
    (as the benchmark); with ``restart`` (a frame) started at 0 (as after reset) and
    restarted before that frame at the true motion of its first row. Cached under
    build/."""
    tail = ("" if restart is None else f"_restart{restart}") + \
        ("" if gain == "scalar" else f"_{gain}")
    name = (f"stereo20_p{''.join(map(str, pairs))}_r{rows}_f{frames}_s{seed}_d{delay}"
            f"{tail}_{VERSION}.pkl")
    return cached(CACHE / name, lambda: _closed_loop(rows, frames, seed, pairs, delay,
                                                     restart, gain))


def restart_after(case):
    """The forecast transfers after which the benches strobe a restart case's
    ``restart`` (with ``initial`` its motion): two rows into the frame before the
    restart's (the loop is then ``loop_delay_rows + 1`` rows ahead of its records, the
    strobe mid-frame); None without a restart."""
    restart = case.get("restart")
    if restart is None:
        return None
    params = case["params"]
    return ((restart[0] - 1) * params.height + 2) * params.cameras


def _closed_loop(rows, frames, seed, pairs, delay, restart, gain):
    from emulator.e2e import true_steps
    from emulator.pipeline import run
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    from hdl.pipeline_config import PipelineConfig

    rig = cut_rig(rows, pairs)
    dataset = simulate(rig, default_scene_spec(seed), make_trajectory("paper"), frames / 120,
                       seed=seed)
    config = PipelineConfig.for_rig(rig, segments=4, stereo_segments=4)
    # rows compared up to half a frame off (the default 16 with 32 rows and more)
    params = config.forecast(loop_delay_rows=delay, motion_gain=gain)
    stage = config.consistency(max_row_offset=min(16, rows // 2))
    inputs, expected = [], []
    request, close = TrackingLoopModel.request, TrackingLoopModel.close

    def recording_request(self, slot, row):
        prediction = request(self, slot, row)
        expected.append(output_transfers(params, prediction, row))
        return prediction

    def recording_close(self, transfers, slot, row):
        inputs.extend(dict(t) for t in transfers)
        return close(self, transfers, slot, row)

    judged = []                  # each measurement's predicted shift and translation part
    apply = ConsistencyModel.apply

    def recording_apply(self, transfers, predicted, delta, translation):
        judged.extend((int(predicted[t["slot"]]), int(translation[t["slot"]]))
                      for t in transfers)
        return apply(self, transfers, predicted, delta, translation)

    if restart is None:
        initial, restarted = true_steps(dataset, [1], [0])[0], None
    else:
        initial, restarted = np.zeros(6), (restart, true_steps(dataset, [restart], [0])[0])
    with mock.patch.object(TrackingLoopModel, "request", recording_request), \
            mock.patch.object(TrackingLoopModel, "close", recording_close), \
            mock.patch.object(ConsistencyModel, "apply", recording_apply):
        out = run(config, dataset, forecast=params, initial_motion=initial,
                  consistency=stage, cue_fallback=True, restart=restarted)
    rec = out.records
    records = [{"row": int(rec["row"][k]), "time": int(rec["time"][k]),
                "flags": int(rec["flags"][k]), "q": [int(v) for v in rec["q"][k]],
                "p": [int(v) for v in rec["p"][k]], "step": [int(v) for v in rec["step"][k]]}
               for k in range(len(rec["row"]))]
    assert len(records) == len(expected) == frames * rows, "a row without measurements"
    coefficients, row_coefficients = config.forecast_stores
    return {"params": params, "stage": stage, "coefficients": coefficients,
            "row_coefficients": row_coefficients, "solver_store": config.coef_store,
            "initial": params.motion_fmt.quantize(initial), "inputs": inputs,
            "expected": expected, "records": records, "judged": judged,
            "track": [[int(v) for v in row] for row in out.loop["track"]],
            "track_saturated": int(out.loop["track_saturated"]),
            "slots": [int(v) for v in out.loop["slot"]], "rows": [int(v) for v in out.loop["row"]],
            "counts": {k: v for k, v in out.loop["counts"].items() if k != "gain_flagged"},
            "gain_flagged": out.loop["counts"].get("gain_flagged"),
            "restart": None if restart is None else
            (restart, params.motion_fmt.quantize(restarted[1]))}

"""Stimulus for the closed-loop ("follow") measurement engine: a small stereo20 slice
(its first two pairs, 256-pixel rows cut to a few rows) run through the emulator's
closed loop (:func:`emulator.pipeline.run` with a forecast and the cue fallback, no
consistency stage), whose per-row forecasts (window centre and source row of each
camera) become the engine's ``forecast`` input.

Plain numpy and dicts, no simulator: the model tests and the cocotb bench build the same
row sets and forecast transfers.
"""

from dataclasses import dataclass, replace

import numpy as np

from emulator.e2e import true_steps
from emulator.hdl_sim.row_stimulus import row_beats
from emulator.pipeline import run
from hdl.pipeline_config import PipelineConfig

from sim_tests.measurement.measurement_engine.stimulus import small_rig

__all__ = ["STEREO_SEGMENTS", "Loop", "follow_config", "closed_loop", "row_sets", "configs",
           "forecast_transfers", "priming", "damage_forecast"]

#: Stereo segments K_s of the slice's pairs (K = 4 temporal segments).
STEREO_SEGMENTS = 2


def follow_config(rig=None):
    """The pipeline of the slice (``PipelineConfig``) and its closed-loop engine's
    parameters (follow, cue fallback)."""
    rig = small_rig() if rig is None else rig
    config = PipelineConfig.for_rig(rig, segments=4, stereo_segments=STEREO_SEGMENTS)
    engine = config.top.engine
    engine = engine.replace(follow=True,
                            router=replace(engine.router, cue_fallback=True))
    return config, engine


@dataclass(frozen=True)
class Loop:
    """The emulator's closed loop on a dataset: its result and the row sets it read."""
    config: object
    params: object
    result: object
    row_sets: list
    forecast: list


def _ticks(dataset, camera, frame, row, config, t0):
    """The pipeline's time stamp of a row (``emulator.pipeline._framed``)."""
    lane = config.router.temporal
    ticks = int(round((dataset.cameras[camera].time[frame, row] - t0) * config.clk_hz))
    return ticks % (1 << lane.timestamp_bits)


def row_sets(config, dataset, frames, frame0=0):
    """Every row of the first ``frames`` frames as a row set, as the pipeline frames
    them (its time stamps; frame numbers from ``frame0``, the pipeline's 0: only the
    ring stores' tags see the numbers, and they compare them with each other)."""
    lane = config.router.temporal
    t0 = min(float(cam.time[0, 0]) for cam in dataset.cameras)
    return [{k: row_beats(cam.rows[f, y], camera=k,
                          frame=(frame0 + f) % (1 << lane.frame_bits), row=y,
                          t_first=_ticks(dataset, k, f, y, config, t0))
             for k, cam in enumerate(dataset.cameras)}
            for f in range(frames) for y in range(lane.height)]


def forecast_transfers(loop):
    """The closed loop's forecast per row set as the engine's ``forecast`` transfers."""
    out = []
    for row, centres, sources in zip(loop["row"], loop["centre"], loop["segment_rows"]):
        cameras = len(centres)
        out += [{"camera": k, "centre": int(c), "segment_rows": [int(r) for r in s],
                 "row": int(row), "last": int(k == cameras - 1)}
                for k, (c, s) in enumerate(zip(centres, sources))]
    return out


def closed_loop(dataset, frames, frame0=0):
    """The emulator's closed loop (no consistency stage: the engine's output is the
    router's) on ``frames`` frames of ``dataset``, with its row sets (numbered from
    ``frame0``) and forecasts."""
    config, params = follow_config(dataset.rig)
    result = run(config, dataset, frames, forecast=config.forecast(loop_delay_rows=1),
                 initial_motion=true_steps(dataset, [1], [0])[0], consistency=None,
                 cue_fallback=True)
    return Loop(config=config, params=params, result=result,
                row_sets=row_sets(config, dataset, frames, frame0),
                forecast=forecast_transfers(result.loop))


def configs(params, n, enable=1):
    """``n`` configurations: stereo centres 0 and the built window (as in the
    pipeline)."""
    return [{"stereo": [0] * len(params.pairs), "enable": enable,
             "half_width": params.temporal.max_half_width}] * n


def priming(params, frame0):
    """Frames of black rows, enough to write every slot of the lanes' ring stores (which
    reset keeps), numbered up to ``frame0 − 2`` (no reference for frame ``frame0``),
    with forecasts centre 0, source = row: ``(row sets, forecast transfers)`` that set
    the rings' bits as in a fresh model."""
    lane = params.temporal
    frames = -(-lane.ring_rows // lane.height)
    black = np.zeros(lane.width, dtype=np.uint8)
    sets, forecast = [], []
    for f in range(frames):
        frame = (frame0 - 1 - frames + f) % (1 << lane.frame_bits)
        for y in range(lane.height):
            sets.append({k: row_beats(black, camera=k, frame=frame, row=y)
                         for k in range(params.cameras)})
            forecast += [{"camera": k, "centre": 0, "segment_rows": [y] * lane.segments,
                          "row": y,
                          "last": int(k == params.cameras - 1)} for k in range(params.cameras)]
    return sets, forecast


def damage_forecast(params, forecast, rng):
    """The forecast transfers with faults at random rows (after the first frame): one
    row's key replaced by an older row's (discarded; its set is dropped), one row
    removed (its set is dropped), one stale row inserted (discarded) and one row with
    its cameras out of order (malformed, its set dropped). Returns the new list."""
    cams, height = params.cameras, params.temporal.height
    rows = [forecast[n:n + cams] for n in range(0, len(forecast), cams)]
    # three rows apart: a stale copy next to a lost row would carry a right key
    spots = np.arange(len(rows) - 2, height - 1, -3)
    picks = sorted(rng.choice(spots, 4, replace=False), reverse=True)
    kinds = ["old_key", "lost", "stale", "malformed"]
    rng.shuffle(kinds)
    for kind, n in zip(kinds, picks):
        row = [dict(t) for t in rows[n]]
        if kind == "old_key":
            for t in row:
                t["row"] = (t["row"] - height // 2) % height
            rows[n] = row
        elif kind == "lost":
            del rows[n]
        elif kind == "stale":
            rows.insert(n, [{**t, "row": (t["row"] - 1) % height} for t in row])
        else:
            row[0]["camera"], row[1]["camera"] = row[1]["camera"], row[0]["camera"]
            rows[n] = row
    return [t for row in rows for t in row]

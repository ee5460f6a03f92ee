"""hdl.front_end.camera_sync: trigger generator and skew monitor against emulator.front_end.camera_sync,
cycle by cycle, with skewed, missing, extra and silent cameras; front-end checks."""

import os
import random

import pytest
from amaranth.sim import Simulator

from emulator.front_end.camera_sync import CameraSyncModel, skew_of
from hdl.front_end.params import CameraParams
from hdl.front_end.camera_sync import CameraFrontEnd, CameraSync
from sim_tests.front_end.test_camera_input import rejected_components

SEED = int(os.environ.get("SEED", "6"))
PARAMS = CameraParams(n_cameras=3, max_width=8, max_height=8, frame_bits=4,
                      timestamp_bits=16, timer_bits=10, skew_bits=6, count_bits=6, master=1)
ROW_PERIOD = 20


def cfg(**changes):
    base = {"trigger_enable": 1, "period": 260, "pulse": 4, "exposure": 30,
            "delay": [0, 7, 90], "skew_threshold": 5, "lost_timeout": 120}
    base.update(changes)
    return base


def no_event():
    return {"frame_start": 0, "frame": 0, "frame_time": 0, "row_start": 0, "row": 0,
            "row_time": 0}


def event_schedule(rng, cycles):
    """Per-cycle events of three cameras: camera 1 is the master; camera 0 follows it
    with a small random skew that now and then jumps past the threshold and skips rows;
    camera 2 sends a frame, then falls silent (lost), then comes back."""
    events = [[no_event() for _ in range(3)] for _ in range(cycles)]

    def put(cycle, camera, **fields):
        if 0 <= cycle < cycles:
            ev = events[cycle][camera]
            ev.update(fields)
            return True
        return False

    injected = []
    for frame in range(4):
        start = 10 + frame * 260
        put(start, 1, frame_start=1, frame=frame, frame_time=start)
        skew = rng.randint(-3, 3)
        put(start + skew, 0, frame_start=1, frame=frame, frame_time=start + skew)
        injected.append(("frame", 0, frame, skew))
        if frame != 1:
            put(start + 2, 2, frame_start=1, frame=frame, frame_time=start + 2)
        for y in range(8):
            t = start + 30 + y * ROW_PERIOD
            put(t, 1, row_start=1, row=y, row_time=t)
            if y == 5:
                continue                                    # camera 0 skips a row
            skew = rng.choice([rng.randint(-4, 4), rng.randint(-9, 9)])
            put(t + skew, 0, row_start=1, row=y, row_time=t + skew)
            injected.append(("row", 0, y, skew))
            if frame != 1:
                put(t + 1, 2, row_start=1, row=y, row_time=t + 1)
    return events, injected


def simulate(params, config, events, cycles):
    dut = CameraSync(params)
    record = []

    async def bench(ctx):
        ctx.set(dut.cfg, config)
        for c in range(cycles):
            for k in range(params.n_cameras):
                ctx.set(dut.events[k], events[c][k])
            record.append(outputs(ctx, dut, params))
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return record


def _fields(view):
    return {name: int(getattr(view, name)) for name, _ in view.shape()}


def outputs(ctx, dut, params):
    n = params.n_cameras
    status = ctx.get(dut.status)
    return {
        "now": ctx.get(dut.now), "frame": ctx.get(dut.frame), "trigger": ctx.get(dut.trigger),
        "expose": ctx.get(dut.expose), "fsin": ctx.get(dut.fsin),
        "skew": [_fields(ctx.get(dut.skew[k])) for k in range(n)],
        "status": {"desync": int(status.desync), "lost": int(status.lost),
                   **{key: [int(v) for v in getattr(status, key)]
                      for key in ("desync_count", "lost_count", "frame_skew", "row_skew")}},
    }


def model_outputs(model):
    st = model.status
    return {"now": model.now, "frame": model.frame, "trigger": model.trigger,
            "expose": model.expose, "fsin": model.fsin, "skew": [dict(s) for s in model.skew],
            "status": {"desync": sum(b << k for k, b in enumerate(st["desync"])),
                       "lost": sum(b << k for k, b in enumerate(st["lost"])),
                       **{key: list(st[key]) for key in
                          ("desync_count", "lost_count", "frame_skew", "row_skew")}}}


def test_sync_matches_model_and_measures_injected_skew():
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    cycles = 1100
    config = cfg()
    events, injected = event_schedule(rng, cycles)
    record = simulate(PARAMS, config, events, cycles)
    model = CameraSyncModel(PARAMS, config)
    for c in range(cycles):
        assert record[c] == model_outputs(model), f"outputs differ in cycle {c}"
        model.step(events[c])

    # Every frame skew and every row skew of camera 0 is measured exactly.
    measured = [("frame", 0, r["skew"][0]["frame_skew"]) for r in record
                if r["skew"][0]["frame_valid"]]
    assert [m[2] for m in measured] == [s for kind, _, _, s in injected if kind == "frame"]
    rows = [(r["skew"][0]["row"], r["skew"][0]["row_skew"]) for r in record
            if r["skew"][0]["row_valid"]]
    assert rows == [(y, s) for kind, _, y, s in injected if kind == "row"]
    # Desync: counted once per frame in which a skew passed the threshold.
    frames_beyond = {i // 7 for i, (kind, _, _, s) in enumerate(
        [x for x in injected if x[0] == "row"]) if abs(s) > 5}
    assert record[-1]["status"]["desync_count"][0] == len(frames_beyond)
    # Camera 2 fell silent for frame 1: lost once, found again at frame 2; after the
    # last frame every camera falls silent and is lost.
    assert record[400]["status"]["lost"] == 0b100
    assert record[1050]["status"]["lost_count"] == [0, 0, 1]
    assert record[1050]["status"]["lost"] == 0
    assert record[-1]["status"]["lost"] == 0b111
    assert record[-1]["status"]["desync_count"][2] == 0


def test_trigger_outputs():
    config = cfg(period=50, pulse=3, exposure=10, delay=[0, 5, 48])
    events = [[no_event()] * 3 for _ in range(120)]
    record = simulate(PARAMS, config, events, 120)
    trigger = [r["trigger"] for r in record]
    rises = [c for c in range(1, 120) if trigger[c] and not trigger[c - 1]]
    assert rises == [1, 51, 101]
    assert sum(trigger[:50]) == 3 and sum(r["expose"] for r in record[:50]) == 10
    fsin = [[r["fsin"] >> k & 1 for r in record] for k in range(3)]
    assert [fsin[k].index(1) for k in range(3)] == [1, 6, 49]
    assert [r["frame"] for r in record[:3]] == [15, 0, 0] and record[60]["frame"] == 1


def test_skew_saturates():
    assert skew_of(PARAMS, 5, 1000) == -32
    assert skew_of(PARAMS, 1000, 5) == 31
    assert skew_of(PARAMS, 3, 2 ** 16 - 2) == 5


def test_constructors_reject_bad_arguments():
    with rejected_components():
        with pytest.raises(TypeError, match="params must be a CameraParams, not 'x'"):
            CameraSync("x")
        with pytest.raises(ValueError, match=r"domains must name one clock domain per "
                                             r"camera \(3\), not 2"):
            CameraFrontEnd(PARAMS, domains=("a", "b"))
        with pytest.raises(ValueError, match="domains must be distinct"):
            CameraFrontEnd(PARAMS, domains=("a", "b", "a"))

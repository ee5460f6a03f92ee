"""hdl.front_end.row_aligner: the aligner against emulator.front_end.row_aligner cycle by cycle, with lanes
that are late, ahead, lost, repeated, out of frame or disabled, with and without random
valid gaps and ready backpressure."""

import os
import random

import pytest
from amaranth.sim import Simulator

from emulator.front_end.row_aligner import RowAlignerModel
from hdl.front_end.params import CameraParams
from hdl.front_end.row_aligner import RowAligner
from sim_tests.front_end.test_camera_input import rejected_components

SEED = int(os.environ.get("SEED", "6"))
PARAMS = CameraParams(n_cameras=3, max_width=8, max_height=6, frame_bits=4,
                      timestamp_bits=12, timer_bits=8, skew_bits=8, count_bits=8)
HEIGHT = 5


def row(camera, frame, index, width=4, flags=0):
    """The beats of one row, with recognisable pixels."""
    base = (camera * 64 + index * 8) & 0xFF
    return [{"data": (base + x) & 0xFF, "first": int(x == 0), "last": int(x == width - 1),
             "camera": camera, "frame": frame, "row": index, "t_first": 100 + index,
             "t_last": 103 + index if x == width - 1 else 0,
             "flags": flags if x == width - 1 else 0} for x in range(width)]


def lanes_scenario():
    """Per-lane beats and a per-lane release cycle for each row (rows arrive skewed)."""
    lanes = {0: [], 1: [], 2: []}
    for y in range(HEIGHT):
        lanes[0].append((y * 12, row(0, 1, y)))
        if y == 2:
            lanes[0].append((y * 12 + 5, row(0, 1, y)))      # a repeated row: stale
        if y != 3:
            lanes[2].append((y * 12 + 3, row(2, 1, y, width=4 if y != 1 else 2)))
        if y < 3:
            lanes[1].append((y * 12 + 7, row(1, 1, y)))      # lane 1 is lost after row 2
    lanes[1].append((70, row(1, 1, 6)))                      # past the frame height
    for y in range(3):                                       # next frame, lane 1 is back
        for k in range(3):
            lanes[k].append((90 + y * 10 + k, row(k, 2, y)))
    return lanes


def simulate(params, cfg, height, lanes, cycles, rng, busy):
    dut = RowAligner(params)
    n = params.n_cameras
    queues = {k: [beat for _, r in lanes[k] for beat in r] for k in range(n)}
    release = {k: [] for k in range(n)}
    for k in range(n):
        for at, r in lanes[k]:
            release[k].extend([at] * len(r))
    record = {"offers": [], "ready": [], "outs": [], "taken": []}

    async def bench(ctx):
        ctx.set(dut.cfg, cfg)
        ctx.set(dut.height, height)
        offering = [False] * n
        for c in range(cycles):
            offers = []
            for k in range(n):
                q = queues[k]
                if not offering[k] and q and release[k][0] <= c and (busy or rng.random() < 0.7):
                    offering[k] = True
                ctx.set(dut.i[k].valid, offering[k])
                if offering[k]:
                    ctx.set(dut.i[k].payload, q[0])
                offers.append(dict(q[0]) if offering[k] else None)
            ready = busy or rng.random() < 0.6
            ctx.set(dut.o.ready, ready)
            out = _set(ctx.get(dut.o.payload), n) if ctx.get(dut.o.valid) else None
            taken = [bool(ctx.get(dut.i[k].ready)) and offering[k] for k in range(n)]
            record["offers"].append(offers)
            record["ready"].append(ready)
            record["outs"].append(out)
            record["taken"].append(taken)
            await ctx.tick()
            for k in range(n):
                if taken[k]:
                    queues[k].pop(0)
                    release[k].pop(0)
                    offering[k] = False
        record["status"] = {key: [int(v) for v in ctx.get(getattr(dut.status, key))]
                            for key in ("missing_count", "stale_count")}

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return record


def _set(view, n):
    return {"lanes": {k: {name: int(getattr(view.lanes[k], name)) for name, _ in
                          view.lanes[k].shape()} for k in range(n)},
            "lane_valid": int(view.lane_valid), "missing": int(view.missing)}


def sets_of(record):
    """Row sets sent: (frame, row, lanes in the set, missing mask, pixels per lane)."""
    sets, current, open_lanes = [], None, set()
    for out, ready in zip(record["outs"], record["ready"]):
        if out is None or not ready:
            continue
        live = [k for k in out["lanes"] if out["lane_valid"] >> k & 1]
        if current is None:
            beat = out["lanes"][live[0]]
            current = (beat["frame"], beat["row"], tuple(live), out["missing"], {})
            open_lanes = set(live)
        for k in live:
            current[4].setdefault(k, []).append(out["lanes"][k]["data"])
            if out["lanes"][k]["last"]:
                open_lanes.discard(k)
        if not open_lanes:
            sets.append(current)
            current = None
    return sets


def assert_matches_model(params, cfg, height, record):
    """Every cycle's output set and lane pops, and the counters, as the model has them."""
    model = RowAlignerModel(params, cfg, height)
    for c, (offers, ready) in enumerate(zip(record["offers"], record["ready"])):
        out, taken = model.cycle(offers, ready)
        assert record["outs"][c] == out, f"o differs in cycle {c}"
        assert record["taken"][c] == taken, f"lane ready differs in cycle {c}"
    assert record["status"] == model.status


@pytest.mark.parametrize("busy", [True, False], ids=["full_rate", "gaps_and_backpressure"])
def test_aligner_matches_model(busy):
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    cfg = {"enable": 0b111, "timeout": 20}
    record = simulate(PARAMS, cfg, HEIGHT, lanes_scenario(), 400, rng, busy)
    assert_matches_model(PARAMS, cfg, HEIGHT, record)

    sets = sets_of(record)
    assert [(f, y, lanes, missing) for f, y, lanes, missing, _ in sets] == [
        (1, 0, (0, 1, 2), 0), (1, 1, (0, 1, 2), 0), (1, 2, (0, 1, 2), 0),
        (1, 3, (0,), 0b110), (1, 4, (0, 2), 0b010),
        (2, 0, (0, 1, 2), 0), (2, 1, (0, 1, 2), 0), (2, 2, (0, 1, 2), 0)]
    for frame, y, lanes, _, pixels in sets:
        for k in lanes:
            width = 2 if (k, frame, y) == (2, 1, 1) else 4
            assert pixels[k] == [beat["data"] for beat in row(k, frame, y, width)]
    assert record["status"] == {"missing_count": [0, 2, 1], "stale_count": [1, 1, 0]}


@pytest.mark.parametrize("busy", [True, False], ids=["full_rate", "gaps_and_backpressure"])
def test_an_older_row_wins_over_the_target(busy):
    """Camera 0 lost row 0 and shows row 1 first; row 0 from the others still forms its
    set (at full rate by moving the target back), before row 1."""
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    cfg = {"enable": 0b111, "timeout": 20}
    lanes = {0: [(0, row(0, 3, 1)), (40, row(0, 3, 2))],
             1: [(3, row(1, 3, 0)), (20, row(1, 3, 1)), (40, row(1, 3, 2))],
             2: [(5, row(2, 3, 0)), (20, row(2, 3, 1)), (40, row(2, 3, 2))]}
    record = simulate(PARAMS, cfg, HEIGHT, lanes, 150, rng, busy)
    assert_matches_model(PARAMS, cfg, HEIGHT, record)
    assert [(f, y, lanes, missing) for f, y, lanes, missing, _ in sets_of(record)] == [
        (3, 0, (1, 2), 0b001), (3, 1, (0, 1, 2), 0), (3, 2, (0, 1, 2), 0)]
    assert record["status"] == {"missing_count": [1, 0, 0], "stale_count": [0, 0, 0]}


def test_disabled_camera_is_drained_and_ignored():
    rng = random.Random(SEED)
    cfg = {"enable": 0b101, "timeout": 5}
    lanes = {k: [(y * 10, row(k, 3, y)) for y in range(3)] for k in range(3)}
    record = simulate(PARAMS, cfg, HEIGHT, lanes, 120, rng, busy=True)
    sets = sets_of(record)
    assert [(f, y, lanes) for f, y, lanes, _, _ in sets] == [(3, y, (0, 2)) for y in range(3)]
    assert sum(taken[1] for taken in record["taken"]) == 12


def test_constructor_rejects_bad_params():
    with rejected_components():
        with pytest.raises(TypeError, match="params must be a CameraParams, not None"):
            RowAligner(None)

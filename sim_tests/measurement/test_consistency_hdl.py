"""Consistency stage gateware (hdl/measurement/consistency.py) in the Amaranth simulator,
bit-exact with :class:`emulator.measurement.consistency.ConsistencyModel`: every output
transfer (the verdict before the gates, and with the row's ``gated`` applied the
transfers the model gives the solver), the counters and the final per-channel scales.
Inputs: rows recorded from a short closed-loop emulator run (stereo20 cut to 32 rows, as
sim_tests/pose/test_closed_loop.py) and random rows at the formats' extremes; with and
without valid gaps and ready backpressure (SEED replays a run, printed). Also the
latency and the parameter checks.
"""

import os
import random

import numpy as np
import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator

import emulator.pipeline as pipeline
import emulator.pose.tracking_loop as tracking_loop
from emulator.hdl_sim.payload import pack
from emulator.measurement.consistency import ConsistencyModel
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory
from hdl.fixed import Overflow, Rounding, mul, resize
from hdl.measurement.consistency import (COUNTS, ConsistencyStage, confidence_floor,
                                         judge_layout)
from hdl.pipeline_config import PipelineConfig
from sim_tests.measurement.consistency.stimulus import (LARGE, SMALL, check_against_model,
                                                       judge_inputs, random_rows)

SEED = int(os.environ.get("SEED", "1"))
FIELDS = ("slot", "row", "time", "shift", "cue", "conf", "last")


def run_stage(params, rows, *, seed, gaps, bits_per_clock=2):
    """Rows ``(transfers, predicted, delta, translation)`` through the gateware; returns the output
    transfers, the ``gated`` bit of each, the clocks of input and output transfers, the
    counters and the final scales."""
    dut = ConsistencyStage(params, bits_per_clock=bits_per_clock)
    rng = random.Random(seed)
    prob = 0.6 if gaps else 1.0
    layout = judge_layout(params)
    count = sum(len(t) for t, *_ in rows)
    out = {"transfers": [], "gated": [], "determinable": [], "judged": [], "outlier": [],
           "in_cycles": [], "out_cycles": []}
    clock = Signal(32)                  # the sink's clock count, for the sources' records

    def source(port, lay, items, rng, record=None):
        async def run(ctx):
            for item in items:
                while rng.random() >= prob:
                    await ctx.tick()
                ctx.set(port.payload.as_value(), pack(lay, item))
                ctx.set(port.valid, 1)
                await ctx.tick().until(port.ready)
                if record is not None:
                    record.append(ctx.get(clock))
                ctx.set(port.valid, 0)
        return run

    async def sink(ctx):
        cycle = 0
        while len(out["transfers"]) < count:
            ready = rng.random() < prob
            ctx.set(dut.o.ready, ready)
            ctx.set(clock, cycle)
            *_, valid, payload, gated, determinable, judged, outlier = \
                await ctx.tick().sample(dut.o.valid, dut.o.payload, dut.gated,
                                        dut.determinable, dut.judged, dut.outlier)
            if valid and ready:
                out["transfers"].append({n: int(getattr(payload, n)) for n in FIELDS})
                out["gated"].append(int(gated))
                out["determinable"].append(int(determinable))
                out["judged"].append(int(judged))
                out["outlier"].append(int(outlier))
                out["out_cycles"].append(cycle)
            cycle += 1
            assert cycle < 100 * count + 1000, "stage hung"
        await ctx.tick().repeat(60)     # no stray transfers, the last update written
        assert not ctx.get(dut.o.valid)
        out["counts"] = {n: ctx.get(getattr(dut.counts, n)) for n in COUNTS}
        out["scale"] = [ctx.get(dut.scale_memory.data[k]) for k in range(params.channels)]

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(source(dut.i, layout, judge_inputs(params, rows),
                             random.Random(rng.random()), out["in_cycles"]), background=True)
    sim.add_testbench(sink)
    sim.run()
    return out




@pytest.mark.parametrize("gaps", [False, True])
@pytest.mark.parametrize("name", ["SMALL", "LARGE"])
def test_random_rows_bit_exact(name, gaps):
    print(f"SEED={SEED}")
    params = {"SMALL": SMALL, "LARGE": LARGE}[name]
    rows = random_rows(params, np.random.default_rng(SEED), 120)
    got = run_stage(params, rows, seed=SEED, gaps=gaps)
    model = check_against_model(params, rows, got)
    print(model.counts)
    # the stimulus reached every decision (scale saturation: at the 1 px ceiling, or at
    # the format's top with the large scales)
    reached = {k for k, v in model.counts.items() if v}
    assert reached == set(COUNTS)
    # depth weights of none, some and all of the confidence
    inputs = judge_inputs(params, rows)
    depth = model.depth_weight([t["cue"] for t in inputs], [t["translation"] for t in inputs])
    one = 1 << params.ratio_fmt.frac_bits
    assert {0, one} <= set(depth.tolist()) and np.any((depth > 0) & (depth < one // 2))
    assert model.counts["gated_rows"] < len(rows)
    # rows on both sides of the determinable test
    rows_last = [d for d, t in zip(got["determinable"], got["transfers"]) if t["last"]]
    assert 0 < sum(rows_last) < len(rows_last)


@pytest.mark.parametrize("bits_per_clock", [1, 3, 4])
def test_other_unit_widths_bit_exact(bits_per_clock):
    """The iterative units at other widths (padded to whole clocks) give the same."""
    print(f"SEED={SEED}")
    rows = random_rows(LARGE, np.random.default_rng(SEED + bits_per_clock), 40)
    got = run_stage(LARGE, rows, seed=SEED, gaps=True, bits_per_clock=bits_per_clock)
    check_against_model(LARGE, rows, got)


# --- rows of a closed-loop emulator run ----------------------------------------------

ROWS = 32


@pytest.fixture(scope="module")
def recorded():
    """The stage's inputs of two frames of the closed loop (stereo20, 32 rows, K = 4)."""
    rig = preset("stereo20").replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                             t_r=1 / (120 * ROWS))
    dataset = simulate(rig, default_scene_spec(1), make_trajectory("paper"), 2 / 120, seed=1)
    config = PipelineConfig.for_rig(rig, segments=4, stereo_segments=4)
    params = config.consistency()
    calls = []

    class Recording(ConsistencyModel):
        def apply(self, transfers, predicted, delta, translation):
            calls.append(([dict(t) for t in transfers], np.array(predicted), np.array(delta),
                          np.array(translation)))
            return super().apply(transfers, predicted, delta, translation)

    original = tracking_loop.ConsistencyModel
    tracking_loop.ConsistencyModel = Recording
    try:
        pipeline.run(config, dataset, frames=2, forecast=config.forecast(loop_delay_rows=1),
                     initial_motion=np.zeros(6), consistency=params, cue_fallback=True)
    finally:
        tracking_loop.ConsistencyModel = original
    return params, calls


@pytest.mark.parametrize("gaps", [False, True])
def test_closed_loop_rows_bit_exact(recorded, gaps):
    """Six rows of the second frame (their measurements have references), replayed from
    the reset scales."""
    print(f"SEED={SEED}")
    params, calls = recorded
    rows = [c for c in calls[ROWS:] if any(t["conf"] for t in c[0])][:6]
    assert len(rows) == 6
    got = run_stage(params, rows, seed=SEED, gaps=gaps)
    model = check_against_model(params, rows, got)
    print(model.counts)
    assert model.counts["outliers"] > 0


@pytest.mark.parametrize("bits_per_clock", [2, 4])
def test_row_rate(recorded, bits_per_clock):
    """A recorded stereo20 row (80 measurements, 20 cameras), no gaps: clocks from its
    first transfer in to its last out, against the bound of the updater's rate."""
    params, calls = recorded
    row = max(calls[ROWS:], key=lambda c: sum(t["conf"] > 0 for t in c[0]))
    got = run_stage(params, [row], seed=SEED, gaps=False, bits_per_clock=bits_per_clock)
    check_against_model(params, [row], got)
    dut = ConsistencyStage(params, bits_per_clock=bits_per_clock)
    clocks = got["out_cycles"][-1] - got["in_cycles"][0]
    # a division P/(P − Δ) wherever the camera or the segment's Δ changes
    keys = [(t["slot"] // params.segments, int(row[2][t["slot"]])) for t in row[0]]
    divisions = 1 + sum(a != b for a, b in zip(keys, keys[1:]))
    bound = len(row[0]) * dut.update_clocks + divisions * dut.time_clocks + dut.latency
    print(f"bits_per_clock {bits_per_clock}: latency {dut.latency}, update "
          f"{dut.update_clocks}; row of {len(row[0])} measurements "
          f"({sum(t['conf'] > 0 for t in row[0])} with confidence, {divisions} time "
          f"divisions): {clocks} clocks (bound {bound})")
    assert clocks <= bound


@pytest.mark.parametrize("apart", [False, True], ids=["one_row_per_camera",
                                                      "a_row_per_segment"])
def test_latency(apart):
    """One row of two measurements per camera, no gaps: a measurement whose camera or
    row offset differs from the previous one's ``latency + time_clocks`` clocks from its
    transfer to ``o.valid`` (the division ``P/(P − Δ)``), one that shares both
    ``latency``: a camera's segments that read one row share the division, segments
    that read their own rows pay one each."""
    rows = random_rows(SMALL, np.random.default_rng(SEED), 1)
    transfers = [{**t, "slot": k, "last": int(k == SMALL.channels - 1), "conf": 0}
                 for k, t in enumerate([rows[0][0][0]] * SMALL.channels)]
    delta = np.repeat(np.arange(SMALL.cameras) % 3, SMALL.segments)
    delta[1::SMALL.segments] += apart
    got = run_stage(SMALL, [(transfers, rows[0][1], delta, rows[0][3])], seed=SEED,
                    gaps=False)
    dut = ConsistencyStage(SMALL)
    took = [o - i for i, o in zip(got["in_cycles"], got["out_cycles"])]
    print("latency", dut.latency, "time", dut.time_clocks, "update", dut.update_clocks,
          "measured", took)
    assert SMALL.segments == 2
    second = dut.latency + dut.time_clocks * apart
    assert took == [dut.latency + dut.time_clocks, second] * SMALL.cameras


def test_the_gates_compare_the_product_with_the_rounding_floor():
    """The row gates compare the confidence product (before its half-even rounding)
    with ``confidence_floor``: for every ``min_confidence`` the product at the floor
    rounds to at least it and the one below to less (rounding is monotonic, so these
    two decide for every product), and products up to ``half`` round to 0."""
    conf_fmt = LARGE.solver.conf_fmt
    fmt = mul(np.zeros(1, dtype=np.int64), conf_fmt, np.zeros(1, dtype=np.int64),
              LARGE.ratio_fmt)[1]
    shift = fmt.frac_bits - conf_fmt.frac_bits
    least, floor = Signal(conf_fmt.width), Signal(fmt.width + 1)
    m = Module()
    m.d.comb += floor.eq(confidence_floor(least, shift))
    floors = []

    async def bench(ctx):
        for value in range(1 << conf_fmt.width):
            ctx.set(least, value)
            floors.append(ctx.get(floor))

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()
    values, floors = np.arange(1 << conf_fmt.width), np.array(floors, dtype=np.int64)

    def rounded(x):
        return resize(x, fmt, conf_fmt, Rounding.HALF_EVEN, Overflow.ERROR)

    assert np.all(rounded(floors) >= values)
    assert np.all(rounded(floors[1:] - 1) < values[1:])
    assert floors[0] == 0 and floors[1] == (1 << (shift - 1)) + 1


@pytest.mark.parametrize("args, error, message", [
    (("nope",), TypeError, "params must be a ConsistencyParams, not 'nope'"),
    ((SMALL,), ValueError, "bits_per_clock must be an integer between 1 and 4, "
                           "not 0"),
])
def test_parameter_checks(args, error, message):
    with pytest.raises(error, match=message):
        ConsistencyStage(*args, **({"bits_per_clock": 0} if args[0] is SMALL else {}))

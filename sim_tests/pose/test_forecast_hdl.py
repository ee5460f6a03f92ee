"""hdl.pose.forecast (the motion forecast's gateware) against emulator.pose.forecast in
the Amaranth simulator: every output transfer and every forecast Ŷ in order, bit for
bit, with and without random valid gaps and ready backpressure; the latency; run-time
gains and restart; saturation flags at the extremes; parameter errors.

Set SEED to replay the randomized tests; the seed in use is printed.
"""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from hdl.pose.forecast import Forecast
from hdl.pose.forecast_filter import MotionFilter
from hdl.pose.forecast_predictor import RowPredictor

from sim_tests.pose.forecast.stimulus import random_case, small_params, expected_outputs

SEED = int(os.environ.get("SEED", "5"))


def simulate(dut, case, *, gaps=False, seed=0, lateness=None, limit=200000, setup=None):
    """Requests and records from two independent drivers (random idle clocks with
    ``gaps``, and ready backpressure on ``o``); returns the outputs per request as
    [(cycle, payload dict)], the Ŷ seen at each request's first output and the cycles
    of the request transfers."""
    rng = random.Random(seed)
    cameras = case["params"].cameras
    outputs, motions, starts = [], [], []

    async def sink(ctx):
        cycle = 0
        while len(outputs) < len(case["requests"]) * cameras and cycle < limit:
            ready = not gaps or rng.random() < 0.5
            ctx.set(dut.o.ready, int(ready))
            if ready and ctx.get(dut.o.valid):
                payload = ctx.get(dut.o.payload)
                if payload.camera == 0:
                    motions.append([ctx.get(dut.motion[i]) for i in range(6)])
                outputs.append((cycle, {name: getattr(payload, name) for name in
                                        ("camera", "centre", "source_row", "centre_saturated",
                                         "row_saturated", "shift_saturated",
                                         "across_saturated", "last")}))
            await ctx.tick()
            cycle += 1

    def driver(port, items, cycles):
        async def run(ctx):
            await ctx.tick()                  # after the restart
            cycle = 1
            for item in items:
                while gaps and rng.random() < 0.4:
                    await ctx.tick()
                    cycle += 1
                ctx.set(port.payload, item)
                ctx.set(port.valid, 1)
                while True:
                    taken = ctx.get(port.ready)
                    await ctx.tick()
                    cycle += 1
                    if taken:
                        break
                cycles.append(cycle - 1)
                ctx.set(port.valid, 0)
        return run

    async def start(ctx):
        ctx.set(dut.initial, [int(v) for v in case["initial"]])
        ctx.set(dut.restart, 1)
        if setup is not None:
            setup(ctx)
        await ctx.tick()
        ctx.set(dut.restart, 0)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(start)
    sim.add_testbench(sink)
    sim.add_testbench(driver(dut.requests, case["requests"], starts))
    sim.add_testbench(driver(dut.records, case["records"], []))
    sim.run()
    grouped = [[p for _, p in outputs[n * cameras:(n + 1) * cameras]]
               for n in range(len(outputs) // cameras)]
    return grouped, motions, starts, [c for c, _ in outputs]


def _build(case):
    return Forecast(case["params"], case["coefficients"], case["row_coefficients"])


def _check(case, got, motions):
    assert len(got) == len(case["expected"])
    for n, (g, e) in enumerate(zip(got, case["expected"])):
        assert g == e, f"request {n}: hardware {g} != model {e}"
    assert motions == case["motion"]


@pytest.mark.parametrize("gaps", [False, True])
def test_outputs_match_the_model(gaps):
    print(f"SEED={SEED}")
    case = random_case(SEED)
    got, motions, _, _ = simulate(_build(case), case, gaps=gaps, seed=SEED)
    _check(case, got, motions)
    assert any(o["centre"] for outs in case["expected"] for o in outs)

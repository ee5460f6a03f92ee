"""hdl.pose.forecast (the motion forecast's gateware) against emulator.pose.forecast in
the Amaranth simulator: every output transfer and every forecast Ŷ in order, bit for
bit, with and without random valid gaps and ready backpressure; the latency; run-time
gains and restart; saturation flags at the extremes; the motion filter alone, its
queries and records back to back; parameter errors.

Set SEED to replay the randomized tests; the seed in use is printed.
"""

import gc
import os
import random
import warnings

import numpy as np
import pytest
from amaranth.hdl import UnusedElaboratable
from amaranth.sim import Simulator

from hdl.pose.forecast import Forecast
from hdl.pose.forecast_filter import MotionFilter

from hdl.pose.params import PoseFlag, PoseSolverParams
from emulator.pose.forecast import ForecastModel

from sim_tests.pose.forecast.stimulus import (expected_outputs, polynomial_params,
                                              random_case, record, run_model, saturations,
                                              small_params)

SEED = int(os.environ.get("SEED", "5"))


def simulate(dut, case, *, gaps=False, seed=0, limit=200000, setup=None, record_wait=0):
    """Requests and records from two independent drivers (random idle clocks with
    ``gaps``, and ready backpressure on ``o``; the records start ``record_wait`` clocks
    late); ``setup(ctx)`` runs with the restart. With the case's ``restart`` (request
    index, raw motion) ``restart`` is strobed again before that request, once the block
    is ``idle``, with ``initial`` the motion. Returns the outputs per request (payload
    dicts), the Ŷ seen at each request's first output, the cycles of the request and
    record transfers and of the outputs, and the saturation counters at the end."""
    rng = random.Random(seed)
    cameras = case["params"].cameras
    outputs, motions, starts, counters = [], [], [], {}

    async def sink(ctx):
        cycle = 0
        while len(outputs) < len(case["requests"]) * cameras and cycle < limit:
            ready = not gaps or rng.random() < 0.5
            ctx.set(dut.o.ready, int(ready))
            if ready and ctx.get(dut.o.valid):
                payload = ctx.get(dut.o.payload)
                if payload.camera == 0:
                    motions.append([ctx.get(dut.motion[i]) for i in range(6)])
                fields = {name: getattr(payload, name) for name in
                          ("camera", "row", "centre", "source_row", "centre_saturated",
                           "row_saturated", "shift_saturated", "across_saturated",
                           "segment_rows_saturated", "last")}
                fields["segment_rows"] = {n: payload.segment_rows[n]
                                          for n in range(len(payload.segment_rows))}
                outputs.append((cycle, fields))
            await ctx.tick()
            cycle += 1
        counters.update({name: ctx.get(getattr(dut.counters, name))
                         for name in ("centre", "row", "segment", "motion")})

    async def restart(ctx, motion):
        """The strobe once the block is idle; returns the clocks it took."""
        clocks = 1
        while not ctx.get(dut.idle):
            await ctx.tick()
            clocks += 1
        ctx.set(dut.initial, [int(v) for v in motion])
        ctx.set(dut.restart, 1)
        await ctx.tick()
        ctx.set(dut.restart, 0)
        return clocks

    def driver(port, items, cycles, wait=0, restart_at=None):
        async def run(ctx):
            await ctx.tick().repeat(1 + wait)  # after the restart
            cycle = 1 + wait
            for n, item in enumerate(items):
                if restart_at is not None and n == restart_at[0]:
                    cycle += await restart(ctx, restart_at[1])
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
    sim.add_testbench(driver(dut.requests, case["requests"], starts,
                             restart_at=case.get("restart")))
    taken = []
    sim.add_testbench(driver(dut.records, case["records"], taken, record_wait))
    sim.run()
    grouped = [[p for _, p in outputs[n * cameras:(n + 1) * cameras]]
               for n in range(len(outputs) // cameras)]
    return grouped, motions, starts, taken, [c for c, _ in outputs], counters


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
    got, motions, *_ = simulate(_build(case), case, gaps=gaps, seed=SEED)
    _check(case, got, motions)
    assert any(o["centre"] for outs in case["expected"] for o in outs)


@pytest.mark.parametrize("gaps", [False, True])
def test_polynomial_stores_match_the_model(gaps):
    """Stores of polynomial terms (degree 1 and 2, random terms up to their formats'
    extremes): the gateware's Horner gives the model's table, saturated values
    included."""
    print(f"SEED={SEED}")
    case = random_case(SEED, params=polynomial_params())
    p = case["params"]
    got, motions, *_ = simulate(_build(case), case, gaps=gaps, seed=SEED)
    _check(case, got, motions)
    for store, table in ((p.solver, case["coef_raw"]), (p.row_store, case["row_coef_raw"])):
        extremes = [store.coef_fmt(k).max_raw for k in range(9)]
        assert (np.abs(table) >= extremes).any(), "no saturated coefficient exercised"


@pytest.mark.parametrize("params, latency", [
    (small_params(), MotionFilter.query_latency + 1 + 6 * 2 - 1 + 7),
    # the slower store (degree 2: read, two Horner steps, rounding) sets the latency
    (polynomial_params(), MotionFilter.query_latency + 1 + 6 * 2 - 1 + 4 + 6),
])
def test_latency_and_row_time_are_the_properties(params, latency):
    """At full rate a request finds the block idle: its first output comes ``latency``
    clocks after its transfer, its last ``row_clocks``; records take ``record_clocks``."""
    case = random_case(SEED, params=params)
    dut = _build(case)
    got, motions, starts, taken, cycles, _ = simulate(dut, case)
    _check(case, got, motions)
    cameras = case["params"].cameras
    firsts, lasts = cycles[::cameras], cycles[cameras - 1::cameras]
    assert {f - s for f, s in zip(firsts, starts)} == {dut.latency}
    assert {last - s for last, s in zip(lasts, starts)} == {dut.row_clocks}
    drain = latency - MotionFilter.query_latency - 6 * 2      # a camera's last term → output
    assert (dut.latency, dut.row_clocks) == (latency, latency + 6 * 2 + drain)


@pytest.mark.parametrize("delay", [0, 2, 3])
def test_every_loop_delay_matches_the_model(delay):
    print(f"SEED={SEED}")
    case = random_case(SEED + delay, params=small_params(loop_delay_rows=delay))
    got, motions, *_ = simulate(_build(case), case, gaps=True, seed=SEED)
    _check(case, got, motions)


def test_late_records_hold_the_requests_that_need_them():
    """With the solver late, only requests whose forecast needs no outstanding record
    are taken (slots up to the first's + delay); the outputs still equal the model's.
    Records waiting with their requests taken come ``record_clocks`` apart."""
    case = random_case(SEED, params=small_params(loop_delay_rows=2), slot_gaps=(1,))
    delay = case["params"].loop_delay_rows
    dut = _build(case)
    got, motions, starts, taken, *_ = simulate(dut, case, record_wait=500)
    _check(case, got, motions)
    assert min(b - a for a, b in zip(taken, taken[1:])) == dut.record_clocks == 32
    early = [n for n, cycle in enumerate(starts) if cycle < taken[0]]
    slots = [r["slot"] for r in case["requests"]]
    assert early and len(early) < len(slots)
    assert all(slots[n] <= slots[0] + delay for n in early)
    assert slots[len(early)] > slots[0] + delay


def filter_steps(params, rng, rows):
    """Per row (step raw (6,), flags): half about a centimetre, a fifth flagged, then
    half at the end of the range with alternating signs, so that (with large gains) the
    level and the trend run into ``motion_fmt``'s bounds and forecasts saturate, several
    axes at once."""
    fmt = params.solver.step_fmt
    calm = [(fmt.quantize(rng.normal(scale=0.01, size=6)), int(rng.random() < 0.2))
            for _ in range(rows // 2)]
    wild = fmt.quantize(0.99 * np.array([1, -1, 1, -1, 1, -1]))
    return calm + [(wild, 0)] * (rows - rows // 2)


@pytest.mark.parametrize("delay", [1, 2])
def test_filter_forecasts_with_records_back_to_back(delay):
    """The filter alone: queries offered back to back, each record offered the clock
    after its query's transfer or later (random). Every query's six axes equal the
    model's, ``motion_valid`` pulses once per query, ``query_latency`` clocks after its
    transfer, and a query waits for the forecast before it; a saturated update or
    forecast strobes ``saturated`` once (the model's count)."""
    print(f"SEED={SEED}")
    params = small_params(loop_delay_rows=delay, alpha=0.5, beta=0.5)
    fmt = params.motion_fmt
    rng = random.Random(SEED + delay)
    rows = filter_steps(params, np.random.default_rng(SEED + delay), 48)
    initial = np.array([-1, 1, -1, 1, -1, 1]) * fmt.max_raw // 2
    model = ForecastModel(params, None, None, initial)
    bound = {fmt.min_raw, fmt.max_raw}
    want, saturated_forecasts, several = [], 0, 0      # forecasts saturated, on 2+ axes
    for slot, (step, flags) in enumerate(rows):
        before = model.saturated
        want.append([int(v) for v in model.motion(slot)])
        if model.saturated > before:
            saturated_forecasts += 1
            several += sum(v in bound for v in want[-1]) > 1
        model.take(slot, None if flags else step)

    dut = MotionFilter(params)
    queried, recorded, forecasts, cycles = [], [], [], []
    strobes = 0

    async def bench(ctx):
        nonlocal strobes
        ctx.set(dut.initial, [int(v) for v in initial])
        ctx.set(dut.restart, 1)
        await ctx.tick()
        ctx.set(dut.restart, 0)
        ctx.set(dut.query.valid, 1)
        wait = 0
        for cycle in range(20000):
            _, _, query_taken, record_taken, valid, strobe, drained, *motion = \
                await ctx.tick().sample(
                    dut.query.valid & dut.query.ready, dut.records.valid & dut.records.ready,
                    dut.motion_valid, dut.saturated, dut.drained,
                    *[dut.motion[i] for i in range(6)])
            strobes += strobe
            if valid:
                forecasts.append(list(motion))
                cycles.append(cycle)
            if len(recorded) == len(rows) and drained:
                break
            if query_taken:
                queried.append(cycle)
                ctx.set(dut.query.payload, len(queried))
                ctx.set(dut.query.valid, len(queried) < len(rows))
            if record_taken:
                recorded.append(cycle)
                ctx.set(dut.records.valid, 0)
                wait = 0 if rng.random() < 0.5 else rng.randrange(1, 40)
            elif len(recorded) < len(queried) and not ctx.get(dut.records.valid):
                if wait:
                    wait -= 1
                else:
                    step, flags = rows[len(recorded)]
                    ctx.set(dut.records.payload, record(params, step, flags=flags))
                    ctx.set(dut.records.valid, 1)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert forecasts == want
    latency = MotionFilter.query_latency
    assert [c - q for c, q in zip(cycles, queried)] == [latency] * len(rows)
    spacing = [b - a for a, b in zip(queried, queried[1:])]
    assert min(spacing) == latency, "no query was offered during a forecast"
    assert sum(r == q + 1 for r, q in zip(recorded, queried)) > 5, \
        "too few records taken during their query's forecast"
    print(f"saturated: {model.saturated} updates and forecasts, {saturated_forecasts} "
          f"forecasts ({several} on several axes)")
    assert strobes == model.saturated
    assert 0 < saturated_forecasts < len(rows) and several > 0


def test_the_slot_counter_may_wrap():
    """Five-bit slots wrap several times over the case (gaps up to 5 slots)."""
    case = random_case(SEED)
    dut = Forecast(case["params"], case["coefficients"], case["row_coefficients"], slot_bits=5)
    wrapped = dict(case, requests=[dict(r, slot=r["slot"] % 32) for r in case["requests"]])
    assert case["requests"][-1]["slot"] > 64
    got, motions, *_ = simulate(dut, wrapped, gaps=True, seed=SEED)
    _check(case, got, motions)


def test_gains_are_run_time_inputs():
    """The block built with the default gains, driven with others: the model with those
    gains, not the default's."""
    case = random_case(SEED)
    params = case["params"]
    other = params.replace(alpha=0.5, beta=0.25)
    dut = _build(case)
    assert (dut.alpha.init, dut.beta.init) == (params.alpha_raw, params.beta_raw)
    expected, motion = expected_outputs(other, case["coef_raw"], case["row_coef_raw"],
                                        case["initial"], case["requests"], case["records"])
    assert motion != case["motion"]

    def setup(ctx):
        ctx.set(dut.alpha, other.alpha_raw)
        ctx.set(dut.beta, other.beta_raw)

    got, motions, *_ = simulate(dut, case, setup=setup)
    _check(dict(case, expected=expected, motion=motion), got, motions)


@pytest.mark.parametrize("sign", [1, -1])
def test_saturation_at_the_extremes_is_flagged(sign):
    """Ŷ at the ends of motion_fmt (every record flagged, so it stays there): shifts and
    displacements beyond displacement_fmt, centres beyond ±centre_range and rows beyond
    the frame, each flagged as the model flags it and counted."""
    case = random_case(SEED)
    params = case["params"]
    fmt = params.motion_fmt
    initial = sign * np.array([1, -1, 1, -1, 1, -1]) * fmt.max_raw
    records = [record(params, flags=PoseFlag.ILL) for _ in case["records"]]
    expected, motion = expected_outputs(params, case["coef_raw"], case["row_coef_raw"],
                                        initial, case["requests"], records)
    case = dict(case, initial=initial, records=records, expected=expected, motion=motion)
    got, motions, *_, counters = simulate(_build(case), case, gaps=True, seed=SEED)
    _check(case, got, motions)
    flat = [o for outs in expected for o in outs]
    assert counters == saturations(flat)          # the motion itself never saturates
    r = params.centre_range
    assert {o["centre"] for o in flat if o["centre_saturated"]} == {-r, r}
    assert {o["source_row"] for o in flat if o["row_saturated"]} == {0, params.height - 1}
    assert any(o["shift_saturated"] for o in flat) and any(o["across_saturated"] for o in flat)


@pytest.mark.parametrize("sign, restarted", [(1, False), (-1, False), (1, True)])
def test_a_diverging_loop_saturates_the_motion_and_counts_it(sign, restarted):
    """Steps at the end of the range from the other end: the level and the trend run
    into motion_fmt's bound; the filter saturates (never wraps to the other sign) as the
    model does, bit for bit, and counts every update and forecast that saturated.
    ``restarted``: after 40 rows the loop restarts at its start and diverges again; the
    count goes on over the restart (a register counter clears only on reset) in both."""
    run = 40
    case = random_case(SEED, rows=2 * run if restarted else run)
    params = case["params"]
    fmt, step_fmt = params.motion_fmt, params.solver.step_fmt
    initial = np.full(6, -sign * fmt.max_raw)
    step = step_fmt.quantize(np.full(6, sign * 0.99))
    records = [record(params, step) for _ in case["records"]]
    restart = (run, initial) if restarted else None
    expected, motion, model = run_model(params, case["coef_raw"], case["row_coef_raw"],
                                        initial, case["requests"], records, restart)
    assert model.saturated > 0, "the stimulus did not drive the filter to its bound"
    for start in range(0, len(motion), run):                               # no wrap
        assert all(np.sign(m[0]) == sign for m in motion[start + run // 2:start + run])
    if restarted:
        fresh = run_model(params, case["coef_raw"], case["row_coef_raw"], initial,
                          case["requests"][run:], records[run:])[2]
        assert model.saturated > fresh.saturated > 0, "the count did not go on"
    case = dict(case, initial=initial, records=records, expected=expected, motion=motion,
                restart=restart)
    got, motions, *_, counters = simulate(_build(case), case, gaps=True, seed=SEED)
    _check(case, got, motions)
    assert counters == saturations([o for outs in expected for o in outs], model.saturated)


@pytest.mark.parametrize("build, error, message", [
    (lambda c: Forecast("params", c["coefficients"], c["row_coefficients"]), TypeError,
     "params must be a ForecastParams, not 'params'"),
    (lambda c: Forecast(c["params"], c["coefficients"], c["row_coefficients"], slot_bits=1),
     ValueError, "slot_bits must be an integer from 2 to 32, not 1"),
    (lambda c: Forecast(c["params"], c["coefficients"][:, :4], c["row_coefficients"]),
     ValueError, r"coefficients must have shape \(4, 8, 9\), not \(4, 4, 9\)"),
    (lambda c: Forecast(c["params"], c["coefficients"], c["row_coefficients"] * 4),
     ValueError, "row_coefficients coefficient [0-9] does not fit SQ"),
    (lambda c: Forecast(polynomial_params(), np.zeros((4, 2, 9), dtype=int),
                        np.full((4, 3, 9), 1 << 40)),
     ValueError, "row_coefficients coefficient 0 term 0 does not fit SQ"),
    (lambda c: Forecast(polynomial_params(), c["coefficients"], c["row_coefficients"]),
     ValueError, r"coefficients must have shape \(4, 2, 9\), not \(4, 8, 9\)"),
    (lambda c: Forecast(small_params(solver=PoseSolverParams(slots=6, rows=8), segments=3),
                        np.zeros((6, 8, 9), dtype=int), np.zeros((6, 8, 9), dtype=int)),
     ValueError, "segments must be a power of two in the gateware .*, not 3"),
])
def test_bad_parameters_are_named(build, error, message):
    case = random_case(SEED, rows=2)
    with warnings.catch_warnings():      # the parts built before the error are unused
        warnings.simplefilter("ignore", UnusedElaboratable)
        with pytest.raises(error, match=message):
            build(case)
        gc.collect()

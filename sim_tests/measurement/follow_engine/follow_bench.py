"""cocotb bench for the closed-loop ("follow") MeasurementEngine: a small stereo20 slice's
simulated rows as row sets and the emulator closed loop's forecasts as the ``forecast``
stream, every solver transfer and the final counters against
emulator.measurement.engine.run_engine, and (clean forecasts) against the closed loop of
emulator/pipeline.py itself."""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.payload import pack
from emulator.hdl_sim.streams import StreamSink, StreamSource
from emulator.measurement.engine import row_set_columns, run_engine
from golden.dataset import Dataset
from hdl.measurement.engine_params import engine_config_layout
from hdl.pose_solver import measurement_layout

from sim_tests.measurement.follow_engine.stimulus import (closed_loop, configs,
                                                          damage_forecast, priming)
from sim_tests.measurement.measurement_engine.engine_bench import _indexed, check_output

FRAMES = 3
TRAFFIC = ("full_rate", "gaps_and_backpressure")
FORECAST = ("clean", "damaged")


@cocotb.parametrize(traffic=TRAFFIC, forecast=FORECAST)
async def follow_engine_matches_model(dut, traffic, forecast):
    """Three frames of the slice after a priming frame; the forecast stream as the
    closed loop produced it, or with an older key, a lost, a stale and a malformed row;
    free-running or random sources (rows and forecasts) and sink."""
    params = load_params()
    busy = traffic == "full_rate"
    rng = random.Random(cocotb.RANDOM_SEED)
    # Reset keeps the ring stores' bits and tags: each case numbers its frames apart (no
    # earlier case's tag matches) and starts with priming frames that write every ring
    # slot, so the bits a reference-less row reads (also where a dropped set left its
    # slot unwritten) are the fresh model's.
    case = 2 * TRAFFIC.index(traffic) + FORECAST.index(forecast)
    frame0 = (4096 * case + 8) % (1 << params.temporal.frame_bits)
    loop = closed_loop(Dataset.load(os.environ["ROWTRACK_FE_DATASET"]), FRAMES, frame0)
    fc = loop.forecast
    if forecast == "damaged":
        fc = damage_forecast(params, fc, np.random.default_rng(cocotb.RANDOM_SEED))
    prime_sets, prime_fc = priming(params, frame0)
    skip = len(run_engine(params, prime_sets, configs(params, len(prime_sets)),
                          prime_fc).transfers)
    row_sets = prime_sets + loop.row_sets
    cfg = configs(params, len(row_sets))
    expected = run_engine(params, row_sets, cfg, prime_fc + fc)
    if forecast == "clean":
        # the model's transfers are the closed loop's, from the first frame with a
        # reference (before it, the shifts of reference-less rows depend on the ring's
        # bits, which the priming frame set and a fresh pipeline has at zero)
        frame = params.temporal.height * params.router.solver.slots
        assert expected.transfers[skip + frame:] == loop.result.transfers[frame:]

    clock = start_clock(dut)
    rows = StreamSource(dut, "rows", params.aligned_layout(), clock, rng=rng,
                        valid_prob=1.0 if busy else 0.8)
    forecasts = StreamSource(dut, "forecast", params.forecast_layout(), clock,
                             rng=random.Random(rng.random()), valid_prob=1.0 if busy else 0.5)
    sink = StreamSink(dut, "o", measurement_layout(params.router.solver), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    dut.cfg.value = pack(engine_config_layout(params), _indexed(cfg[0]))
    await reset(dut)
    feeder = cocotb.start_soon(forecasts.send(prime_fc + fc))
    await ClockCycles(dut.clk, 2 * params.cameras)     # the first forecast row is there
    columns = [_indexed(c) for s in row_sets for c in row_set_columns(params, s)]
    await rows.send(columns)
    # clean forecasts at full rate: one column per clock, the forecast never late
    await check_output(dut, params, rows, sink, expected, skip,
                       steady=busy and forecast == "clean")
    feeder.kill()

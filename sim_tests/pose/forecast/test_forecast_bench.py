"""Runs the forecast's cocotb bench on a real closed loop (``emulator.pipeline.run``,
stereo20 cut to 32 rows, the papers' motion, delay 1 row): on Verilator its three
frames (96 rows, 1,920 camera transfers), on Icarus its first 12 rows; with RUN_SLOW=1
also six frames of 64 rows at delay 2 on Verilator. The case is built once (about 20 s)
and kept under build/forecast_stimulus."""

import os
import pickle

import pytest

from hdl.pose.forecast import Forecast
from emulator.hdl_sim.runner import run_cocotb

from sim_tests.pose.forecast.stimulus import CACHE, closed_loop_case

SLOW = bool(os.environ.get("RUN_SLOW"))


def _run(sim, rows, frames=3, count=None, delay=1):
    case = closed_loop_case(rows=rows, frames=frames, delay=delay)
    path = CACHE / f"bench_r{rows}_f{frames}_d{delay}.pkl"
    with open(path, "wb") as f:
        pickle.dump(case, f)
    dut = Forecast(case["params"], case["coefficients"], case["row_coefficients"])
    count = len(case["requests"]) if count is None else count
    print(f"forecast bench: {count} rows of stereo20 cut to {rows} rows, delay {delay}, "
          f"latency {dut.latency} clocks, row {dut.row_clocks} clocks")
    run_cocotb(dut, name="forecast", tag=f"r{rows}_d{delay}", sim=sim,
               test_module="sim_tests.pose.forecast.forecast_bench",
               extra_env={"FORECAST_CASE": str(path), "FORECAST_ROWS": str(count),
                          "FORECAST_ROW_CLOCKS": str(dut.row_clocks)})


def test_forecast_verilator_closed_loop():
    _run("verilator", 32)


def test_forecast_icarus_closed_loop():
    _run("icarus", 32, count=12)


@pytest.mark.skipif(not SLOW, reason="the longer closed loop runs with RUN_SLOW=1")
def test_forecast_verilator_long_closed_loop():
    _run("verilator", 64, frames=6, delay=2)

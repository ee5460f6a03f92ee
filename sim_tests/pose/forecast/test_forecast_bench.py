"""Runs the forecast's cocotb bench. On Verilator: a real closed loop
(``emulator.pipeline.run``, stereo20 cut to 32 rows, the papers' motion, delay 1 row),
its three frames (96 rows, 1,920 camera transfers); with RUN_SLOW=1 also six frames of
64 rows at delay 2. On Icarus (which simulates the 20-camera block at about 30 clocks
per second): the small random case of two cameras, 12 rows. The closed loop is built
once (about 20 s) and kept under build/forecast_stimulus."""

import os
import pickle

import pytest

from hdl.pose.forecast import Forecast
from emulator.hdl_sim.runner import run_cocotb

from sim_tests.pose.forecast.stimulus import CACHE, closed_loop_case, random_case

SLOW = bool(os.environ.get("RUN_SLOW"))


def _run(sim, case, tag):
    path = CACHE / f"bench_{tag}.pkl"
    CACHE.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        pickle.dump(case, f)
    dut = Forecast(case["params"], case["coefficients"], case["row_coefficients"])
    count = len(case["requests"])
    print(f"forecast bench {tag}: {count} rows, delay {case['params'].loop_delay_rows}, "
          f"latency {dut.latency} clocks, row {dut.row_clocks} clocks")
    run_cocotb(dut, name="forecast", tag=tag, sim=sim,
               test_module="sim_tests.pose.forecast.forecast_bench",
               extra_env={"FORECAST_CASE": str(path), "FORECAST_ROWS": str(count),
                          "FORECAST_ROW_CLOCKS": str(dut.row_clocks)})


def test_forecast_verilator_closed_loop():
    _run("verilator", closed_loop_case(rows=32), "stereo20_r32")


def test_forecast_icarus_small_random():
    seed = int(os.environ.get("SEED", "7"))
    print(f"SEED={seed}")
    _run("icarus", random_case(seed, rows=12), "small")


@pytest.mark.skipif(not SLOW, reason="the longer closed loop runs with RUN_SLOW=1")
def test_forecast_verilator_long_closed_loop():
    _run("verilator", closed_loop_case(rows=64, frames=6, delay=2), "stereo20_r64_d2")

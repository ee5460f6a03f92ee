"""The camera front end at full rate for the benchmark (``emulator/benches/camera.py``):
pixels per clock per camera, the latency from a row's last pixel at the pins to its last
pixel out of the aligner, and the skew error; written to ``$ROWTRACK_FIGURES``."""

import json
import os
import random

import cocotb

from emulator.hdl_sim.camera_harness import (SYS_PS, FrontEndRun, Scenario, all_rows,
                                             check_rows, check_skews, latencies)
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.dvp import DvpTiming


@cocotb.test(skip=not os.environ.get("ROWTRACK_FIGURES"))
async def performance(dut):
    """Full rate, PCLK as fast as the system clock: pixels per clock per camera and the
    latency from a row's last pixel at the pins to its last pixel out of the aligner."""
    params = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    n = params.n_cameras
    width = params.max_width
    timing = DvpTiming(width=width, height=4, hblank=8)
    periods = tuple([SYS_PS] * n)
    phases = tuple(1_001 + 2_222 * k for k in range(n))
    frame = timing.frame_pclks + 40
    run = FrontEndRun(dut, params, Scenario(
        n_frames=2, timing=timing, periods_ps=periods, phases_ps=phases,
        delays=tuple(k % 3 for k in range(n)), period=frame, skew_threshold=100,
        align_timeout=200), rng)
    await run.run()
    run.check_model()
    sets = run.sets()
    check_rows(run, sets, all_rows(run))
    rates = []
    for s in sets:
        first = min(lane["first_cycle"] for lane in s["lanes"].values())
        rates.append(width / (s["last_cycle"] - first + 1))
    figures = {"cameras": n, "width": width, "sets": len(sets),
               "px_per_clock": min(rates), "latency_clocks": max(latencies(run, sets)),
               "skew_error_clocks": check_skews(run, range(2))["write"]}
    dut._log.info(f"performance: {figures}")
    path = os.environ.get("ROWTRACK_FIGURES")
    if path:
        with open(path, "w") as f:
            json.dump(figures, f)

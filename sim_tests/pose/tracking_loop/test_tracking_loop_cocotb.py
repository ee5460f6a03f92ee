"""Runs the tracking loop's cocotb bench on a real closed loop (stereo20 cut to pairs 0, 1
and 4) with the default information gain: on Verilator 32 rows, three frames (96 rows,
2,304 measurements); on Icarus 8 rows, three frames with a restart strobed in frame 0
(the model restarted before frame 1). With RUN_SLOW=1 also the scalar gain (Verilator 32
rows × 3 frames, Icarus 8 × 2 and the restart case), the information gain's 8 × 2 on
Icarus, and 64 rows, three frames at loop delay 2.
The case is built once (a few seconds) and kept under build/."""

import os
import pickle

import pytest

from emulator.hdl_sim.runner import run_cocotb
from hdl.pose.tracking_loop import TrackingLoop

from sim_tests.pose.tracking_loop.stimulus import CACHE, closed_loop_case


def _run(sim, case, tag):
    path = CACHE / f"bench_{tag}.pkl"
    CACHE.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        pickle.dump(case, f)
    dut = TrackingLoop(case["params"], case["stage"], case["coefficients"],
                       case["row_coefficients"], case["solver_store"], track_stream=True)
    print(f"tracking loop bench {tag}: {len(case['expected'])} rows, "
          f"{len(case['inputs'])} measurements, delay {case['params'].loop_delay_rows}")
    run_cocotb(dut, name="tracking_loop", tag=tag, sim=sim,
               test_module="sim_tests.pose.tracking_loop.tracking_loop_bench",
               extra_env={"LOOP_CASE": str(path)})


SLOW = pytest.mark.skipif(not os.environ.get("RUN_SLOW"),
                          reason="the scalar gain's and the longer loop runs with RUN_SLOW=1")


def test_tracking_loop_verilator_information_gain():
    _run("verilator", closed_loop_case(rows=32, frames=3, gain="information"),
         "p014_r32_f3_information")


def test_tracking_loop_icarus_information_gain_restart():
    _run("icarus", closed_loop_case(rows=8, frames=3, restart=1, gain="information"),
         "p014_r8_f3_restart1_information")


@SLOW
def test_tracking_loop_verilator_closed_loop():
    _run("verilator", closed_loop_case(rows=32, frames=3), "p014_r32_f3")


@SLOW
def test_tracking_loop_icarus_small():
    _run("icarus", closed_loop_case(rows=8, frames=2), "p014_r8_f2")


@SLOW
def test_tracking_loop_icarus_restart():
    _run("icarus", closed_loop_case(rows=8, frames=3, restart=1), "p014_r8_f3_restart1")


@SLOW
def test_tracking_loop_icarus_information_gain():
    _run("icarus", closed_loop_case(rows=8, frames=2, gain="information"),
         "p014_r8_f2_information")


@SLOW
def test_tracking_loop_verilator_long_delay_2():
    _run("verilator", closed_loop_case(rows=64, frames=3, delay=2), "p014_r64_f3_d2")

"""Runs the pose solver's cocotb bench: the random mix on Verilator in frame order
(300 rows: 4.7 frames of the case's 64 rows, so every row slot's pose is read back)
and on Icarus in random order (slots repeat, some back to back); the simulated
sequences (stereo8, radial4) and the long mixes only with RUN_SLOW=1 (their Verilator
builds take minutes; the Amaranth-simulator tests cover those cases by default). With
RUN_SLOW=1 the Verilator runs total 12,000 rows."""

import os

import pytest

from hdl.pose_solver import PoseSolver
from emulator.hdl_sim.runner import run_cocotb

from sim_tests.pose.pose_solver.stimulus import build_case

SLOW = bool(os.environ.get("RUN_SLOW"))
#: Rows per traffic mode: (default, RUN_SLOW).
ROWS = {"random": (300, 4000), "stereo8": (150, 1000), "radial4": (150, 1000)}
ICARUS_ROWS = 20


def _run(case, sim, rows, framed=False):
    params, coefficients, _ = build_case(case)
    if framed:
        assert rows >= 3 * params.rows, "at least three frames of rows"
    run_cocotb(PoseSolver(params, coefficients), name="pose_solver", tag=case, sim=sim,
               test_module="sim_tests.pose.pose_solver.pose_solver_bench",
               extra_env={"POSE_CASE": case, "POSE_ROWS": str(rows),
                          "POSE_FRAMED": str(int(framed))})


def test_pose_solver_verilator_random():
    _run("random", "verilator", ROWS["random"][SLOW], framed=True)


@pytest.mark.skipif(not SLOW, reason="simulated-sequence cases run with RUN_SLOW=1")
@pytest.mark.parametrize("case", ["stereo8", "radial4"])
def test_pose_solver_verilator_sequences(case):
    _run(case, "verilator", ROWS[case][SLOW])


def test_pose_solver_icarus():
    _run("random", "icarus", ICARUS_ROWS)

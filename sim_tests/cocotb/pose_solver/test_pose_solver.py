"""Runs the pose solver's cocotb bench: every case on Verilator, the random case on
Icarus too. RUN_SLOW=1 sends thousands of rows per case (the ≥ 10,000-row regression)."""

import os

import pytest

from hdl.pose_solver import PoseSolver
from sim_tests.common.cocotb_runner import run_cocotb

from .stimulus import build_case

#: Rows per traffic mode: (default, RUN_SLOW).
ROWS = {"random": (300, 3000), "stereo8": (150, 1000), "radial4": (150, 1000)}
ICARUS_ROWS = 20


def _run(case, sim, rows):
    params, coefficients, _ = build_case(case)
    run_cocotb(PoseSolver(params, coefficients), name="pose_solver", tag=case, sim=sim,
               test_module="sim_tests.cocotb.pose_solver.pose_solver_bench",
               extra_env={"POSE_CASE": case, "POSE_ROWS": str(rows)})


@pytest.mark.parametrize("case", sorted(ROWS))
def test_pose_solver_verilator(case):
    _run(case, "verilator", ROWS[case][1 if os.environ.get("RUN_SLOW") else 0])


def test_pose_solver_icarus():
    _run("random", "icarus", ICARUS_ROWS)

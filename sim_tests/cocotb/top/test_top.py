"""Runs the top-level cocotb bench (registers, cameras, solver, UART, PS FIFO) on a
small build of RowtrackTop: two cameras and the pose solver's ``random`` coefficient
case. Icarus in the default suite: Verilator's C++ build of this design alone takes
about two minutes on the project machines, while Icarus runs the whole bench in about
half a minute; Verilator with ``RUN_SLOW=1``."""

import os

import pytest

from hdl.camera_input import CameraParams
from hdl.pose_packet import PoseOutputParams
from hdl.top import RowtrackTop, TopParams, solver_source
from sim_tests.cocotb.pose_solver.stimulus import build_case
from sim_tests.cocotb.top.top_bench import SOLVER_CASE
from sim_tests.common.cocotb_runner import run_cocotb


def bench_params():
    solver, _, _ = build_case(SOLVER_CASE)
    camera = CameraParams(n_cameras=2, max_width=16, max_height=solver.rows, frame_bits=8,
                          count_bits=8, buffer_depth=128, row_queue_depth=4)
    return TopParams(camera=camera, solver=solver,
                     pose_output=PoseOutputParams(source=solver_source(solver), fifo_depth=64))


@pytest.mark.parametrize("sim", [
    pytest.param("verilator", marks=pytest.mark.skipif(not os.environ.get("RUN_SLOW"),
                                                       reason="long build: set RUN_SLOW=1")),
    "icarus",
])
def test_top_cocotb(sim):
    run_cocotb(RowtrackTop(bench_params()), name="rowtrack_top", sim=sim,
               test_module="sim_tests.cocotb.top.top_bench")

"""Runs the top-level cocotb bench (registers, cameras into the measurement engine) on a
small build of RowtrackTop: one stereo pair of 256-pixel cameras (the narrowest the
lanes accept), eight rows. Icarus in the default suite; Verilator's C++ build of the
whole top takes minutes, so it runs with ``RUN_SLOW=1``. The pose path is the
co-simulated slice (``sim_tests/unit/test_top_cosim.py``)."""

import os

import pytest

from hdl.camera_input import CameraParams
from hdl.top import RowtrackTop, TopParams
from sim_tests.common.cocotb_runner import run_cocotb


def bench_params():
    camera = CameraParams(max_width=256, max_height=8, frame_bits=8, count_bits=8,
                          buffer_depth=256, row_queue_depth=4)
    return TopParams.for_pairs(((0, 1),), camera=camera)


@pytest.mark.parametrize("sim", [
    pytest.param("verilator", marks=pytest.mark.skipif(not os.environ.get("RUN_SLOW"),
                                                       reason="long build: set RUN_SLOW=1")),
    "icarus",
])
def test_top_cocotb(sim):
    run_cocotb(RowtrackTop(bench_params()), name="rowtrack_top", sim=sim,
               test_module="sim_tests.cocotb.top.top_bench")

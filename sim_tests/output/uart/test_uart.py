"""Runs the pose-link cocotb bench (UART line decoded, compared with the emulator's
packets byte for byte) on both simulators."""

import pytest

from hdl.output.link import PoseLink
from hdl.top_params import TopParams
from emulator.hdl_sim.runner import run_cocotb


@pytest.mark.parametrize("sim", ["verilator", "icarus"])
def test_pose_link_cocotb(sim):
    run_cocotb(PoseLink(TopParams()), name="pose_link", sim=sim,
               test_module="sim_tests.output.uart.uart_bench")

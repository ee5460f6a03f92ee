"""Runs the register-file cocotb bench (rowtrack's map) on both simulators."""

import pytest

from hdl.top import register_file
from hdl.top_params import TopParams
from emulator.hdl_sim.runner import run_cocotb


@pytest.mark.parametrize("sim", ["verilator", "icarus"])
def test_regs_cocotb(sim):
    run_cocotb(register_file(TopParams()), name="regs", sim=sim,
               test_module="sim_tests.bus.regs.regs_bench")

"""Runs the MAC cocotb bench on both simulators."""

import pytest

from hdl.pose.mac import MultiplyAccumulate
from hdl.pose.mac_params import MacParams
from hdl.fixed import Overflow, Rounding, SQ, UQ
from emulator.hdl_sim.runner import run_cocotb

CASES = {
    "default": MacParams(),
    "unsigned_wrap_floor": MacParams(a_fmt=UQ(4, 4), b_fmt=SQ(3, 5), acc_fmt=SQ(8, 9),
                                     out_fmt=SQ(6, 2), rounding=Rounding.FLOOR,
                                     overflow=Overflow.WRAP),
}


@pytest.mark.parametrize("sim", ["verilator", "icarus"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_mac_cocotb(sim, case):
    run_cocotb(MultiplyAccumulate(CASES[case]), name="mac", tag=case, sim=sim,
               test_module="sim_tests.pose.mac.mac_bench")


@pytest.mark.parametrize("sim, waveform", [("verilator", "dump.vcd"), ("icarus", "mac.fst")])
def test_waveforms_on_request(sim, waveform):
    """WAVES=1 (here: waves=True) leaves a GTKWave-readable file in the build directory."""
    results = run_cocotb(MultiplyAccumulate(), name="mac", tag="waves", sim=sim, waves=True,
                         test_module="sim_tests.pose.mac.mac_bench")
    path = results.parent / waveform
    assert path.exists() and path.stat().st_size > 0

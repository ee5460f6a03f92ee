"""The prior store's Verilog (Verilator, and Icarus in a shorter run) against the model:
:mod:`sim_tests.pose.prior_store.prior_store_bench`."""

from emulator.hdl_sim.runner import run_cocotb
from hdl.pose.prior_store import PriorStore

from sim_tests.pose.prior_stimulus import cut_stereo20

BENCH = "sim_tests.pose.prior_store.prior_store_bench"


def _store():
    # α = 0.07: a prior weight with a fraction, so every rounding of the update counts
    return PriorStore(cut_stereo20().forecast(motion_gain="information", alpha=0.07))


def test_prior_store_verilator():
    run_cocotb(_store(), name="prior_store", sim="verilator", test_module=BENCH,
               extra_env={"PRIOR_ROWS": "40"})


def test_prior_store_icarus():
    run_cocotb(_store(), name="prior_store", sim="icarus", test_module=BENCH,
               extra_env={"PRIOR_ROWS": "12"})

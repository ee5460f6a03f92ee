"""Runs the consistency stage's cocotb bench: random rows of the small stage on Verilator
(60 rows, scales started low and near the top) and on Icarus (12 rows)."""

import pytest

from emulator.hdl_sim.runner import run_cocotb
from hdl.measurement.consistency import ConsistencyStage

from sim_tests.measurement.consistency.stimulus import LARGE, SMALL


@pytest.mark.parametrize("case", ["SMALL", "LARGE"])
def test_consistency_verilator(case):
    params = {"SMALL": SMALL, "LARGE": LARGE}[case]
    run_cocotb(ConsistencyStage(params), name="consistency", tag=case, sim="verilator",
               test_module="sim_tests.measurement.consistency.consistency_bench",
               extra_env={"CONS_ROWS": "60"})


def test_consistency_icarus():
    run_cocotb(ConsistencyStage(SMALL), name="consistency", tag="SMALL", sim="icarus",
               test_module="sim_tests.measurement.consistency.consistency_bench",
               extra_env={"CONS_ROWS": "12"})

"""Runs the status unit's cocotb bench: random regime rows of the small unit on Verilator
(300 rows, with window changes and clears) and on Icarus (60 rows), and the records of a
closed-loop emulator run (stereo20 cut to 32 rows, 3 frames) on Verilator; and the row
counter's bench (200 random rows of verdicts on Verilator, 40 on Icarus)."""

import pickle

from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb
from golden.tracker_params import TrackerParams
from hdl.pose.status_params import StatusParams
from hdl.pose.row_counter import RowCounter
from hdl.pose.status_unit import StatusUnit

from sim_tests.pose.status_stimulus import SMALL, SOLVER

BENCH = "sim_tests.pose.status_unit.status_unit_bench"


def test_status_unit_verilator():
    run_cocotb(StatusUnit(SMALL, SOLVER), name="status_unit", tag="SMALL", sim="verilator",
               test_module=BENCH, extra_env={"STATUS_CASE": "SMALL", "STATUS_ROWS": "300"})


def test_status_unit_icarus():
    run_cocotb(StatusUnit(SMALL, SOLVER), name="status_unit", tag="SMALL", sim="icarus",
               test_module=BENCH, extra_env={"STATUS_CASE": "SMALL", "STATUS_ROWS": "60"})


def test_status_unit_real_run_verilator():
    from sim_tests.pose.status_runs import dataset, emulator_run, frame_rows
    data = dataset()
    config, records, rows = emulator_run(data)
    solver = config.router.solver
    params = StatusParams.for_tracker(TrackerParams(), slots=solver.slots,
                                      frame_rows=frame_rows(data), max_window=64)
    fields = [{name: records[name][k].tolist() for name in ("row", "time", "q", "p", "step")}
              for k in range(len(rows))]
    path = BUILD_ROOT / "status_unit-REAL" / "records.pkl"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps({"solver": solver, "records": fields, "rows": rows}))
    run_cocotb(StatusUnit(params, solver), name="status_unit", tag="REAL", sim="verilator",
               test_module=BENCH, extra_env={"STATUS_CASE": "REAL",
                                             "STATUS_RECORDS": str(path)})



def test_row_counter_verilator():
    run_cocotb(RowCounter(SMALL), name="row_counter", tag="SMALL", sim="verilator",
               test_module="sim_tests.pose.status_unit.row_counter_bench",
               extra_env={"COUNTER_ROWS": "200"})


def test_row_counter_icarus():
    run_cocotb(RowCounter(SMALL), name="row_counter", tag="SMALL", sim="icarus",
               test_module="sim_tests.pose.status_unit.row_counter_bench",
               extra_env={"COUNTER_ROWS": "40"})

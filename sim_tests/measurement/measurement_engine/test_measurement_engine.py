"""Runs the measurement-engine cocotb bench: a four-camera, two-pair engine with
256-pixel rows on Verilator (every variant) and Icarus (one variant), rows from the
golden simulator (dataset made once under build/)."""

import pytest

from hdl.measurement.engine import MeasurementEngine
from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb

from sim_tests.measurement.measurement_engine.stimulus import (engine_params, simulated_dataset,
                                                          small_rig)

BENCH = "sim_tests.measurement.measurement_engine.engine_bench"
#: Seed of the simulated scene (the bench's own randomness follows SEED).
DATASET_SEED = 1


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def dataset_path(rig):
    path = BUILD_ROOT / f"measurement_engine-dataset-{DATASET_SEED}.npz"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        simulated_dataset(rig, DATASET_SEED).save(path)
    return path


def test_engine_verilator(rig, dataset_path):
    run_cocotb(MeasurementEngine(engine_params(rig)), name="measurement_engine",
               tag="stereo4", sim="verilator", test_module=BENCH,
               extra_env={"ROWTRACK_ME_DATASET": str(dataset_path)})


def test_engine_icarus(rig, dataset_path):
    run_cocotb(MeasurementEngine(engine_params(rig)), name="measurement_engine",
               tag="stereo4", sim="icarus", test_module=BENCH,
               extra_env={"ROWTRACK_ME_DATASET": str(dataset_path)},
               testcase=["engine_matches_model/traffic=1/faults=True"])


def test_engine_shared_matchers_verilator(rig, dataset_path):
    """Two lanes per shift matcher (two temporal matchers, one stereo matcher): the
    same transfers as the model, bit for bit."""
    run_cocotb(MeasurementEngine(engine_params(rig).replace(matcher_ports=2)),
               name="measurement_engine", tag="stereo4-shared", sim="verilator",
               test_module=BENCH, extra_env={"ROWTRACK_ME_DATASET": str(dataset_path)})

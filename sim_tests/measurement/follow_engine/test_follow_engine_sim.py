"""Runs the closed-loop measurement-engine cocotb bench: four cameras in two pairs
(stereo20's first two), 256-pixel rows, 6 rows, K = 4, K_s = 2, cue fallback, on
Verilator (every variant) and Icarus (damaged forecasts with gaps), rows from the golden
simulator (dataset made once under build/)."""

import pytest

from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb
from hdl.measurement.engine import MeasurementEngine

from sim_tests.measurement.follow_engine.stimulus import follow_config
from sim_tests.measurement.measurement_engine.stimulus import simulated_dataset, small_rig

BENCH = "sim_tests.measurement.follow_engine.follow_bench"
#: Seed of the simulated scene (the bench's own randomness follows SEED).
DATASET_SEED = 1


@pytest.fixture(scope="module")
def dataset_path():
    path = BUILD_ROOT / f"follow_engine-dataset-{DATASET_SEED}.npz"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        simulated_dataset(small_rig(), DATASET_SEED).save(path)
    return path


def _run(sim, dataset_path, **kwargs):
    _, params = follow_config()
    run_cocotb(MeasurementEngine(params), name="follow_engine", tag="stereo4", sim=sim,
               test_module=BENCH, extra_env={"ROWTRACK_FE_DATASET": str(dataset_path)},
               **kwargs)


def test_follow_engine_verilator(dataset_path):
    _run("verilator", dataset_path)


def test_follow_engine_icarus(dataset_path):
    _run("icarus", dataset_path,
         testcase=["follow_engine_matches_model/traffic=1/forecast=damaged"])

"""Runs the row-descriptor cocotb benches: the temporal lane on Verilator and Icarus,
the stereo lane on Verilator. Rows come from seeded textures, injected faults, and the
golden simulator's dataset."""

import pytest

from golden.descriptor import STEREO_MATCH, MatchParams
from hdl.row_descriptor import RowDescriptor, StereoRowDescriptor
from hdl.descriptor.params import RowDescriptorParams
from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb

from emulator.hdl_sim.row_stimulus import simulator_dataset

#: 160-pixel rows, 4 rows per frame, 2 segments; 240-pixel stereo rows (window [10, 70]).
TEMPORAL = RowDescriptorParams(width=160, height=4, centre_range=4,
                               match=MatchParams(segments=2))
STEREO = RowDescriptorParams(width=240, height=3, centre_range=4, match=STEREO_MATCH)


@pytest.fixture(scope="module")
def dataset_path():
    return simulator_dataset(BUILD_ROOT / "row_descriptor-yaw-dataset.npz")


@pytest.mark.parametrize("sim", ["verilator", "icarus"])
def test_temporal_lane_cocotb(sim, dataset_path):
    run_cocotb(RowDescriptor(TEMPORAL), name="row_descriptor", sim=sim,
               test_module="sim_tests.descriptor.row_descriptor.temporal_bench",
               extra_env={"ROWTRACK_RD_DATASET": str(dataset_path)})


def test_stereo_lane_cocotb():
    run_cocotb(StereoRowDescriptor(STEREO), name="stereo_row_descriptor", sim="verilator",
               test_module="sim_tests.descriptor.row_descriptor.stereo_bench")

"""Runs the row-descriptor cocotb benches: the temporal lane on Verilator and Icarus,
the following temporal lane (ring store) on Verilator and, smaller, Icarus, the stereo
lane on Verilator. Rows come from seeded textures, injected faults, the golden
simulator's dataset, and a closed-loop emulator run of the stereo20 rig."""

import numpy as np
import pytest

from golden.descriptor import STEREO_MATCH, MatchParams
from hdl.row_descriptor import RowDescriptor, StereoRowDescriptor
from hdl.descriptor.params import RowDescriptorParams
from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb

from emulator.hdl_sim.row_stimulus import simulator_dataset
from emulator.row_descriptor import TemporalLaneModel
from emulator.descriptor.framer import FramedRow
from sim_tests.descriptor.row_descriptor.closed_loop import closed_loop_stimulus, loop_lane

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


@pytest.fixture(scope="module")
def loop_path():
    return closed_loop_stimulus(BUILD_ROOT / "row_descriptor-closed-loop-segment-rows.npz")


def test_the_bench_rows_are_the_closed_loops(loop_path):
    """The following lane model, fed the saved camera rows with the loop's centres and
    source rows, gives the pipeline's own measurements of that camera: the bench plays
    what the closed loop did."""
    lane, loop = loop_lane(loop_path), np.load(loop_path)
    frames, height = loop["pixels"].shape[:2]
    expected = [dict(zip(loop["fields"].tolist(), m.tolist())) for m in loop["expected"]]
    rows = [FramedRow(pixels=loop["pixels"][f, y].astype(np.int64),
                      camera=int(loop["camera"]), frame=f, row=y,
                      t_first=expected[(f * height + y) * lane.segments]["t_first"],
                      centre=int(loop["centre"][f * height + y]), bad=False, padded=False)
                 for f in range(frames) for y in range(height)]
    got = TemporalLaneModel(lane, follow=True).process_rows(rows, loop["source"].tolist())
    assert got == expected
    assert (np.arange(frames * height)[:, None] % height - loop["source"] > 0).any()


@pytest.mark.parametrize("sim", ["verilator", "icarus"])
def test_following_lane_cocotb(sim, loop_path):
    """Verilator: the loop's 640-pixel, 32-row lane with D = 2 (d = 3 is served, d = 4
    is not: the loop asks for both). Icarus: 160 middle columns of the first 8 rows,
    2 segments, D = 1."""
    lane = loop_lane(loop_path).replace(max_row_displacement=2)
    if sim == "icarus":
        lane = lane.replace(width=160, height=8, centre_range=8, max_row_displacement=1,
                            match=MatchParams(segments=2))
    run_cocotb(RowDescriptor(lane, follow=True), name="followed_row_descriptor", sim=sim,
               test_module="sim_tests.descriptor.row_descriptor.followed_bench",
               extra_env={"ROWTRACK_RD_LOOP": str(loop_path)})

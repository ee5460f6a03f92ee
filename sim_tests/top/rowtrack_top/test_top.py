"""Runs the top-level cocotb bench (registers, cameras into the measurement engine) on a
small build of RowtrackTop: one stereo pair of 256-pixel cameras (the narrowest the
lanes accept), eight rows. Icarus in the default suite; Verilator's C++ build of the
whole top takes minutes, so it runs with ``RUN_SLOW=1``. The pose path is the
co-simulated slice (``sim_tests/top/test_top_cosim.py``)."""

import os

import numpy as np
import pytest

from hdl.front_end.params import CameraParams
from hdl.top import RowtrackTop
from hdl.top_params import TopParams
from emulator.hdl_sim.runner import run_cocotb


def bench_params():
    camera = CameraParams(max_width=256, max_height=8, frame_bits=8, count_bits=8,
                          buffer_depth=256, row_queue_depth=4)
    return TopParams.for_pairs(((0, 1),), camera=camera)


@pytest.mark.parametrize("sim", [
    pytest.param("verilator", marks=pytest.mark.skipif(not os.environ.get("RUN_SLOW"),
                                                       reason="long build: set RUN_SLOW=1")),
    "icarus",
])
def test_top_cocotb(sim):
    run_cocotb(RowtrackTop(bench_params()), name="rowtrack_top", sim=sim,
               test_module="sim_tests.top.rowtrack_top.top_bench")


# --- the co-simulated slice ------------------------------------------------------------

#: The tiny slice of the default suite: three stereo pairs of stereo20 (no two pairs
#: observe all six degrees of freedom, so a smaller slice solves no row), rows of 640
#: pixels, two frames (the first has no temporal reference) of two rows.
SLICE = {"cameras": 6, "frames": 2, "rows": 2}


def tiny_dataset(seed):
    """The slice's cameras of stereo20 cut to 16 rows, two frames at 120 fps (only the
    cameras the slice uses are rendered)."""
    from emulator.cosim import slice_rig
    from golden.rig import preset
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    rows = 16
    rig = preset("stereo20").replace_cameras(height=rows, cy=(rows - 1) / 2,
                                             t_r=1 / (120 * rows))
    rig, _ = slice_rig(rig, SLICE["cameras"])
    return simulate(rig, default_scene_spec(seed), make_trajectory("paper"),
                    SLICE["frames"] / 120, seed=seed)


@pytest.mark.parametrize("sim", [
    pytest.param("verilator", marks=pytest.mark.skipif(not os.environ.get("RUN_SLOW"),
                                                       reason="long build: set RUN_SLOW=1")),
    "icarus",
])
def test_cosim_slice_is_bit_exact(sim, tmp_path):
    """The open-loop top (the Arty's build): HDL pose records (PS FIFO and UART) equal the
    emulator's for the row sets the HDL front end produced, records were produced and
    rows were solved. ``rowtrack run`` co-simulates the closed-loop top instead
    (``test_run.py``), so this is the default suite's co-simulation of the open-loop
    one."""
    from emulator.cosim import cosim_slice
    seed = int(os.environ.get("SEED", "1"))
    print(f"SEED={seed}")
    result = cosim_slice(tiny_dataset(seed), **SLICE, sim=sim, seed=seed,
                         build_dir=tmp_path, progress=True)
    print(f"{result.row_sets} row sets, {len(result.records['row'])} records, "
          f"{result.clocks} clocks in {result.wall_s:.1f} s ({result.cycles_per_s:.0f} "
          f"cycles/s), {result.clocks_per_row_set:.0f} clocks per row set, latency "
          f"{result.latency_clocks} clocks")
    assert result.row_sets == SLICE["frames"] * SLICE["rows"]
    assert len(result.records["row"]) == result.row_sets, "a record per row set"
    assert result.mismatches == 0, result.first_mismatch
    assert result.uart_packets_match
    assert np.any(result.records["flags"] == 0), "no row was solved"
    assert result.latency_clocks > 0

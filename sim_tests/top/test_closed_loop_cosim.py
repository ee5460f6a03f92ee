"""The whole closed-loop top (issue 16) co-simulated against the emulator's closed loop,
bit for bit (:func:`emulator.cosim_loop.closed_loop_cosim`): stereo8 cut to a few rows,
every camera's rows played on the DVP pins, the PS starting the loop over AXI, every
pose record read from the PS FIFO (flags with the status bits) and every solver record
(step and pose) compared with :func:`emulator.pipeline.run`'s closed loop.

The Verilator case (24 rows × 3 frames: two whole frames of solved rows) takes minutes:
``RUN_SLOW=1``. The default suite runs a smaller case on Icarus.
"""

import os

import numpy as np
import pytest

from golden.rig import preset
from emulator.cosim_loop import cut_rig

SEED = int(os.environ.get("SEED", "1"))


def _dataset(rows, frames, seed=SEED):
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    rig = cut_rig(preset("stereo8"), rows)
    return simulate(rig, default_scene_spec(seed), make_trajectory("paper"),
                    frames / rig.cameras[0].fps, seed=seed)


def test_the_cut_rig_keeps_a_whole_number_of_row_periods_per_frame():
    from hdl.pipeline_config import PipelineConfig
    for rows in (24, 32):
        config = PipelineConfig.for_rig(cut_rig(preset("stereo8"), rows), closed_loop=True,
                                        stereo_segments=4)
        assert config.frame_rows == pytest.approx(rows * 600 / 480, abs=1e-9)
        assert config.top.consistency.frame_rows == int(config.frame_rows)


def _check(result, frames, rows):
    print(f"SEED={SEED}: {len(result.records['row'])} records ({result.solved} solved), "
          f"{result.mismatches} FIFO + {result.solver_mismatches} solver mismatches "
          f"({result.first_mismatch}); latency {result.latency_clocks} clocks; forecast "
          f"lead {np.nanmin(result.forecast_lead_clocks)}…"
          f"{np.nanmax(result.forecast_lead_clocks)} clocks; engine stalls "
          f"{result.engine_stall_clocks} clocks; {result.clocks} clocks in "
          f"{result.wall_s:.0f} s; {result.status}")
    assert result.rows_match, "the HDL's row sets are not the dataset's rows"
    assert result.row_sets == frames * rows
    assert len(result.records["row"]) == frames * rows
    assert len(result.solver["row"]) == frames * rows
    assert result.mismatches == 0 and result.solver_mismatches == 0, result.first_mismatch
    # every solved row of frames 1 on had its step compared
    assert result.solved >= (frames - 1) * rows // 2
    assert np.all(result.forecast_lead_clocks > 0), "a row set waited for its forecast"
    assert result.status["loop.counters"]["mismatched"] == 0
    for k in range(8):
        assert result.status[f"camera.inputs[{k}]"]["dropped_rows"] == 0


@pytest.mark.skipif(not os.environ.get("RUN_SLOW"), reason="minutes on Verilator: RUN_SLOW=1")
def test_closed_loop_top_equals_the_emulator_on_verilator():
    from emulator.cosim_loop import closed_loop_cosim
    rows, frames = 24, 3
    result = closed_loop_cosim(_dataset(rows, frames), frames=frames, sim="verilator",
                               seed=SEED, build_dir="build/cosim_loop_verilator")
    _check(result, frames, rows)

"""Runs the cue mapper's cocotb bench: the cues stereo20's stereo lanes measured on real
simulated rows (K = K_s = 8, the hardware path's map, its ten pairs in one mapper as the
router builds it) and random cues at the formats' extremes on Verilator (the board
top's map, K = K_s = 4, four pairs); random ones on Icarus with K = 4, K_s = 2 and one
pair, and with K = K_s = 2 and two pairs (both with fewer items per pass than pipeline
stages: a pass waits for the previous pass's results)."""

import dataclasses
import os
import pickle

import pytest

from golden.descriptor import STEREO_MATCH, MatchParams
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory
from hdl.descriptor.params import RowDescriptorParams
from hdl.fixed import UQ
from hdl.measurement.cue_map import CueMapper
from hdl.measurement.cue_map_params import CueMap
from hdl.top import board_config
from emulator.hardware_path import hardware_config
from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb

from sim_tests.measurement.cue_map.stimulus import real_rows

BENCH = "sim_tests.measurement.cue_map.cue_map_bench"
#: stereo20 cut to its 16 middle rows, two frames at 120 fps.
ROWS, FRAMES = 16, 2


def _real_config(seed):
    rig = preset("stereo20").replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                             t_r=1 / (120 * ROWS))
    dataset = simulate(rig, default_scene_spec(seed), make_trajectory("paper"),
                       FRAMES / 120, seed=seed)
    return hardware_config(rig), dataset


def test_cue_map_real_rows_verilator():
    seed = int(os.environ.get("SEED", "1"))
    print(f"SEED={seed}")
    config, dataset = _real_config(seed)
    rows = real_rows(config, dataset, FRAMES)
    usable = sum(c is not None for row in rows for c in row)
    partial = sum(any(c is None for c in row) and any(c is not None for c in row)
                  for row in rows)
    print(f"{len(rows)} rows of {config.router.stereo.segments} cues, {usable} usable, "
          f"{partial} rows partly usable")
    assert usable and partial, "the real rows must exercise usable and missing cues"
    path = BUILD_ROOT / "cue_map-real.pkl"
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        pickle.dump(rows, f)
    run_cocotb(CueMapper(config.router.cue_map, len(config.router.pairs)), name="cue_map",
               tag="real",
               sim="verilator", seed=seed, test_module=BENCH,
               extra_env={"CUE_MAP_STIMULUS": str(path)})


def test_cue_map_random_verilator():
    router = board_config(preset("stereo8-board")).top.engine.router
    run_cocotb(CueMapper(router.cue_map, len(router.pairs)), name="cue_map", tag="random",
               sim="verilator", test_module=BENCH, extra_env={"CUE_MAP_ROWS": "300"})


@pytest.mark.parametrize("segments, stereo_segments, pairs", [(4, 2, 1), (2, 2, 2)])
def test_cue_map_random_icarus(segments, stereo_segments, pairs):
    lane = RowDescriptorParams(width=320, height=8, match=MatchParams(segments=segments))
    stereo = RowDescriptorParams(width=320, height=8, match=dataclasses.replace(
        STEREO_MATCH, segments=stereo_segments))
    cue_map = CueMap.for_lanes(lane, stereo, UQ(5, 4))
    assert CueMapper.gap_of(cue_map, pairs) > 0, "each case must leave a gap after a pass"
    run_cocotb(CueMapper(cue_map, pairs), name="cue_map",
               tag=f"small{segments}{stereo_segments}{pairs}", sim="icarus",
               test_module=BENCH, extra_env={"CUE_MAP_ROWS": "60"})


@pytest.mark.parametrize("pairs, error", [(0, ValueError), (1.5, TypeError)])
def test_cue_mapper_rejects_bad_pairs(pairs, error):
    config, _ = _real_config(1)
    with pytest.raises(error, match="pairs"):
        CueMapper(config.router.cue_map, pairs)

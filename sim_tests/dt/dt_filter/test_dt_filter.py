"""Runs the domain-transform filter's cocotb bench (Verilator, and Icarus for one case).

The frames are written here: a synthetic scene with edges and texture as PNG files
(8-bit grey guide, 8-bit and 16-bit value images) and a short rolling-shutter simulator
dataset. ``RUN_SLOW=1`` adds the 640-pixel-wide build.
"""

import os

import cv2
import numpy as np
import pytest

from golden.dt_scenes import make_scene
from hdl.dt.filter import DomainTransformFilter
from hdl.dt.rounds import DomainTransformRounds
from hdl.dt.params import DtFilterParams
from emulator.hdl_sim.runner import run_cocotb

SLOW = pytest.mark.skipif(not os.environ.get("RUN_SLOW"), reason="set RUN_SLOW=1")

CASES = {
    "8bit": DtFilterParams(width=64, window=4),
    "16bit": DtFilterParams(width=48, window=3, value_bits=16),
    "vga_rows": DtFilterParams(width=640, window=8),
    "3rounds": DtFilterParams(width=48, window=3),
}
#: Rounds per case (the golden default schedule is three rounds); 1 unless listed.
ROUNDS = {"3rounds": 3}


def _scene_images(directory):
    """A guide PNG and matching 8- and 16-bit value PNGs; returns the pair list."""
    scene = make_scene(48, 640, seed=9)
    guide, depth = directory / "scene_guide.png", directory / "scene_depth16.png"
    grey = directory / "scene_grey.png"
    cv2.imwrite(str(guide), scene.guide)
    cv2.imwrite(str(depth), np.rint(scene.depth * 257).astype(np.uint16))
    cv2.imwrite(str(grey), cv2.cvtColor(scene.guide, cv2.COLOR_BGR2GRAY))
    return [f"{guide},{grey}", f"{guide},{depth}"]


def _simulator_dataset(directory):
    """Two frames of a short simulated sequence (one per camera)."""
    from golden.dataset import Dataset
    from golden.rig import load_rig
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import SpeedProfile, make_trajectory
    path = directory / "radial4.npz"
    trajectory = make_trajectory("head", seed=9, linear_speed=SpeedProfile.parse("1.4", "v"),
                                 angular_speed=SpeedProfile.parse("2.0", "w"))
    simulate(load_rig("radial4"), default_scene_spec(9), trajectory, 0.004, seed=9).save(path)
    assert Dataset.load(path).cameras[0].rows.shape[1:] == (480, 640)
    return path


@pytest.fixture(scope="module")
def frame_sources(tmp_path_factory):
    directory = tmp_path_factory.mktemp("dt_filter_frames")  # one per test worker
    return {"DT_IMAGE_PAIRS": os.pathsep.join(_scene_images(directory)),
            "DT_DATASET": str(_simulator_dataset(directory))}


@pytest.mark.parametrize("sim,case", [("verilator", "8bit"), ("verilator", "16bit"),
                                      ("icarus", "8bit"), ("verilator", "3rounds"),
                                      pytest.param("verilator", "vga_rows", marks=SLOW)])
def test_dt_filter_cocotb(sim, case, frame_sources):
    rounds = ROUNDS.get(case, 1)
    env = dict(frame_sources, DT_ROWS="6" if case == "vga_rows" else "12", DT_ROUNDS=str(rounds))
    dut = (DomainTransformFilter(CASES[case]) if rounds == 1
           else DomainTransformRounds(CASES[case], rounds))
    run_cocotb(dut, name="dt_filter", tag=case, sim=sim,
               test_module="sim_tests.dt.dt_filter.dt_filter_bench", extra_env=env)

"""Runs the camera front-end cocotb bench: every scenario on Verilator, the clean,
fault and dataset scenarios on Icarus. The cameras of the dataset scenario play a small
dataset written by ``rowtrack simulate``."""

import subprocess
import sys

import pytest

from hdl.front_end.params import CameraParams
from hdl.front_end.camera_sync import CameraFrontEnd
from emulator.hdl_sim.runner import BUILD_ROOT, run_cocotb

BENCH = "sim_tests.front_end.camera.front_end_bench"

#: Three cameras with short rows: every mechanism, small enough for the default suite.
PARAMS = CameraParams(n_cameras=3, max_width=16, max_height=8, frame_bits=8,
                      timestamp_bits=24, timer_bits=12, skew_bits=10, count_bits=8,
                      buffer_depth=128, row_queue_depth=4)

#: A three-camera rig small enough to simulate in a second.
TINY_RIG = """\
name: tiny3
allow_unobservable: true
defaults: {width: 24, height: 8, fps: 120, vfov_deg: 60}
cameras:
  - {yaw_deg: 0}
  - {yaw_deg: 90, roll_deg: 90}
  - {yaw_deg: 180, pitch_deg: 30}
"""


@pytest.fixture(scope="module")
def dataset():
    """Three frames of the tiny rig from the golden simulator."""
    work = BUILD_ROOT / "camera_front-dataset"
    work.mkdir(parents=True, exist_ok=True)
    rig = work / "tiny3.yaml"
    rig.write_text(TINY_RIG)
    path = work / "tiny3.npz"
    subprocess.run([sys.executable, "-m", "emulator.cli", "simulate", "--rig", str(rig),
                    "--duration", "0.025", "--no-progress", "-o", str(path)],
                   check=True, capture_output=True)
    return path


def test_front_end_verilator(dataset):
    run_cocotb(CameraFrontEnd(PARAMS), name="camera_front", tag="small", sim="verilator",
               test_module=BENCH, extra_env={"ROWTRACK_DATASET": str(dataset)})


def test_front_end_icarus(dataset):
    run_cocotb(CameraFrontEnd(PARAMS), name="camera_front", tag="small", sim="icarus",
               test_module=BENCH, extra_env={"ROWTRACK_DATASET": str(dataset)},
               testcase=["clean_cluster/traffic=1", "faults_flagged", "dataset_playback"])

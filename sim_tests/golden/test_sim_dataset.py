"""golden/ dataset file and ``rowtrack simulate``."""

import subprocess
import sys

import numpy as np
import pytest

from emulator.cli import main
from golden.dataset import Dataset
from golden.rig import preset, rig_from_config
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory

SEED = 3


@pytest.fixture(scope="module")
def dataset():
    rig = preset("radial4").replace_cameras(noise_sigma=1.5)
    return simulate(rig, default_scene_spec(SEED), make_trajectory("head", seed=SEED), 2 / 120,
                    seed=SEED)


def test_dataset_round_trips_through_npz(dataset, tmp_path):
    dataset.save(tmp_path / "d.npz")
    loaded = Dataset.load(tmp_path / "d.npz")
    assert loaded.rig == dataset.rig
    assert loaded.info["seed"] == SEED and loaded.info["trajectory"]["kind"] == "head"
    assert loaded.info["observability"]["rank"] == 6
    for a, b in zip(loaded.cameras, dataset.cameras):
        for name in ("rows", "time", "rotation", "position", "velocity", "angular_velocity"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    with np.load(tmp_path / "d.npz") as raw:  # calibration readable without golden/
        np.testing.assert_allclose(raw["K"][2], dataset.rig.cameras[2].K)
        np.testing.assert_allclose(raw["timing"][0], [120, 1 / 57600, 0, 0])
        assert raw["cam3_rows"].shape == (2, 480, 640) and raw["cam3_rows"].dtype == np.uint8


def test_rows_carry_their_time_and_ground_truth_pose(dataset):
    trajectory = make_trajectory("head", seed=SEED)
    rec = dataset.cameras[1]
    assert rec.rows.shape == (2, 480, 640)
    cam = dataset.rig.cameras[1]
    np.testing.assert_allclose(rec.time[1], 1 / 120 + np.arange(480) * cam.t_r)
    rotation, position = trajectory.pose(rec.time.ravel())
    np.testing.assert_allclose(rec.rotation.reshape(-1, 3, 3), rotation)
    np.testing.assert_allclose(rec.position.reshape(-1, 3), position)
    cam_rotation, cam_centre = dataset.camera_pose(1)
    np.testing.assert_allclose(cam_rotation[0, 5], rotation[5] @ cam.R)
    np.testing.assert_allclose(cam_centre[0, 5], rotation[5] @ cam.c + position[5])


def test_row_order_is_readout_order(dataset):
    order = dataset.row_order()
    assert len(order) == 4 * 2 * 480
    assert np.all(np.diff(order["time"]) >= 0)
    first = order[:4]
    assert sorted(first["camera"]) == [0, 1, 2, 3] and np.all(first["row"] == 0)


def test_trigger_offsets_and_jitter_are_in_the_row_times():
    config = preset("radial4").to_config()
    config["cameras"][1]["trigger_offset"] = 1e-3
    config["cameras"][2]["trigger_jitter"] = 2e-5
    rig = rig_from_config(config)
    data = simulate(rig, default_scene_spec(SEED), make_trajectory("static"), 3 / 120, seed=SEED)
    t_r = rig.cameras[0].t_r
    np.testing.assert_allclose(data.cameras[1].time[:, 0], 1e-3 + np.arange(3) / 120)
    jitter = data.cameras[2].time[:, 0] - np.arange(3) / 120
    assert np.all(jitter != 0) and np.all(np.abs(jitter) < 1e-4)
    np.testing.assert_allclose(np.diff(data.cameras[2].time, axis=1), t_r)  # a frame is rigid


def test_load_rejects_other_files(tmp_path):
    np.savez(tmp_path / "x.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match="is not a rowtrack-rs-dataset file"):
        Dataset.load(tmp_path / "x.npz")


def rowtrack(*args):
    return subprocess.run([sys.executable, "-m", "emulator.cli", *args], capture_output=True,
                          text=True)


def test_simulate_command_writes_a_dataset_with_a_progress_bar(tmp_path):
    out = tmp_path / "data.npz"
    result = rowtrack("simulate", "--rig", "radial4", "--lens", "OV5647", "--duration",
                      str(1 / 120), "--seed", "1", "--motion", "paper", "--noise", "2", "-o", str(out))
    assert result.returncode == 0, result.stderr
    assert "simulate radial4" in result.stderr and "100%" in result.stderr
    assert "rank 6/6" in result.stdout
    data = Dataset.load(out)
    assert data.rig.cameras[0].k1 == -0.31 and data.rig.cameras[0].noise_sigma == 2
    assert data.info["trajectory"]["kind"] == "paper"


FLAT_RIG = """
cameras:
  - {yaw_deg: 0}
  - {yaw_deg: 90, position: [0.1, 0, 0]}
"""


@pytest.mark.parametrize("args, message", [
    (["--rig", "stereo30"], "rig must be one of stereo20, radial4, radial6"),
    (["--duration", "0"], "--duration must be positive, not 0.0"),
    (["--motion", "paper", "--duration", "4"], "comes within .* of a surface"),
    (["--speed", "fast"], "--speed must be a number or time:value pairs"),
    (["--texture", "missing.png"], "texture 'missing.png' cannot be read as an image"),
    (["--rig", "FLAT"], r"rig 'flat' cannot observe .*Ty.*allow_unobservable"),
])
def test_simulate_command_rejects_bad_input_cleanly(tmp_path, args, message):
    (tmp_path / "flat.yaml").write_text(FLAT_RIG)
    args = [str(tmp_path / "flat.yaml") if a == "FLAT" else a for a in args]
    result = rowtrack("simulate", *args, "-o", str(tmp_path / "x.npz"))
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    import re
    assert re.search(message, result.stderr), result.stderr
    assert not (tmp_path / "x.npz").exists()


def test_unobservable_rig_is_accepted_with_the_flag(tmp_path):
    (tmp_path / "flat.yaml").write_text(FLAT_RIG)
    out = tmp_path / "flat.npz"
    assert main(["simulate", "--rig", str(tmp_path / "flat.yaml"), "--allow-unobservable",
                 "--duration", str(1 / 120), "--no-progress", "-o", str(out)]) == 0
    data = Dataset.load(out)
    assert "Ty" in data.info["observability"]["unobservable"]
    assert data.rig.allow_unobservable

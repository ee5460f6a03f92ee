"""``rowtrack track``: metrics (table and JSON), trajectory file, plot, and bad input."""

import json
import os

import numpy as np
import pytest

from emulator.cli import main
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.trajectory import make_trajectory

SEED = int(os.environ.get("SEED", "2"))


@pytest.fixture(scope="module")
def data_file(tmp_path_factory):
    """Three frames of the 64-row stereo20 strip (see test_tracker.py) with noise."""
    rig = preset("stereo20").replace_cameras(height=64, cy=31.5, t_r=1 / (120 * 64),
                                             noise_sigma=2.0)
    print(f"SEED={SEED}")
    dataset = simulate(rig, default_scene_spec(SEED), make_trajectory("paper"), 3 / 120,
                       seed=SEED)
    path = tmp_path_factory.mktemp("track") / "strip.npz"
    dataset.save(path)
    return path


def test_json_metrics_trajectory_and_plot(data_file, capsys):
    assert main(["track", str(data_file), "--json", "--no-progress"]) == 0
    metrics = json.loads(capsys.readouterr().out)
    for key in ("rms_t_cm", "rms_r_rad"):
        assert len(metrics[key]) == 3 and all(0 <= v < 0.1 for v in metrics[key])
    for key in ("render_px", "update_fraction", "cond_median", "cond_max"):
        assert isinstance(metrics[key], float)
    assert metrics["update_fraction"] > 0.9 and metrics["rows"] == 128
    assert metrics["status"] in ("tracking", "degraded") and metrics["lost_at_ms"] is None
    assert metrics["tracking_fraction"] + metrics["degraded_fraction"] == 1.0
    with np.load(data_file.with_suffix(".track.npz")) as out:
        assert out["quaternion"].shape == (192, 4) and out["position"].shape == (192, 3)
        assert np.allclose(np.linalg.norm(out["quaternion"], axis=1), 1)
        assert out["tracked"].sum() == 128
        assert json.loads(str(out["metrics"]))["rms_t_cm"] == metrics["rms_t_cm"]
        assert json.loads(str(out["params"]))["reference"] == "homography"
        assert out["status"].shape == (192,) and not out["drifted"].any()
    png = data_file.with_suffix(".track.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 20000


def test_table_output_and_chosen_paths(data_file, tmp_path, capsys):
    out = tmp_path / "t.npz"
    assert main(["track", str(data_file), "--reference", "previous", "--no-plot", "-o",
                 str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "per-row Y RMS" in text and "render error" in text and str(out) in text
    assert "TRACKING LOST" not in text and "\nstatus " in text
    assert out.exists() and not (tmp_path / "t.png").exists()


@pytest.mark.parametrize("args, message", [
    (["missing.npz"], "does not exist"),
    (["{data}", "--segments", "0"], "segments must be an integer at least 1"),
    (["{data}", "--loop-delay-rows", "-2"], "loop_delay_rows must be an integer at least 0"),
    (["{data}", "--depth", "oracle", "-o", "/no/such/dir/t.npz"], "does not exist"),
])
def test_bad_input_is_a_clear_error(data_file, args, message, capsys):
    args = [a.format(data=data_file) for a in args]
    assert main(["track", *args, "--no-progress"]) == 2
    assert message in capsys.readouterr().err


def test_a_file_that_is_not_a_dataset(tmp_path, capsys):
    path = tmp_path / "x.npz"
    np.savez(path, a=np.zeros(3))
    assert main(["track", str(path)]) == 2
    assert "cannot read dataset" in capsys.readouterr().err


def test_stereo_depth_needs_pairs(tmp_path, capsys):
    rig = preset("radial4").replace_cameras(width=64, height=16, cx=31.5, cy=7.5,
                                            t_r=1 / (120 * 16))
    dataset = simulate(rig, default_scene_spec(SEED), make_trajectory("static"), 2 / 120,
                       seed=SEED)
    dataset.save(tmp_path / "r.npz")
    assert main(["track", str(tmp_path / "r.npz"), "--depth", "stereo"]) == 2
    assert "needs rectified stereo pairs" in capsys.readouterr().err


def test_a_lost_run_exits_non_zero_and_marks_its_trajectory(tmp_path, capsys):
    """The last of three frames of the 32-row strip blanked (a covered lens): the run
    says when tracking was lost, in one stderr line, exits 1, and the trajectory file
    marks the rows as lost and drifted."""
    rig = preset("stereo20").replace_cameras(height=32, cy=15.5, t_r=1 / (120 * 32))
    dataset = simulate(rig, default_scene_spec(SEED), make_trajectory("paper"), 3 / 120,
                       seed=SEED)
    for recording in dataset.cameras:
        recording.rows[2] = 128
    path = tmp_path / "blank.npz"
    dataset.save(path)
    assert main(["track", str(path), "--no-plot", "--no-progress"]) == 1
    captured = capsys.readouterr()
    assert captured.out.startswith("TRACKING LOST: tracking lost at ")
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rowtrack track: tracking lost at ")
    lost_ms = float(lines[0].split("lost at ")[1].split(" ms")[0])
    assert 2000 / 120 <= lost_ms < 3000 / 120
    with np.load(path.with_suffix(".track.npz")) as out:
        assert out["status"].max() == 2 and out["drifted"][-1]
        assert json.loads(str(out["metrics"]))["status"] == "lost"
    assert main(["track", str(path), "--no-plot", "--no-progress", "--json"]) == 1
    metrics = json.loads(capsys.readouterr().out)
    assert metrics["status"] == "lost" and abs(metrics["lost_at_ms"] - lost_ms) <= 0.05

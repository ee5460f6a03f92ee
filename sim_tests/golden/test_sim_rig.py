"""golden/ rigs: presets, observability check, YAML/TOML configs."""

import numpy as np
import pytest

from golden.camera import Camera
from golden.lens import LENS_PRESETS
from golden.observability import row_constraints
from golden.depth import stereo_pairs
from golden.rig import (PRESETS, Rig, load_rig, preset, rig_from_config, scaled_rig,
                        slot_conditions)
from golden.rotations import orientation_ypr


#: Presets whose synchronized stack is well conditioned; stereo8's is not (below).
SYNCHRONIZED_OK = sorted(set(PRESETS) - {"stereo8", "stereo8-board"})


@pytest.mark.parametrize("name", SYNCHRONIZED_OK)
@pytest.mark.parametrize("lens", [None, "OV5647", "Zed", "SCam2"])
def test_presets_observe_all_six_degrees_of_freedom(name, lens):
    rig = preset(name, lens)
    assert rig.observability.rank == 6
    assert rig.observability.unobservable == ()
    assert rig.observability.condition < 100


def test_stereo20_matches_the_paper_setup():
    rig = preset("stereo20")
    assert len(rig.cameras) == 20
    for left, right in zip(rig.cameras[::2], rig.cameras[1::2]):
        assert left.width == 640 and left.height == 480 and left.fps == 120
        assert left.height * left.fps == 57600  # rows per second
        np.testing.assert_allclose(left.R, right.R)  # rectified pair
        baseline = right.c - left.c
        assert np.linalg.norm(baseline) == pytest.approx(0.10)
        np.testing.assert_allclose(baseline / 0.10, left.R[:, 0], atol=1e-12)  # along rows
    directions = {tuple(np.round(c.R[:, 2], 6)) for c in rig.cameras}
    assert len(directions) == 10  # pairs face different directions
    vertical_rows = [c for c in rig.cameras if abs(c.R[1, 0]) > 0.5]
    assert vertical_rows, "some pairs must have rows that are not horizontal"


@pytest.mark.parametrize("name, fps", [("stereo8", 100), ("stereo8-board", 120)])
def test_stereo8_is_the_issue_18_rig(name, fps):
    rig = preset(name)
    assert len(rig.cameras) == 8 and len(stereo_pairs(rig)) == 4
    forward = {k: rig.cameras[2 * k].R[:, 2] for k in range(4)}
    up = -np.array([0.0, 1.0, 0.0])                           # rig y points down
    assert np.degrees(np.arcsin(forward[0] @ up)) == pytest.approx(30)     # front: up 30°
    assert np.degrees(np.arcsin(forward[2] @ up)) == pytest.approx(-30)    # back: down 30°
    assert forward[1] @ [-1, 0, 0] == pytest.approx(1) and forward[3] @ [1, 0, 0] == pytest.approx(1)
    for k in range(4):
        left, right = rig.cameras[2 * k], rig.cameras[2 * k + 1]
        assert np.linalg.norm(right.c - left.c) == pytest.approx(0.08)
        assert np.linalg.norm((left.c + right.c) / 2) == pytest.approx(0.10)
        assert left.trigger_offset == right.trigger_offset == pytest.approx(0.5e-3 * k)
        assert left.fps == fps and left.height * left.t_r * fps == pytest.approx(0.8)
        assert (left.width, left.height) == (640, 480)
        assert 2 * np.degrees(np.arctan(240 / left.fy)) == pytest.approx(60)
        rolled = abs(left.R[1, 0]) > 0.5                      # rows run vertically
        assert rolled == (k in (1, 3))


@pytest.mark.parametrize("name", ["stereo8", "stereo8-board"])
def test_stereo8_condition_needs_the_trigger_stagger(name):
    """Synchronized, the middle rows leave θx nearly unseen (rows through the side
    pairs' image centres are blind to their roll): condition ~1e4. With the 0.5 ms
    stagger the slots where all eight cameras read stay below 51; the slots around the
    frame gap, with fewer cameras, are ill-conditioned (issue 18's frame boundary)."""
    rig = preset(name)
    assert rig.observability.rank == 6 and rig.observability.condition > 1000
    for k in (4, 8):
        conditions, reading = slot_conditions(rig, k)
        full = reading == 8
        assert conditions[full].max() < 60
        assert np.mean(conditions[~full] > 100) > 0.5


def test_scaled_rig_keeps_field_of_view_and_timing():
    rig = preset("stereo8")
    small = scaled_rig(rig, 0.5)
    assert small.name == "stereo8@0.5"
    for a, b in zip(rig.cameras, small.cameras):
        assert (b.width, b.height) == (320, 240) and b.fx == pytest.approx(a.fx / 2)
        assert (b.cx, b.cy) == (159.5, 119.5)
        assert b.t_r * b.height == pytest.approx(a.t_r * a.height)
        assert b.trigger_offset == a.trigger_offset
    with pytest.raises(ValueError, match="factor must be a number greater than 0 and at most 1"):
        scaled_rig(rig, 1.5)


def test_radial_presets_roll_even_cameras():
    for name, count in (("radial4", 4), ("radial6", 6)):
        rig = preset(name)
        assert len(rig.cameras) == count
        assert (rig.cameras[0].k1, rig.cameras[0].k2) == LENS_PRESETS["GoPro4"]
        for k, cam in enumerate(rig.cameras):
            row_direction = cam.R[:, 0]  # camera x axis in the rig
            rolled = abs(row_direction[1]) > 0.9  # rows run vertically
            assert rolled == (k % 2 == 1), (name, k)


def _horizontal_rig(allow=False):
    cameras = tuple(Camera.from_fov(name=f"c{k}", rotation=orientation_ypr(yaw, 0, 0),
                                    position=0.1 * orientation_ypr(yaw, 0, 0)[:, 2])
                    for k, yaw in enumerate((0, 90, 180, 270)))
    return Rig(name="flat", cameras=cameras, row_points=8, allow_unobservable=allow)


def test_rig_with_only_horizontal_rows_cannot_see_vertical_translation():
    with pytest.raises(ValueError, match=r"rig 'flat' cannot observe .*\bTy\b.* \(rank [0-5] "
                                         r"of 6, .*allow_unobservable"):
        _horizontal_rig()
    rig = _horizontal_rig(allow=True)
    assert "Ty" in rig.observability.unobservable
    assert rig.observability.rank < 6 and rig.observability.condition > 1e6


def test_linear_row_constraint_predicts_the_measured_shift():
    """A·Y/Z equals the shift along the row of a point under a small rig motion."""
    rng = np.random.default_rng(7)
    cam = preset("radial4").cameras[1]
    depth, row = 2.5, 100
    a = row_constraints(cam, row, 8, depth)
    px = (np.arange(8) + 0.5) * cam.width / 8 - 0.5
    xu, yu = cam.pixel_to_normalized(px, np.full(8, float(row)))
    x_rig = (cam.R @ (depth * np.stack([xu, yu, np.ones(8)]))).T + cam.c
    for _ in range(3):
        y = rng.normal(size=6) * 1e-6
        moved = x_rig - y[:3] - np.cross(y[3:], x_rig)  # the rig moves by (T, θ)
        before = cam.project((x_rig - cam.c) @ cam.R)
        after = cam.project((moved - cam.c) @ cam.R)
        ahead = cam.pixel_to_normalized(px + 0.5, np.full(8, float(row)))
        behind = cam.pixel_to_normalized(px - 0.5, np.full(8, float(row)))
        tangent = np.stack(ahead) - np.stack(behind)
        tangent /= np.linalg.norm(tangent, axis=0)
        shift = np.stack(cam.pixel_to_normalized(*after.T)) - np.stack(cam.pixel_to_normalized(*before.T))
        measured = np.sum(tangent * shift, axis=0) * depth
        np.testing.assert_allclose(a @ y, measured, rtol=1e-3, atol=1e-12)


YAML_RIG = """
name: mine
row_points: 4
defaults: {width: 320, height: 240, vfov_deg: 70, lens: Zed, fps: 100, t_e: 0.002}
cameras:
  - {position: [0.05, 0, 0], yaw_deg: -30, trigger_offset: 0.001}
  - {position: [-0.05, 0, 0], yaw_deg: 30, roll_deg: 90, trigger_jitter: 0.00001}
  - {position: [0, -0.05, 0], pitch_deg: 60, k1: 0.1, k2: 0.0, lens: null, noise_sigma: 2}
"""

TOML_RIG = """
name = "mine"
row_points = 4
[defaults]
width = 320
height = 240
vfov_deg = 70
lens = "Zed"
fps = 100
t_e = 0.002
[[cameras]]
position = [0.05, 0, 0]
yaw_deg = -30
trigger_offset = 0.001
[[cameras]]
position = [-0.05, 0, 0]
yaw_deg = 30
roll_deg = 90
trigger_jitter = 0.00001
[[cameras]]
position = [0, -0.05, 0]
pitch_deg = 60
k1 = 0.1
k2 = 0.0
noise_sigma = 2
"""


def test_yaml_and_toml_rigs_load_the_same(tmp_path):
    (tmp_path / "r.yaml").write_text(YAML_RIG)
    toml = TOML_RIG.replace('lens = "Zed"\nfps', 'fps')  # TOML has no null: no default lens
    toml = toml.replace("[defaults]", "[defaults]\nk1 = -0.17\nk2 = 0.023")
    toml = toml.replace("k1 = 0.1\nk2 = 0.0", "k1 = 0.1\nk2 = 0.0")
    (tmp_path / "r.toml").write_text(toml)
    from_yaml = load_rig(tmp_path / "r.yaml")
    from_toml = load_rig(tmp_path / "r.toml")
    assert from_yaml == from_toml
    cam0, cam1, cam2 = from_yaml.cameras
    assert (cam0.width, cam0.height, cam0.fps, cam0.t_e) == (320, 240, 100, 0.002)
    assert cam0.height * cam0.t_r + cam0.t_e == pytest.approx(0.01)
    assert (cam0.k1, cam0.k2) == LENS_PRESETS["Zed"] and (cam2.k1, cam2.k2) == (0.1, 0.0)
    assert cam1.trigger_jitter == 1e-5 and cam2.noise_sigma == 2
    assert from_yaml.row_points == 4 and from_yaml.observability.rank == 6
    assert rig_from_config(from_yaml.to_config()) == from_yaml


@pytest.mark.parametrize("text, message", [
    ("cameras: [{positon: [0, 0, 0]}]", r"unknown key 'positon' in camera 0 of .*r.yaml"),
    ("cameras: []", r"cameras in .* must be a non-empty list"),
    ("cameras: [{fps: 120, t_r: 0.00002}]", r"camera 0 of .*: infeasible timing: fps, t_r"),
    ("cameras: [{lens: Fisheye}]", r"lens in camera 0 of .* must be one of"),
    ("bogus: 1\ncameras: [{}]", r"unknown key 'bogus' in .*r.yaml"),
])
def test_bad_rig_files_name_the_problem(tmp_path, text, message):
    (tmp_path / "r.yaml").write_text(text)
    with pytest.raises(ValueError, match=message):
        load_rig(tmp_path / "r.yaml")


def test_unknown_rig_names_and_suffixes():
    with pytest.raises(ValueError, match="rig must be one of stereo20, radial4, radial6"):
        load_rig("stereo30")
    with pytest.raises(ValueError, match="lens applies to the preset rigs"):
        load_rig("x.yaml", lens="Zed")

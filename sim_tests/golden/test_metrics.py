"""golden.metrics: per-row Y errors, trajectory errors and the HMD rendering error, on
ground truth with known errors added (no rendering)."""

import math

import numpy as np
import pytest

from golden.metrics import evaluate, hmd_focal, render_error
from golden.rig import preset
from golden.rotations import exp_so3
from golden.tracker import TrackResult
from golden.tracker_motion import ground_truth_track
from golden.trajectory import make_trajectory
from sim_tests.golden.test_tracker_parts import short_sequence

FRAMES = 3


@pytest.fixture(scope="module")
def dataset():
    """Three frames of stereo20 cut down to 16 rows (only the ground truth is used)."""
    rig = preset("stereo20").replace_cameras(height=16, cy=7.5, t_r=1 / (120 * 16))
    return short_sequence(rig, make_trajectory("paper"), FRAMES)


def _result(dataset, rotations, positions):
    times = dataset.cameras[0].time.ravel()
    n = len(times)
    return TrackResult(times=times, rotations=rotations, positions=positions,
                       tracked=np.arange(n) >= 16, updated=np.ones(n, bool),
                       condition=np.full(n, 3.0), equations=np.full(n, 20),
                       camera_confidence=np.ones((n, 20)), motion=np.zeros((n, 6)),
                       forecast=np.zeros((n, 6)), measured=np.zeros((n, 6)),
                       linear_step=np.full((n, 6), np.nan), refined_step=np.full((n, 6), np.nan),
                       status=np.zeros(n, np.uint8), drifted=np.zeros(n, bool),
                       judged=np.zeros(n, int), outliers=np.zeros(n, int),
                       dropped_group=np.full(n, -1), partial=np.zeros(n, bool),
                       determinable=np.ones(n, bool), period=1 / 120, params={})


def test_display_focal_matches_the_stated_field_of_view():
    assert hmd_focal() == pytest.approx(540 / math.tan(math.radians(50)))
    assert hmd_focal() == pytest.approx(453.1, abs=0.05)


def test_render_error_of_a_yaw_and_of_a_sideways_offset():
    eye, zero = np.eye(3), np.zeros(3)
    assert render_error(eye, zero, eye, zero) == 0
    yaw = exp_so3(np.array([0.0, 0.01, 0.0]))      # turned 0.01 rad about the rig's y axis
    assert render_error(eye, zero, yaw, zero) == pytest.approx(hmd_focal() * math.tan(0.01))
    side = np.array([0.01, 0.0, 0.0])              # 1 cm to the right, point 1 m ahead
    assert render_error(eye, zero, eye, side) == pytest.approx(hmd_focal() * 0.01)


def test_perfect_estimate_has_no_error(dataset):
    times = dataset.cameras[0].time.ravel()
    rotations, positions = ground_truth_track(dataset).at(times)
    metrics = evaluate(_result(dataset, rotations, positions), dataset)
    for key in ("rms_t_cm", "rms_r_rad", "abs_t_cm", "abs_r_rad"):
        assert np.allclose(metrics[key], 0, atol=1e-9), key
    assert metrics["render_px"] < 1e-6 and metrics["rows"] == FRAMES * 16 - 16
    assert metrics["update_fraction"] == 1 and metrics["cond_max"] == 3.0


def test_constant_offset_shows_in_the_trajectory_not_in_the_per_row_motion(dataset):
    """An error made once (say, in the first frame) and carried along is drift, not a
    per-row estimation error."""
    times = dataset.cameras[0].time.ravel()
    rotations, positions = ground_truth_track(dataset).at(times)
    offset = exp_so3(np.array([0.0, 0.0, 0.002]))   # 2 mrad about the forward axis
    metrics = evaluate(_result(dataset, rotations @ offset, positions + [0.003, 0, 0]),
                       dataset)
    # a 2 mrad turned body frame sees the frame's 1.2 cm and 17 mrad of motion along
    # axes 2 mrad off: second-order errors only
    assert np.all(np.array(metrics["rms_t_cm"]) < 0.002 * 1.2 * 1.1)
    assert np.all(np.array(metrics["rms_r_rad"]) < 0.002 * 0.0175 * 1.1)
    assert np.allclose(metrics["abs_t_cm"], [0.3, 0, 0], atol=1e-9)
    assert np.allclose(metrics["abs_r_rad"], [0, 0, 0.002], atol=1e-9)
    assert metrics["render_px"] == pytest.approx(hmd_focal() * 0.003, rel=1e-3)


def test_a_wrong_step_in_one_frame_is_a_per_row_error(dataset):
    times = dataset.cameras[0].time.ravel()
    rotations, positions = ground_truth_track(dataset).at(times)
    positions = positions.copy()
    positions[32:] += [0.0, 0.0, 0.001]              # frame 2 stepped 1 mm too far up
    metrics = evaluate(_result(dataset, rotations, positions), dataset)
    # Y of frame 1's rows is right, Y of frame 2's rows is 1 mm off (world z = rig −y)
    assert metrics["rms_t_cm"][1] == pytest.approx(0.1 * math.sqrt(0.5), rel=1e-3)
    assert metrics["final_t_cm"] == pytest.approx([0.0, 0.0, 0.1])

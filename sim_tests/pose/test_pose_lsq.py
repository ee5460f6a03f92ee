"""golden.pose_lsq: the per-row linear system against exact projection, the solve, the
integration and the synthetic sequences."""

import math

import numpy as np
import pytest

from golden import pose_lsq as G
from golden.camera import Camera
from golden.rig import preset
from golden.rotations import exp_so3, orientation_ypr
from golden.trajectory import make_trajectory

SEED = 8


def _camera(lens=(0.0, 0.0), ypr=(0, 0, 0), position=(0, 0, 0)):
    return Camera.from_fov(k1=lens[0], k2=lens[1], rotation=orientation_ypr(*ypr),
                           position=position)


CAMERAS = {
    "pinhole_at_origin": _camera(),
    "pinhole_mounted": _camera(ypr=(30, -20, 90), position=(0.05, -0.02, 0.1)),
    "distorted_mounted": _camera(lens=(-0.27, 0.11), ypr=(-40, 15, 0), position=(-0.09, 0.02, -0.01)),
}


@pytest.mark.parametrize("axis", [0, 1], ids=["along-row", "across-rows"])
@pytest.mark.parametrize("name", sorted(CAMERAS))
def test_rows_match_finite_difference_projection(name, axis):
    """Each column of A is the derivative of the exact pixel-x (pixel-y) displacement."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(SEED)
    px, py = rng.uniform(0, cam.width - 1, 40), rng.uniform(0, cam.height - 1, 40)
    depth = rng.uniform(0.4, 6.0, 40)
    rows = G.design_rows(G.shift_coefficients(cam, px, py, axis=axis), 1 / depth)
    h = 1e-6
    for k in range(6):
        step = np.zeros(6)
        step[k] = h
        central = (G.project_shift(cam, px, py, depth, step, axis)
                   - G.project_shift(cam, px, py, depth, -step, axis)) / (2 * h)
        scale = np.linalg.norm(rows, axis=1)
        assert np.max(np.abs(central - rows[:, k]) / scale) < 1e-6, G.UNKNOWNS[k]


def test_translation_scales_with_inverse_depth_and_rotation_does_not():
    cam = CAMERAS["pinhole_at_origin"]
    coefficients = G.shift_coefficients(cam, [100.0], [50.0])
    near, far = G.design_rows(coefficients, [1 / 0.5]), G.design_rows(coefficients, [1 / 2.0])
    assert np.allclose(near[:, :3], 4 * far[:, :3])
    assert np.allclose(near[:, 3:], far[:, 3:])  # camera at the origin: a_C = 0
    assert np.allclose(coefficients.a_c, 0)


def test_cue_scale_folds_disparity_into_the_coefficients():
    cam = CAMERAS["pinhole_mounted"]
    depth, baseline = 1.7, 0.1
    disparity = cam.fx * baseline / depth
    by_depth = G.design_rows(G.shift_coefficients(cam, 300.0, 200.0), 1 / depth)
    by_disparity = G.design_rows(G.shift_coefficients(cam, 300.0, 200.0,
                                                      1 / (cam.fx * baseline)), disparity)
    assert np.allclose(by_depth, by_disparity)


def test_signs_of_a_camera_at_the_origin():
    """Moving right or turning right (about y, down) moves the image left."""
    cam = CAMERAS["pinhole_at_origin"]
    row = G.design_rows(G.shift_coefficients(cam, cam.cx, cam.cy), 1.0)
    assert row[0] == pytest.approx(-cam.fx)
    assert row[4] == pytest.approx(-cam.fx)


def test_a_bad_axis_is_named():
    with pytest.raises(ValueError, match="axis must be 0 or 1, not 2"):
        G.shift_coefficients(CAMERAS["pinhole_at_origin"], 1.0, 1.0, axis=2)


def test_table_round_trip_and_errors():
    coefficients = G.shift_coefficients(CAMERAS["distorted_mounted"], [1.0, 2.0], [3.0, 4.0])
    again = G.ShiftCoefficients.from_table(coefficients.table())
    assert np.array_equal(again.table(), coefficients.table())
    with pytest.raises(ValueError, match="9 coefficients"):
        G.ShiftCoefficients.from_table(np.zeros((2, 8)))
    with pytest.raises(ValueError, match="segments must be an integer at least 1, not 0"):
        G.segment_columns(640, 0)


def _random_system(rng, count=12):
    rows = rng.normal(0, 300, (count, 6))
    step = rng.normal(0, 1e-4, 6)
    return rows, step


def test_solve_recovers_the_step_of_consistent_shifts():
    rng = np.random.default_rng(SEED)
    rows, step = _random_system(rng)
    weights = rng.uniform(0.5, 2, len(rows))
    normal, rhs = G.normal_equations(rows, rows @ step, weights)
    solution = G.solve_normal(normal, rhs)
    assert solution.ok and np.allclose(solution.step, step, rtol=1e-9, atol=1e-15)


def test_weights_select_the_least_squares_solution():
    rng = np.random.default_rng(SEED)
    rows, step = _random_system(rng)
    shifts = rows @ step + rng.normal(0, 0.05, len(rows))
    weights = rng.uniform(0.5, 2, len(rows))
    solution = G.solve_normal(*G.normal_equations(rows, shifts, weights))
    root = np.sqrt(weights)[:, None]
    reference = np.linalg.lstsq(rows * root, shifts * root[:, 0], rcond=None)[0]
    assert np.allclose(solution.step, reference, rtol=1e-9)


def test_empty_and_singular_systems_give_no_step():
    rng = np.random.default_rng(SEED)
    rows, step = _random_system(rng)
    zero = G.solve_normal(*G.normal_equations(rows, rows @ step, np.zeros(len(rows))))
    assert not zero.ok and np.isinf(zero.condition) and np.all(zero.step == 0)
    rank4 = rows[:4]
    singular = G.solve_normal(*G.normal_equations(rank4, rank4 @ step, np.ones(4)))
    assert not singular.ok and np.all(singular.step == 0)


def test_condition_is_scale_free():
    rng = np.random.default_rng(SEED)
    rows, _ = _random_system(rng)
    normal, _ = G.normal_equations(rows, np.zeros(len(rows)), np.ones(len(rows)))
    units = np.diag([1e3, 1e-2, 5.0, 1.0, 1e4, 0.3])
    assert G.scaled_condition(units @ normal @ units) == pytest.approx(G.scaled_condition(normal))


def test_integration_composes_body_steps_exactly():
    rng = np.random.default_rng(SEED)
    rot_a, rot_b = exp_so3(rng.normal(0, 0.5, 3)), exp_so3(rng.normal(0, 0.5, 3))
    pos_a, pos_b = rng.normal(0, 1, 3), rng.normal(0, 1, 3)
    step = G.body_step(rot_a, pos_a, rot_b, pos_b)
    q, p = G.integrate(G.quat_from_matrix(rot_a), pos_a, step)
    assert np.allclose(G.quat_to_matrix(q), rot_b, atol=1e-12)
    assert np.allclose(p, pos_b, atol=1e-12)


@pytest.mark.parametrize("rig_name", ["stereo20", "radial4"])
def test_noise_free_sequence_is_tracked(rig_name):
    """Exact shifts of the papers' motion: the per-row solutions integrate to the true
    trajectory within the linearization error."""
    rig = preset(rig_name)
    scale = [1 / (c.fx * 0.1) for c in rig.cameras] if rig_name == "stereo20" else 1 / 64
    rows = G.simulate_rows(rig, make_trajectory("paper"), 0.01, cue_scale=scale,
                           rng=np.random.default_rng(SEED))
    coefficients = G.ShiftCoefficients.from_table(rows.table[rows.slot, rows.row[:, None]])
    solution = G.solve_step(coefficients, rows.cue, rows.shift, rows.weight)
    assert np.all(solution.ok)
    error = np.abs(solution.step - rows.true_step)
    assert np.max(error[:, :3]) < 1e-6 and np.max(error[:, 3:]) < 1e-6
    q, p = G.integrate_steps(*rows.start, solution.step)
    q_true, p_true = G.integrate_steps(*rows.start, rows.true_step)
    assert np.max(np.linalg.norm(p - p_true, axis=1)) < 1e-4
    angle = 2 * np.arcsin(np.minimum(1, np.linalg.norm(
        G.quat_multiply(q_true * [1, -1, -1, -1], q)[:, 1:], axis=1)))
    assert math.degrees(np.max(angle)) < 1e-3


@pytest.mark.parametrize("name", sorted(CAMERAS))
def test_both_axes_predict_the_trackers_reference_pixel(name):
    """``a·Y`` along and across rows is the current pixel minus the previous frame's pixel
    of the same point (``golden.tracker_geometry.reference_pixels``, which the tracker's
    window centre and followed row use), to first order in a small motion."""
    from golden.tracker_geometry import camera_poses, reference_pixels
    from golden.tracker_motion import compose
    cam = CAMERAS[name]
    row, columns, inverse_depth = 150, np.arange(20, 620, 40), 0.5
    motion = np.array([4e-3, -3e-3, 5e-3, 2e-3, -4e-3, 3e-3])
    rotation, position = compose(np.eye(3)[None], np.zeros((1, 3)), motion[None])
    vx, vy = reference_pixels(cam, cam.rays[row][columns][None],
                              np.full((1, len(columns)), inverse_depth), rotation, position,
                              np.eye(3)[None], camera_poses(cam, np.eye(3), np.zeros(3))[1])
    for axis, moved in ((0, columns - vx[0]), (1, row - vy[0])):
        linear = G.design_rows(G.shift_coefficients(cam, columns, row, axis=axis),
                               inverse_depth) @ motion
        assert np.max(np.abs(linear - moved)) < 0.05, axis     # pixels; motion ~ 1-3 px

"""golden/ trajectories: closed-form poses, consistent derivatives, speed profiles."""

import math

import numpy as np
import pytest

from golden.rotations import is_rotation
from golden.trajectory import MOTIONS, HeadMotion, SpeedProfile, make_trajectory


def _finite_difference(trajectory, t, dt=1e-6):
    """Central differences of position and rotation (world-frame angular velocity)."""
    r0, p0 = trajectory.pose(t - dt)
    r1, p1 = trajectory.pose(t + dt)
    delta = r1 @ np.swapaxes(r0, -1, -2)
    skew = (delta - np.swapaxes(delta, -1, -2)) / 2
    omega = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1) / (2 * dt)
    return (p1 - p0) / (2 * dt), omega


@pytest.mark.parametrize("motion", MOTIONS)
def test_velocities_are_the_derivatives_of_the_pose(motion):
    trajectory = make_trajectory(motion, seed=5)
    t = np.linspace(0, 1.0, 23)
    rotation, _ = trajectory.pose(t)
    assert all(is_rotation(r, 1e-9) for r in rotation)
    velocity, omega = trajectory.velocity(t)
    fd_velocity, fd_omega = _finite_difference(trajectory, t)
    np.testing.assert_allclose(velocity, fd_velocity, atol=1e-6)
    np.testing.assert_allclose(omega, fd_omega, atol=1e-6)


def test_papers_test_case_has_exact_speeds():
    trajectory = make_trajectory("paper")
    t = np.linspace(0, 0.5, 11)
    velocity, omega = trajectory.velocity(t)
    np.testing.assert_allclose(np.linalg.norm(velocity, axis=1), 1.4)
    np.testing.assert_allclose(np.degrees(np.linalg.norm(omega, axis=1)), 120)
    _, position = trajectory.pose(t)
    np.testing.assert_allclose(np.linalg.norm(position - position[0], axis=1), 1.4 * t)


def test_static_rotation_and_translation_cases():
    t = np.linspace(0, 0.3, 7)
    r, p = make_trajectory("static").pose(t)
    assert np.all(r == r[0]) and np.all(p == p[0])
    r, p = make_trajectory("rotation").pose(t)
    assert np.all(p == p[0]) and not np.allclose(r, r[0])
    r, p = make_trajectory("translation").pose(t)
    assert np.all(r == r[0]) and not np.allclose(p, p[0])


def test_speed_profile_integral_is_exact():
    profile = SpeedProfile.parse("0.05:0,0.1:1.4,0.2:0.7")
    t = np.linspace(-0.05, 0.4, 19)
    dense = [np.linspace(0, x, 40001) for x in t]
    numeric = np.array([np.trapezoid(profile.value(g), g) for g in dense])
    np.testing.assert_allclose(profile.integral(t), numeric, atol=1e-9)
    assert SpeedProfile.parse("1.4").value(3.0) == 1.4
    with pytest.raises(ValueError, match="speed profile times must increase strictly"):
        SpeedProfile.parse("0:1,0:2")
    with pytest.raises(ValueError, match="--speed must be a number or time:value pairs"):
        SpeedProfile.parse("fast", "--speed")


def test_speed_profile_drives_a_trajectory():
    ramp = SpeedProfile.parse("0:0,0.1:1.4")
    trajectory = make_trajectory("translation", linear_speed=ramp)
    velocity, _ = trajectory.velocity(np.array([0.0, 0.05, 0.2]))
    np.testing.assert_allclose(np.linalg.norm(velocity, axis=1), [0, 0.7, 1.4])


def test_head_motion_is_seeded_and_hits_its_rms_speeds():
    a, b, c = HeadMotion(seed=3), HeadMotion(seed=3), HeadMotion(seed=4)
    t = np.linspace(0, 2, 50)
    np.testing.assert_array_equal(a.pose(t)[1], b.pose(t)[1])
    assert not np.allclose(a.pose(t)[1], c.pose(t)[1])
    long = np.linspace(0, 400, 400001)
    velocity, omega = a.velocity(long)
    assert np.sqrt(np.mean(np.sum(velocity**2, axis=1))) == pytest.approx(1.4, rel=0.02)
    # RMS of r'(t) is the target; the angular velocity J_l(r)·r' differs slightly.
    assert math.degrees(np.sqrt(np.mean(np.sum(omega**2, axis=1)))) == pytest.approx(120, rel=0.1)
    r0, p0 = a.pose(0.0)
    np.testing.assert_allclose(p0[0], [0, 0, 1.6], atol=1e-12)

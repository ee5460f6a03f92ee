"""golden/ camera model: Brown lens and its inverse, rolling-shutter timing, parameters."""

import math

import numpy as np
import pytest

from golden.camera import Camera, focal_for_vfov
from golden.lens import LENS_PRESETS, distort, fold_radius, undistort


@pytest.mark.parametrize("lens", sorted(LENS_PRESETS))
def test_distortion_round_trip_over_the_whole_image(lens):
    """Every pixel (and points between pixels) survives undistort → distort and
    distort → undistort to within 1e-6 px."""
    cam = Camera.from_fov(lens=lens)
    rng = np.random.default_rng(4)
    xs, ys = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    xs = np.concatenate([xs.ravel(), rng.uniform(-0.5, cam.width - 0.5, 10000)])
    ys = np.concatenate([ys.ravel(), rng.uniform(-0.5, cam.height - 0.5, 10000)])
    xu, yu = cam.pixel_to_normalized(xs, ys)
    px, py = cam.normalized_to_pixel(xu, yu)
    assert np.max(np.hypot(px - xs, py - ys)) < 1e-6
    xd, yd = distort(xu, yu, cam.k1, cam.k2)
    xu2, yu2 = undistort(xd, yd, cam.k1, cam.k2)
    assert np.max(np.hypot(xu2 - xu, yu2 - yu)) * cam.fx < 1e-6


def test_distortion_matches_the_brown_model():
    xu, yu = np.array([0.3, -0.5]), np.array([0.2, 0.4])
    k1, k2 = LENS_PRESETS["GoPro4"]
    r2 = xu**2 + yu**2
    xd, yd = distort(xu, yu, k1, k2)
    np.testing.assert_allclose(xd, xu * (1 + k1 * r2 + k2 * r2**2))
    np.testing.assert_allclose(yd, yu * (1 + k1 * r2 + k2 * r2**2))


def test_folding_lens_is_rejected():
    k1, k2 = -0.6, 0.05  # folds at r_u ≈ 0.8
    r_fold = fold_radius(k1, k2)
    assert 0.5 < r_fold < 1.5
    rd_max = r_fold * (1 + k1 * r_fold**2 + k2 * r_fold**4)
    with pytest.raises(ValueError, match=r"folds over"):
        undistort(np.array([rd_max * 1.01]), np.array([0.0]), k1, k2)
    with pytest.raises(ValueError, match=r"lens k1=-0.6, k2=0.05 folds over inside the image"):
        Camera(fx=200, fy=200, cx=319.5, cy=239.5, k1=k1, k2=k2, t_r=1 / 57600)


def test_vertical_fov_is_true_through_the_lens():
    for lens in ("Pinhole", "OV5647", "SCam1"):
        cam = Camera.from_fov(vfov_deg=60, lens=lens)
        _, top = cam.pixel_to_normalized(cam.cx, -0.5)
        _, bottom = cam.pixel_to_normalized(cam.cx, cam.height - 0.5)
        assert math.degrees(math.atan(-top) + math.atan(bottom)) == pytest.approx(60, abs=1e-9)
    assert focal_for_vfov(60, 480) == pytest.approx(240 / math.tan(math.radians(30)))


def test_row_times_follow_the_thesis_formula():
    cam = Camera.from_fov(fps=120, t_e=1e-3, t_f=5e-4, trigger_offset=2e-3)
    assert cam.height * cam.t_r + cam.t_f + cam.t_e == pytest.approx(1 / 120, rel=1e-12)
    times = cam.row_times([0, 3], jitter=[0.0, 1e-5])
    assert times.shape == (2, cam.height)
    assert times[0, 0] == pytest.approx(2e-3)
    assert times[1, 7] == pytest.approx(2e-3 + 1e-5 + 7 * cam.t_r + 3 / 120)
    assert cam.frame_count(0.1) == 12  # frames starting at 2 ms + i/120 before 0.1 s


def test_infeasible_timing_names_the_parameters():
    with pytest.raises(ValueError, match=r"infeasible timing: fps, t_r, t_f, t_e must satisfy "
                                         r"1/fps = H·t_r \+ t_f \+ t_e \(H = height = 480\)"):
        Camera(fx=400, fy=400, cx=319.5, cy=239.5, fps=120, t_r=2e-5, t_e=1e-3)
    with pytest.raises(ValueError, match=r"infeasible timing: .* \(fps, t_f, t_e\)"):
        Camera.from_fov(fps=120, t_e=5e-3, t_f=4e-3)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"width": 0}, ValueError, "width must be an integer at least 1, not 0"),
    ({"fx": "400"}, TypeError, "fx must be a number, not '400'"),
    ({"t_e": -1e-3}, ValueError, "t_e must be a number at least 0, not -0.001"),
    ({"noise_sigma": -1}, ValueError, "noise_sigma must be a number at least 0, not -1"),
    ({"rotation": ((1, 0, 0), (0, 1, 0), (0, 0, -1))}, ValueError,
     "rotation must be a 3×3 proper rotation matrix"),
    ({"position": (0, 0)}, ValueError, r"position must be 3 finite numbers"),
    ({"trigger_offset": 0.01}, ValueError, r"trigger_offset must be less than 1/fps"),
    ({"exposure_samples": 4}, ValueError, r"exposure_samples 4 needs an exposure time t_e > 0"),
])
def test_bad_parameters_name_the_parameter(kwargs, error, message):
    base = dict(fx=400.0, fy=400.0, cx=319.5, cy=239.5, t_r=1 / 57600)
    with pytest.raises(error, match=message):
        Camera(**{**base, **kwargs})

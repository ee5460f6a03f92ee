"""golden/ simulator rendering: the issue's correctness tests.

Static rigs repeat, pure rotation matches the homography-predicted image, every RS row
is the global-shutter render at that row's time, stereo pairs see disparity f·b/Z.
"""

import math

import cv2
import numpy as np
import pytest
from scipy import ndimage

from golden.camera import Camera
from golden.render import Renderer
from golden.rig import Rig, preset
from golden.rotations import orientation_ypr
from golden.scene import Box, SceneSpec, build_scene, default_scene_spec
from golden.simulator import render_frames, schedule, sensor, simulate
from golden.trajectory import START_ROTATION, ScrewTrajectory, SpeedProfile, make_trajectory

SEED = 11


@pytest.fixture(scope="module")
def scene():
    return build_scene(default_scene_spec(SEED))


def _single_camera_rig(**camera):
    cam = Camera.from_fov(name="c", **camera)
    return Rig(name="one", cameras=(cam,), row_points=8, allow_unobservable=True)


def test_static_rig_renders_identical_frames():
    rig = preset("radial4")
    data = simulate(rig, default_scene_spec(SEED), make_trajectory("static"), 3 / 120, seed=SEED)
    for rec in data.cameras:
        assert rec.rows.shape[0] == 3
        assert np.array_equal(rec.rows[0], rec.rows[1]) and np.array_equal(rec.rows[0], rec.rows[2])
        assert rec.rows.std() > 20  # textured, not blank


def test_rolling_shutter_row_equals_global_shutter_render_at_its_time(scene):
    rig = preset("stereo20")
    trajectory = make_trajectory("paper")
    times = schedule(rig, 2 / 120, SEED)
    frames = {(k, i): rows for k, i, rows in render_frames(rig, scene, trajectory, times, SEED)}
    rng = np.random.default_rng(SEED)
    for k in (0, 7, 19):
        cam = rig.cameras[k]
        renderer = Renderer(scene, cam)
        for y in rng.integers(0, cam.height, 4):
            t = times[k][1, y]
            rotation, position = trajectory.pose(np.full(cam.height, t))
            global_shutter = sensor(renderer.render(rotation @ cam.R, rotation @ cam.c + position),
                                    0.0, 0)
            assert np.array_equal(frames[(k, 1)][y], global_shutter[y])
            # ... and the motion is large enough for rows of other times to differ.
            assert not np.array_equal(frames[(k, 1)][(y + 240) % 480], global_shutter[(y + 240) % 480])


def test_pure_rotation_matches_the_homography_prediction(scene):
    """Under pure rotation each RS row is the reference image warped by
    H = K R_refᵀ R(t_row) K⁻¹ (exact up to texture interpolation)."""
    rig = _single_camera_rig()
    cam = rig.cameras[0]
    trajectory = ScrewTrajectory(axis=(0.2, 0.3, 1.0), angular_speed=SpeedProfile.constant(
        math.radians(120)), kind="rotation")
    renderer = Renderer(scene, cam)
    r_ref, p_ref = trajectory.pose(np.zeros(cam.height))
    reference = renderer.render(r_ref @ cam.R, p_ref)
    times = cam.row_times([1])[0]
    rotation, position = trajectory.pose(times)
    np.testing.assert_allclose(position, p_ref)  # camera centre fixed
    rolling = renderer.render(rotation @ cam.R, position)

    def predict(row_rotations):
        """Warp ``reference`` with the per-row homographies of ``row_rotations``."""
        xs, ys = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
        rays = np.stack([(xs - cam.cx) / cam.fx, (ys - cam.cy) / cam.fy, np.ones_like(xs)], -1)
        relative = np.swapaxes(r_ref @ cam.R, -1, -2) @ row_rotations @ cam.R
        back = np.einsum("yij,yxj->yxi", relative, rays)
        mx = (cam.fx * back[..., 0] / back[..., 2] + cam.cx).astype(np.float32)
        my = (cam.fy * back[..., 1] / back[..., 2] + cam.cy).astype(np.float32)
        warped = cv2.remap(reference, mx, my, cv2.INTER_CUBIC)
        inside = (mx > 2) & (mx < cam.width - 3) & (my > 2) & (my < cam.height - 3)
        return warped, inside & (back[..., 2] > 0)

    warped, inside = predict(rotation)
    assert inside.mean() > 0.5
    error = np.abs(warped - rolling)[inside]
    # A global warp with the frame-start rotation (no rolling shutter) is clearly wrong.
    frame_start = np.repeat(rotation[:1], cam.height, axis=0)
    wrong, inside_wrong = predict(frame_start)
    wrong_error = np.abs(wrong - rolling)[inside & inside_wrong]
    print(f"pure rotation: mean |error| {error.mean():.3f}, 99th pct {np.percentile(error, 99):.2f}"
          f" gray levels; global-warp model {wrong_error.mean():.2f}")
    assert error.mean() < 1.0
    assert np.percentile(error, 99) < 12
    assert wrong_error.mean() > 8 * error.mean()


def test_stereo_pair_disparity_is_f_b_over_z():
    """A fronto-parallel wall at depth Z: the right image is the left one shifted by
    f·b/Z pixels along the rows."""
    depth, baseline = 2.0, 0.10
    spec = SceneSpec(room=(10.0, 2 * depth, 4.0), seed=SEED)  # wall at y = depth
    scene = build_scene(spec)
    left = Camera.from_fov(name="L", position=(-baseline / 2, 0, 0))
    right = Camera.from_fov(name="R", position=(baseline / 2, 0, 0))
    images = []
    for cam in (left, right):
        origin = START_ROTATION @ cam.c + np.array([0, 0, 2.0])
        images.append(Renderer(scene, cam).render(np.repeat((START_ROTATION @ cam.R)[None], 480, 0),
                                                  np.repeat(origin[None], 480, 0)))
    expected = left.fx * baseline / depth
    measured = [_row_shift(images[0][top:top + 64], images[1][top:top + 64])
                for top in (20, 140, 260, 380)]
    print(f"disparity expected {expected:.4f} px, measured {np.round(measured, 4)}")
    np.testing.assert_allclose(measured, expected, atol=0.01)


def _row_shift(left, right, iterations=6):
    """Shift d (px) along the rows with right(x) ≈ left(x + d): best integer shift, then
    Gauss–Newton with exact cubic-spline warps (cv2.remap would quantize the warp to
    1/32 px, which alone biases the estimate by up to 0.03 px)."""
    width, cols = left.shape[1], slice(100, left.shape[1] - 100)
    ssd = [np.mean((right[:, cols] - left[:, 100 + s:width - 100 + s]) ** 2) for s in range(90)]
    d = float(np.argmin(ssd))
    left, right = left.astype(float), right.astype(float)
    for _ in range(iterations):
        warped = ndimage.shift(left, (0, -d), order=3, mode="nearest")
        gradient = np.gradient(warped, axis=1)[:, cols]
        d += float(np.sum(gradient * (right - warped)[:, cols]) / np.sum(gradient * gradient))
    return d


def test_box_culling_never_drops_a_visible_box(scene):
    rng = np.random.default_rng(SEED)
    for cam in preset("radial6").cameras[:3]:
        renderer = Renderer(scene, cam)
        for _ in range(3):
            trajectory = ScrewTrajectory(axis=rng.normal(size=3), angular_speed=SpeedProfile.constant(6.0),
                                         direction=rng.normal(size=3), linear_speed=SpeedProfile.constant(1.0),
                                         start_rotation=orientation_ypr(*rng.uniform(-180, 180, 3)))
            rotation, position = trajectory.pose(cam.row_times([0])[0] * 3)
            culled = renderer.render(rotation @ cam.R, rotation @ cam.c + position)
            renderer._visible_boxes = lambda *args: np.arange(len(scene.box_lo))
            everything = renderer.render(rotation @ cam.R, rotation @ cam.c + position)
            del renderer._visible_boxes
            assert np.array_equal(culled, everything)


def test_exposure_integration_averages_over_the_exposure(scene):
    """With t_e > 0 and N samples a row is the mean of N renders across [t, t + t_e]."""
    rig = _single_camera_rig(t_e=4e-3, exposure_samples=4)
    cam = rig.cameras[0]
    trajectory = make_trajectory("paper")
    times = schedule(rig, 1 / 120, SEED)
    (_, _, blurred), = list(render_frames(rig, scene, trajectory, times, SEED))
    renderer = Renderer(scene, cam)
    parts = []
    for s in range(4):
        rotation, position = trajectory.pose(times[0][0] + (s + 0.5) / 4 * cam.t_e)
        parts.append(renderer.render(rotation @ cam.R, rotation @ cam.c + position))
    assert np.array_equal(blurred, sensor((parts[0] + parts[1] + parts[2] + parts[3]) / 4, 0, 0))
    sharp_rig = _single_camera_rig(t_e=4e-3)
    (_, _, sharp), = list(render_frames(sharp_rig, scene, trajectory, times, SEED))
    gradient = [np.abs(np.diff(img.astype(float), axis=1)).mean() for img in (blurred, sharp)]
    assert gradient[0] < 0.9 * gradient[1]  # motion blur removes detail


def test_sensor_noise_is_seeded_gaussian():
    flat = np.full((480, 640), 100.0, np.float32)
    a, b, c = sensor(flat, 3.0, 1), sensor(flat, 3.0, 1), sensor(flat, 3.0, 2)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert a.dtype == np.uint8
    assert a.astype(float).std() == pytest.approx(math.sqrt(9 + 1 / 12), rel=0.03)
    assert a.astype(float).mean() == pytest.approx(100, abs=0.05)
    assert np.array_equal(sensor(np.array([[-3.0, 255.6, 12.5]], np.float32), 0, 0), [[0, 255, 12]])


def test_scene_with_user_texture_and_panel(tmp_path):
    image = (np.indices((64, 96)).sum(axis=0) % 16 * 16).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "stripes.png"), image)
    spec = SceneSpec(room=(4.0, 4.0, 3.0), seed=1,
                     boxes=(Box(lo=(-0.5, 1.0, 1.0), hi=(0.5, 1.0, 2.0)),)).with_textures(
                         [tmp_path / "stripes.png"])
    scene = build_scene(spec)
    cam = Camera.from_fov()
    rotation = START_ROTATION @ cam.R
    img = Renderer(scene, cam).render(np.repeat(rotation[None], 480, 0),
                                      np.repeat(np.array([[0, 0, 1.5]]), 480, 0))
    centre = img[200:280, 280:360]  # the panel straight ahead, 1 m away
    assert centre.std() > 30
    with pytest.raises(ValueError, match="cannot be read as an image"):
        build_scene(SceneSpec(room_texture=str(tmp_path / "missing.png")))


SCENE_YAML = """
room: [5, 4, 3]
texel: 0.01
seed: 2
room_texture: stripes.png
boxes:
  - {lo: [1, 1, 0], hi: [2, 1.5, 1]}
"""


def test_scene_files(tmp_path):
    from golden.scene import load_scene_spec
    cv2.imwrite(str(tmp_path / "stripes.png"), np.tile(np.arange(0, 256, 32, dtype=np.uint8), (8, 4)))
    (tmp_path / "room.yaml").write_text(SCENE_YAML)
    (tmp_path / "room.toml").write_text('room = [5, 4, 3]\ntexel = 0.01\nseed = 2\n'
                                        'room_texture = "stripes.png"\n'
                                        '[[boxes]]\nlo = [1, 1, 0]\nhi = [2, 1.5, 1]\n')
    spec = load_scene_spec(tmp_path / "room.yaml")
    assert spec == load_scene_spec(tmp_path / "room.toml")
    assert spec.room == (5.0, 4.0, 3.0) and spec.boxes[0].hi == (2.0, 1.5, 1.0)
    assert spec.room_texture == str(tmp_path / "stripes.png")
    plain = build_scene(SceneSpec(room=spec.room, boxes=spec.boxes, texel=0.01, seed=2))
    textured = build_scene(spec)
    (x0, y0), (x6, y6) = textured.atlas.offsets[0], textured.atlas.offsets[6]
    room_patch = (slice(y0, y0 + 20), slice(x0, x0 + 20))
    box_patch = (slice(y6, y6 + 20), slice(x6, x6 + 20))
    assert not np.array_equal(textured.atlas.pyramid[0][room_patch], plain.atlas.pyramid[0][room_patch])
    assert np.array_equal(textured.atlas.pyramid[0][box_patch], plain.atlas.pyramid[0][box_patch])
    (tmp_path / "bad.yaml").write_text("room: [5, 4, 3]\nwalls: 2\n")
    with pytest.raises(ValueError, match="unknown key 'walls' in .*bad.yaml"):
        load_scene_spec(tmp_path / "bad.yaml")
    (tmp_path / "out.yaml").write_text("boxes: [{lo: [0, 0, 0], hi: [9, 1, 1]}]\n")
    with pytest.raises(ValueError, match="box 0 .* must lie inside the room"):
        load_scene_spec(tmp_path / "out.yaml")

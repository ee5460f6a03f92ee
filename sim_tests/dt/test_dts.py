"""The domain transform solver (golden.dts) and its synthetic depth-upsampling scenes."""

import numpy as np
import pytest

from golden.dt_scenes import bicubic_target, downsample, make_scene, rmse
from golden.dts import DtsParams, dts, target_confidence

SEED = 9

#: DTS must cut the RMSE of bicubic 8x upsampling at least this much on piecewise-constant
#: scenes (measured 3.8-7.7x on seeds 0-2 at 192x256 when this was written).
MIN_GAIN_8X = 2.5


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dts_beats_bicubic_on_piecewise_constant_depth(seed):
    scene = make_scene(192, 256, seed, slanted=False)
    low = downsample(scene.depth, 8, noise=3.0, seed=seed)  # sparse, noisy samples
    target = bicubic_target(low, 8)
    out = dts(target, scene.guide / 255.0, target_confidence(target))
    gain = rmse(target, scene.depth) / rmse(out, scene.depth)
    print(f"seed {seed}: bicubic {rmse(target, scene.depth):.2f}, "
          f"DTS {rmse(out, scene.depth):.2f} ({gain:.1f}x)")
    assert gain >= MIN_GAIN_8X


@pytest.mark.parametrize("robust", [None, 4.0])
def test_constant_target_is_a_fixed_point(robust):
    rng = np.random.default_rng(SEED)
    target = np.full((24, 31), 77.5)
    out = dts(target, rng.random((24, 31, 3)), rng.random((24, 31)),
              DtsParams(robust=robust, iterations=4))
    np.testing.assert_allclose(out, target, rtol=0, atol=1e-10)


def test_full_confidence_stays_stable():
    """alpha = lam = 0.99 with c = 1 everywhere: the step must not blow up."""
    rng = np.random.default_rng(SEED)
    target = rng.normal(0, 1, (40, 50))
    out = dts(target, np.zeros((40, 50)), np.ones((40, 50)), DtsParams(iterations=60))
    assert np.abs(out).max() <= np.abs(target).max()


def test_hard_constraint_pins_confident_pixels():
    rng = np.random.default_rng(SEED)
    target = rng.random((20, 30)) * 10
    confidence = np.where(rng.random((20, 30)) < 0.1, 1.0, 0.05)
    out = dts(target, rng.random((20, 30)), confidence, DtsParams(hard_threshold=1.0))
    pinned = confidence >= 1.0
    np.testing.assert_array_equal(out[pinned], target[pinned])
    assert not np.allclose(out[~pinned], target[~pinned])


def test_robust_data_term_resists_outliers():
    scene = make_scene(96, 128, SEED, slanted=False, textured=False)
    target = scene.depth.copy()
    rng = np.random.default_rng(SEED)
    spikes = rng.random(target.shape) < 0.02
    target[spikes] += 120.0
    confidence = np.full(target.shape, 0.5)
    l2 = dts(target, scene.guide / 255.0, confidence)
    robust = dts(target, scene.guide / 255.0, confidence, DtsParams(robust=2.0))
    assert rmse(robust, scene.depth) < 0.5 * rmse(l2, scene.depth)


def test_colour_targets_are_solved_per_channel():
    rng = np.random.default_rng(SEED)
    guide = rng.random((16, 18))
    target = rng.random((16, 18, 2))
    both = dts(target, guide, None, DtsParams(iterations=3))
    one = dts(target[..., 1], guide, None, DtsParams(iterations=3))
    np.testing.assert_allclose(both[..., 1], one, atol=1e-12)


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="lam must be a positive finite number, not 0"):
        DtsParams(lam=0)
    with pytest.raises(TypeError, match="iterations must be an integer"):
        DtsParams(iterations=2.5)
    with pytest.raises(ValueError, match=r"hard_threshold must be in \(0, 1\], not 2"):
        DtsParams(hard_threshold=2)
    with pytest.raises(ValueError, match="norm must be one of l1, l2, not 'max'"):
        DtsParams(norm="max")
    with pytest.raises(ValueError, match="robust must be a positive finite number, not -1"):
        DtsParams(robust=-1)
    with pytest.raises(ValueError, match=r"peak must be in \(0, 1\], not 1.5"):
        target_confidence(np.zeros((3, 4)), peak=1.5)
    with pytest.raises(ValueError, match=r"confidence must lie in \[0, 1\]"):
        dts(np.zeros((3, 4)), np.zeros((3, 4)), np.full((3, 4), 2.0))
    with pytest.raises(ValueError, match=r"confidence must have shape \(3, 4\)"):
        dts(np.zeros((3, 4)), np.zeros((3, 4)), np.ones((4, 3)))
    with pytest.raises(TypeError, match="params must be a DtsParams"):
        dts(np.zeros((3, 4)), np.zeros((3, 4)), None, {"lam": 1})

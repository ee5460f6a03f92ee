"""Stereo depth that knows when it is wrong (issue 18), on constructed rows: the window
from the depth range, the guard bands, no spreading across rejected blocks or depth
jumps, depth carried from the previous frame, and reference pixels without depth.

Set SEED to replay a run; the seed in use is printed.
"""

import math
import os

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from golden.depth import DepthRange, StereoDepth, forward_map, spread_blocks
from golden.depth_maps import OracleDepth
from golden.descriptor import DescriptorParams, MatchParams, describe, match, strength
from golden.reference_rows import HomographyReference, fill_row_gaps
from golden.rig import Rig, preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.tracker_motion import ground_truth_track
from golden.trajectory import make_trajectory

SEED = int(os.environ.get("SEED", "5"))
DESC = DescriptorParams()


def pair_rows(disparity, rng, width=640, flat=None):
    """A left and a right row (1, W) of band-limited noise with the given per-column
    disparity (scalar or (W,)); ``flat`` = (lo, hi) columns of the left row made flat
    (and their matches in the right row)."""
    base = gaussian_filter1d(rng.uniform(0, 255, width + 300), 2.0)
    x = np.arange(width, dtype=float)
    left = np.interp(x + 150, np.arange(width + 300), base)
    d = np.broadcast_to(np.asarray(disparity, dtype=float), x.shape)
    # right column xr sees the left point xl with xl − d(xl) = xr: solve by inversion
    right = np.interp(x, x - d, left)
    if flat is not None:
        lo, hi = flat
        left[lo:hi] = 128.0
        right = np.interp(x, x - d, left)
    return left[None], right[None]


def bits(*rows):
    return [describe(r, DESC) for r in rows]


@pytest.fixture(scope="module")
def rig():
    print(f"SEED={SEED}")
    return preset("stereo8")


# --- the window follows the pair and the depth range ----------------------------------------

def test_window_from_focal_baseline_and_depth_range(rig):
    fb = rig.cameras[0].fx * 0.08
    assert DepthRange(near=0.5, far=math.inf, guard=2).window(fb) == (-2, math.ceil(fb / 0.5) + 2)
    assert DepthRange(near=1.0, far=4.0, guard=3).window(fb) == (math.floor(fb / 4) - 3,
                                                                 math.ceil(fb / 1) + 3)
    depth = StereoDepth(rig, DESC, depth_range=DepthRange(near=1.0, far=4.0))
    assert len(depth.pairs) == 4
    assert all((w.shift_min, w.shift_max) == (6, 36) for w in depth.windows)   # fb 33.3 px·m


@pytest.mark.parametrize("kwargs, message", [
    (dict(near=0), "near must be a number greater than 0, not 0"),
    (dict(near=2.0, far=1.0), "far must be a number greater than 2.0, not 1.0"),
    (dict(far=math.nan), "far must be a finite number, not nan"),
    (dict(guard=0), "guard must be an integer at least 1, not 0"),
])
def test_depth_range_checks(kwargs, message):
    with pytest.raises(ValueError, match=message):
        DepthRange(**kwargs)


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(max_jump=0), ValueError, "max_jump must be a number greater than 0, not 0"),
    (dict(carry_frames=-1), ValueError, "carry_frames must be an integer at least 0, not -1"),
    (dict(min_peak_ratio=0.5), ValueError, "min_peak_ratio must be a number at least 1, not 0.5"),
    (dict(depth_range=(0.5, 10)), TypeError, "depth_range must be a DepthRange"),
])
def test_stereo_depth_checks(rig, kwargs, error, message):
    with pytest.raises(error, match=message):
        StereoDepth(rig, DESC, **kwargs)


def test_far_wall_below_the_old_window_gets_its_depth():
    """A wall 8 m away (disparity 4.2 px, below the old fixed [10, 70] window): the
    default range (0.5 m to infinity) finds it; the old window could only give it a
    wrong value or none."""
    rig = preset("stereo8")
    fb = rig.cameras[0].fx * 0.08
    rng = np.random.default_rng(SEED)
    left, right = pair_rows(fb / 8.0, rng)
    blocks = StereoDepth(rig, DESC).block_disparity(0, *bits(left, right))
    assert blocks.accepted.mean() > 0.3
    assert np.nanmax(np.abs(blocks.disparity - fb / 8.0)) < 0.5


def test_minimum_beyond_the_range_is_unknown_not_clamped():
    """A surface just beyond ``far`` has its cost minimum in the guard band: unknown
    (before issue 18 a minimum one pixel inside the window edge was accepted)."""
    rig = preset("stereo8")
    fb = rig.cameras[0].fx * 0.08
    depth_range = DepthRange(near=0.5, far=fb / 10.0)         # window [8, 69]
    depth = StereoDepth(rig, DESC, depth_range=depth_range)
    rng = np.random.default_rng(SEED)
    for true in (9.0, 8.6, 7.0):                               # guard band, edge, beyond
        left, right = pair_rows(true, rng)
        blocks = depth.block_disparity(0, *bits(left, right))
        assert not blocks.accepted.any()
        assert blocks.out_of_range.mean() > 0.5
    left, right = pair_rows(12.0, rng)                         # inside: accepted
    assert depth.block_disparity(0, *bits(left, right)).accepted.mean() > 0.3


# --- nothing spread across rejected blocks or depth jumps -----------------------------------

def test_no_interpolation_across_a_rejected_block(rig):
    fb = rig.cameras[0].fx * 0.08
    depth = StereoDepth(rig, DESC)
    rng = np.random.default_rng(SEED)
    disparity = np.linspace(20, 30, 640)                       # a slanted plane
    left, right = pair_rows(disparity, rng)
    accepted = depth.block_disparity(0, *bits(left, right)).accepted[0]
    # a block whose neighbours both give depth, made flat (the old code bridged it)
    k = next(k for k in range(2, 14) if accepted[k - 1] and accepted[k + 1])
    lo, hi = depth.bounds[0][k]
    flat = left.copy()
    flat[0, lo:hi] = 128.0
    right = np.interp(np.arange(640), np.arange(640) - disparity, flat[0])[None]
    left, strong = flat, strength(flat, DESC)
    blocks = depth.block_disparity(0, *bits(left, right), strong)
    assert not blocks.accepted[0, k] and blocks.accepted[0, k - 1] and blocks.accepted[0, k + 1]
    inverse, _ = depth.inverse_depth(0, *bits(left, right), strong)
    assert np.isnan(inverse[0, lo:hi]).all()
    truth = disparity / fb
    known = np.isfinite(inverse[0])
    # half a block held constant next to a rejected block: 17 px × 1/64 px/px of the
    # plane's slope, plus the sub-pixel error
    assert np.abs(inverse[0, known] - truth[known]).max() < 0.8 / fb


def test_depth_jump_is_not_interpolated():
    bounds = np.array([[0, 10], [10, 20], [20, 30], [30, 40]])
    inverse = np.array([[0.10, 0.11, 0.50, 0.51]])
    out = spread_blocks(inverse, bounds, 40, max_jump=0.05)
    # across the jump between blocks 1 and 2 each side keeps its own value
    assert np.all(out[0, 15:20] == 0.11) and np.all(out[0, 20:25] == 0.50)
    # within a surface (difference below max_jump): linear between centres (exact for
    # planes); outside the outermost centres the block's own value
    assert out[0, 7] == pytest.approx(0.10 + 0.01 * (7 - 4.5) / 10)
    assert out[0, 30] == pytest.approx(0.51 - 0.01 * 4.5 / 10) and out[0, 39] == 0.51
    assert out[0, 0] == 0.10


def test_forward_map_keeps_the_nearer_surface():
    left = np.full((1, 40), np.nan)
    left[0, 5:15] = 0.1            # far: d = 1 px at f·b = 10
    left[0, 15:25] = 1.0           # near: d = 10 px, lands on 5..14 and hides the far one
    right = forward_map(left, 10.0, 0.2)
    assert np.all(right[0, 5:15] == 1.0) and right[0, 4] == 0.1


# --- carried from the previous frame ----------------------------------------------------------

def test_depth_carried_where_the_match_fails_and_only_for_a_while(rig):
    fb = rig.cameras[0].fx * 0.08
    depth = StereoDepth(rig, DESC, carry_frames=2)
    lo, hi = depth.bounds[0][5]
    rng = np.random.default_rng(SEED)
    good = bits(*pair_rows(25.0, rng))
    failed = bits(*pair_rows(25.0, rng, flat=(lo - 8, hi + 8)))
    first, _ = depth.inverse_depth(0, *good, frame=0)
    assert np.isfinite(first[0, lo:hi]).all()
    carried = [depth.inverse_depth(0, *failed, frame=f)[0][0, lo:hi] for f in (1, 2, 3)]
    assert np.array_equal(carried[0], first[0, lo:hi])      # frame 1: from frame 0
    assert np.array_equal(carried[1], first[0, lo:hi])      # frame 2: still (age 2)
    assert np.isnan(carried[2]).all()                       # frame 3: too old
    depth.inverse_depth(0, *good, frame=10)
    skipped = depth.inverse_depth(0, *failed, frame=12)[0]   # not the next frame: no carry
    assert np.isnan(skipped[0, lo:hi]).all()
    assert abs(np.nanmedian(first) * fb - 25.0) < 0.3


# --- reference pixels without depth ---------------------------------------------------------

def test_fill_row_gaps_takes_the_nearest_depth():
    values = np.array([[np.nan, 1, np.nan, np.nan, np.nan, 5, np.nan], [np.nan] * 7])
    filled = fill_row_gaps(values)
    assert np.array_equal(filled[0], [1, 1, 1, 1, 5, 5, 5]) and np.isnan(filled[1]).all()


def test_reference_pixels_without_depth_are_not_infinitely_far():
    """Translation past a wall: parallax-compensated reference rows at the true poses
    line up with the current rows; in a stretch without depth the nearest depth keeps
    them lined up, while "infinitely far" (what NaN meant before) shifts them by the
    whole frame's parallax."""
    base = preset("stereo20")
    cameras = tuple(c.replace(height=48, cy=23.5, t_r=1 / (120 * 48)) for c in base.cameras[:2])
    pair = Rig(name="pair", cameras=cameras, allow_unobservable=True)
    dataset = simulate(pair, default_scene_spec(SEED), make_trajectory("translation"),
                       2 / 120, seed=SEED)
    truth, oracle = ground_truth_track(dataset), OracleDepth(dataset)
    rows, columns = np.arange(8, 40, 2), np.arange(640)
    rec = dataset.cameras[0]
    rotation, position = rec.rotation[1, rows], rec.position[1, rows]
    inverse = oracle.inverse_depth(0, 1, rows)
    hole = slice(260, 380)
    errors = {}
    for name, fill in (("true", None), ("missing", np.nan), ("infinitely far", 0.0)):
        given = inverse.copy()
        if fill is not None:
            given[:, hole] = fill
        reference = HomographyReference(pair, dataset.cameras, truth, DESC, 0.06)
        ref = reference.rows(0, 1, rows, rotation, position, columns, given)
        params = MatchParams(shift_min=-12, shift_max=12, segments=1)
        cur = describe(rec.rows[1, rows], DESC)[:, 240:400]
        result = match(cur, ref.bits[:, 240:400], DESC, params)
        errors[name] = np.median(np.abs(result.shift))
    print(errors)
    assert errors["true"] < 0.3
    assert errors["infinitely far"] > 1.0                      # the test can tell
    assert errors["missing"] < 0.3 * errors["infinitely far"]


# --- the measurement tool -------------------------------------------------------------------

def test_depth_check_counts_gross_errors_against_the_truth(tmp_path):
    """On a short stereo8 clip at 1/4 size (f·b = 8.3 px·m) the counts are consistent;
    the old fixed [10, 70] window finds no depth at all there (every surface is beyond
    0.83 m), the range-derived one does; and the trajectory errors are read back."""
    from golden.depth_check import block_errors, track_errors
    from golden.rig import scaled_rig
    rig = scaled_rig(preset("stereo8"), 0.25).replace_cameras(noise_sigma=2.0)
    dataset = simulate(rig, default_scene_spec(SEED), make_trajectory("head", seed=SEED),
                       2 / 100, seed=SEED)
    for rule in ("before", "after"):
        counts = block_errors(dataset, rule, row_step=4, blocks=4)   # 30-px blocks
        print(rule, counts)
        assert 0 <= counts["gross"] <= counts["accepted"] <= counts["blocks"]
        assert 0 <= counts["pixel_depth_share"] <= 1 and 0 <= counts["pixel_gross_share"] <= 1
        assert (counts["accepted"] > 0.2 * counts["blocks"]) == (rule == "after")
    # a trajectory file 0.3 s long, 2 cm off in x from 0.1 s on
    time = np.linspace(0, 0.3, 301)
    position = np.zeros((301, 3))
    true = position.copy()
    position[time >= 0.1, 0] = 0.02
    quaternion = np.tile([1.0, 0, 0, 0], (301, 1))
    np.savez(tmp_path / "run.track.npz", time=time, position=position, true_position=true,
             quaternion=quaternion, true_quaternion=quaternion, tracked=np.ones(301, bool))
    errors = track_errors(tmp_path / "run.track.npz")
    assert errors["t_cm"] == pytest.approx([2.0, 0, 0]) and errors["at_s"] == pytest.approx(0.2)
    assert errors["over_1cm_s"] == pytest.approx(0.1) and errors["over_5cm_s"] is None

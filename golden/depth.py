"""Where the tracker's depths come from.

* :class:`StereoDepth` (TVCG 2016): the two cameras of a rectified pair read the same row
  at the same time; matching the left row against the right one in ``blocks`` segments
  gives one disparity ``d`` per block, ``1/Z = d / (f·b)``. It is built to know when it
  is wrong (issue 18): a wrong depth turns into confident wrong motion measurements,
  a missing one only into fewer measurements.

  - The disparity window comes from the pair's ``f·b`` and the scene's depth range
    (:class:`DepthRange`): ``[f·b/far, f·b/near]`` widened by ``guard`` pixels on each
    side, so every surface inside the range has its cost minimum inside the window.
  - A block is unknown when it is textureless, ambiguous (peak ratio), or its best cost
    lies in a guard band or on the window edge (the minimum is at, or beyond, the end
    of the depth range: the true disparity may lie outside the window, and a window
    minimum is then a different surface's or an alias).
  - Inverse depth is interpolated linearly (exact for planes) only between the centres
    of two *adjacent accepted* blocks whose disparities differ by at most ``max_jump``
    pixels; otherwise each accepted block keeps its own value up to its edges. A
    rejected block gives no depth to its pixels; nothing is spread across it.
  - Pixels still without depth take the pair's previous map at the same pixel when the
    previous frame had one there (carried at most ``carry_frames`` frames).
  - The right camera's map is the left one's forward-mapped by the disparity (a point
    at left column ``x`` is at right column ``x − d``; the nearer point wins).

* :mod:`golden.depth_maps` (CVPR 2018): per-camera depth maps bootstrapped from the
  overlap of neighbouring cameras and carried from frame to frame.

Unknown depth is NaN; the tracker drops segments where too little of it is known.
"""

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from .checks import check_int, check_number
from .descriptor import STEREO_MATCH, match, segment_bounds

__all__ = ["stereo_pairs", "DepthRange", "DEFAULT_RANGE", "MIN_PEAK_RATIO", "BlockDisparity",
           "StereoDepth"]


def stereo_pairs(rig, tol=1e-6):
    """Rectified pairs of ``rig``: ``[(left, right, f·baseline), ...]`` (camera indices).

    Two cameras pair up when they share intrinsics, have no lens distortion, the same
    mounting rotation and row timing, and their baseline lies along the camera x axis;
    the left camera is the one with the smaller x. Each camera joins at most one pair.
    """
    cams = rig.cameras
    pairs, used = [], set()
    for i, a in enumerate(cams):
        for j in range(i + 1, len(cams)):
            b = cams[j]
            if i in used or j in used:
                continue
            same = (np.allclose(a.K, b.K) and a.k1 == a.k2 == b.k1 == b.k2 == 0
                    and np.allclose(a.R, b.R, atol=tol) and a.t_r == b.t_r and a.fps == b.fps
                    and a.trigger_offset == b.trigger_offset
                    and (a.width, a.height) == (b.width, b.height))
            if not same:
                continue
            base = a.R.T @ (b.c - a.c)
            length = np.linalg.norm(base)
            if length == 0 or np.hypot(base[1], base[2]) > tol * length:
                continue
            left, right = (i, j) if base[0] > 0 else (j, i)
            pairs.append((left, right, a.fx * length))
            used.update((i, j))
    return pairs


@dataclass(frozen=True, kw_only=True)
class DepthRange:
    """Depths (m) the stereo matcher looks for, and how it guards the window's ends.

    Parameters
    ----------
    near, far : float
        Nearest and farthest depth of the scene (``far`` may be ``inf``: disparity 0).
    guard : int
        Pixels the window reaches beyond the disparities of ``[near, far]`` on each side;
        a minimum there or on the window's edge means the surface lies outside the range
        (or the match is wrong) and the block stays unknown.
    """
    near: float = 0.5
    far: float = math.inf
    guard: int = 2

    def __post_init__(self):
        check_number("near", self.near, 0, low_open=True)
        check_number("far", self.far, self.near, low_open=True, finite=False)
        check_int("guard", self.guard, 1)

    replace = replace

    def disparities(self, focal_baseline):
        """Disparity range ``(f·b/far, f·b/near)`` (pixels) of a pair."""
        check_number("focal_baseline", focal_baseline, 0, low_open=True)
        return focal_baseline / self.far, focal_baseline / self.near

    def accepted(self, focal_baseline):
        """Integer disparities ``(low, high)`` a block's best match may have and still
        give a depth: the disparity range rounded outwards."""
        low, high = self.disparities(focal_baseline)
        return math.floor(low), math.ceil(high)

    def window(self, focal_baseline):
        """Integer search window ``(shift_min, shift_max)`` of a pair: the accepted
        disparities widened by ``guard``."""
        low, high = self.accepted(focal_baseline)
        return low - self.guard, high + self.guard


#: Default range of the stereo depth: anything from 0.5 m to infinitely far (a far wall
#: beyond any "stereo range" still has its minimum inside the window, near disparity 0).
DEFAULT_RANGE = DepthRange()

#: A block whose peak ratio is below this is ambiguous and gives no depth.
MIN_PEAK_RATIO = 1.2


class BlockDisparity(NamedTuple):
    """Per-block outcome of the disparity match, arrays (B, K)."""
    disparity: np.ndarray    # d (pixels) of the best cost, NaN where not accepted
    accepted: np.ndarray     # bool
    out_of_range: np.ndarray  # best cost in a guard band or on the window edge
    ambiguous: np.ndarray    # textureless, or peak ratio below the threshold
    raw: np.ndarray          # d of the best cost whatever the verdict


class StereoDepth:
    """Per-pixel inverse depth of current rows from the stereo disparity of their pair.

    Parameters
    ----------
    rig : golden.rig.Rig
    desc : golden.descriptor.DescriptorParams
    blocks : int
        Disparity blocks per row.
    depth_range : DepthRange
        Scene depth range; each pair's window follows from its ``f·b``.
    window : golden.descriptor.MatchParams
        Matcher settings (its shift window and segments are replaced).
    min_peak_ratio : float
        A block whose peak ratio is lower is ambiguous and gives no depth.
    max_jump : float
        Largest disparity difference (pixels) between adjacent accepted blocks that is
        still interpolated; a larger one is a depth jump (an occlusion edge).
    carry_frames : int
        Frames a pixel's depth may be carried where the match fails (0: never).

    Raises
    ------
    ValueError
        If the rig has no rectified stereo pair.
    """

    def __init__(self, rig, desc, *, blocks=16, depth_range=DEFAULT_RANGE,
                 window=STEREO_MATCH, min_peak_ratio=MIN_PEAK_RATIO, max_jump=2.0, carry_frames=3):
        self.pairs = stereo_pairs(rig)
        if not self.pairs:
            raise ValueError(f"rig {rig.name!r} has no rectified stereo pair (same intrinsics "
                             f"and rotation, no distortion, baseline along x)")
        check_int("blocks", blocks, 1)
        check_number("min_peak_ratio", min_peak_ratio, 1)
        check_number("max_jump", max_jump, 0, low_open=True)
        check_int("carry_frames", carry_frames, 0)
        if not isinstance(depth_range, DepthRange):
            raise TypeError(f"depth_range must be a DepthRange, not {depth_range!r}")
        self.pair_of = {}
        for k, (left, right, _) in enumerate(self.pairs):
            self.pair_of[left] = self.pair_of[right] = k
        self.desc, self.depth_range = desc, depth_range
        self.width = rig.cameras[0].width
        self.windows, self.bounds = [], []
        for _, _, fb in self.pairs:
            low, high = depth_range.window(fb)
            params = window.replace(segments=blocks, shift_min=low, shift_max=high)
            self.windows.append(params)
            self.bounds.append(np.array(segment_bounds(self.width, desc, params)))
        self.min_peak_ratio, self.max_jump = min_peak_ratio, max_jump
        self.carry_frames = carry_frames
        self._previous = {}

    def has_depth(self, camera):
        return camera in self.pair_of

    def block_disparity(self, pair, left_bits, right_bits, left_strong=None):
        """Match the left rows against the right ones block by block (see
        :class:`BlockDisparity`)."""
        params = self.windows[pair]
        result = match(left_bits, right_bits, self.desc, params, cur_strong=left_strong)
        low, high = self.depth_range.accepted(self.pairs[pair][2])
        d = result.int_shift
        out = result.edge_hit | (d < low) | (d > high)
        ambiguous = result.textureless | (result.peak_ratio < self.min_peak_ratio)
        accepted = ~out & ~ambiguous
        return BlockDisparity(disparity=np.where(accepted, result.shift, np.nan),
                              accepted=accepted, out_of_range=out, ambiguous=ambiguous,
                              raw=result.shift)

    def inverse_depth(self, pair, left_bits, right_bits, left_strong=None, *, frame=None):
        """1/Z (B, W) along rows of the left and the right camera of pair ``pair`` from
        their descriptor bits (B, W) (and the left rows' strong columns for the matcher's
        flat-segment test); NaN where unknown.

        ``frame`` numbers the rows' frame: pixels without depth take the map of frame
        ``frame − 1`` of the same rows when that was the pair's previous call. Without
        it, successive calls for a pair are taken as successive frames (the tracker's
        order: every frame once, in order).
        """
        fb = self.pairs[pair][2]
        blocks = self.block_disparity(pair, left_bits, right_bits, left_strong)
        left = spread_blocks(blocks.disparity / fb, self.bounds[pair], self.width,
                             self.max_jump / fb)
        right = forward_map(left, fb, self.max_jump / fb)
        left, right = self._carry(pair, frame, left, right)
        return left, right

    def _carry(self, pair, frame, left, right):
        """Fill holes from the pair's previous map (same pixel) and remember this one."""
        previous = self._previous.get(pair)
        consecutive = previous is not None and (
            frame is None or previous["frame"] is None or previous["frame"] == frame - 1)
        same_shape = previous is not None and previous["maps"][0].shape == left.shape
        ages = []
        maps = []
        for k, current in enumerate((left, right)):
            age = np.where(np.isfinite(current), 0, self.carry_frames + 1)
            if consecutive and same_shape and self.carry_frames:
                old, old_age = previous["maps"][k], previous["ages"][k]
                take = ~np.isfinite(current) & np.isfinite(old) & (old_age < self.carry_frames)
                current = np.where(take, old, current)
                age = np.where(take, old_age + 1, age)
            maps.append(current)
            ages.append(age)
        self._previous[pair] = {"frame": frame, "maps": maps, "ages": ages}
        return maps[0], maps[1]


def spread_blocks(inverse, bounds, width, max_jump):
    """Per-pixel 1/Z (B, W) from per-block values (B, K) (NaN: rejected) on blocks
    ``bounds`` (K, 2) of columns ``[lo, hi)``.

    Between the centres of two adjacent accepted blocks whose values differ by at most
    ``max_jump``, linear interpolation; elsewhere inside an accepted block its own value;
    rejected blocks and columns outside every block stay NaN.
    """
    rows, k = inverse.shape
    lo, hi = bounds[:, 0], bounds[:, 1]
    centre = (lo + hi - 1) / 2
    columns = np.arange(width)
    block = np.searchsorted(hi, columns, side="right")          # block of each column
    inside = (block < k) & (columns >= lo[np.minimum(block, k - 1)])
    block = np.minimum(block, k - 1)
    # the other block a column is interpolated with: the neighbour on its side of centre
    other = np.clip(np.where(columns < centre[block], block - 1, block + 1), 0, k - 1)
    own, nxt = inverse[:, block], inverse[:, other]
    span = np.abs(centre[other] - centre[block])
    weight = np.abs(columns - centre[block]) / np.where(span > 0, span, 1.0)
    joined = np.isfinite(nxt) & (np.abs(nxt - own) <= max_jump)
    value = np.where(joined, own + weight * (np.nan_to_num(nxt) - own), own)
    return np.where(inside[None, :], value, np.nan)


def forward_map(left, focal_baseline, max_jump):
    """The right camera's 1/Z (B, W) from the left one's: each left pixel ``x`` lands at
    ``x − f·b·w``; where two land on one pixel the nearer (larger ``w``) wins, and a
    one-pixel crack between two landed neighbours that are not a depth jump apart takes
    their mean."""
    rows, width = left.shape
    out = np.full(left.shape, -np.inf)
    r, x = np.nonzero(np.isfinite(left))
    w = left[r, x]
    target = np.rint(x - focal_baseline * w).astype(int)
    keep = (target >= 0) & (target < width)
    np.maximum.at(out, (r[keep], target[keep]), w[keep])
    out[out == -np.inf] = np.nan
    before, after = out[:, :-2], out[:, 2:]
    crack = (np.isnan(out[:, 1:-1]) & np.isfinite(before) & np.isfinite(after)
             & (np.abs(before - after) <= max_jump))
    out[:, 1:-1] = np.where(crack, (before + after) / 2, out[:, 1:-1])
    return out

"""Where the tracker's depths come from.

* :class:`StereoDepth` (TVCG 2016): the two cameras of a rectified pair read the same row
  at the same time; matching the left row against the right one with the disparity
  window (``STEREO_MATCH``, [10, 70] px) in ``blocks`` segments gives one disparity
  ``d`` per segment, ``1/Z = d / (f·b)``. Inverse depth is interpolated linearly between
  segment centres (exact for planes: ``1/Z`` is affine in the normalized coordinates of
  a plane's points) and unknown beyond the outermost ones. Each camera of the pair gets
  its own map (right against left with the mirrored window).
* :mod:`golden.depth_maps` (CVPR 2018): per-camera depth maps bootstrapped from the
  overlap of neighbouring cameras and carried from frame to frame.

Unknown depth is NaN; the tracker drops segments where too little of it is known.
"""

import numpy as np

from .descriptor import STEREO_MATCH, match, segment_bounds

__all__ = ["stereo_pairs", "StereoDepth"]


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


class StereoDepth:
    """Per-pixel inverse depth of current rows from the stereo disparity of their pair.

    Parameters
    ----------
    rig : golden.rig.Rig
    desc : golden.descriptor.DescriptorParams
    blocks : int
        Disparity segments per row.
    window : golden.descriptor.MatchParams
        Disparity window for left-against-right matching (its segments are replaced).
    min_peak_ratio : float
        A block whose peak ratio is lower is ambiguous and gives no depth.

    Raises
    ------
    ValueError
        If the rig has no rectified stereo pair.
    """

    def __init__(self, rig, desc, *, blocks=16, window=STEREO_MATCH, min_peak_ratio=1.2):
        self.pairs = stereo_pairs(rig)
        if not self.pairs:
            raise ValueError(f"rig {rig.name!r} has no rectified stereo pair (same intrinsics "
                             f"and rotation, no distortion, baseline along x)")
        self.pair_of = {}
        for k, (left, right, _) in enumerate(self.pairs):
            self.pair_of[left] = self.pair_of[right] = k
        self.desc = desc
        self.width = rig.cameras[0].width
        self.window = window.replace(segments=blocks)
        self.centres = np.array([(lo + hi - 1) / 2 for lo, hi in
                                 segment_bounds(self.width, desc, self.window)])
        self.min_peak_ratio = min_peak_ratio

    def has_depth(self, camera):
        return camera in self.pair_of

    def inverse_depth(self, pair, left_bits, right_bits, left_strong=None):
        """1/Z (B, W) along rows of the left and the right camera of pair ``pair`` from
        their descriptor bits (B, W) (and the left rows' strong columns for the matcher's
        flat-segment test); NaN where unknown.

        The right camera's map is the left one's carried over by the disparity: the
        point at left column ``x`` is at right column ``x − d`` (the same physical points,
        one matcher call per pair).
        """
        _, _, fb = self.pairs[pair]
        result = match(left_bits, right_bits, self.desc, self.window, cur_strong=left_strong)
        ok = ~result.textureless & ~result.edge_hit & (result.peak_ratio >= self.min_peak_ratio)
        inverse = result.shift / fb
        columns = np.arange(self.width)
        left = np.full((len(left_bits), self.width), np.nan)
        right = np.full_like(left, np.nan)
        for b in range(len(left_bits)):
            good = ok[b]
            if good.any():
                left[b] = _interpolate_inside(columns, self.centres[good], inverse[b, good])
                moved = self.centres[good] - result.shift[b, good]
                order = np.argsort(moved)
                right[b] = _interpolate_inside(columns, moved[order], inverse[b, good][order])
        return left, right


def _interpolate_inside(x, points, values):
    """Linear interpolation between ``points``; NaN outside their span (no guessing)."""
    inside = (x >= points[0]) & (x <= points[-1])
    return np.where(inside, np.interp(x, points, values), np.nan)

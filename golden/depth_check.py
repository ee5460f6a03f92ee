"""How often stereo depth is confidently wrong, measured against the simulator's truth.

``python -m golden.depth_check DATA.npz [--rule before|after] [--row-step N]
[--blocks K]`` matches
every ``row-step``-th row of every frame of every rectified pair of a simulated dataset
and compares each block's disparity with the true disparities ``f·b/Z`` of the block's
pixels (:class:`golden.depth_maps.OracleDepth`). A block is a *gross error* when it is
accepted and more than ``GROSS_PX`` away from every true disparity in it (so a block that
straddles a depth jump and matches either side is not counted). Pixels: the left
camera's per-pixel map (after spreading and carrying; the pair's rows are carried from
one sampled frame to the next) against the true disparity of the same pixel, gross
beyond ``GROSS_PX`` too. ``--rule before`` is the rule before issue 18 (fixed [10, 70]
window, reject only the window's edge, textureless or peak ratio < 1.2; linear
interpolation between all accepted block centres), kept here only to measure the change.

Tracker error: ``python -m golden.depth_check --track RUN.track.npz`` prints the position
and rotation error after 0.2 s of tracking and when the position error first exceeds
1 cm and 5 cm.
"""

import argparse
import json

import numpy as np

from .depth import StereoDepth
from .descriptor import STEREO_MATCH, DescriptorParams, describe, match, segment_bounds

__all__ = ["GROSS_PX", "block_errors", "track_errors"]

#: A block is grossly wrong beyond this distance (pixels) from every true disparity.
GROSS_PX = 2.0


def _before_rule(depth, pair, left_bits, right_bits):
    """Accepted disparities (NaN: rejected), block bounds and the left camera's per-pixel
    1/Z of the rule before issue 18 (linear between accepted block centres)."""
    window = STEREO_MATCH.replace(segments=len(depth.bounds[pair]))
    result = match(left_bits, right_bits, depth.desc, window)
    ok = ~result.textureless & ~result.edge_hit & (result.peak_ratio >= depth.min_peak_ratio)
    bounds = np.array(segment_bounds(left_bits.shape[-1], depth.desc, window))
    centres = (bounds[:, 0] + bounds[:, 1] - 1) / 2
    columns = np.arange(left_bits.shape[-1])
    inverse = np.full(left_bits.shape, np.nan)
    for b in range(len(left_bits)):
        good = ok[b]
        if good.any():
            inside = (columns >= centres[good][0]) & (columns <= centres[good][-1])
            values = np.interp(columns, centres[good], result.shift[b, good])
            inverse[b] = np.where(inside, values / depth.pairs[pair][2], np.nan)
    return np.where(ok, result.shift, np.nan), bounds, inverse


def block_errors(dataset, rule="after", row_step=8, blocks=16):
    """Counts of blocks, accepted blocks and accepted gross errors (see the module
    docstring) over a dataset; ``rule`` is ``"after"`` (:class:`StereoDepth` defaults)
    or ``"before"``; ``blocks`` disparity blocks per row."""
    from .depth_maps import OracleDepth
    desc = DescriptorParams()
    depth, oracle = StereoDepth(dataset.rig, desc, blocks=blocks), OracleDepth(dataset)
    rows = np.arange(0, dataset.rig.cameras[0].height, row_step)
    counts = {"blocks": 0, "accepted": 0, "gross": 0, "true_below_window": 0,
              "pixels": 0, "pixels_with_depth": 0, "pixels_gross": 0}
    for pair, (left, right, fb) in enumerate(depth.pairs):
        for frame in range(len(dataset.cameras[left].time)):
            lb = describe(dataset.cameras[left].rows[frame, rows], desc)
            rb = describe(dataset.cameras[right].rows[frame, rows], desc)
            if rule == "before":
                disparity, bounds, inverse = _before_rule(depth, pair, lb, rb)
            else:
                disparity = depth.block_disparity(pair, lb, rb).disparity
                bounds = depth.bounds[pair]
                inverse = depth.inverse_depth(pair, lb, rb, frame=frame)[0]
            true = fb * oracle.inverse_depth(left, frame, rows)
            known = np.isfinite(inverse)
            counts["pixels"] += inverse.size
            counts["pixels_with_depth"] += int(known.sum())
            counts["pixels_gross"] += int((np.abs(fb * inverse[known] - true[known])
                                           > GROSS_PX).sum())
            for k, (lo, hi) in enumerate(bounds):
                d = disparity[:, k]
                off = np.abs(true[:, lo:hi] - d[:, None]).min(axis=1)
                counts["blocks"] += len(d)
                counts["accepted"] += int(np.isfinite(d).sum())
                counts["gross"] += int((np.isfinite(d) & (off > GROSS_PX)).sum())
                counts["true_below_window"] += int((np.median(true[:, lo:hi], axis=1)
                                                    < 10).sum())
    counts["accepted_share"] = counts["accepted"] / counts["blocks"]
    counts["gross_share_of_accepted"] = counts["gross"] / max(counts["accepted"], 1)
    counts["pixel_depth_share"] = counts["pixels_with_depth"] / counts["pixels"]
    counts["pixel_gross_share"] = counts["pixels_gross"] / max(counts["pixels_with_depth"], 1)
    return counts


def track_errors(path, after=0.2):
    """Errors of a ``rowtrack track`` trajectory file: position (cm, per axis) and
    rotation (rad, per axis) ``after`` seconds into tracking, and the tracked time (s)
    at which the position error first exceeds 1 cm and 5 cm (None: never)."""
    from scipy.spatial.transform import Rotation
    run = np.load(path)
    tracked = run["tracked"]
    time = run["time"][tracked] - run["time"][tracked][0]
    position = 100 * (run["position"] - run["true_position"])[tracked]
    est = Rotation.from_quat(run["quaternion"][tracked], scalar_first=True)
    true = Rotation.from_quat(run["true_quaternion"][tracked], scalar_first=True)
    rotation = (true.inv() * est).as_rotvec()
    at = min(int(np.searchsorted(time, after)), len(time) - 1)
    norm = np.linalg.norm(position, axis=1)

    def first_over(limit):
        over = np.flatnonzero(norm > limit)
        return float(time[over[0]]) if len(over) else None

    return {"at_s": float(time[at]), "t_cm": position[at].tolist(),
            "r_rad": rotation[at].tolist(), "over_1cm_s": first_over(1.0),
            "over_5cm_s": first_over(5.0)}


def main(argv=None):
    from .dataset import Dataset
    parser = argparse.ArgumentParser(prog="python -m golden.depth_check",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("path", help="dataset .npz (or, with --track, a .track.npz)")
    parser.add_argument("--rule", choices=("before", "after"), default="after")
    parser.add_argument("--row-step", type=int, default=8)
    parser.add_argument("--blocks", type=int, default=16, help="disparity blocks per row")
    parser.add_argument("--track", action="store_true", help="path is a trajectory file")
    args = parser.parse_args(argv)
    if args.track:
        print(json.dumps(track_errors(args.path)))
    else:
        print(json.dumps(block_errors(Dataset.load(args.path), args.rule, args.row_step,
                                      args.blocks)))


if __name__ == "__main__":
    main()

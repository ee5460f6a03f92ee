"""How biased are the hardware path's measurements? (issue 16)

The closed loop's figure mixes measurement errors with the forecast filter's dynamics.
This study takes the dynamics out: the forecast is frozen at the true motion (the paper
motion turns and moves at constant rates, so its true one-frame motion is the same on
every row; the filter starts there and moves by ``alpha`` = 0.004 of each innovation,
the smallest the scalar gain's prior format takes), and the raw solved steps (the
hardware's ``Ŷ + δ``, golden (b)'s ``measured``) are compared with the true motion row
by row. Their **mean** error is the measurement model's bias (what a filter cannot
average away), their standard deviation its noise.

Usage: ``PYTHONPATH=. .venv/bin/python scripts/bias_study.py [--segments 8]
[--stereo-segments 8] [--frames 4] [--only name,name]`` on hw_tracking's stereo20 paper
sequence (12 frames, noise σ = 2; the first ``--frames`` used). ``--window W`` also
prints the errors' slow part, what a filter passes: the RMS of their ``W``-row moving
means within each frame, and how alike those means are from frame to frame (the mean
correlation of the frames' ``W``-row means: near 1, an error pattern fixed to the row,
which the paper motion's constant rates repeat every frame). Runs (``--only``):

* ``golden_b``: golden (b) with ``segments`` (its own depth: 16 blocks, per pixel);
* ``hw``: the hardware path (:func:`emulator.hardware_path.closed_loop` settings) with
  ``segments`` and ``stereo_segments``;
* ``oracle_own`` / ``oracle_stereo``: the hardware path with gap_study's cue swaps
  (each camera's own true disparity over its segment's compared columns / camera A's
  true disparity over the stereo segment, for both cameras); ``oracle_own_a`` /
  ``oracle_own_b``: "own" for camera A (B) of each pair, "stereo" for the other;
* ``float_match`` / ``float_solver``: the hardware path with gap_study's swaps of the
  lanes' matcher or the solve for float64; ``depth_weight``: with gap_study's float
  depth-sensitivity weight (golden (b)'s, σ_d 1 px, 0.3 px);
* ``column_cue``: the hardware path with each temporal segment's cue taken from the
  stereo segments its columns overlap (:func:`column_cue_patch`), the measured cues;
  ``centre_cue``: the same cues interpolated at the segment's centre column
  (:func:`centre_cue_patch`).
* ``coverage``: the hardware path with no weight for a temporal segment whose columns,
  as camera A sees them, lie less than half inside the stereo lane's compared columns
  (:func:`coverage_patch`; golden (b) has no depth there and takes no measurement;
  the float study behind the product's cue-map coverage test of stop 38, which makes
  this run a no-op on later checkouts).
* ``row_residual``: the hardware path with each shift corrected by ``r·∂s/∂y``, ``r``
  how far the segment's followed row is from its exact displacement across rows
  (:func:`row_residual_patch`).
* golden side, each one of the hardware's simplifications inside golden (b)
  (:func:`golden_swap`): ``gb_mean_depth`` (design rows from the segment's mean
  ``R + T·ρ``, one depth per segment), ``gb_mean_depth_linear`` (that and the linear
  predicted shift with the reference-time factor: the hardware's measurement model),
  ``gb_word_rows`` (each 36-column reference word from the row of the segment of its
  middle column, as the followed store reads it).

``--by-camera`` (with the hardware runs) splits each row's Ty error into the cameras'
shares (:func:`camera_shares`: the float solve of the row's judged measurements, the
error of each measurement against the true motion through the solve's gain) and prints
each camera's mean, slow part and frame likeness.
"""

import argparse
import sys
import time

import numpy as np

import gap_study

FROZEN = {"motion_gain": "scalar", "alpha": 0.004, "beta": 0.0}
#: Per-axis scale of the printed figures: cm, 1e-4 rad.
UNITS = np.array([100, 100, 100, 1e4, 1e4, 1e4])


def golden_steps(dataset, segments):
    """(frames, rows, raw measured steps) of golden (b) with a frozen forecast."""
    return _golden_rows(dataset, gap_study.golden_b(dataset, segments=segments, **FROZEN))


def _golden_rows(dataset, result):
    """(frames, rows, raw measured steps) of a golden (b) result, frames ≥ 1."""
    height = dataset.rig.cameras[0].height
    frames = len(dataset.cameras[0].rows)
    fr = np.repeat(np.arange(1, frames), height)
    rw = np.tile(np.arange(height), frames - 1)
    return fr, rw, gap_study._golden_measured(result, dataset, fr, rw)


def hardware_steps(dataset, config, patch=None):
    """(frames, rows, raw solved steps) of the hardware path with a frozen forecast."""
    run = gap_study.hardware(dataset, None, config=config, patch=patch,
                             forecast_changes=FROZEN)
    return run[3]


def _cue_patch(config, cue_of, keep_cue=False):
    """The router's cue of each temporal segment replaced by ``cue_of(k, shift, cues)``
    (float pixels, or None: the segment gets no weight; with ``keep_cue`` a value keeps
    the router's cue): ``k`` the temporal segment,
    ``shift`` how far right of its own columns camera A sees them (0 for camera A; for
    camera B the pair's disparity of stereo segment ``k·K_s // K``, the router's cue
    before the cue map), ``cues`` the pair's usable cues by stereo segment (float).
    Applied to today's router it overrides the cue map's cues."""
    import emulator.pipeline as pl
    from emulator.measurement.router import usable_cues
    lane, stereo = config.router.temporal, config.router.stereo
    original = pl.route_row

    def route_row(params, temporal, stereo_records, fallback=None):
        out = original(params, temporal, stereo_records, fallback)
        fmt = params.solver.cue_fmt
        cues = {key: fmt.to_float(raw) for key, raw in
                {**(fallback or {}), **usable_cues(params, stereo_records)}.items()}
        edge = {(m["camera"], m["segment"]): m["edge_hit"] for m in temporal}
        for t in out:
            n, k = divmod(t["slot"], lane.segments)
            a = params.pair_of[n]
            shift = cues.get((a, k * stereo.segments // lane.segments), 0.0) if a != n else 0.0
            cue = cue_of(k, shift, {j: c for (pair, j), c in cues.items() if pair == a})
            if cue is not None and not edge[(n, k)]:
                if not keep_cue:
                    t["cue"] = int(fmt.quantize(cue))
            else:
                t["conf"] = 0
        return out
    return gap_study.patched(pl, "route_row", route_row)


def _bounds(lane):
    from golden.descriptor import segment_bounds
    return segment_bounds(lane.width, lane.descriptor, lane.match)


def column_cue_patch(config):
    """Each temporal segment's cue: the overlap-weighted mean of the usable stereo cues
    over the segment's columns (centre 0) as camera A sees them, instead of stereo
    segment ``k·K_s // K`` alone (the router's rule before the cue map), whose columns start at the stereo lane's first
    comparable column (76 on stereo20, 26 for the temporal lanes). Beyond the stereo
    lane's columns the nearest end segment; none usable: no weight."""
    temporal = _bounds(config.router.temporal)
    stereo = _bounds(config.router.stereo)

    def cue_of(k, shift, cues):
        lo = max(temporal[k][0] + shift, stereo[0][0])
        hi = min(temporal[k][1] + shift, stereo[-1][1])
        if hi <= lo:
            j = 0 if temporal[k][1] + shift <= stereo[0][0] else -1
            lo, hi = stereo[j][0], stereo[j][0] + 1
        parts = [(max(0.0, min(hi, s_hi) - max(lo, s_lo)), cues[j])
                 for j, (s_lo, s_hi) in enumerate(stereo) if j in cues]
        weight = sum(w for w, _ in parts)
        return sum(w * c for w, c in parts) / weight if weight > 0 else None
    return _cue_patch(config, cue_of)


def centre_cue_patch(config):
    """The hardware-friendly form of :func:`column_cue_patch`: the stereo cues
    interpolated linearly at the segment's centre column between the two stereo
    segment centres around it (equally spaced: a constant reciprocal), the nearer alone
    where the other is not usable, the end segment's beyond the first or last centre
    (no extrapolation)."""
    temporal = [(lo + hi - 1) / 2 for lo, hi in _bounds(config.router.temporal)]
    stereo = np.array([(lo + hi - 1) / 2 for lo, hi in _bounds(config.router.stereo)])

    def cue_of(k, shift, cues):
        if len(stereo) == 1:
            return cues.get(0)
        x = min(max(temporal[k] + shift, stereo[0]), stereo[-1])
        j = min(int(np.searchsorted(stereo, x, side="right")) - 1, len(stereo) - 2)
        w = (x - stereo[j]) / (stereo[j + 1] - stereo[j])
        near = [(cues[i], v) for i, v in ((j, 1 - w), (j + 1, w)) if i in cues]
        if len(near) == 2:
            return near[0][0] * near[0][1] + near[1][0] * near[1][1]
        return near[0][0] if near else None
    return _cue_patch(config, cue_of)


def coverage_patch(config, least=0.5):
    """No weight for a temporal segment whose columns, as camera A sees them (camera B's
    moved right by the pair's cue, as :func:`_cue_patch` gives it), lie less than
    ``least`` inside the stereo lane's compared columns; the router's cues otherwise."""
    temporal = _bounds(config.router.temporal)
    stereo = _bounds(config.router.stereo)
    first, last = stereo[0][0], stereo[-1][1]

    def cue_of(k, shift, cues):
        lo, hi = temporal[k][0] + shift, temporal[k][1] + shift
        inside = max(0.0, min(hi, last) - max(lo, first)) / (hi - lo)
        return None if inside < least else 0.0
    return _cue_patch(config, cue_of, keep_cue=True)


def row_residual_patch(config):
    """Each measured shift corrected by ``r·∂s/∂y`` (float): ``r`` = the segment's
    followed row minus its exact source row ``row − across``, ``∂s/∂y`` half the
    difference of the forecast's predicted shifts of the rows below and above."""
    import emulator.pose.tracking_loop as tl
    original = tl.TrackingLoopModel.close

    def close(self, transfers, slot, row):
        if transfers and self.prediction is not None:
            p, forecast = self.params, self.forecast
            cue = np.zeros(p.solver.slots, dtype=np.int64)
            cue[[t["slot"] for t in transfers]] = [t["cue"] for t in transfers]
            motion, unit = self.prediction["motion"], 1 << p.displacement_fmt.frac_bits
            r = self.prediction["segment_rows"].ravel() - (row - self.prediction["across"] / unit)
            below, _ = forecast._displacements(p.solver, self.coef_raw,
                                               min(row + 1, p.height - 1), cue, motion)
            above, _ = forecast._displacements(p.solver, self.coef_raw, max(row - 1, 0),
                                               cue, motion)
            slope = (below - above) / 2 / unit * (1 << p.solver.shift_fmt.frac_bits)
            transfers = [{**t, "shift": int(np.rint(t["shift"] - r[t["slot"]] *
                                                    slope[t["slot"]]))}
                         for t in transfers]
        return original(self, transfers, slot, row)
    return gap_study.patched(tl.TrackingLoopModel, "close", close)


def golden_swap(name):
    """Golden (b) with one of the hardware's simplifications (the ``gb_*`` runs of the
    module docstring but ``gb_mean_depth_linear``'s linear prediction), as a context
    manager."""
    import inspect
    import textwrap
    from golden import tracker as gt
    from golden.tracker_geometry import segment_means
    if name == "gb_word_rows":
        source = textwrap.dedent(inspect.getsource(gt.Tracker._segment_rows))
        exact = "by_column = segment_of(np.arange(cam.width) + centres[:, None])"
        if exact not in source:
            raise RuntimeError("golden.tracker._segment_rows changed: update gb_word_rows")
        source = source.replace(exact, (
            "words = np.minimum(np.arange(cam.width) // 36, "
            "(cam.width - 2 * self.desc.radius) // 36 - 1)\n"
            "    by_column = segment_of(36 * words + 18 + centres[:, None])"))
        space = dict(vars(gt))
        exec(source, space)
        return gap_study.patched(gt.Tracker, "_segment_rows", space["_segment_rows"])
    equations = gt.Tracker._equations

    def mean_depth(self, e):
        equations(self, e)
        table = self.design_tables[e.camera]
        usable = np.isfinite(e.inverse_depth) & np.isfinite(e.predicted)
        stride = self.params.geometry_stride
        lo, hi = -(-e.lo // stride), -(-e.hi // stride)
        zero = table.rows(e.rows, np.zeros_like(e.inverse_depth))
        unit = table.rows(e.rows, np.ones_like(e.inverse_depth))
        rotation, _ = segment_means(zero, usable, lo, hi)
        translation, _ = segment_means(unit - zero, usable, lo, hi)
        depth, _ = segment_means(np.where(usable, e.inverse_depth, 0.0), usable, lo, hi)
        e.design = rotation + translation * depth[..., None]
    return gap_study.patched(gt.Tracker, "_equations", mean_depth)


def golden_swap_steps(dataset, segments, name):
    """(frames, rows, raw measured steps) of golden (b), frozen forecast, with a swap."""
    linear = "time" if name == "gb_mean_depth_linear" else None
    with golden_swap("gb_word_rows" if name == "gb_word_rows" else "gb_mean_depth"):
        result = gap_study.golden_b(dataset, segments=segments, linear=linear, **FROZEN)
    return _golden_rows(dataset, result)


def camera_shares(dataset, config, patch=None):
    """(frames, rows, steps, shares): a hardware run with a frozen forecast and each
    row's error split into the cameras' shares (rows, cameras, 6; NaN where the row's
    float solve is singular), float: the weighted least-squares solve of the row's judged
    measurements (the solver's design rows from ``config.table`` and the cue), each
    measurement's error against the true motion carried through the solve's gain."""
    import emulator.pose.tracking_loop as tl
    from emulator.e2e import true_steps
    from golden.pose_lsq import ShiftCoefficients, design_rows, normal_equations
    taken, frame = [], {"index": 0, "row": -1}
    original = tl.TrackingLoopModel.close

    def close(self, transfers, slot, row):
        if row < frame["row"]:
            frame["index"] += 1
        frame["row"] = row
        judged, level = original(self, transfers, slot, row)
        s = self.params.solver
        if judged:
            taken.append((frame["index"], row, np.array([t["slot"] for t in judged]),
                          *(fmt.to_float(np.array([t[key] for t in judged])) for key, fmt in
                            (("shift", s.shift_fmt), ("conf", s.conf_fmt),
                             ("cue", s.cue_fmt)))))
        return judged, level
    with gap_study.patched(tl.TrackingLoopModel, "close", close):
        frames, rows, steps = hardware_steps(dataset, config, patch)
    segments = config.router.temporal.segments
    cameras, height = len(dataset.rig.cameras), dataset.rig.cameras[0].height
    shares = np.full((len(dataset.cameras[0].rows), height, cameras, 6), np.nan)
    for f, row, slots, shift, conf, cue in taken:
        a = design_rows(ShiftCoefficients.from_table(config.table[slots, row]), cue)
        normal, _ = normal_equations(a, shift, conf)
        if f < 1 or np.linalg.cond(normal) > 1e12:
            continue
        error = shift - a @ true_steps(dataset, np.array([f]), np.array([row]))[0]
        each = np.linalg.solve(normal, (a * (conf * error)[:, None]).T).T
        shares[f, row] = 0.0
        np.add.at(shares[f, row], slots // segments, each)
    return frames, rows, steps, shares[frames, rows]


def slow_part(error, frames, window):
    """Per axis: the RMS of the ``window``-row moving means of ``error`` (rows, 6; a row
    not solved is NaN and left out of its windows' means) within each of ``frames`` equal
    frames, and the mean correlation of those means between frames (NaN with one frame)."""
    per_frame = error.reshape(frames, -1, error.shape[1])
    solved = np.isfinite(per_frame)
    kernel = np.ones(window)

    def moving(values):
        return np.array([[np.convolve(f[:, a], kernel, "valid") for a in range(f.shape[1])]
                         for f in values])                           # (frames, 6, n)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = moving(np.where(solved, per_frame, 0.0)) / moving(solved.astype(float))
    rms = np.sqrt(np.nanmean(means**2, axis=(0, 2)))
    if frames < 2:
        return rms, np.full(len(rms), np.nan)
    upper = np.triu_indices(frames, 1)
    alike = np.array([np.corrcoef(means[:, a])[upper].mean() for a in range(means.shape[1])])
    return rms, alike


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--segments", type=int, default=8)
    ap.add_argument("--stereo-segments", type=int, default=8)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--only", default=None)
    ap.add_argument("--window", type=int, default=None, metavar="W")
    ap.add_argument("--by-camera", action="store_true",
                    help="also each camera's share of the Ty error (runs hw, coverage)")
    args = ap.parse_args(argv)
    if args.by_camera and not args.window:
        ap.error("--by-camera needs --window")
    from emulator.benches.hw_tracking import MOTIONS
    from emulator.benches.tracker import _first_frames, noisy_sequence
    from emulator.e2e import true_steps
    from hdl.pipeline_config import PipelineConfig
    dataset = _first_frames(noisy_sequence("stereo20", "paper", MOTIONS["paper"]),
                            args.frames)
    config = PipelineConfig.for_rig(dataset.rig, segments=args.segments,
                                    stereo_segments=args.stereo_segments)
    runs = {
        "golden_b": lambda: golden_steps(dataset, args.segments),
        "hw": lambda: hardware_steps(dataset, config),
        "oracle_own": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, "own")),
        "oracle_stereo": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, "stereo")),
        "oracle_own_a": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, own_role="A")),
        "oracle_own_b": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.oracle_cue_patch(dataset, c, own_role="B")),
        "float_match": lambda: hardware_steps(
            dataset, config, lambda c: gap_study.float_match_patch(dataset, c)),
        "float_solver": lambda: hardware_steps(dataset, config, gap_study.float_solver_patch),
        "depth_weight": lambda: hardware_steps(dataset, config, gap_study.depth_weight_patch),
        "column_cue": lambda: hardware_steps(dataset, config, column_cue_patch),
        "centre_cue": lambda: hardware_steps(dataset, config, centre_cue_patch),
        "coverage": lambda: hardware_steps(dataset, config, coverage_patch),
        "row_residual": lambda: hardware_steps(dataset, config, row_residual_patch),
        **{name: (lambda name=name: golden_swap_steps(dataset, args.segments, name))
           for name in ("gb_mean_depth", "gb_mean_depth_linear", "gb_word_rows")},
    }
    patches = {"hw": None, "coverage": coverage_patch}
    wanted = list(runs) if args.only is None else args.only.split(",")
    unknown = sorted(set(wanted) - set(runs))
    if unknown:
        ap.error(f"--only: unknown runs {unknown}; choose from {sorted(runs)}")
    print(f"K = {args.segments}, K_s = {args.stereo_segments}, frames 1..{args.frames - 1};"
          " errors of the raw steps in cm and 1e-4 rad (Tx Ty Tz θx θy θz)", flush=True)
    for name in wanted:
        start = time.time()
        shares = None
        if args.by_camera and name in patches:
            frames, rows, steps, shares = camera_shares(dataset, config, patches[name])
        else:
            frames, rows, steps = runs[name]()
        error = (steps - true_steps(dataset, frames, rows)) * UNITS
        finite = np.all(np.isfinite(error), axis=1)
        lines = [("mean", error[finite].mean(axis=0)), ("std", error[finite].std(axis=0))]
        if args.window:
            slow, alike = slow_part(np.where(finite[:, None], error, np.nan),
                                    args.frames - 1, args.window)
            lines += [("slow", slow), ("alike", alike)]
        for label, values in lines:
            print(f"{name:14s} {label:4s} " + " ".join(f"{v:+8.4f}" for v in values),
                  flush=True)
        if shares is not None:
            _print_shares(name, shares[:, :, 1] * UNITS[1], args.frames - 1, args.window)
        print(f"{name:14s} rows {finite.sum()}, {time.time() - start:.0f} s", flush=True)


def _print_shares(name, shares, frames, window):
    """Each camera's Ty share (rows, cameras): its mean, slow part and frame likeness."""
    for n in range(shares.shape[1]):
        share = shares[:, n]
        slow, alike = slow_part(share[:, None], frames, window)
        print(f"{name:14s} camera {n:2d} Ty mean {np.nanmean(share):+.4f} "
              f"slow {slow[0]:.4f} alike {alike[0]:+.2f}", flush=True)


if __name__ == "__main__":
    sys.exit(main())

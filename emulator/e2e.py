"""Level-1 and level-2 comparison of the hardware path (:mod:`emulator.hardware_path`:
the bit-accurate emulator's closed measurement loop, issue 16) against ground truth,
against the golden tracker's reference (b) with the same loop delay, and against float64
on its own measurements.

The quantity compared is the one-frame motion ``Y = [T θ]`` of each row (the papers'
Table 1 quantity). The hardware path's estimate is its motion track's ``Y`` (golden (b)'s
pose track read in ``Y``: :meth:`emulator.hardware_path.HardwarePath.estimate`); the
forecast filter's level after each row's step and the solver's raw steps are compared
beside it. The truth is the exact body-frame step from the pose of the same row
one frame earlier (:func:`true_steps`).

Tolerances (:func:`check_closed_loop`, from issue 16's targets): per axis, the
estimate's RMS against truth at most :data:`GOLDEN_B_RATIO` × golden (b)'s and at most
:data:`SHARE_OF_MOTION` × the true motion's RMS; at least :data:`SOLVED_FRACTION` of the
rows of frames ≥ 1 solved; level 2: the fixed-point solver within :data:`FLOAT_TOLERANCE`
of a float64 solve of the same routed measurements, and the lanes' measurements in the
loop against the float matcher on the same rows and centres (:func:`lane_agreement`,
:data:`SUBPIXEL_SHARE` within :data:`SUBPIXEL_TOLERANCE`, none beyond
:data:`SHIFT_BOUND`). The pipeline is fed row sets of row ``y`` of every camera; a rig
whose trigger offsets put its cameras further apart than the front end's row aligner can
buffer (:meth:`hdl.pipeline_config.PipelineConfig.alignment_shortfall`) fails too: the
hardware could not form those row sets.
"""

import numpy as np

from golden.descriptor import describe, match, strength
from golden.pose_lsq import UNKNOWNS, ShiftCoefficients, body_step, quat_to_matrix, solve_step

__all__ = ["true_steps", "golden_steps", "golden_poses", "golden_trajectory_steps",
           "float_steps", "agreement",
           "pose_errors", "relative_poses", "compare_closed_loop", "lane_agreement",
           "check_closed_loop", "GOLDEN_B_RATIO", "SHARE_OF_MOTION", "SOLVED_FRACTION",
           "FLOAT_TOLERANCE", "WELL_TEXTURED", "SUBPIXEL_TOLERANCE", "SUBPIXEL_SHARE",
           "SHIFT_BOUND"]

#: Issue 16's target: per axis, the hardware path's per-row Y RMS against truth at most
#: this multiple of golden (b)'s with the same loop delay (docs/results/hw_tracking.md
#: measures 2.2–4.2× on the tracker benchmark's stereo20 sequence: missed today).
GOLDEN_B_RATIO = 1.5
#: Per axis, the hardware path's per-row Y RMS against truth at most this share of the
#: true one-frame motion's RMS (the absolute bound of sim_tests/pose/test_closed_loop.py;
#: measured there at most 0.11, Ty). An estimate no better than this does not track.
SHARE_OF_MOTION = 0.2
#: Issue 16's target: at least this share of the rows of frames ≥ 1 solved.
SOLVED_FRACTION = 0.95
#: Level 2: per axis (m, rad), the emulator's solved steps against a float64 solve of the
#: same routed measurements (:func:`float_steps`): the fixed-point solver's error alone.
#: Measured in the closed loop: RMS ≤ 7e-8 (stereo20 cut to 32 rows, 3 frames) — see
#: docs/e2e.md; the solver's exact-shift test holds 1e-6 on the worst row.
FLOAT_TOLERANCE = 1e-6
#: Level 2 of the lanes in the loop (:func:`lane_agreement`): a measurement is well
#: textured where the float matcher's and the lane's peak ratio are both at least this;
#: that share of them must agree within the lanes' documented sub-pixel tolerance
#: (docs/descriptor/row_descriptor.md), and every one within SHIFT_BOUND px (the open
#: loop's bounds). The integer kernel flips a few descriptor bits of a segment and the
#: parabola through the costs moves with them. Measured in the closed loop, stereo20
#: 640×480, 4 frames, seed 1: 99.4 % of 64,793 within 1/16 px, worst 0.179 px. With the
#: float ratio alone (the open loop's rule) one more segment counted, float 1.55 but
#: lane 1.23 — weak by the lane's own measure —, and differed by 0.396 px: hence both.
WELL_TEXTURED = 1.5
SUBPIXEL_TOLERANCE = 1 / 16
SUBPIXEL_SHARE = 0.97
SHIFT_BOUND = 0.25

#: A row and a golden slot are the same when their times differ by less than this (s):
#: slot times are recomputed from the row period, so they carry rounding error.
SLOT_TIME_TOLERANCE = 1e-9


def true_steps(dataset, frames, rows, camera=0):
    """Exact one-frame motions (n, 6) at the rows ``(frames, rows)`` of ``camera``;
    NaN in the first frame (no previous frame)."""
    frames, rows = np.asarray(frames), np.asarray(rows)
    rec = dataset.cameras[camera]
    out = np.full((len(frames), 6), np.nan)
    ok = frames > 0
    out[ok] = body_step(rec.rotation[frames[ok] - 1, rows[ok]],
                        rec.position[frames[ok] - 1, rows[ok]],
                        rec.rotation[frames[ok], rows[ok]], rec.position[frames[ok], rows[ok]])
    return out


def _golden_slots(track_result, dataset, frames, rows, camera=0):
    """The golden tracker's slot of each row ``(frames, rows)`` of ``camera``."""
    times = dataset.cameras[camera].time[np.asarray(frames), np.asarray(rows)]
    slot = np.searchsorted(track_result.times, times - SLOT_TIME_TOLERANCE)
    slot = np.clip(slot, 0, len(track_result.times) - 1)
    if not np.allclose(track_result.times[slot], times, rtol=0, atol=SLOT_TIME_TOLERANCE):
        raise ValueError("rows do not fall on the golden tracker's slots")
    return slot


def golden_steps(track_result, dataset, frames, rows, camera=0):
    """The golden tracker's smoothed one-frame motion (n, 6) of the slot of each row
    ``(frames, rows)`` of ``camera``; NaN where that slot made no measurement step."""
    slot = _golden_slots(track_result, dataset, frames, rows, camera)
    made_step = track_result.tracked[slot] & track_result.updated[slot]
    return np.where(made_step[:, None], track_result.motion[slot], np.nan)


def golden_poses(track_result, dataset, frames, rows, camera=0):
    """The golden tracker's pose (rotation (n, 3, 3), position (n, 3)) at the slot of
    each row (on the first frame's slots, the ground truth it was given)."""
    slot = _golden_slots(track_result, dataset, frames, rows, camera)
    return track_result.rotations[slot], track_result.positions[slot]


def golden_trajectory_steps(track_result, dataset, frames, rows, camera=0):
    """The golden tracker's one-frame motion (n, 6) of each row ``(frames, rows)`` from its
    trajectory: the body-frame step from its pose at the same row one frame earlier to
    its pose at the row — what :func:`golden.metrics.evaluate` scores (``rms_t_cm``,
    ``rms_r_rad``), the papers' Table 1 quantity. NaN in frame 0 and on untracked slots."""
    frames, rows = np.asarray(frames), np.asarray(rows)
    out = np.full((len(frames), 6), np.nan)
    ok = frames > 0
    before = golden_poses(track_result, dataset, frames[ok] - 1, rows[ok], camera)
    after = golden_poses(track_result, dataset, frames[ok], rows[ok], camera)
    tracked = track_result.tracked[_golden_slots(track_result, dataset, frames[ok],
                                                 rows[ok], camera)]
    out[ok] = np.where(tracked[:, None], body_step(*before, *after), np.nan)
    return out


def float_steps(config, rows):
    """float64 least-squares steps (:func:`golden.pose_lsq.solve_step`) of the routed,
    quantized measurements ``rows`` with the float coefficients: the emulator's solver
    without its fixed-point arithmetic and coefficient rounding. NaN where not solved."""
    solver = config.router.solver
    coefficients = ShiftCoefficients.from_table(config.table[rows.slot, rows.row[:, None]])
    weight = np.where(rows.present, solver.conf_fmt.to_float(rows.conf), 0.0)
    solution = solve_step(coefficients, solver.cue_fmt.to_float(rows.cue),
                          solver.shift_fmt.to_float(rows.shift), weight)
    return np.where(solution.ok[:, None], solution.step, np.nan)


def _record_poses(config, result):
    """Frames, rows and the integrated poses (rotation, position) of the records of
    frames ≥ 1."""
    solver, records = config.router.solver, result.records
    use = result.frame > 0
    q = solver.quat_fmt.to_float(records["q"][use])
    return (result.frame[use], records["row"][use],
            quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True)),
            solver.position_fmt.to_float(records["p"][use]))


def _true_relative(dataset, frames, rows, camera):
    """The true pose of rows ``(frames, rows)`` relative to the same rows of frame 0."""
    rec = dataset.cameras[camera]
    start_r, start_p = rec.rotation[0, rows], rec.position[0, rows]
    return (np.swapaxes(start_r, -1, -2) @ rec.rotation[frames, rows],
            np.einsum("nji,nj->ni", start_r, rec.position[frames, rows] - start_p))


def pose_errors(config, result, dataset, camera=0):
    """Error ``[T θ]`` (n, 6) of each record's integrated pose against ground truth,
    records of frames ≥ 1.

    The solver keeps one pose per row slot, starting at the reset pose, and composes
    each row's one-frame step onto its slot's pose of the previous frame
    (:func:`emulator.pose_solver.integrate_rows`); so a record of frame ``i``, row ``y``
    is the rig's pose relative to row ``y`` of frame 0. The truth is the same relative
    pose from the dataset, and the error is the body-frame step between the two."""
    frames, rows, est_r, est_p = _record_poses(config, result)
    return body_step(*_true_relative(dataset, frames, rows, camera), est_r, est_p)


def relative_poses(config, result, dataset, track_result, camera=0):
    """The trajectory of the records of frames ≥ 1 as poses relative to the same row of
    frame 0, ``[T θ]`` (n, 6): ``(frames, rows, {"truth", "hardware path", "golden (b)":
    (n, 6)})``; the hardware's are its records' integrated poses (:func:`pose_errors`),
    the golden's its poses at the same rows (``track_result``)."""
    frames, rows, est_r, est_p = _record_poses(config, result)
    identity = np.broadcast_to(np.eye(3), est_r.shape)
    start_r, start_p = golden_poses(track_result, dataset, np.zeros_like(rows), rows, camera)
    golden_r, golden_p = golden_poses(track_result, dataset, frames, rows, camera)
    golden = body_step(start_r, start_p, golden_r, golden_p)
    return frames, rows, {
        "truth": body_step(identity, np.zeros_like(est_p),
                           *_true_relative(dataset, frames, rows, camera)),
        "hardware path": body_step(identity, np.zeros_like(est_p), est_r, est_p),
        "golden (b)": golden}


def agreement(steps, reference):
    """Per-axis RMS, median and largest absolute difference of two (n, 6) step arrays over the
    rows where both are finite, and how many rows that is."""
    both = np.all(np.isfinite(steps) & np.isfinite(reference), axis=1)
    diff = steps[both] - reference[both]
    figures = {"rows": int(both.sum())}
    for k, name in enumerate(UNKNOWNS):
        figures[f"rms.{name}"] = float(np.sqrt(np.mean(diff[:, k] ** 2))) if both.any() \
            else float("nan")
        figures[f"median_abs.{name}"] = float(np.median(np.abs(diff[:, k]))) if both.any() \
            else float("nan")
        figures[f"max_abs.{name}"] = float(np.max(np.abs(diff[:, k]))) if both.any() \
            else float("nan")
    return figures


def compare_closed_loop(path, dataset, golden_b, golden=None):
    """Figures (flat dict, dotted keys, m and rad) of the hardware path ``path``
    (:class:`emulator.hardware_path.HardwarePath`) against truth and against golden (b)
    (``golden_b``, a :class:`golden.tracker.TrackResult` of
    :func:`emulator.hardware_path.golden_b_params` on ``dataset``), each
    ``<a>_vs_<b>.{rms,median_abs,max_abs}.<axis>`` over the rows where both are defined:

    ``emulator_vs_truth`` (the estimate, :meth:`HardwarePath.estimate`; ``estimate``
    names it), ``emulator_level_vs_truth`` (the filter's level, reported),
    ``emulator_steps_vs_truth`` (the raw solved steps), ``golden_b_vs_truth`` (golden (b)'s Y from its trajectory,
    :func:`golden_trajectory_steps`: the figure of :func:`golden.metrics.evaluate` and of
    ``rowtrack bench --only hw_tracking``, the judge's reference),
    ``golden_b_motion_vs_truth`` (its filter's motion, :func:`golden_steps`, reported),
    ``emulator_vs_golden_b`` (the estimate), ``true_motion`` (the truth
    against zero: the motion's own RMS), ``emulator_vs_float`` (level 2: the solver
    against float64 on the same routed measurements), ``emulator_pose_vs_truth``, with
    ``golden`` (the default golden tracker) also ``golden_vs_truth``; and
    ``ratio_to_golden_b.<axis>``, ``share_of_motion.<axis>``, ``solved_fraction`` (rows
    of frames ≥ 1), ``loop_delay_rows`` and ``loop_delay_clocks`` (rows × row period at
    the pipeline's clock), ``motion_gain`` (the filter's gain law, golden (b)'s too), ``lanes.*`` (:func:`lane_agreement`, ``lanes.worst_at``),
    ``front_end.trigger_skew_rows``, ``front_end.skew_rows_held`` and
    ``front_end.shortfall`` (:meth:`hdl.pipeline_config.PipelineConfig.alignment_shortfall`:
    ``None`` when the row aligner can form the row sets the pipeline is fed)."""
    frames, rows, estimate, label = path.estimate()
    level = path.levels()[2]
    truth = true_steps(dataset, frames, rows)
    step_frames, step_rows, steps = path.steps()
    result, config = path.result, path.config
    t_r = dataset.rig.cameras[0].t_r
    figures = {"solved_fraction": float(np.mean(np.isfinite(steps[:, 0])))
               if len(steps) else float("nan"),
               "loop_delay_rows": path.loop_delay_rows,
               "estimate": label,
               "motion_gain": path.forecast.motion_gain,
               "loop_delay_clocks": int(round(path.loop_delay_rows * t_r * config.clk_hz)),
               "emulator_rows_per_s": result.rows_per_s}
    gold_b = golden_trajectory_steps(golden_b, dataset, frames, rows)
    pairs = {"emulator_vs_truth": (estimate, truth),
             "emulator_level_vs_truth": (level, truth),
             "emulator_steps_vs_truth": (steps, true_steps(dataset, step_frames, step_rows)),
             "golden_b_vs_truth": (gold_b, truth),
             "golden_b_motion_vs_truth": (golden_steps(golden_b, dataset, frames, rows),
                                          truth),
             "emulator_vs_golden_b": (estimate, gold_b),
             "true_motion": (truth, np.zeros_like(truth)),
             "emulator_vs_float": (result.steps(config), float_steps(config, result.rows))}
    figures.update({"front_end.trigger_skew_rows": config.trigger_skew_rows,
                    "front_end.skew_rows_held": config.top.camera.skew_rows_held(
                        config.router.temporal.width),
                    "front_end.shortfall": config.alignment_shortfall()})
    if golden is not None:
        pairs["golden_vs_truth"] = (golden_trajectory_steps(golden, dataset, frames, rows),
                                    truth)
    for name, (a, b) in pairs.items():
        figures.update({f"{name}.{key}": value for key, value in agreement(a, b).items()})
    error = pose_errors(config, result, dataset)
    figures.update({f"emulator_pose_vs_truth.{key}": value
                    for key, value in agreement(error, np.zeros_like(error)).items()})
    lanes, where = lane_agreement(path, dataset)
    figures.update({f"lanes.{key}": value for key, value in lanes.items()})
    if where is not None:
        figures["lanes.worst_at"] = "frame {}, row {}, camera {}, segment {}".format(*where)
    with np.errstate(divide="ignore", invalid="ignore"):
        for name in UNKNOWNS:
            rms = figures[f"emulator_vs_truth.rms.{name}"]
            gold = figures[f"golden_b_vs_truth.rms.{name}"]
            figures[f"ratio_to_golden_b.{name}"] = rms / gold
            figures[f"share_of_motion.{name}"] = rms / figures[f"true_motion.rms.{name}"]
    return figures


def _unit(name):
    return "m" if name.startswith("T") else "rad"


def check_closed_loop(figures):
    """Failure lines (empty when the hardware path meets its tolerances) for the
    figures of :func:`compare_closed_loop`, one per axis and bound, each with the
    measured value and the bound."""
    failures = []
    lanes = f"worst at {figures.get('lanes.worst_at')}: {figures['lanes.max_shift_px']:.3f} px"
    if not figures["lanes.well_textured"]:
        failures.append("lanes ↔ float matcher: no well-textured measurement to compare")
    elif not figures["lanes.within_subpixel"] >= SUBPIXEL_SHARE:
        failures.append(f"lanes ↔ float matcher: {figures['lanes.within_subpixel']:.1%} of "
                        f"well-textured shifts within {SUBPIXEL_TOLERANCE} px, below "
                        f"{SUBPIXEL_SHARE:.0%} ({lanes})")
    if figures["lanes.max_shift_px"] > SHIFT_BOUND:
        failures.append(f"lanes ↔ float matcher: a well-textured shift differs by more than "
                        f"{SHIFT_BOUND} px ({lanes})")
    if figures.get("front_end.shortfall"):
        failures.append(f"front end: {figures['front_end.shortfall']}; the hardware path "
                        f"assumes row sets this front end cannot form")
    solved = figures["solved_fraction"]
    if not solved >= SOLVED_FRACTION:
        failures.append(f"hardware path: {solved:.1%} of the rows of frames ≥ 1 solved, "
                        f"below {SOLVED_FRACTION:.0%}")
    for name in UNKNOWNS:
        unit = _unit(name)
        rms = figures[f"emulator_vs_truth.rms.{name}"]
        gold = figures[f"golden_b_vs_truth.rms.{name}"]
        motion = figures[f"true_motion.rms.{name}"]
        ratio = figures[f"ratio_to_golden_b.{name}"]
        share = figures[f"share_of_motion.{name}"]
        if not ratio <= GOLDEN_B_RATIO:
            failures.append(f"hardware path {name}: per-row Y RMS {rms:.3g} {unit} against "
                            f"truth is {ratio:.2f} × golden (b)'s {gold:.3g} {unit} (same "
                            f"loop delay); bound {GOLDEN_B_RATIO} ×")
        if not share <= SHARE_OF_MOTION:
            failures.append(f"hardware path {name}: per-row Y RMS {rms:.3g} {unit} against "
                            f"truth is {share:.2f} of the true motion's RMS {motion:.3g} "
                            f"{unit}; bound {SHARE_OF_MOTION}")
        solver = figures[f"emulator_vs_float.rms.{name}"]
        if not solver <= FLOAT_TOLERANCE:
            failures.append(f"emulator ↔ float64 solve of its own measurements {name}: step "
                            f"RMS {solver:.3g} {unit}; bound {FLOAT_TOLERANCE:g} over "
                            f"{figures['emulator_vs_float.rows']} rows")
    return failures


def _lane_measurements(path):
    """The temporal lanes' measurements of every row set, (rows, cameras, K) arrays:
    shift + subpixel (px), peak ratio, and whether the lane had no reference row."""
    lane, cameras = path.config.router.temporal, path.config.router.cameras
    t = path.result.temporal

    def field(name):
        return np.array([m[name] for m in t], dtype=np.int64).reshape(-1, cameras,
                                                                       lane.segments)
    shift = lane.shift_fmt.to_float(field("shift")) + \
        lane.subpixel_fmt.to_float(field("subpixel"))
    return shift, lane.confidence_fmt.to_float(field("confidence")), \
        field("no_reference").astype(bool) | field("edge_hit").astype(bool)


def followed_rows(lane, bits, frames, sources, centre):
    """The reference rows (n, W) following lanes read from descriptor bits ``bits``
    (frames, H, W): row ``sources[i]`` (K rows, one per segment) of frame ``frames[i]``,
    each column from its segment's row (``lane.column_segments(centre)``)."""
    pick = np.array(lane.column_segments(centre))                      # (W,)
    rows = np.asarray(sources)[:, pick]                                # (n, W)
    return bits[np.asarray(frames)[:, None], rows, np.arange(bits.shape[-1])]


def lane_agreement(path, dataset):
    """Level 2 of the lanes inside the loop: each temporal measurement of frames ≥ 1
    against :func:`golden.descriptor.match` (the float kernel) of the same current row
    and the same stored rows of the previous frame the forecast named
    (:func:`followed_rows`), at the same window centre. Figures (flat dict):
    ``well_textured`` (both kernels' peak ratio ≥ :data:`WELL_TEXTURED`, neither side
    at the window edge, a reference row),
    ``within_subpixel`` (their share within :data:`SUBPIXEL_TOLERANCE`),
    ``max_shift_px``; and where the worst is, ``(frame, row, camera, segment, px)``."""
    lane, loop = path.config.router.temporal, path.result.loop
    shift, confidence, unusable = _lane_measurements(path)
    later = np.flatnonzero(loop["frame"] > 0)
    frame, row = loop["frame"][later], loop["row"][later]
    diff = np.full((len(later),) + shift.shape[1:], np.nan)
    for n in range(shift.shape[1]):
        pixels = np.asarray(dataset.cameras[n].rows[:frame.max() + 1], dtype=np.float64)
        bits, strong = describe(pixels, lane.descriptor), strength(pixels, lane.descriptor)
        centre, source = loop["centre"][later, n], loop["segment_rows"][later, n]
        for c in np.unique(centre):
            i = np.flatnonzero(centre == c)
            m = match(bits[frame[i], row[i]],
                      followed_rows(lane, bits, frame[i] - 1, source[i], int(c)),
                      lane.descriptor, lane.match, int(c),
                      cur_strong=strong[frame[i], row[i]])
            good = (m.peak_ratio >= WELL_TEXTURED) & ~m.edge_hit & \
                (confidence[later[i], n] >= WELL_TEXTURED) & ~unusable[later[i], n]
            diff[i, n] = np.where(good, np.abs(shift[later[i], n] - m.shift), np.nan)
    good = np.isfinite(diff)
    if not good.any():
        return {"well_textured": 0, "within_subpixel": float("nan"),
                "max_shift_px": float("nan")}, None
    worst = np.unravel_index(np.nanargmax(diff), diff.shape)
    where = (int(frame[worst[0]]), int(row[worst[0]]), int(worst[1]), int(worst[2]),
             float(diff[worst]))
    return {"well_textured": int(good.sum()),
            "within_subpixel": float(np.mean(diff[good] <= SUBPIXEL_TOLERANCE)),
            "max_shift_px": float(np.nanmax(diff))}, where

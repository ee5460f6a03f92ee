"""Level-2 comparison of the bit-accurate pipeline: its per-row steps against the golden
tracker's and against ground truth, on the same dataset rows.

The quantity compared is the one-frame motion ``Y = [T θ]`` of each row slot (the
pipeline's solved step, :mod:`emulator.pipeline`; ``TrackResult.motion`` of
:func:`golden.tracker.track`; the exact body-frame step from the pose of the same row
one frame earlier). The records' integrated poses are compared with ground truth too
(:func:`pose_errors`): the solver composes each row's step onto the same row's pose one
frame earlier, so they are poses relative to the first frame's rows.

The hardware scheme (each row against the same row of the previous frame, search
centre 0) differs from the golden tracker's (forecast window, rows followed), so
emulator ↔ golden is judged against :func:`scheme_steps`, the hardware's scheme in
float64, with the tolerances stated below; the golden tracker's accuracy against truth
is reported, not compared.
"""

from dataclasses import dataclass

import numpy as np

from golden.descriptor import describe, match, strength
from golden.pose_lsq import UNKNOWNS, ShiftCoefficients, body_step, quat_to_matrix, solve_step

__all__ = ["true_steps", "golden_steps", "float_steps", "agreement", "compare_steps",
           "pose_errors",
           "SchemeResult", "scheme_steps", "measurement_agreement", "check_tolerances",
           "SUBPIXEL_TOLERANCE", "WELL_TEXTURED", "STEP_TOLERANCE"]

#: The lanes' documented sub-pixel agreement with the float matcher (docs/descriptor/row_descriptor.md).
SUBPIXEL_TOLERANCE = 1 / 16
#: A segment is well textured where the float scheme's weight (peak ratio) is at least
#: this, as in the lanes' own comparison with the golden matcher.
WELL_TEXTURED = 1.5
#: Share of well-textured measurements that must agree within SUBPIXEL_TOLERANCE, and the
#: bound on every one of them (px). Measured on stereo20 640×480, 4 frames: 98.6 %,
#: worst 0.20 px (paper motion, seed 1); the integer kernel flips a few bits of a
#: segment and the parabola through the costs moves with them.
SUBPIXEL_SHARE = 0.97
SHIFT_BOUND = 0.25
#: Per-axis RMS bound of emulator − float-scheme steps (m, rad). Measured on the same
#: run: 5.1e-4 7.2e-4 7.0e-4, 3.6e-4 1.6e-4 2.2e-4; a few weak segments whose integer
#: argmin differs move single rows by up to 1e-2, so the maximum is reported, not bounded.
STEP_TOLERANCE = 2e-3

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


def golden_steps(track_result, dataset, frames, rows, camera=0):
    """The golden tracker's smoothed one-frame motion (n, 6) of the slot of each row
    ``(frames, rows)`` of ``camera``; NaN where that slot made no measurement step."""
    times = dataset.cameras[camera].time[np.asarray(frames), np.asarray(rows)]
    slot = np.searchsorted(track_result.times, times - SLOT_TIME_TOLERANCE)
    slot = np.clip(slot, 0, len(track_result.times) - 1)
    if not np.allclose(track_result.times[slot], times, rtol=0, atol=SLOT_TIME_TOLERANCE):
        raise ValueError("rows do not fall on the golden tracker's slots")
    made_step = track_result.tracked[slot] & track_result.updated[slot]
    return np.where(made_step[:, None], track_result.motion[slot], np.nan)


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


@dataclass(frozen=True)
class SchemeResult:
    """The golden counterpart of the hardware scheme, rows ``(frame, row)`` of frames
    1 … F−1 in (frame, row) order; measurement arrays (n, slots), slot = camera·K + k.

    Members
    -------
    frame, row : ndarray (n,)
    shift, cue, weight : ndarray (n, slots)
        Float shift (px), disparity cue (px; 0 where unusable) and weight (the peak
        ratio; 0 where the router would give 0).
    steps : ndarray (n, 6)
        :func:`golden.pose_lsq.solve_step` of those measurements; NaN where not solved.
    """
    frame: np.ndarray
    row: np.ndarray
    shift: np.ndarray
    cue: np.ndarray
    weight: np.ndarray
    steps: np.ndarray


def _float_bits(pixels, lane):
    """Float descriptor bits and strong columns of rows ``(..., W)``."""
    rows = np.asarray(pixels, dtype=np.float64)
    return describe(rows, lane.descriptor), strength(rows, lane.descriptor)


def scheme_steps(config, dataset, frames):
    """The hardware's measurement scheme in float64: each camera's row ``y`` of frame
    ``i`` matched by :func:`golden.descriptor.match` against row ``y`` of frame ``i − 1``
    (centre 0, the lanes' K segments), each pair's disparity by the float stereo match
    of the same rows, the router's rules for cue and weight, the float coefficient table
    and :func:`golden.pose_lsq.solve_step`. What the emulator must equal up to its
    fixed-point arithmetic; frames ``1 … frames − 1``."""
    router = config.router
    temporal, stereo = router.temporal, router.stereo
    height, k = temporal.height, temporal.segments
    bits, strong = zip(*(_float_bits(dataset.cameras[n].rows[:frames], temporal)
                         for n in range(router.cameras)))
    cues = {}
    for a, b in router.pairs:
        m = match(bits[a], bits[b], stereo.descriptor, stereo.match, 0, cur_strong=strong[a])
        usable = (m.peak_ratio > 0) & ~m.edge_hit & (m.shift > 0)
        cues[a] = np.where(usable, m.shift, np.nan)[1:]             # (F−1, H, K_s)
    shift, cue, weight = [], [], []
    for n in range(router.cameras):
        m = match(bits[n][1:], bits[n][:-1], temporal.descriptor, temporal.match, 0,
                  cur_strong=strong[n][1:])
        c = cues[router.pair_of[n]][..., np.arange(k) * stereo.segments // k]
        usable = np.isfinite(c) & ~m.edge_hit
        shift.append(m.shift)
        cue.append(np.where(usable, c, 0.0))
        weight.append(np.where(usable, m.peak_ratio, 0.0))
    n_rows = (frames - 1) * height

    def slots(parts):
        return np.concatenate(parts, axis=-1).reshape(n_rows, -1)
    shift, cue, weight = slots(shift), slots(cue), slots(weight)
    frame, row = np.divmod(np.arange(n_rows), height)
    coefficients = ShiftCoefficients.from_table(config.table[:, row].transpose(1, 0, 2))
    solution = solve_step(coefficients, cue, shift, weight)
    return SchemeResult(frame=frame + 1, row=row, shift=shift, cue=cue, weight=weight,
                        steps=np.where(solution.ok[:, None], solution.step, np.nan))



def emulator_measurements(config, result):
    """The emulator's routed shifts (px) and weights (n, slots) of the records of frames
    ≥ 1, in :class:`SchemeResult` order (slot = column)."""
    solver, rows = config.router.solver, result.rows
    records = np.flatnonzero(result.frame > 0)
    shift = np.zeros((len(records), solver.slots))
    weight = np.zeros_like(shift)
    index = np.arange(len(records))[:, None]
    slot = rows.slot[records]
    present = rows.present[records]
    shift[index, slot] = np.where(present, solver.shift_fmt.to_float(rows.shift[records]), 0)
    weight[index, slot] = np.where(present, solver.conf_fmt.to_float(rows.conf[records]), 0)
    return shift, weight


def measurement_agreement(config, result, scheme):
    """Emulator ↔ float scheme per measurement: figures (flat dict) and where the worst
    well-textured difference is, ``(frame, row, camera, segment, difference)``."""
    if not (np.array_equal(result.frame[result.frame > 0], scheme.frame)
            and np.array_equal(result.records["row"][result.frame > 0], scheme.row)):
        raise ValueError("emulator records and the float scheme cover different rows")
    shift, weight = emulator_measurements(config, result)
    good = scheme.weight >= WELL_TEXTURED
    diff = np.abs(shift - scheme.shift)
    worst = np.unravel_index(np.argmax(np.where(good, diff, -1)), diff.shape)
    k = config.router.temporal.segments
    where = (int(scheme.frame[worst[0]]), int(scheme.row[worst[0]]), int(worst[1] // k),
             int(worst[1] % k), float(diff[worst]))
    figures = {"well_textured": int(good.sum()),
               "within_subpixel": float(np.mean(diff[good] <= SUBPIXEL_TOLERANCE))
               if good.any() else float("nan"),
               "max_shift_px": float(diff[good].max()) if good.any() else float("nan"),
               "weight_disagrees": float(np.mean((weight > 0) != (scheme.weight > 0)))}
    return figures, where


def check_tolerances(figures, where):
    """Failure messages (empty when the emulator meets the stated tolerances) for the
    figures of :func:`compare_steps` with ``scheme`` and ``where`` from
    :func:`measurement_agreement`."""
    failures = []
    frame, row, camera, segment, worst = where
    at = f"worst at frame {frame}, row {row}, camera {camera}, segment {segment}: {worst:.3f} px"
    if not figures["measurement.well_textured"]:
        failures.append("emulator ↔ golden scheme: no well-textured measurement to compare")
    elif figures["measurement.within_subpixel"] < SUBPIXEL_SHARE:
        failures.append(f"emulator ↔ golden scheme: {figures['measurement.within_subpixel']:.1%} "
                        f"of well-textured shifts within {SUBPIXEL_TOLERANCE} px, below "
                        f"{SUBPIXEL_SHARE:.0%} ({at})")
    if figures.get("measurement.max_shift_px", 0) > SHIFT_BOUND:
        failures.append(f"emulator ↔ golden scheme: a well-textured shift differs by more "
                        f"than {SHIFT_BOUND} px ({at})")
    for name in UNKNOWNS:
        rms = figures[f"emulator_vs_scheme.rms.{name}"]
        if not rms <= STEP_TOLERANCE:
            failures.append(f"emulator ↔ golden scheme: step RMS {name} {rms:.3g} exceeds "
                            f"{STEP_TOLERANCE:g} over {figures['emulator_vs_scheme.rows']} rows")
    return failures


def pose_errors(config, result, dataset, camera=0):
    """Error ``[T θ]`` (n, 6) of each record's integrated pose against ground truth,
    records of frames ≥ 1.

    The solver keeps one pose per row slot, starting at the reset pose, and composes
    each row's one-frame step onto its slot's pose of the previous frame
    (:func:`emulator.pose_solver.integrate_rows`); so a record of frame ``i``, row ``y``
    is the rig's pose relative to row ``y`` of frame 0. The truth is the same relative
    pose from the dataset, and the error is the body-frame step between the two."""
    solver, records = config.router.solver, result.records
    use = result.frame > 0
    frames, rows = result.frame[use], records["row"][use]
    rec = dataset.cameras[camera]
    start_r, start_p = rec.rotation[0, rows], rec.position[0, rows]
    true_r = np.swapaxes(start_r, -1, -2) @ rec.rotation[frames, rows]
    true_p = np.einsum("nji,nj->ni", start_r, rec.position[frames, rows] - start_p)
    q = solver.quat_fmt.to_float(records["q"][use])
    est_r = quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))
    est_p = solver.position_fmt.to_float(records["p"][use])
    return body_step(true_r, true_p, est_r, est_p)


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


def compare_steps(config, result, dataset, track_result, scheme=None):
    """Step agreement (flat dict of figures, dotted keys): emulator ↔ float64 solution
    of the same measurements (the fixed-point error alone), emulator ↔ golden tracker,
    emulator ↔ truth, golden ↔ truth; plus the fraction of rows the emulator solved.
    With ``scheme`` (:func:`scheme_steps`) also emulator ↔ float scheme, scheme ↔ truth
    and the per-measurement figures (``measurement.*``)."""
    frames, rows = result.frame, result.records["row"]
    emulator = result.steps(config)
    golden = golden_steps(track_result, dataset, frames, rows)
    truth = true_steps(dataset, frames, rows)
    figures = {"solved_fraction": float(np.mean(result.records["flags"] == 0)),
               "emulator_rows_per_s": result.rows_per_s}
    pairs = {"emulator_vs_float": (emulator, float_steps(config, result.rows)),
             "emulator_vs_golden": (emulator, golden),
             "emulator_vs_truth": (emulator, truth),
             "golden_vs_truth": (golden, truth)}
    if scheme is not None:
        float_scheme = np.full_like(emulator, np.nan)
        float_scheme[frames > 0] = scheme.steps
        pairs.update({"emulator_vs_scheme": (emulator, float_scheme),
                      "scheme_vs_truth": (float_scheme, truth)})
        measured, _ = measurement_agreement(config, result, scheme)
        figures.update({f"measurement.{key}": value for key, value in measured.items()})
    for name, (a, b) in pairs.items():
        figures.update({f"{name}.{key}": value for key, value in agreement(a, b).items()})
    error = pose_errors(config, result, dataset)
    figures.update({f"emulator_pose_vs_truth.{key}": value
                    for key, value in agreement(error, np.zeros_like(error)).items()})
    return figures

"""Level-2 comparison of the bit-accurate pipeline: its per-row steps against the golden
tracker's and against ground truth, on the same dataset rows.

The quantity compared is the one-frame motion ``Y = [T θ]`` of each row slot (the
pipeline's solved step, :mod:`emulator.pipeline`; ``TrackResult.motion`` of
:func:`golden.tracker.track`; the exact body-frame step from the pose of the same row
one frame earlier). Poses are not compared yet: the hardware's integrator composes
steps row on row, which does not match a one-frame motion (``docs/e2e.md``).
"""

import numpy as np

from golden.pose_lsq import UNKNOWNS, ShiftCoefficients, body_step, solve_step

__all__ = ["true_steps", "golden_steps", "float_steps", "agreement", "compare_steps"]

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


def agreement(steps, reference):
    """Per-axis RMS and median absolute difference of two (n, 6) step arrays over the
    rows where both are finite, and how many rows that is."""
    both = np.all(np.isfinite(steps) & np.isfinite(reference), axis=1)
    diff = steps[both] - reference[both]
    figures = {"rows": int(both.sum())}
    for k, name in enumerate(UNKNOWNS):
        figures[f"rms.{name}"] = float(np.sqrt(np.mean(diff[:, k] ** 2))) if both.any() \
            else float("nan")
        figures[f"median_abs.{name}"] = float(np.median(np.abs(diff[:, k]))) if both.any() \
            else float("nan")
    return figures


def compare_steps(config, result, dataset, track_result):
    """Step agreement (flat dict of figures, dotted keys): emulator ↔ float64 solution
    of the same measurements (the fixed-point error alone), emulator ↔ golden tracker,
    emulator ↔ truth, golden ↔ truth; plus the fraction of rows the emulator solved."""
    frames, rows = result.frame, result.records["row"]
    emulator = result.steps(config)
    golden = golden_steps(track_result, dataset, frames, rows)
    truth = true_steps(dataset, frames, rows)
    figures = {"solved_fraction": float(np.mean(result.records["flags"] == 0)),
               "emulator_rows_per_s": result.rows_per_s}
    for name, (a, b) in {"emulator_vs_float": (emulator, float_steps(config, result.rows)),
                         "emulator_vs_golden": (emulator, golden),
                         "emulator_vs_truth": (emulator, truth),
                         "golden_vs_truth": (golden, truth)}.items():
        figures.update({f"{name}.{key}": value for key, value in agreement(a, b).items()})
    return figures

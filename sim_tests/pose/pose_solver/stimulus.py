"""Coefficient tables and row mixes for the pose solver's tests and bench.

A *case* fixes the hardware (parameters and coefficient store contents, from the case
name alone, so a cocotb bench can rebuild exactly what the pytest runner elaborated);
its rows are drawn from a seeded generator:

* ``random``: 8 slots × 64 table rows. Table rows 0–31 are random (well-conditioned
  systems); rows 32–63 are built with a prescribed singular-value spread so that the
  Jacobi-scaled normal matrix has condition 10⁴–10⁶ (near-singular). Rows mix full,
  partial, zero-confidence and over-long (OVERRUN) measurement sets and extreme values.
* ``stereo8`` and ``radial4``: the rig cases of :mod:`emulator.benches.pose_solver`
  (eight cameras of stereo20 with disparity cues; radial4 with 8 segments per row and
  inverse-depth cues), 480 rows, the papers' test motion through the room.
"""

import math

import numpy as np

from emulator.benches.pose_solver import rig_case
from emulator.pose_solver import PoseRows, rows_from_float
from golden import pose_lsq
from hdl.pose.params import PoseSolverParams, coefficient_formats, quantize_coefficients

__all__ = ["CASES", "build_case", "random_rows", "sequence_rows", "mixed_rows"]

#: Table rows of the ``random`` case with near-singular systems.
NEAR_SINGULAR_ROWS = range(32, 64)
#: Condition numbers (of the Jacobi-scaled normal matrix) the near-singular rows aim at.
NEAR_SINGULAR_CONDITION = (1e4, 1e6)


def _random_table(rng, slots, rows):
    """Coefficients of well-conditioned rows (0–31) and near-singular rows (32–63)."""
    table = np.concatenate([rng.normal(0, 300, (slots, rows, 3)),
                            rng.normal(0, 20, (slots, rows, 3)),
                            rng.normal(0, 400, (slots, rows, 3))], axis=-1)
    for r in NEAR_SINGULAR_ROWS:
        # A = U Σ Vᵀ with cond(A)² spread over the target range; the cue is 1 and
        # a_C = 0 in these rows, so the design rows are A itself.
        target = math.exp(rng.uniform(*np.log(NEAR_SINGULAR_CONDITION)))
        u, _ = np.linalg.qr(rng.normal(size=(slots, 6)))
        v, _ = np.linalg.qr(rng.normal(size=(6, 6)))
        sigma = np.geomspace(1.0, 1.0 / math.sqrt(target), 6)
        design = (u * sigma) @ v.T * 400 / np.max(np.abs((u * sigma) @ v.T))
        table[:, r, 0:3], table[:, r, 3:6], table[:, r, 6:9] = design[:, :3], 0.0, design[:, 3:]
    return table


CASES = ("random", "stereo8", "radial4")


def build_case(name):
    """``(params, raw coefficients, rig or None)`` of case ``name``; deterministic."""
    if name == "random":
        table = _random_table(np.random.default_rng(2026), 8, 64)
        params = PoseSolverParams(slots=8, rows=64, row_bits=6,
                                  **coefficient_formats(table, 18))
        return params, quantize_coefficients(params, table), None
    if name in ("stereo8", "radial4"):
        params, coefficients, _, rig, _ = rig_case(name)
        return params, coefficients, rig
    raise ValueError(f"case must be one of {', '.join(CASES)}, not {name!r}")


def random_rows(params, rng, count, framed=False):
    """Rows for the ``random`` case: a mix of well-conditioned, near-singular,
    zero-confidence, partial, over-long and extreme rows; in random table-row order, or
    ``framed``: table rows 0, 1, … in order, frame after frame (the near-singular rows
    then make half of each frame)."""
    m = params.slots + 2
    slot = np.zeros((count, m), dtype=np.int64)
    shift = rng.normal(0, 2.0, (count, m))
    cue = rng.uniform(0.1, 0.6, (count, m))
    weight = rng.uniform(0.25, 3.9, (count, m))
    present = np.zeros((count, m), dtype=bool)
    row = rng.integers(0, params.rows, count)
    kind = rng.choice(["full", "near", "zero", "partial", "overrun", "extreme"], count,
                      p=[0.45, 0.3, 0.05, 0.1, 0.05, 0.05])
    if framed:
        row = np.arange(count) % params.rows
        kind = np.where(np.isin(row, NEAR_SINGULAR_ROWS), "near",
                        np.where(kind == "near", "full", kind))
    for r in range(count):
        n = params.slots
        if kind[r] == "near":
            row[r] = row[r] if framed else rng.choice(NEAR_SINGULAR_ROWS)
            cue[r], weight[r] = 1.0, 1.0
        elif not framed:
            row[r] = rng.integers(0, NEAR_SINGULAR_ROWS.start)
        if kind[r] == "zero":
            weight[r] = 0.0
        elif kind[r] == "partial":
            n = int(rng.integers(1, params.slots))
        elif kind[r] == "overrun":
            n = int(rng.integers(params.slots + 1, m + 1))
        elif kind[r] == "extreme":
            shift[r] = rng.choice([-40.0, 40.0, 0.0], m)
            weight[r] = rng.choice([0.0, 4.0, weight[r, 0]], m)
        slot[r, :n] = rng.permutation(np.resize(np.arange(params.slots), n))
        present[r, :n] = True
    rows = rows_from_float(params, slot, shift, cue, weight, row,
                           rng.integers(0, 1 << params.time_bits, count))
    return PoseRows(slot=rows.slot, shift=rows.shift, cue=rows.cue, conf=rows.conf,
                    present=present, row=rows.row, time=rows.time), kind


def sequence_rows(params, rig, rng, count):
    """``count`` consecutive rows of ``rig`` on the papers' motion from a random start
    time, with 0.01 px shift noise and some zero weights; returns (rows, synthetic)."""
    from golden.trajectory import make_trajectory
    scale = rig_case(rig.name)[4]
    start = float(rng.uniform(0, 0.3))
    synthetic = pose_lsq.simulate_rows(rig, _Shifted(make_trajectory("paper"), start),
                                       count * rig.cameras[0].t_r, cue_scale=scale, rng=rng,
                                       shift_noise=0.01, zero_weight_fraction=0.05)
    ticks = np.round(synthetic.time * 150e6).astype(np.int64)
    rows = rows_from_float(params, synthetic.slot, synthetic.shift, synthetic.cue,
                           synthetic.weight, synthetic.row, ticks)
    return rows, synthetic


class _Shifted:
    """A trajectory started ``offset`` seconds late (rows of a random stretch)."""

    def __init__(self, trajectory, offset):
        self.trajectory, self.offset = trajectory, offset

    def pose(self, t):
        return self.trajectory.pose(np.asarray(t) + self.offset)


def mixed_rows(case, params, rig, rng, count, framed=False):
    """The rows a case's bench sends: ``random_rows`` (``framed`` or not) or
    ``sequence_rows`` (consecutive rows of a sequence: always in frame order)."""
    if case == "random":
        return random_rows(params, rng, count, framed)[0]
    return sequence_rows(params, rig, rng, count)[0]

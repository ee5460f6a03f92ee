"""Bit-accurate model of :class:`hdl.pose_solver.PoseSolver`.

Integers only, quantizing exactly where the hardware does, with the formats of
:class:`hdl.pose.params.PoseSolverParams` and the arithmetic of :mod:`hdl.fixed`.
Every rounded value is the half-even rounding of an *exact* sum of exact products, so
the order in which the hardware accumulates does not matter. The algorithm, step by
step, is in ``docs/pose/pose_solver.md``:

1. design rows ``a = [w a_T, a_R + w a_C]`` from the coefficient store (rounded to
   ``a_fmt``), then exact sums ``N = Σ c aᵀa`` and ``r = Σ c a s``;
2. power-of-two Jacobi scaling ``N̂ = S N S``, ``b̂ = S r``, ``S = diag(2**-e_i)``;
3. Cholesky ``N̂ = G Gᵀ`` (every factor entry within ±1) with the forward
   substitution carried along, pivots checked against ``2**-pivot_log2``, ``D^-1/2``
   from an interpolated seed and one Newton step;
4. back substitution with ``L = G·D^-1/2``, ``Y = S x``;
5. integration onto the pose of the same row one frame earlier (one pose per row
   slot): ``q ← q ⊗ (1 − |θ|²/12, θ/2)`` renormalized by one Newton step,
   ``p ← p + R(q) T`` (R from the quaternion before the step), committed only if the
   row was solved.

Steps 1 and 2 are the accumulator's and the normalizer's. Steps 3 to 5 are not written
out here: the model executes the engine's program
(:func:`hdl.pose.program.build_row_program`), the op list the engine's ROM is built
from, so the two cannot drift apart. The solve runs on every row at once; the
integration in waves of rows of distinct slots (a slot's next row needs its pose), each
op batched with the independent ops of the same shape
(:func:`emulator.pose.program.batches`).
"""

from dataclasses import dataclass

import numpy as np

from hdl.fixed import Overflow, QFormat, Rounding, mul
from golden import pose_lsq
from hdl.pose.params import DEFAULT_COEF_WIDTH, PoseFlag
from hdl.pose.program import STATE_NAMES, UPPER, build_row_program

from emulator.pose.program import (Value, batches, bit_length, dot, execute, exact_sum,
                                   operand_key, round_half_even, split_program)

__all__ = ["PoseRows", "StepResult", "accumulate", "diagonal", "jacobi_exponents",
           "scale_matrix", "scale_system", "solve_rows", "solve_system",
           "integrate_rows",
           "pose_solver_model", "identity_pose", "initial_poses", "flags_from_checks",
           "rows_from_float", "rig_solver", "solve_trace"]


@dataclass(frozen=True)
class PoseRows:
    """Measurement rows, raw integers, padded to the longest row.

    Members
    -------
    slot, shift, cue, conf : ndarray (n, m)
        Coefficient slot, and raw ``shift_fmt``/``cue_fmt``/``conf_fmt`` values.
    present : ndarray of bool (n, m)
        Which of the m positions hold a measurement (a row needs at least one).
    row, time : ndarray (n,)
        Row index (addresses the coefficient store) and time stamp.
    """
    slot: np.ndarray
    shift: np.ndarray
    cue: np.ndarray
    conf: np.ndarray
    present: np.ndarray
    row: np.ndarray
    time: np.ndarray

    def __post_init__(self):
        shape = np.shape(self.present)
        for name in ("slot", "shift", "cue", "conf"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name} must have the shape of present {shape}, not "
                                 f"{np.shape(getattr(self, name))}")
        if len(shape) != 2 or not np.all(np.any(self.present, axis=1)):
            raise ValueError("present must be (rows, measurements) with at least one "
                             "measurement in every row")
        for name in ("row", "time"):
            if np.shape(getattr(self, name)) != shape[:1]:
                raise ValueError(f"{name} must have one entry per row, not shape "
                                 f"{np.shape(getattr(self, name))}")

    def __len__(self):
        return len(self.row)

    @property
    def counts(self):
        return np.sum(self.present, axis=1)

    def transfers(self):
        """The rows as the hardware's input transfers: dicts in stream order."""
        out = []
        for r in range(len(self)):
            index = np.flatnonzero(self.present[r])
            for n, k in enumerate(index):
                out.append({"slot": int(self.slot[r, k]), "row": int(self.row[r]),
                             "time": int(self.time[r]), "shift": int(self.shift[r, k]),
                             "cue": int(self.cue[r, k]), "conf": int(self.conf[r, k]),
                             "last": int(n == len(index) - 1)})
        return out


# --- 1. accumulation ---------------------------------------------------------------------

def design_row(params, coef_raw, rows):
    """The rounded design rows ``a`` (six Values of shape (n, m)) of every measurement."""
    if coef_raw.shape != (params.slots, params.rows, 9):
        raise ValueError(f"coef_raw must have shape ({params.slots}, {params.rows}, 9), "
                         f"not {coef_raw.shape}")
    if np.any(rows.slot[rows.present] >= params.slots) or np.any(rows.slot < 0):
        raise ValueError(f"slot must be in [0, {params.slots}), not {rows.slot.max()}")
    if np.any(rows.row >= params.rows) or np.any(rows.row < 0):
        raise ValueError(f"row must be in [0, {params.rows}), not {rows.row.max()}")
    coef = coef_raw[np.where(rows.present, rows.slot, 0), rows.row[:, None]]
    cue = Value(params.cue_fmt.raw(rows.cue), params.cue_fmt)
    out = []
    for k in range(3):
        t = Value(coef[..., k], params.coef_t_fmt)
        out.append(dot(params.a_fmt, terms=[(1, t, cue)])[0])
    for k in range(3):
        c = Value(coef[..., 3 + k], params.coef_c_fmt)
        r = Value(coef[..., 6 + k], params.coef_r_fmt)
        out.append(dot(params.a_fmt, init=r, terms=[(1, c, cue)])[0])
    return out


def accumulate(params, coef_raw, rows):
    """Normal equations of every row: 21 Values ``N_ij`` (``UPPER`` order) and 6 Values
    ``r_i``, each of shape (n,)."""
    a = design_row(params, coef_raw, rows)
    conf = np.where(rows.present, params.conf_fmt.raw(rows.conf), 0)
    shift = np.where(rows.present, params.shift_fmt.raw(rows.shift), 0)
    weighted = [mul(conf, params.conf_fmt, ak.raw, params.a_fmt) for ak in a]
    normal = []
    for i, j in UPPER:
        raw, fmt = mul(weighted[i][0], weighted[i][1], a[j].raw, params.a_fmt)
        normal.append(exact_sum(raw, fmt, 1, params.normal_fmt))
    rhs = []
    for i in range(6):
        raw, fmt = mul(weighted[i][0], weighted[i][1], shift, params.shift_fmt)
        rhs.append(exact_sum(raw, fmt, 1, params.normal_fmt))
    return normal, rhs


# --- 2. scaling --------------------------------------------------------------------------

def _shift_scaled(value, shift, shift_range, dst):
    """``value · 2**-shift`` rounded into ``dst`` for per-row ``shift`` within
    ``shift_range = (low, high)``: an exact left shift by ``high - shift`` and one static
    rounding (the hardware's barrel shifter followed by one ``hdl_resize``)."""
    low, high = shift_range
    src = value.fmt
    wide = QFormat(True, max(1, src.int_bits + (high - low) - high) + 1, src.frac_bits + high)
    raw = np.asarray(value.raw, dtype=object) << (high - np.asarray(shift)).astype(object)
    return round_half_even(raw, wide, dst)


def diagonal(normal):
    """The diagonal of 21 ``UPPER`` Values as raw Python integers (6, n)."""
    index = {pair: k for k, pair in enumerate(UPPER)}
    return np.stack([np.asarray(normal[index[(i, i)]].raw, dtype=object) for i in range(6)])


def jacobi_exponents(params, diag, exponent_range):
    """Per unknown and row (6, n): the exponent ``e`` with ``N_ii·2**(-2e)`` in
    ``[1/4, 1)``, clipped to ``exponent_range``."""
    return np.clip(params.exponent(bit_length(diag.ravel())).reshape(diag.shape),
                   *exponent_range)


def scale_matrix(params, matrix, exponents, exponent_range):
    """``S A S`` of 21 ``UPPER`` Values into ``unit_fmt`` with ``S = diag(2**-e)``:
    (21 Values, saturated mask (n,))."""
    low, high = exponent_range
    saturated = np.zeros(exponents.shape[1], dtype=bool)
    scaled = []
    for (i, j), value in zip(UPPER, matrix):
        v, sat = _shift_scaled(value, exponents[i] + exponents[j], (2 * low, 2 * high),
                                params.unit_fmt)
        scaled.append(v)
        saturated |= sat
    return scaled, saturated


def scale_system(params, normal, rhs):
    """Jacobi scaling. Returns (N̂ as 21 Values, b̂ as 6 Values, scales ``2**-e`` as 6
    Values, empty mask (n,), saturated mask (n,))."""
    diag = diagonal(normal)
    empty = np.any(diag < params.min_diagonal_raw, axis=0)
    exponents = jacobi_exponents(params, diag, params.exponent_range)
    scaled, saturated = scale_matrix(params, normal, exponents, params.exponent_range)
    low, high = params.exponent_range
    scaled_rhs = []
    for i, value in enumerate(rhs):
        v, sat = _shift_scaled(value, exponents[i], (low, high), params.solution_fmt)
        scaled_rhs.append(v)
        saturated |= sat
    fmt = params.scale_fmt
    scales = [Value(np.array([1 << (fmt.frac_bits - int(e)) for e in exponents[i]],
                             dtype=fmt.dtype()), fmt) for i in range(6)]
    return scaled, scaled_rhs, scales, empty, saturated


# --- 3-5. the engine's program -------------------------------------------------------

@dataclass(frozen=True)
class StepResult:
    """Per-row outcome of the solve (before integration).

    Members
    -------
    step : ndarray (n, 6)
        Raw ``step_fmt`` step, zero where ``flags`` is non-zero.
    flags : ndarray (n,)
        :class:`PoseFlag` bits (one reason, by priority).
    """
    step: np.ndarray
    flags: np.ndarray


def flags_from_checks(overrun, empty, ill, saturated):
    """One :class:`PoseFlag` per row, by priority OVERRUN, EMPTY, ILL, SATURATED: a later
    check is meaningless once an earlier one failed."""
    return np.select([overrun, empty, ill, saturated],
                     [int(PoseFlag.OVERRUN), int(PoseFlag.EMPTY), int(PoseFlag.ILL),
                      int(PoseFlag.SATURATED)], 0).astype(np.int64)


def _solve(params, scaled, rhs, scales, pivot_log2=None):
    """The solve part of the engine's program (Cholesky with the forward substitution,
    back substitution, ``Y = S x``) on every row at once, the pivots checked against
    the run-time ``pivot_log2`` (:func:`execute`). Returns (values: (bank, name) ->
    Value of the inputs and every result, the program, ILL mask, saturated mask)."""
    program = build_row_program(params)
    values = {("input", f"N{i}{j}"): v for (i, j), v in zip(UPPER, scaled)}
    values.update({("input", f"b{i}"): v for i, v in enumerate(rhs)})
    values.update({("input", f"s{i}"): v for i, v in enumerate(scales)})
    _, ill, saturated = execute(params, program, batches(split_program(program)[0]),
                                 values, len(np.asarray(scales[0].raw)), pivot_log2)
    return values, program, ill, saturated


def solve_trace(params, coef_raw, rows):
    """Every intermediate of the solve of every row: dict name -> Value under the names
    of :func:`hdl.pose.program.build_row_program` (``N``/``b``/``s`` for the scaled
    inputs; an alias names the value it stands for), for comparison with the engine's
    registers and for the value ranges of the benchmark."""
    normal, rhs = accumulate(params, coef_raw, rows)
    scaled, scaled_rhs, scales, _, _ = scale_system(params, normal, rhs)
    values, program, _, _ = _solve(params, scaled, scaled_rhs, scales)
    trace = {name: value for (bank, name), value in values.items()
             if bank != "constant"}
    trace.update({name: values[operand_key(v)] for name, v in program.aliases.items()})
    return trace


def solve_rows(params, coef_raw, rows, pivot_log2=None):
    """Steps and flags of every row (no integration): a :class:`StepResult`.
    ``pivot_log2``: the solver's run-time register when each row was solved (int or
    (n,); None: the build's value, its reset)."""
    normal, rhs = accumulate(params, coef_raw, rows)
    return solve_system(params, normal, rhs, rows.counts > params.slots, pivot_log2)


def solve_system(params, normal, rhs, overrun, pivot_log2=None):
    """:func:`solve_rows` from the accumulated system (:func:`accumulate`) and the
    rows' OVERRUN mask (n,)."""
    scaled, scaled_rhs, scales, empty, sat_scale = scale_system(params, normal, rhs)
    values, program, ill, sat_solve = _solve(params, scaled, scaled_rhs, scales, pivot_log2)
    flags = flags_from_checks(overrun, empty, ill, sat_scale | sat_solve)
    raw = np.stack([np.asarray(values[operand_key(v)].raw, dtype=object) for v in program.step],
                   axis=1)
    raw = np.where((flags == 0)[:, None], raw, 0).astype(np.int64)
    return StepResult(step=raw, flags=flags)


# --- 5. integration ----------------------------------------------------------------------

def identity_pose(params):
    """The reset pose of every slot: raw quaternion (1, 0, 0, 0) and position 0."""
    q = np.array([int(params.quat_fmt.quantize(1.0)), 0, 0, 0], dtype=np.int64)
    return q, np.zeros(3, dtype=np.int64)


def initial_poses(params, pose=None):
    """The pose ring before the first row: raw quaternions (rows, 4) and positions
    (rows, 3). ``pose`` is None (every slot at the reset pose, as after reset), one raw
    ``(q (4,), p (3,))`` (every slot starts there) or ``(q (rows, 4), p (rows, 3))``
    (one pose per slot)."""
    q, p = identity_pose(params) if pose is None else pose
    q, p = np.asarray(q, dtype=np.int64), np.asarray(p, dtype=np.int64)
    if q.shape not in ((4,), (params.rows, 4)) or p.shape != q.shape[:-1] + (3,):
        raise ValueError(f"pose must be raw (q (4,), p (3,)) or (q ({params.rows}, 4), "
                         f"p ({params.rows}, 3)), not shapes {q.shape} and {p.shape}")
    return (np.array(np.broadcast_to(q, (params.rows, 4))),
            np.array(np.broadcast_to(p, (params.rows, 3))))


def _waves(row):
    """Wave of every row: how many rows of the same slot come before it. A row's pose
    depends on the previous row of its slot only, so the rows of one wave are
    integrated together."""
    wave, seen = np.empty(len(row), dtype=np.int64), {}
    for k, y in enumerate(np.asarray(row).tolist()):
        wave[k] = seen[y] = seen.get(y, -1) + 1
    return wave


def integrate_rows(params, result, row, pose=None):
    """Poses after every row: raw quaternions (n, 4) and positions (n, 3).

    The solver keeps one pose per row slot (a ring of ``params.rows`` poses, see
    :func:`initial_poses` for ``pose``): row ``row[k]``'s step is the rig's motion since
    the same row of the previous frame, so it is composed onto that slot's pose — the
    integration ops of the engine's program — and the result is written back and
    emitted. A flagged row leaves its slot and emits it."""
    row = np.asarray(row)
    if row.shape != (len(result.flags),) or np.any((row < 0) | (row >= params.rows)):
        raise ValueError(f"row must be {len(result.flags)} slot indices in "
                         f"[0, {params.rows})")
    ring = np.concatenate(initial_poses(params, pose), axis=1)  # STATE_NAMES order
    program = build_row_program(params)
    integration = batches(split_program(program)[1])
    wave = _waves(row)
    poses = np.empty((len(row), len(STATE_NAMES)), dtype=np.int64)
    for w in range(wave.max(initial=-1) + 1):
        rows = np.flatnonzero(wave == w)
        solved = rows[result.flags[rows] == 0]
        if len(solved):
            values = {operand_key(v): Value(ring[row[solved], k], v.fmt)
                      for k, v in enumerate(program.state[name] for name in STATE_NAMES)}
            values.update({operand_key(v): Value(result.step[solved, k], v.fmt)
                           for k, v in enumerate(program.step)})
            committed, _, _ = execute(params, program, integration, values, len(solved))
            ring[row[solved]] = np.stack([np.asarray(committed[name].raw, dtype=object)
                                          for name in STATE_NAMES], axis=1).astype(np.int64)
        poses[rows] = ring[row[rows]]
    return poses[:, :4], poses[:, 4:]


def pose_solver_model(params, coef_raw, rows, pose=None, pivot_log2=None):
    """Pose records of every row, as the hardware emits them: dict of raw arrays
    ``row``, ``time``, ``flags``, ``q`` (n, 4), ``p`` (n, 3), ``step`` (n, 6). ``pose``:
    the ring before the first row (:func:`initial_poses`; the reset state by default);
    ``pivot_log2``: :func:`solve_rows`'."""
    result = solve_rows(params, coef_raw, rows, pivot_log2)
    quats, positions = integrate_rows(params, result, rows.row, pose)
    return {"row": np.asarray(rows.row), "time": np.asarray(rows.time), "flags": result.flags,
            "q": quats, "p": positions, "step": result.step}


# --- inputs from float measurements ----------------------------------------------------

def rows_from_float(params, slot, shift, cue, weight, row, time):
    """Quantize float measurements (n, m) into :class:`PoseRows` (half-even, saturating);
    every position is present. ``time`` is already an integer time stamp."""
    def q(fmt, values):
        return fmt.quantize(values, Rounding.HALF_EVEN, Overflow.SATURATE)
    return PoseRows(slot=np.asarray(slot, dtype=np.int64), shift=q(params.shift_fmt, shift),
                    cue=q(params.cue_fmt, cue), conf=q(params.conf_fmt, weight),
                    present=np.ones(np.shape(shift), dtype=bool),
                    row=np.asarray(row, dtype=np.int64),
                    time=np.asarray(time, dtype=np.int64) & ((1 << params.time_bits) - 1))


def rig_solver(rig, cue_scale, coef_width=DEFAULT_COEF_WIDTH, **changes):
    """Parameters and coefficient store for a rig: ``(params, raw coefficients, float
    table)``, with the coefficient formats picked from the rig's table at ``coef_width``
    bits and ``changes`` applied to the other parameters."""
    from hdl.pose.params import PoseSolverParams, coefficient_formats, quantize_coefficients
    table = pose_lsq.rig_coefficient_table(rig, cue_scale)
    params = PoseSolverParams(slots=table.shape[0], rows=table.shape[1],
                              **coefficient_formats(table, coef_width), **changes)
    return params, quantize_coefficients(params, table), table

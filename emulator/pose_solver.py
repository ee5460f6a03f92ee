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
"""

from dataclasses import dataclass

import numpy as np

from hdl.fixed import SQ, UQ, Overflow, QFormat, Rounding, mul, resize
from golden import pose_lsq
from hdl.pose.params import (DEFAULT_COEF_WIDTH, DELTA_BITS, SEED_TABLE_FMT, SLOPE_FMT,
                             PoseFlag, seed_tables)

__all__ = ["PoseRows", "Value", "StepResult", "accumulate", "scale_system",
           "rsqrt_seed", "solve_rows", "integrate_rows",
           "pose_solver_model", "identity_pose", "initial_poses", "flags_from_checks",
           "rows_from_float", "rig_solver", "solve_trace"]

#: The 21 (i, j), i ≤ j, entries of the symmetric normal matrix, in accumulator order.
UPPER = tuple((i, j) for i in range(6) for j in range(i, 6))


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


@dataclass(frozen=True)
class Value:
    """Raw integers of one quantity over all rows, with their format."""
    raw: np.ndarray
    fmt: QFormat


def _exact_sum(raw, fmt, axis, out_fmt):
    """Exact sum along ``axis`` of int64 raw values, wrapped into ``out_fmt`` (the
    accumulator wraps; guard bits make that impossible for at most ``slots`` terms)."""
    raw = np.asarray(raw)
    if raw.dtype == object:
        total = np.sum(raw, axis=axis)
    else:  # split so that int64 partial sums cannot overflow
        high, low = raw >> 32, raw & 0xFFFFFFFF
        total = (np.sum(high, axis=axis).astype(object) * (1 << 32)
                 + np.sum(low, axis=axis).astype(object))
    wide = QFormat(True, fmt.int_bits + 64, fmt.frac_bits)
    return Value(resize(np.asarray(total, dtype=object), wide, out_fmt, Rounding.FLOOR,
                        Overflow.WRAP), out_fmt)


def _round(raw, fmt, dst):
    """Half-even into ``dst``, saturating; returns (Value, saturated mask)."""
    wide_fmt = SQ(max(fmt.int_bits, dst.int_bits) + 2, dst.frac_bits)
    wide = resize(raw, fmt, wide_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
    saturated = np.asarray((wide < dst.min_raw) | (wide > dst.max_raw), dtype=bool)
    return Value(resize(wide, wide_fmt, dst, Rounding.FLOOR, Overflow.SATURATE), dst), saturated


#: Elementwise int(): object arrays of Python ints (numpy integers would overflow).
_ints = np.frompyfunc(int, 1, 1)


def _dot(dst, init=None, terms=(), scale_log2=0):
    """``round(init + 2**scale_log2 · Σ ±a·b)`` into ``dst``: one rounding of the exact
    value (the hardware's multiply-accumulate op). Signs may be arrays. Returns
    (Value, saturated mask)."""
    parts = [(_ints(sign) * _ints(a.raw) * _ints(b.raw),
              a.fmt.frac_bits + b.fmt.frac_bits - scale_log2,
              a.fmt.int_bits + b.fmt.int_bits + scale_log2) for sign, a, b in terms]
    if init is not None:
        parts.append((_ints(init.raw), init.fmt.frac_bits, init.fmt.int_bits))
    frac = max(f for _, f, _ in parts)
    int_bits = max(i for _, _, i in parts) + len(parts).bit_length() + 1
    total = sum(raw * (1 << (frac - f)) for raw, f, _ in parts)
    return _round(total, QFormat(True, int_bits, frac), dst)


def _constant(value, fmt, shape):
    return Value(np.full(shape, int(fmt.quantize(value)), dtype=fmt.dtype()), fmt)


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
        out.append(_dot(params.a_fmt, terms=[(1, t, cue)])[0])
    for k in range(3):
        c = Value(coef[..., 3 + k], params.coef_c_fmt)
        r = Value(coef[..., 6 + k], params.coef_r_fmt)
        out.append(_dot(params.a_fmt, init=r, terms=[(1, c, cue)])[0])
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
        normal.append(_exact_sum(raw, fmt, 1, params.normal_fmt))
    rhs = []
    for i in range(6):
        raw, fmt = mul(weighted[i][0], weighted[i][1], shift, params.shift_fmt)
        rhs.append(_exact_sum(raw, fmt, 1, params.normal_fmt))
    return normal, rhs


# --- 2. scaling --------------------------------------------------------------------------

def _bit_length(raw):
    return np.array([int(v).bit_length() for v in np.asarray(raw).tolist()], dtype=np.int64)


def _shift_scaled(value, shift, shift_range, dst):
    """``value · 2**-shift`` rounded into ``dst`` for per-row ``shift`` within
    ``shift_range = (low, high)``: an exact left shift by ``high - shift`` and one static
    rounding (the hardware's barrel shifter followed by one ``hdl_resize``)."""
    low, high = shift_range
    src = value.fmt
    wide = QFormat(True, max(1, src.int_bits + (high - low) - high) + 1, src.frac_bits + high)
    raw = np.asarray(value.raw, dtype=object) << (high - np.asarray(shift)).astype(object)
    return _round(raw, wide, dst)


def scale_system(params, normal, rhs):
    """Jacobi scaling. Returns (N̂ as 21 Values, b̂ as 6 Values, scales ``2**-e`` as 6
    Values, empty mask (n,), saturated mask (n,))."""
    index = {pair: k for k, pair in enumerate(UPPER)}
    diag = np.stack([np.asarray(normal[index[(i, i)]].raw, dtype=object) for i in range(6)])
    empty = np.any(diag < params.min_diagonal_raw, axis=0)
    low, high = params.exponent_range
    exponents = np.clip(params.exponent(_bit_length(diag.ravel())).reshape(diag.shape),
                        low, high)
    saturated = np.zeros(diag.shape[1], dtype=bool)
    scaled = []
    for (i, j), value in zip(UPPER, normal):
        v, sat = _shift_scaled(value, exponents[i] + exponents[j], (2 * low, 2 * high),
                                params.unit_fmt)
        scaled.append(v)
        saturated |= sat
    scaled_rhs = []
    for i, value in enumerate(rhs):
        v, sat = _shift_scaled(value, exponents[i], (low, high), params.solution_fmt)
        scaled_rhs.append(v)
        saturated |= sat
    fmt = params.scale_fmt
    scales = [Value(np.array([1 << (fmt.frac_bits - int(e)) for e in exponents[i]],
                             dtype=fmt.dtype()), fmt) for i in range(6)]
    return scaled, scaled_rhs, scales, empty, saturated


# --- 3. inverse square root seed -----------------------------------------------------------

def rsqrt_seed(params, pivot):
    """Seeds ``≈ D^-1/2`` in ``seed_fmt`` for pivots ``D`` (a Value in ``unit_fmt``).

    ``m = D·2**(2k) ∈ [1/4, 1)`` from the pivot's bit length (an even shift, so exact);
    the top ``seed_bits`` fraction bits of ``m`` index the tables, the next
    ``DELTA_BITS`` (truncated) interpolate; the seed is ``y0·2**k`` (exact). Pivots at
    or below zero give the seed of the smallest positive pivot (the row is flagged ILL).
    """
    unit = params.unit_fmt
    raw = np.maximum(np.asarray(pivot.raw, dtype=object), 1)
    excess = unit.frac_bits - _bit_length(raw)                   # D·2**excess ∈ [1/2, 1)
    k = excess // 2                                              # m = D·2**(2k) ∈ [1/4, 1)
    mantissa = np.array([int(r) << int(2 * e + 2) for r, e in zip(raw.tolist(), k)],
                        dtype=object)                            # mantissa_bits fraction bits
    low = params.mantissa_bits - params.seed_bits
    index = np.array([int(v) >> low for v in mantissa])
    delta = np.array([(int(v) >> (low - DELTA_BITS)) & ((1 << DELTA_BITS) - 1)
                      for v in mantissa], dtype=np.int64)
    values, slopes = seed_tables(params.seed_bits)
    t0 = Value(np.array([values[i] for i in index], dtype=np.int64), SEED_TABLE_FMT)
    t1 = Value(np.array([slopes[i] for i in index], dtype=np.int64), SLOPE_FMT)
    delta_fmt = UQ(0, params.seed_bits + DELTA_BITS)
    y0, _ = _dot(SEED_TABLE_FMT, init=t0, terms=[(-1, t1, Value(delta, delta_fmt))])
    shift = params.seed_fmt.frac_bits - SEED_TABLE_FMT.frac_bits   # y0·2**k, exact
    seed_raw = np.array([int(v) << int(e + shift) for v, e in
                         zip(np.asarray(y0.raw).tolist(), k)], dtype=object)
    # wraps only for pivots below 2**-pivot_log2 (flagged ILL), as the hardware does
    wide = QFormat(True, params.seed_fmt.int_bits + params.mantissa_bits, params.seed_fmt.frac_bits)
    return Value(resize(seed_raw, wide, params.seed_fmt, Rounding.FLOOR, Overflow.WRAP),
                 params.seed_fmt)


# --- 3/4. solve ----------------------------------------------------------------------------

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


def _cholesky_solve(params, scaled, rhs, scales, trace=None):
    """Cholesky ``N̂ = G Gᵀ`` with the forward substitution carried along, the back
    substitution with ``L = G·ρ``, then ``Y = S x``. Returns (six step Values, ILL mask,
    saturated mask). ``trace``, a dict, receives every intermediate under the names of
    :func:`hdl.pose.program.build_row_program`."""
    n = len(np.asarray(scales[0].raw))
    entry = {pair: v for pair, v in zip(UPPER, scaled)}
    unit, lower, sol = params.unit_fmt, params.lower_fmt, params.solution_fmt
    three_halves = _constant(1.5, unit, n)
    threshold = int(unit.quantize(2.0 ** -params.pivot_log2))
    ill = np.zeros(n, dtype=bool)
    saturated = np.zeros(n, dtype=bool)

    def op(name, dst, init=None, terms=(), scale_log2=0):
        nonlocal saturated
        value, sat = _dot(dst, init, terms, scale_log2)
        saturated |= sat
        if trace is not None:
            trace[name] = value
        return value

    g, low, rho, z = {}, {}, [], []
    for j in range(6):
        pivot = op(f"D{j}", unit, entry[(j, j)], [(-1, g[(j, k)], g[(j, k)]) for k in range(j)])
        ill |= np.asarray(pivot.raw, dtype=object) < threshold
        seed = rsqrt_seed(params, pivot)
        if trace is not None:
            trace[f"seed{j}"] = seed
        # one Newton step of D^-1/2 from the seed: ρ = seed·(3/2 − D·seed²/2)
        root = op(f"h{j}", unit, terms=[(1, pivot, seed)])
        newton = op(f"e{j}", unit, three_halves, [(-1, root, seed)], -1)
        rho.append(op(f"rho{j}", lower, terms=[(1, seed, newton)]))
        for i in range(j + 1, 6):
            schur = op(f"W{i}{j}", unit, entry[(j, i)],
                       [(-1, g[(i, k)], g[(j, k)]) for k in range(j)])
            product = op(f"P{i}{j}", unit, terms=[(1, schur, seed)])
            g[(i, j)] = op(f"G{i}{j}", unit, terms=[(1, product, newton)])
            low[(i, j)] = op(f"L{i}{j}", lower, terms=[(1, g[(i, j)], rho[j])])
        forward = op(f"c{j}", sol, rhs[j], [(-1, g[(j, k)], z[k]) for k in range(j)])
        z.append(op(f"z{j}", sol, terms=[(1, forward, rho[j])]))
    # back substitution, right-looking: once x_k is known, every x_j (j < k) loses its
    # L_kj·x_k term, so each unknown is one single-term op after the previous one
    partial = [op(f"w{j}", sol, terms=[(1, z[j], rho[j])]) for j in range(6)]
    x = [None] * 6
    for k in reversed(range(6)):
        x[k] = partial[k]
        for j in reversed(range(k)):
            partial[j] = op(f"u{j}_{k}", sol, partial[j], [(-1, low[(k, j)], x[k])])
    step = [op(f"Y{j}", params.step_fmt, terms=[(1, x[j], scales[j])]) for j in range(6)]
    return step, ill, saturated


def solve_trace(params, coef_raw, rows):
    """Every intermediate of the solve of every row: dict name -> Value (the names of
    :func:`hdl.pose.program.build_row_program`; ``N``/``b``/``s`` for the scaled inputs)."""
    normal, rhs = accumulate(params, coef_raw, rows)
    scaled, scaled_rhs, scales, _, _ = scale_system(params, normal, rhs)
    trace = {f"N{i}{j}": v for (i, j), v in zip(UPPER, scaled)}
    trace.update({f"b{i}": v for i, v in enumerate(scaled_rhs)})
    trace.update({f"s{i}": v for i, v in enumerate(scales)})
    _cholesky_solve(params, scaled, scaled_rhs, scales, trace)
    return trace


def solve_rows(params, coef_raw, rows):
    """Steps and flags of every row (no integration): a :class:`StepResult`."""
    normal, rhs = accumulate(params, coef_raw, rows)
    scaled, scaled_rhs, scales, empty, sat_scale = scale_system(params, normal, rhs)
    step, ill, sat_solve = _cholesky_solve(params, scaled, scaled_rhs, scales)
    flags = flags_from_checks(rows.counts > params.slots, empty, ill, sat_scale | sat_solve)
    raw = np.stack([np.asarray(v.raw, dtype=object) for v in step], axis=1)
    raw = np.where((flags == 0)[:, None], raw, 0).astype(np.int64)
    return StepResult(step=raw, flags=flags)


# --- 5. integration ----------------------------------------------------------------------

def identity_pose(params):
    """The reset pose of every slot: raw quaternion (1, 0, 0, 0) and position 0."""
    q = np.array([int(params.quat_fmt.quantize(1.0)), 0, 0, 0], dtype=np.int64)
    return q, np.zeros(3, dtype=np.int64)


def _integrate_one(params, q, p, step):
    """One committed step: raw (q, p) → raw (q, p); the hardware's op sequence, several
    components at a time."""
    qf, sf, pf = params.quat_fmt, params.step_fmt, params.position_fmt
    w, x, y, z = q
    tx, ty, tz, ax, ay, az = step

    def quat(*raw):
        return Value(np.array(raw, dtype=object), qf)

    def steps(*raw):
        return Value(np.array(raw, dtype=object), sf)

    # R(q) of the pose before the step, row by row: diagonal 1 − 2(..), the rest 2(..)
    one = _constant(1.0, qf, 9)
    diagonal = np.array([1, 0, 0, 0, 1, 0, 0, 0, 1])
    rotation, _ = _dot(qf, Value(np.where(diagonal == 1, one.raw, 0), qf),
                       [((-1, 1, 1, 1, -1, 1, 1, 1, -1), quat(y, x, x, x, x, y, x, y, x),
                         quat(y, y, z, y, x, z, z, z, x)),
                        ((-1, -1, 1, 1, -1, -1, -1, 1, -1), quat(z, w, w, w, z, w, w, w, y),
                         quat(z, z, y, z, z, x, y, x, y))], scale_log2=1)
    # q ⊗ (1 − |θ|²/12, θ/2): normalized, the increment turns by
    # 2·atan((|θ|/2)/(1 − |θ|²/12)) = |θ| + O(|θ|⁵), where (1, θ/2) loses |θ|³/12 per
    # step. First q ⊗ (1, θ/2) (w' = w − v·θ/2, v' = v + (w θ + v × θ)/2), then
    # − q·|θ|²/12.
    q0 = quat(w, x, y, z)
    first, _ = _dot(qf, q0, [((-1, 1, 1, 1), quat(x, w, w, w), steps(ax, ax, ay, az)),
                             ((-1, 1, 1, 1), quat(y, y, z, x), steps(ay, az, ax, ay)),
                             ((-1, -1, -1, -1), quat(z, z, x, y), steps(az, ay, az, ax))],
                    scale_log2=-1)
    square, _ = _dot(qf, terms=[(1, steps(a), steps(a)) for a in (ax, ay, az)],
                     scale_log2=-2)                                   # |θ|²/4 < 3/4
    cubic, _ = _dot(qf, terms=[(1, square, _constant(1 / 3, qf, 1))])  # |θ|²/12
    q1, _ = _dot(qf, first, [(-1, q0, Value(np.repeat(cubic.raw, 4), qf))])
    # one Newton step of 1/sqrt(|q'|²) from 1: g = 3/2 − |q'|²/2
    g, _ = _dot(qf, _constant(1.5, qf, 1), [(-1, Value(q1.raw[k:k + 1], qf),
                                            Value(q1.raw[k:k + 1], qf)) for k in range(4)],
                scale_log2=-1)
    q2, _ = _dot(qf, terms=[(1, q1, Value(np.repeat(g.raw, 4), qf))])
    # p + R T in two roundings: the T_y, T_z terms, then T_x (last out of the solve)
    r = rotation.raw
    early, _ = _dot(pf, Value(np.array(p, dtype=object), pf),
                    [(1, quat(r[1], r[4], r[7]), steps(ty, ty, ty)),
                     (1, quat(r[2], r[5], r[8]), steps(tz, tz, tz))])
    p2, _ = _dot(pf, early, [(1, quat(r[0], r[3], r[6]), steps(tx, tx, tx))])
    return (np.array(q2.raw.tolist(), dtype=np.int64), np.array(p2.raw.tolist(), dtype=np.int64))


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


def integrate_rows(params, result, row, pose=None):
    """Poses after every row: raw quaternions (n, 4) and positions (n, 3).

    The solver keeps one pose per row slot (a ring of ``params.rows`` poses, see
    :func:`initial_poses` for ``pose``): row ``row[k]``'s step is the rig's motion since
    the same row of the previous frame, so it is composed onto that slot's pose, and the
    result is written back and emitted. A flagged row leaves its slot and emits it."""
    row = np.asarray(row)
    if row.shape != (len(result.flags),) or np.any((row < 0) | (row >= params.rows)):
        raise ValueError(f"row must be {len(result.flags)} slot indices in "
                         f"[0, {params.rows})")
    ring_q, ring_p = initial_poses(params, pose)
    quats = np.empty((len(result.flags), 4), dtype=np.int64)
    positions = np.empty((len(result.flags), 3), dtype=np.int64)
    for k, (y, step, flag) in enumerate(zip(row, result.step, result.flags)):
        if flag == 0:
            ring_q[y], ring_p[y] = _integrate_one(params, ring_q[y], ring_p[y], step)
        quats[k], positions[k] = ring_q[y], ring_p[y]
    return quats, positions


def pose_solver_model(params, coef_raw, rows, pose=None):
    """Pose records of every row, as the hardware emits them: dict of raw arrays
    ``row``, ``time``, ``flags``, ``q`` (n, 4), ``p`` (n, 3), ``step`` (n, 6). ``pose``:
    the ring before the first row (:func:`initial_poses`; the reset state by default)."""
    result = solve_rows(params, coef_raw, rows)
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

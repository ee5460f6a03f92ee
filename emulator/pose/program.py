"""The pose engine's program executed on integer arrays: the model side of
:mod:`hdl.pose.program`.

Every value is a :class:`Value` (raw integers over rows, with their format). A
multiply-accumulate op is one half-even rounding of its exact sum (:func:`dot`), as the
engine's MAC unit does; a seed op is :func:`rsqrt_seed` with the pivot check. The ops of
a program run in :func:`batches` of independent ops of the same shape, vectorised over
rows (:func:`execute`); :mod:`emulator.pose_solver` runs the solve on every row at once
and the integration in waves.
"""

from dataclasses import dataclass

import numpy as np

from hdl.fixed import SQ, UQ, Overflow, QFormat, Rounding, resize
from hdl.pose.params import DELTA_BITS, SEED_TABLE_FMT, SLOPE_FMT, seed_tables

__all__ = ["Value", "exact_sum", "round_half_even", "dot", "constant", "bit_length",
           "rsqrt_seed", "operand_key", "split_program", "batches", "execute"]


@dataclass(frozen=True)
class Value:
    """Raw integers of one quantity over all rows, with their format."""
    raw: np.ndarray
    fmt: QFormat


def exact_sum(raw, fmt, axis, out_fmt):
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


def round_half_even(raw, fmt, dst):
    """Half-even into ``dst``, saturating; returns (Value, saturated mask)."""
    wide_fmt = SQ(max(fmt.int_bits, dst.int_bits) + 2, dst.frac_bits)
    wide = resize(raw, fmt, wide_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
    saturated = np.asarray((wide < dst.min_raw) | (wide > dst.max_raw), dtype=bool)
    return Value(resize(wide, wide_fmt, dst, Rounding.FLOOR, Overflow.SATURATE), dst), saturated


#: Elementwise int(): object arrays of Python ints (numpy integers would overflow).
_ints = np.frompyfunc(int, 1, 1)


def dot(dst, init=None, terms=(), scale_log2=0):
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
    return round_half_even(total, QFormat(True, int_bits, frac), dst)


def constant(value, fmt, shape):
    return Value(np.full(shape, int(fmt.quantize(value)), dtype=fmt.dtype()), fmt)


def bit_length(raw):
    return np.array([int(v).bit_length() for v in np.asarray(raw).tolist()], dtype=np.int64)


def rsqrt_seed(params, pivot):
    """Seeds ``≈ D^-1/2`` in ``seed_fmt`` for pivots ``D`` (a Value in ``unit_fmt``).

    ``m = D·2**(2k) ∈ [1/4, 1)`` from the pivot's bit length (an even shift, so exact);
    the top ``seed_bits`` fraction bits of ``m`` index the tables, the next
    ``DELTA_BITS`` (truncated) interpolate; the seed is ``y0·2**k`` (exact). Pivots at
    or below zero give the seed of the smallest positive pivot (the row is flagged ILL).
    """
    unit = params.unit_fmt
    raw = np.maximum(np.asarray(pivot.raw, dtype=object), 1)
    excess = unit.frac_bits - bit_length(raw)                   # D·2**excess ∈ [1/2, 1)
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
    y0, _ = dot(SEED_TABLE_FMT, init=t0, terms=[(-1, t1, Value(delta, delta_fmt))])
    shift = params.seed_fmt.frac_bits - SEED_TABLE_FMT.frac_bits   # y0·2**k, exact
    seed_raw = np.array([int(v) << int(e + shift) for v, e in
                         zip(np.asarray(y0.raw).tolist(), k)], dtype=object)
    # wraps only for pivots below 2**-pivot_log2 (flagged ILL), as the hardware does
    wide = QFormat(True, params.seed_fmt.int_bits + params.mantissa_bits, params.seed_fmt.frac_bits)
    return Value(resize(seed_raw, wide, params.seed_fmt, Rounding.FLOOR, Overflow.WRAP),
                 params.seed_fmt)


def operand_key(operand):
    return operand.bank, operand.name


def split_program(program):
    """The program's ops in two parts, each in program order: the solve (every op the
    step depends on, the same for every row) and the integration (the ops that read the
    slot's pose or the step, directly or through another integration op). No
    integration op is checked, so a row's flags are known after the solve."""
    later = {operand_key(v) for v in (*program.state.values(), *program.step)}
    solve, integration = [], []
    for op in program.ops:
        if any(operand_key(s) in later for s in op.sources):
            integration.append(op)
            later.add(operand_key(op.dst))
        else:
            solve.append(op)
    return solve, integration


def batches(ops):
    """``ops`` in batches that one vectorised :func:`dot` can run: ops of one level
    (every source written at an earlier level; a commit writes the state, which the
    program reads as it was at the row's start, so it raises no level) with the same
    kind, destination format, scale and operand formats. Running a batch at once is
    what keeps the integration fast when each wave is a single row."""
    level, batches = {}, {}
    for op in ops:
        depth = 1 + max((level.get(operand_key(s), 0) for s in op.sources), default=0)
        if not op.commit:
            level[operand_key(op.dst)] = depth
        signature = (depth, op.kind, op.dst.fmt, op.scale_log2,
                     op.init.fmt if op.init is not None else None,
                     tuple((a.fmt, b.fmt) for _, a, b in op.terms))
        batches.setdefault(signature, []).append(op)
    return [batches[s] for s in sorted(batches, key=lambda s: s[0])]


def _stack(values, operands):
    return Value(np.stack([np.asarray(values[operand_key(v)].raw) for v in operands]),
                 operands[0].fmt)


def execute(params, program, batches, values, n, pivot_log2=None):
    """Run the :func:`batches` of ops of ``program`` on ``values`` ((bank, name) ->
    Value over ``n`` rows, updated in place with every result) as the engine does: a
    multiply-accumulate op is one rounding of its exact sum (:func:`dot`), a seed op is
    :func:`rsqrt_seed` of its source with the pivot check against the solver's run-time
    ``pivot_log2`` (int or (n,): :meth:`PoseSolverParams.pivot_thresholds`; None: the
    build's). Commit ops do not overwrite
    the state they replace: the engine's reads of the state see the row's starting pose,
    so their results are returned apart. Returns (committed: state name -> Value, ILL
    mask, saturated mask)."""
    values.update({(operand.bank, name): constant(value, operand.fmt, n)
                   for name, (operand, value) in program.constants.items()})
    threshold = np.broadcast_to(params.pivot_thresholds(pivot_log2)[0], (n,)).astype(object)
    ill, saturated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    committed = {}
    for batch in batches:
        first = batch[0]
        if first.kind == "seed":
            source = _stack(values, [op.source for op in batch])
            raw = np.asarray(source.raw, dtype=object)
            ill |= np.any(raw < threshold, axis=0)
            seed = rsqrt_seed(params, Value(raw.ravel(), source.fmt))
            result = Value(np.reshape(seed.raw, raw.shape), seed.fmt)
        else:
            init = (_stack(values, [op.init for op in batch]) if first.init is not None
                    else None)
            terms = [(np.array([op.terms[t][0] for op in batch])[:, None],
                      _stack(values, [op.terms[t][1] for op in batch]),
                      _stack(values, [op.terms[t][2] for op in batch]))
                     for t in range(len(first.terms))]
            result, sat = dot(first.dst.fmt, init, terms, first.scale_log2)
        for k, op in enumerate(batch):
            value = Value(np.asarray(result.raw)[k], result.fmt)
            if op.checked and first.kind == "mac":
                saturated |= sat[k]
            if op.commit:
                committed[op.dst.name] = value
            else:
                values[operand_key(op.dst)] = value
    return committed, ill, saturated

"""Bit-accurate model of the motion filter's information gain (issue 16,
``ForecastParams.motion_gain = "information"``): the golden tracker's
:func:`golden.temporal_filter.information_gain` in the solver's fixed point, the
specification of its gateware (:class:`hdl.pose.prior_store.PriorStore`, the engine's
gain program and normalizer inputs, :class:`hdl.pose.forecast_filter.MotionFilter`'s
``gains``), bit-exact with it.

With a solved row's normal matrix ``N`` (the accumulator's, exact), the prior
information ``Λ = (1 − α)/α · N_typical`` and the filter's prediction ``p``, the level
moves by ``d = (N + Λ)⁻¹ N (Y − p)`` instead of ``α (Y − p)``: a row that measures a
direction as well as a typical row moves it by ``α``, one that barely measures it leaves
it at the prediction.

1. :class:`PriorInformation` keeps ``Λ`` (``information_fmt``): the first solved row
   sets ``Λ = c·N`` (``c = prior_raw``, rounded half-even), every later solved row
   ``Λ ← Λ + s·(c·N − Λ)`` (``s = smoothing_raw``, rounded half-even; ``information_fmt``
   is wide enough that neither can overflow). As in the golden
   tracker, a row's own ``N`` is in the ``Λ`` of its gain (the gain of a typical row is
   then ``α``), and a row that did not solve changes nothing.
2. :func:`gain_inputs` is the normalizer's share: ``M = N + Λ`` (exact) scaled by its own
   Jacobi exponents ``e_M`` into ``unit_fmt``, the prediction in N's scaled unknowns
   ``f = p·2**e`` (``solution_fmt``, half-even, saturation flagged), ``2**(e − e_M)`` and
   ``2**-e_M`` (exact, or 0 below the format's last bit).
3. :func:`gain_step` runs the engine program :func:`hdl.pose.program.build_gain_program`
   on them: ``d`` in ``step_fmt`` and the gain solve's own flags (ILL, SATURATED). A
   flagged gain leaves the row's step and pose record alone; the filter then moves by
   ``α`` and the loop counts the row (``TrackingLoopModel.counts["gain_flagged"]``).
"""

import numpy as np

from hdl.fixed import SQ, QFormat, Rounding, Overflow, mul, resize
from hdl.pose.engine import prior_exponent_high
from hdl.pose.prior_store import total_fmt
from hdl.pose.program import UPPER, build_gain_program
from emulator.pose.program import Value, batches, execute, operand_key, round_half_even
from emulator.pose_solver import (diagonal, flags_from_checks, jacobi_exponents, scale_matrix,
                                  scale_system)

__all__ = ["PriorInformation", "gain_inputs", "gain_step"]


class PriorInformation:
    """The prior information ``Λ`` (21 raw ``information_fmt`` integers, ``UPPER``
    order) of the information gain.

    Parameters
    ----------
    params : ForecastParams
    """

    def __init__(self, params):
        self.params = params
        self.prior = np.zeros(len(UPPER), dtype=object)
        #: Whether a row has solved yet (before: the first solved row sets ``Λ = c·N``).
        self.valid = False

    def updated(self, normal):
        """``Λ`` after a solved row of normal matrix ``normal`` (21 raw ``normal_fmt``
        integers), not yet kept (:meth:`keep`). ``information_fmt`` holds ``c·N`` for every
        ``c`` of ``prior_fmt`` and ``N`` of ``normal_fmt``, and ``Λ`` stays between its
        old value and ``c·N``: nothing here can overflow."""
        p = self.params
        fmt = p.information_fmt
        product, product_fmt = mul(np.array([p.prior_raw], dtype=object), p.prior_fmt,
                                   np.asarray(normal, dtype=object), p.solver.normal_fmt)
        weighted = resize(product, product_fmt, fmt, Rounding.HALF_EVEN, Overflow.ERROR)
        if not self.valid:
            return weighted
        diff_fmt = SQ(fmt.int_bits + 1, fmt.frac_bits)
        moved, moved_fmt = mul(np.array([p.smoothing_raw], dtype=object), p.gain_fmt,
                               weighted - self.prior, diff_fmt)
        return self.prior + resize(moved, moved_fmt, diff_fmt, Rounding.HALF_EVEN,
                                   Overflow.ERROR)

    def keep(self, prior):
        """Take :meth:`updated`'s result as the new ``Λ``."""
        self.prior, self.valid = np.asarray(prior, dtype=object), True


def gain_inputs(params, normal, rhs, prior, predicted):
    """The gain program's inputs for rows of accumulated systems ``normal`` (21 Values
    (n,)) and ``rhs`` (6 Values (n,)), priors ``prior`` (n, 21) raw ``information_fmt``
    and predictions ``predicted`` (n, 6) raw ``motion_fmt``: (dict input name -> Value,
    saturated mask (n,))."""
    solver = params.solver
    if solver.exponent_range[0] < 0:
        raise ValueError(f"the solver's exponent_range {solver.exponent_range} has negative "
                         f"exponents; the gain's prediction p·2**e needs e >= 0")
    scaled, scaled_rhs, scales, _, saturated = scale_system(solver, normal, rhs)
    exponents = jacobi_exponents(solver, diagonal(normal), solver.exponent_range)
    prior = np.asarray(prior, dtype=object)
    total = [Value(np.asarray(v.raw, dtype=object) + prior[:, k], total_fmt(params))
             for k, v in enumerate(normal)]
    total_range = (solver.exponent_range[0], prior_exponent_high(params))
    total_exponents = jacobi_exponents(solver, diagonal(total), total_range)
    scaled_total, sat = scale_matrix(solver, total, total_exponents, total_range)
    saturated = saturated | sat
    inputs = {f"N{i}{j}": v for (i, j), v in zip(UPPER, scaled)}
    inputs.update({f"M{i}{j}": v for (i, j), v in zip(UPPER, scaled_total)})
    inputs.update({f"b{i}": v for i, v in enumerate(scaled_rhs)})
    inputs.update({f"s{i}": v for i, v in enumerate(scales)})
    motion = params.motion_fmt
    predicted = np.asarray(predicted, dtype=object)
    wide = QFormat(True, motion.int_bits + total_range[1], motion.frac_bits)
    scale_fmt = solver.scale_fmt
    for i in range(6):
        shifted = np.array([int(v) << int(e) for v, e in zip(predicted[:, i], exponents[i])],
                           dtype=object)
        inputs[f"f{i}"], sat = round_half_even(shifted, wide, solver.solution_fmt)
        saturated = saturated | sat
        inputs[f"ratio{i}"] = Value(np.array(
            [(1 << scale_fmt.frac_bits) >> int(d) for d in total_exponents[i] - exponents[i]],
            dtype=object), scale_fmt)
        inputs[f"sM{i}"] = Value(np.array([1 << (scale_fmt.frac_bits - int(e))
                                           for e in total_exponents[i]], dtype=object),
                                 scale_fmt)
    return inputs, saturated


def gain_step(params, normal, rhs, prior, predicted, pivot_log2=None):
    """The level's moves ``d`` (n, 6) raw ``solver.step_fmt`` and the gain solve's
    :class:`hdl.pose.params.PoseFlag` flags (n,) (ILL, SATURATED; 0: ``d`` stands) of
    :func:`gain_inputs`' rows; ``pivot_log2`` is the solver's run-time register."""
    solver = params.solver
    program = build_gain_program(solver)
    inputs, saturated = gain_inputs(params, normal, rhs, prior, predicted)
    values = {("input", name): value for name, value in inputs.items()}
    n = len(np.asarray(prior))
    _, ill, sat = execute(solver, program, batches(program.ops), values, n, pivot_log2)
    flags = flags_from_checks(np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), ill,
                              saturated | sat)
    step = np.stack([np.asarray(values[operand_key(v)].raw, dtype=object)
                     for v in program.step], axis=1)
    return np.where((flags == 0)[:, None], step, 0).astype(np.int64), flags

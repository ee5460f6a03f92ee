"""Parameters and number formats of the pose solver (no Amaranth here: the emulator and
the golden-side table builder use them too).

The formats were chosen from measured dynamic range; ``docs/pose/pose_solver.md`` gives the
derivation and the error budget, ``docs/fixed_point.md`` the table.
"""

import enum
import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from golden.checks import check_int, check_number

from hdl.fixed import SQ, UQ, Overflow, QFormat, Rounding, check_format
from hdl.output.params import PoseSource

__all__ = ["PoseFlag", "PoseSolverParams", "solver_source", "coefficient_formats",
           "quantize_coefficients", "COEF_GROUPS", "DEFAULT_COEF_WIDTH", "SEED_TABLE_FMT",
           "SLOPE_FMT", "DELTA_BITS", "seed_tables", "MIN_PIVOT_LOG2"]

#: The three coefficient groups of a table row (see golden.pose_lsq): a_T, a_C, a_R.
COEF_GROUPS = ("t", "c", "r")
#: Coefficient store width picked for a rig's table (one 18-bit DSP48 operand).
DEFAULT_COEF_WIDTH = 18
#: The strictest pivot check (``pivot_log2``, built or run-time): pivots below 1/4 ILL.
MIN_PIVOT_LOG2 = 2


class PoseFlag(enum.IntFlag):
    """Why a row gave no step (``flags`` of a pose record). No bit set: the row was solved.

    Any bit means: step zero, pose unchanged, and the matching counter incremented.
    """
    #: A column of the normal matrix is below ``min_diagonal``: an unknown has no
    #: constraint (all confidences zero, no measurement, or an unobservable direction).
    EMPTY = 1 << 0
    #: A pivot of the scaled Cholesky factorization fell below ``2**-pivot_log2``: the
    #: system is too ill-conditioned to solve.
    ILL = 1 << 1
    #: An intermediate of the solve or the step left its format (saturated).
    SATURATED = 1 << 2
    #: The row had more than ``slots`` measurements (the accumulator has guard bits for
    #: ``slots`` only).
    OVERRUN = 1 << 3


@dataclass(frozen=True, kw_only=True)
class PoseSolverParams:
    """Sizes and formats of :class:`hdl.pose_solver.PoseSolver`.

    Parameters
    ----------
    slots : int
        Measurement slots per row (cameras × segments); the coefficient store holds
        ``slots × rows`` entries and a row may carry at most ``slots`` measurements.
    rows : int
        Rows per frame.
    shift_fmt, cue_fmt, conf_fmt : QFormat
        Input formats: shift along the row (pixels), depth cue (disparity in pixels, or
        inverse depth; the table's ``cue_scale`` says which), confidence weight.
    coef_t_fmt, coef_c_fmt, coef_r_fmt : QFormat
        Formats of the stored coefficients a_T, a_C, a_R; all of one width (the store
        is an array of equal lanes). :func:`coefficient_formats` picks them from a table.
    coef_poly_fmts : tuple
        Empty: the store holds every row's coefficients (``slots × rows`` entries, any
        lens). Otherwise the formats ``((t, c, r), …)`` of the terms ``c_0 … c_d`` of
        each coefficient as a polynomial in the row (:mod:`hdl.pose.row_polynomials`;
        ``slots × (d + 1)`` entries, evaluated per measurement). The terms of a group
        share one fraction width, at least the group's coefficient format's (so a
        window's terms, :func:`hdl.pose.row_polynomials.shift_polynomials`, are exact).
    a_fmt : QFormat
        Design-row entries ``w·a_T`` and ``a_R + w·a_C`` (rounded half-even, saturated).
    engine_width : int
        Raw width of every value in the solver's register file.
    pivot_log2 : int
        A pivot below ``2**-pivot_log2`` flags :attr:`PoseFlag.ILL`: the reset value
        of the solver's run-time ``pivot_log2`` and the loosest check it accepts (it
        sets ``lower_fmt``, which holds ``D^-1/2`` only for pivots it passes; see
        :meth:`pivot_thresholds`).
    min_diagonal : float
        A diagonal entry of the normal matrix below this flags :attr:`PoseFlag.EMPTY`
        (units: pixel² per unknown² times confidence).
    seed_bits : int
        Index bits of the ``1/sqrt`` seed table (linear interpolation between entries).
    row_bits, time_bits : int
        Widths of the row index and time stamp carried to the pose record.
    counter_bits : int
        Width of the status counters (they wrap).
    lanes : int
        Multipliers that form the 27 products of the normal equations per measurement
        (27 / lanes clocks per measurement).
    """
    slots: int = 8
    rows: int = 480
    shift_fmt: QFormat = SQ(6, 12)
    cue_fmt: QFormat = UQ(8, 10)
    conf_fmt: QFormat = UQ(2, 8)
    coef_t_fmt: QFormat = SQ(5, 13)
    coef_c_fmt: QFormat = SQ(2, 16)
    coef_r_fmt: QFormat = SQ(11, 7)
    coef_poly_fmts: tuple = ()
    a_fmt: QFormat = SQ(13, 12)
    engine_width: int = 42
    pivot_log2: int = 20
    min_diagonal: float = 1.0
    seed_bits: int = 10
    row_bits: int = 10
    time_bits: int = 32
    counter_bits: int = 32
    lanes: int = 3

    def __post_init__(self):
        check_int("slots", self.slots, 1, 1 << 12)
        check_int("rows", self.rows, 1, 1 << 16)
        for name in ("shift_fmt", "cue_fmt", "conf_fmt", "coef_t_fmt", "coef_c_fmt",
                     "coef_r_fmt", "a_fmt"):
            check_format(name, getattr(self, name))
        for name in ("shift_fmt", "coef_t_fmt", "coef_c_fmt", "coef_r_fmt", "a_fmt"):
            if not getattr(self, name).signed:
                raise ValueError(f"{name} must be signed, not {getattr(self, name)}")
        if (self.shift_fmt.int_bits > self.a_fmt.int_bits
                or self.shift_fmt.frac_bits > self.a_fmt.frac_bits):
            raise ValueError(f"shift_fmt {self.shift_fmt} must fit a_fmt {self.a_fmt} (the "
                             f"accumulator forms its products alike)")
        for name in ("cue_fmt", "conf_fmt"):
            if getattr(self, name).signed:
                raise ValueError(f"{name} must be unsigned, not {getattr(self, name)}")
        widths = {self.coef_t_fmt.width, self.coef_c_fmt.width, self.coef_r_fmt.width}
        if len(widths) != 1:
            raise ValueError(f"coef_t_fmt, coef_c_fmt and coef_r_fmt must have one width, "
                             f"not {sorted(widths)}")
        self._check_poly_fmts()
        check_int("engine_width", self.engine_width, 32, 64)
        # the seed register keeps the table's fraction bits and one more
        check_int("pivot_log2", self.pivot_log2, MIN_PIVOT_LOG2,
                   2 * (self.engine_width - SEED_TABLE_FMT.frac_bits - 3))
        check_number("min_diagonal", self.min_diagonal, 0, low_open=True)
        check_int("seed_bits", self.seed_bits, 3, 12)
        check_int("row_bits", self.row_bits, max(1, (self.rows - 1).bit_length()), 16)
        check_int("time_bits", self.time_bits, 1, 64)
        check_int("counter_bits", self.counter_bits, 1, 64)
        check_int("lanes", self.lanes, 1, 27)
        if self.min_diagonal_raw > self.normal_fmt.max_raw:
            raise ValueError(f"min_diagonal {self.min_diagonal} does not fit the normal "
                             f"matrix format {self.normal_fmt}")

    def _check_poly_fmts(self):
        fmts = self.coef_poly_fmts
        if not isinstance(fmts, tuple) or not all(
                isinstance(term, tuple) and len(term) == 3 for term in fmts):
            raise TypeError(f"coef_poly_fmts must be a tuple of (t, c, r) format tuples, "
                            f"not {fmts!r}")
        if len(fmts) > 4:
            raise ValueError(f"coef_poly_fmts must have at most 4 terms (degree 3), not "
                             f"{len(fmts)}")
        for g, (name, coef_fmt) in enumerate(zip(COEF_GROUPS, self.coef_group_fmts)):
            for k, term in enumerate(fmts):
                check_format(f"coef_poly_fmts[{k}][{g}]", term[g], signed=True)
            fracs = {term[g].frac_bits for term in fmts}
            if fracs and (len(fracs) != 1 or fracs.pop() < coef_fmt.frac_bits):
                raise ValueError(f"coef_poly_fmts terms of group {name} must share one "
                                 f"fraction width of at least {coef_fmt.frac_bits}, not "
                                 f"{[str(term[g]) for term in fmts]}")

    replace = replace

    # --- sizes -------------------------------------------------------------------------

    @property
    def coef_group_fmts(self):
        """Formats of the three coefficient groups: a_T, a_C, a_R."""
        return (self.coef_t_fmt, self.coef_c_fmt, self.coef_r_fmt)

    def coef_fmt(self, index, term=None):
        """Format of coefficient ``index`` (0–8): of its value in a row, or of its
        polynomial term ``term``."""
        group = index // 3
        return self.coef_group_fmts[group] if term is None else self.coef_poly_fmts[term][group]

    @property
    def coef_terms(self):
        """Polynomial terms per coefficient (0: a store of every row)."""
        return len(self.coef_poly_fmts)

    @property
    def entries_per_slot(self):
        """Store entries of one slot: its rows, or its polynomial terms."""
        return self.coef_terms or self.rows

    @property
    def entries(self):
        """Coefficient store depth: entry ``slot · entries_per_slot + row`` (or
        ``+ term``)."""
        return self.slots * self.entries_per_slot

    @property
    def coef_store_width(self):
        """Raw width of a stored entry (a run-time write's data)."""
        return max([self.coef_width] + [f.width for term in self.coef_poly_fmts
                                        for f in term])

    @property
    def coef_latency(self):
        """Clocks from a (slot, row) to its coefficients: the memory read, then for a
        polynomial store one clock per Horner step and one for the rounding."""
        return 1 if not self.coef_terms else self.coef_terms + 1

    @property
    def slot_bits(self):
        return max(1, (self.slots - 1).bit_length())

    @property
    def entry_bits(self):
        return max(1, (self.entries - 1).bit_length())

    @property
    def coef_width(self):
        return self.coef_t_fmt.width

    # --- accumulator formats -----------------------------------------------------------

    @property
    def weighted_fmt(self):
        """``c·a`` (exact)."""
        return _mul(self.conf_fmt, self.a_fmt)

    @property
    def guard_bits(self):
        return max(1, (self.slots - 1).bit_length())

    @property
    def normal_fmt(self):
        """Accumulated ``Σ c a_i a_j`` and ``Σ c a_i s`` (exact for up to ``slots``
        measurements; the shift is a narrower format than ``a_fmt``, so its sums fit)."""
        product = _mul(self.weighted_fmt, self.a_fmt)
        return SQ(product.int_bits + self.guard_bits, product.frac_bits)

    @property
    def min_diagonal_raw(self):
        return int(math.ceil(self.min_diagonal * 2.0 ** self.normal_fmt.frac_bits))

    # --- scaling exponents -------------------------------------------------------------

    def exponent(self, bit_length):
        """Jacobi exponent ``e`` of a diagonal entry whose raw value has ``bit_length``
        bits: ``N_ii · 2**(-2e)`` lies in ``[1/4, 1)``."""
        return -((self.normal_fmt.frac_bits - bit_length) // 2)

    @property
    def exponent_range(self):
        """Smallest and largest exponent of a diagonal entry that is not EMPTY."""
        return (self.exponent(self.min_diagonal_raw.bit_length()),
                self.exponent(self.normal_fmt.width - 1))

    @property
    def pivot_log2_bits(self):
        """Width of the run-time ``pivot_log2`` (holds the build's value)."""
        return self.pivot_log2.bit_length()

    def pivot_thresholds(self, pivot_log2=None):
        """The pivot check's raw ``unit_fmt`` thresholds ``2**-v`` for run-time values
        ``pivot_log2`` (int or array of them, as written to the ``pivot_log2_bits``-wide
        register; None: the build's), and whether each was out of range. A value from
        ``MIN_PIVOT_LOG2`` to the build's ``pivot_log2`` is used; any other the field
        holds is replaced by the build's (a looser check would let ``D^-1/2`` wrap in
        ``lower_fmt``) and flagged; one the field cannot hold is a ``ValueError``."""
        value = np.asarray(self.pivot_log2 if pivot_log2 is None else pivot_log2)
        if value.dtype.kind not in "iu" or np.any((value < 0)
                                                   | (value >= 1 << self.pivot_log2_bits)):
            raise ValueError(f"pivot_log2 must be integers from 0 to "
                             f"{(1 << self.pivot_log2_bits) - 1}, not {pivot_log2!r}")
        error = (value < MIN_PIVOT_LOG2) | (value > self.pivot_log2)
        used = np.where(error, self.pivot_log2, value).astype(np.int64)
        return np.left_shift(1, self.unit_fmt.frac_bits - used), error

    # --- engine formats ----------------------------------------------------------------

    def engine_fmt(self, int_bits):
        return SQ(int_bits, self.engine_width - int_bits)

    @property
    def unit_fmt(self):
        """Scaled normal matrix N̂, Schur complements and pivots, the Cholesky factor G
        (|G_ij| ≤ 1), the Newton factors: |·| < 2."""
        return self.engine_fmt(2)

    @property
    def lower_fmt(self):
        """``ρ = D^-1/2`` and ``L = G·ρ`` (back substitution): up to
        ``2**(pivot_log2/2)``."""
        return self.engine_fmt(-(-self.pivot_log2 // 2) + 2)

    @property
    def seed_fmt(self):
        """Seeds ``y0·2**k ≈ D^-1/2`` (exact shifted table values)."""
        return self.lower_fmt

    @property
    def solution_fmt(self):
        """Scaled right-hand side b̂ and the substitution values c, z, w, x."""
        return self.engine_fmt(12)

    @property
    def scale_fmt(self):
        """``2**-e``, the Jacobi scale of an unknown (exact)."""
        low, high = self.exponent_range
        return self.engine_fmt(max(2, 2 - low))

    @property
    def step_fmt(self):
        """The step ``[T θ]``: metres and radians, |·| < 1."""
        return self.engine_fmt(1)

    @property
    def quat_fmt(self):
        return self.engine_fmt(2)

    @property
    def position_fmt(self):
        """Position in metres, ±512 m (saturates)."""
        return self.engine_fmt(10)

    @property
    def mantissa_bits(self):
        """Fraction bits of the normalized pivot ``m ∈ [1/4, 1)`` in the seed unit
        (two more than the pivot's, so that every even normalization is exact)."""
        return self.unit_fmt.frac_bits + 2


def solver_source(params):
    """The pose record's formats for solver ``params``: the solver emits
    :meth:`PoseSource.layout <hdl.output.params.PoseSource.layout>` of this, the layout
    :class:`hdl.output.packet.PoseOutput` takes, so the two connect without renaming."""
    return PoseSource(position_fmt=params.position_fmt, quaternion_fmt=params.quat_fmt,
                      step_fmt=params.step_fmt, row_bits=params.row_bits,
                      time_bits=params.time_bits, flag_bits=len(PoseFlag))


def _mul(a, b):
    return QFormat(a.signed or b.signed, a.int_bits + b.int_bits, a.frac_bits + b.frac_bits)


def coefficient_formats(table, width):
    """Formats of the three coefficient groups of ``table`` (..., 9) at ``width`` bits:
    the fewest integer bits that hold each group's largest magnitude."""
    table = np.asarray(table, dtype=float)
    if table.shape[-1] != 9:
        raise ValueError(f"table must have 9 coefficients on its last axis, not shape {table.shape}")
    check_int("width", width, 4, 48)
    formats = {}
    for k, group in enumerate(COEF_GROUPS):
        largest = float(np.max(np.abs(table[..., 3 * k:3 * k + 3]), initial=0.0))
        int_bits = 1 + max(0, math.floor(math.log2(largest)) + 1 if largest > 0 else 0)
        if int_bits >= width:
            raise ValueError(f"coefficient group a_{group.upper()} reaches {largest:g}, "
                             f"which needs more than width {width} bits")
        formats[f"coef_{group}_fmt"] = SQ(int_bits, width - int_bits)
    return formats


def quantize_coefficients(params, table):
    """Raw coefficient store contents (slots, rows, 9) of a float table; half-even
    rounding, and an error if a coefficient does not fit its format."""
    table = np.asarray(table, dtype=float)
    if table.shape != (params.slots, params.rows, 9):
        raise ValueError(f"table must have shape ({params.slots}, {params.rows}, 9), "
                         f"not {table.shape}")
    return np.concatenate([fmt.quantize(table[..., 3 * k:3 * k + 3], Rounding.HALF_EVEN,
                                        Overflow.ERROR)
                           for k, fmt in enumerate(params.coef_group_fmts)], axis=-1)


#: Format of the seed table's values ``1/sqrt(m) ∈ (1, 2]`` (the interpolation is good to
#: about 2**-18, so more bits would buy nothing).
SEED_TABLE_FMT = UQ(2, 20)
#: Format of the seed slopes (18 bits: one DSP B port).
SLOPE_FMT = UQ(3, 15)
#: Bits of ``m`` below the table index that the interpolation uses.
DELTA_BITS = 12


@lru_cache(maxsize=None)
def seed_tables(seed_bits):
    """Secant interpolation tables of ``1/sqrt(m)`` on ``m ∈ [0, 1)`` in steps of
    ``h = 2**-seed_bits`` (raw ints; entries below 1/4 are never used): values
    ``T0[i] = m_i^-1/2`` and slopes ``T1[i] = (m_i^-1/2 − m_{i+1}^-1/2) / h``, so that
    ``m^-1/2 ≈ T0[i] − T1[i]·(m − m_i)``."""
    h = 2.0 ** -seed_bits
    m = np.maximum(np.arange(1 << seed_bits) * h, 0.25)
    value = SEED_TABLE_FMT.quantize(1.0 / np.sqrt(m))
    slope = SLOPE_FMT.quantize((1.0 / np.sqrt(m) - 1.0 / np.sqrt(m + h)) / h)
    return tuple(int(v) for v in value), tuple(int(s) for s in slope)

"""The solver's coefficients as polynomials in the camera row (no Amaranth here).

For a rectified pinhole camera the three coefficient groups of a segment (the shift
along the row per unit of motion, :func:`golden.pose_lsq.shift_coefficients`) are exactly
linear in the row index ``y``: at a fixed column ``x`` the entries are ``−1/Z``, ``x/Z``,
``x·y``, ``−(1 + x²)``, ``y`` in normalised coordinates, rotated by the camera's fixed
mounting. So instead of ``slots × rows`` stored rows (171 BRAM36 for stereo20), the
store keeps ``slots × terms`` polynomial terms and the hardware evaluates
``c(y) = Σ c_k y^k`` per measurement (issue 17, "memory that fits").

The arithmetic, shared by the emulator's table and the gateware
(:class:`hdl.pose.coef_store.CoefficientStore`): each term ``c_k`` of group ``g`` is a raw
integer of its format in ``PoseSolverParams.coef_poly_fmts``; the terms of a group share
``d·b + guard_bits`` more fraction bits than the group's coefficient format (``b`` the
bits of the largest row, ``d`` the degree), so that every ``c_k y^k`` is good to
``2^-(guard_bits+1)`` LSB and a window's shifted terms are exact integers; Horner's
scheme ``acc = c_d; acc = acc·y + c_k`` is exact (:func:`hdl.fixed.mul`,
:func:`hdl.fixed.add`), and only the result is rounded half-even into the coefficient's
format. The error against the exact table is the fit's residual (round-off for a
pinhole camera) plus ``0.5 + (d + 1) / 2^(guard_bits+1)`` LSB.
"""

import math
from math import comb

import numpy as np

from golden.checks import check_int

from hdl.fixed import SQ, UQ, Overflow, Rounding, add, mul, resize

__all__ = ["DEFAULT_GUARD_BITS", "fit_row_polynomials", "polynomial_formats",
           "quantize_polynomials", "evaluate_polynomials", "shift_polynomials"]

#: Fraction bits of each term beyond what its power of the row needs: each term adds at
#: most 2^-4 LSB to the 0.5 LSB of the final rounding.
DEFAULT_GUARD_BITS = 3


def fit_row_polynomials(table, degree):
    """Least-squares polynomials in the row (slots, degree + 1, 9), lowest power first,
    of a float table (slots, rows, 9), and the largest absolute residual per coefficient
    (9,)."""
    table = np.asarray(table, dtype=float)
    if table.ndim != 3 or table.shape[-1] != 9:
        raise ValueError(f"table must have shape (slots, rows, 9), not {table.shape}")
    check_int("degree", degree, 0, 3)
    slots, rows, _ = table.shape
    if rows <= degree:
        raise ValueError(f"degree {degree} needs more than {degree} rows, not {rows}")
    y = np.arange(rows, dtype=float) / rows            # scaled: a well-conditioned fit
    basis = np.vander(y, degree + 1, increasing=True)
    flat = table.transpose(1, 0, 2).reshape(rows, -1)
    coef, *_ = np.linalg.lstsq(basis, flat, rcond=None)
    residual = np.abs(basis @ coef - flat).reshape(rows, slots, 9).max(axis=(0, 1))
    coef /= (float(rows) ** np.arange(degree + 1))[:, None]   # back to powers of y
    return coef.reshape(degree + 1, slots, 9).transpose(1, 0, 2), residual


def _taylor(poly, first):
    """Float polynomials (slots, terms, 9) in ``y − first``."""
    out = np.zeros_like(poly)
    for j in range(poly.shape[1]):
        for k in range(j, poly.shape[1]):
            out[:, j] += comb(k, j) * float(first) ** (k - j) * poly[:, k]
    return out


def polynomial_formats(poly, coef_fmts, rows, guard_bits=DEFAULT_GUARD_BITS):
    """Formats of the terms ``((t, c, r) per term)``: the fraction bits of the group's
    coefficient format plus ``d·b + guard_bits`` (``d`` the degree, ``b`` the bits of row
    ``rows − 1``) and, per term, the fewest integer bits that hold its largest magnitude over all
    slots and over every window start ``0 … rows − 1`` (:func:`shift_polynomials`: a
    co-simulated window's store holds the shifted terms)."""
    check_int("guard_bits", guard_bits, 0, 24)
    check_int("rows", rows, 1)
    poly = np.asarray(poly, dtype=float)
    largest = np.max([np.abs(_taylor(poly, first)) for first in range(rows)], axis=(0, 1))
    row_bits = max(1, (rows - 1).bit_length())
    formats = []
    for k in range(poly.shape[1]):
        group_fmts = []
        for g, fmt in enumerate(coef_fmts):
            frac = fmt.frac_bits + (poly.shape[1] - 1) * row_bits + guard_bits
            # the magnitude rounded to the term's LSB must fit too
            top = float(largest[k, 3 * g:3 * g + 3].max()) + 2.0 ** -(frac + 1)
            int_bits = 1 + max(0, math.floor(math.log2(top)) + 1)
            group_fmts.append(SQ(int_bits, frac))
        formats.append(tuple(group_fmts))
    return tuple(formats)


def quantize_polynomials(params, poly):
    """Raw terms (slots, terms, 9) of float polynomials; half-even rounding, an error
    if a term does not fit its format."""
    poly = np.asarray(poly, dtype=float)
    shape = (params.slots, params.coef_terms, 9)
    if poly.shape != shape:
        raise ValueError(f"poly must have shape {shape}, not {poly.shape}")
    return np.stack([np.concatenate([
        fmt.quantize(poly[:, k, 3 * g:3 * g + 3], Rounding.HALF_EVEN, Overflow.ERROR)
        for g, fmt in enumerate(params.coef_poly_fmts[k])], axis=-1)
        for k in range(params.coef_terms)], axis=1)


def evaluate_polynomials(params, poly_raw, rows, overflow=Overflow.SATURATE):
    """The store's coefficients (slots, len(rows), 9), raw in the coefficient formats, at
    camera rows ``rows``: exact Horner on the raw terms, then half-even rounding into the
    coefficient format with ``overflow`` (the gateware saturates; a build checks with
    ``Overflow.ERROR`` that every row of its rig fits)."""
    poly_raw = np.asarray(poly_raw, dtype=np.int64)
    y = np.asarray(rows, dtype=np.int64)[None, :]
    row_fmt = UQ(params.row_bits, 0)
    out = np.empty((poly_raw.shape[0], y.shape[1], 9), dtype=np.int64)
    for index in range(9):
        top = params.coef_terms - 1
        acc = np.broadcast_to(poly_raw[:, top, index, None], (len(poly_raw), y.shape[1]))
        fmt = params.coef_fmt(index, top)
        for k in range(top - 1, -1, -1):
            acc, fmt = mul(acc, fmt, y, row_fmt)
            acc, fmt = add(acc, fmt, poly_raw[:, k, index, None], params.coef_fmt(index, k))
        out[..., index] = resize(acc, fmt, params.coef_fmt(index),
                                 Rounding.HALF_EVEN, overflow)
    return out


def shift_polynomials(poly_raw, first):
    """The same polynomials in ``y' = y − first`` (a window whose row 0 is camera row
    ``first``): ``c'_j = Σ_{k≥j} C(k, j) first^(k−j) c_k``, exact on raw integers (the
    terms keep their formats; the caller checks they still fit)."""
    poly_raw = np.asarray(poly_raw, dtype=object)
    terms = poly_raw.shape[1]
    shifted = np.zeros_like(poly_raw)
    for j in range(terms):
        for k in range(j, terms):
            shifted[:, j] += comb(k, j) * first ** (k - j) * poly_raw[:, k]
    return shifted.astype(np.int64)

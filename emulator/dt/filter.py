"""Bit-accurate model of :class:`hdl.dt.filter.DomainTransformFilter`.

Integers only, rounding exactly where the hardware does, with the constants, tables and
formats imported from :mod:`hdl.dt.filter` and every narrowing through :mod:`hdl.fixed`.
The hardware streams rows; the model computes whole frames with the loops running along
the recursions and numpy across them. Frames are independent (a frame's first row and
every row's first pixel have weight 0), so a stream of frames is a list of frames.
"""

import numpy as np

from golden.checks import check_number

from hdl.dt.params import (COEF_FMT, COEF_NUMERATOR, GUIDE_BITS, SCHEDULE_FMT, SIGMA_FMT,
                           SIGMA_MIN_RAW, TABLE_ADDR_BITS, DtFilterParams, lookup_fmt,
                           schedule_scales, weight_tables)
from hdl.fixed import UQ, Overflow, Rounding, add, mul, resize

__all__ = ["sigma_register", "coefficient", "weights", "frame_weights", "rf_step",
           "horizontal_pass", "vertical_pass", "output", "filter_frame", "round_registers",
           "filter_rounds"]

def sigma_register(name, value):
    """A sigma in real units to its register value (raw ``SIGMA_FMT``); at least 1.0."""
    check_number(name, value, 1.0, SIGMA_FMT.max_value)
    return int(SIGMA_FMT.quantize(value))


def coefficient(sigma_raw):
    """``k = sqrt(2) / ln(2) / sigma`` as the hardware divider computes it (raw ``COEF_FMT``)."""
    return COEF_NUMERATOR // max(int(SIGMA_FMT.raw(sigma_raw)), SIGMA_MIN_RAW)


def weights(params, k_s, k_r, g):
    """Weights ``2**-(k_s + k_r g)`` (raw ``weight_fmt``) for guide differences ``g``."""
    g = UQ(GUIDE_BITS, 0).raw(g)
    scaled, scaled_fmt = mul(np.full(g.shape, k_r), COEF_FMT, g, UQ(GUIDE_BITS, 0))
    exponent, exact_fmt = add(np.full(g.shape, k_s), COEF_FMT, scaled, scaled_fmt)
    exponent = resize(exponent, exact_fmt, lookup_fmt(), Rounding.FLOOR, Overflow.ERROR)
    frac, mask = lookup_fmt().frac_bits, (1 << TABLE_ADDR_BITS) - 1
    whole = exponent >> frac
    high, low = (np.array(t, dtype=np.int64) for t in weight_tables(params.table_fmt))
    product, product_fmt = mul(high[(exponent >> (frac - TABLE_ADDR_BITS)) & mask],
                               params.table_fmt,
                               low[(exponent >> (frac - 2 * TABLE_ADDR_BITS)) & mask],
                               params.table_fmt)
    rounded = resize(product, product_fmt, params.product_fmt, Rounding.HALF_UP, Overflow.ERROR)
    shift = np.minimum(whole, params.zero_exponent)
    shifted = (rounded << params.weight_fmt.frac_bits) >> np.minimum(shift, params.weight_fmt.frac_bits)
    w = resize(shifted, params.shifted_fmt, params.weight_fmt, Rounding.HALF_UP, Overflow.SATURATE)
    return np.where(shift == params.zero_exponent, 0, w)


def frame_weights(params, guide, sigma_s_raw, sigma_r_raw):
    """Horizontal and vertical weights of a frame, 0 where a row or the frame starts.

    ``w_h[y, x]`` links pixel ``x - 1`` to ``x``; ``w_v[y, x]`` links row ``y - 1`` to ``y``.
    """
    g = np.asarray(guide, dtype=np.int64)
    k_s, k_r = coefficient(sigma_s_raw), coefficient(sigma_r_raw)
    w_h = np.zeros(g.shape, dtype=np.int64)
    w_v = np.zeros(g.shape, dtype=np.int64)
    w_h[:, 1:] = weights(params, k_s, k_r, np.abs(np.diff(g, axis=1)))
    w_v[1:, :] = weights(params, k_s, k_r, np.abs(np.diff(g, axis=0)))
    return w_h, w_v


def rf_step(params, k, p, w):
    """``k + round_half_up(w (p - k))`` on raw ``value_fmt`` arrays (see ``hdl_rf_step``)."""
    vf, df = params.value_fmt, params.diff_fmt
    prod, prod_fmt = mul(vf.raw(p) - vf.raw(k), df, w, params.weight_fmt)
    delta = resize(prod, prod_fmt, df, Rounding.HALF_UP, Overflow.ERROR)
    total, total_fmt = add(k, vf, delta, df)
    return resize(total, total_fmt, vf, Rounding.FLOOR, Overflow.ERROR)


def horizontal_pass(params, value, w_h):
    """Causal then anti-causal recursion along each row; raw ``value_fmt`` out."""
    k = np.asarray(value, dtype=np.int64) << params.frac_bits
    width = k.shape[1]
    causal = k.copy()
    for x in range(1, width):
        causal[:, x] = rf_step(params, k[:, x], causal[:, x - 1], w_h[:, x])
    anti = causal.copy()
    for x in range(width - 2, -1, -1):
        anti[:, x] = rf_step(params, causal[:, x], anti[:, x + 1], w_h[:, x + 1])
    return anti


def vertical_pass(params, values, w_v, window=None):
    """Causal recursion down the columns, then the anti-causal one over ``window`` lines.

    Row ``y`` of the anti-causal pass starts at row ``min(y + window - 1, H - 1)`` and
    folds in the rows above it one by one, as the hardware's chain of line buffers does.
    ``window`` defaults to ``params.window``; at least ``H`` gives the exact pass (what a
    frame buffer would allow).
    """
    window = params.window if window is None else window
    height = values.shape[0]
    causal = values.copy()
    for y in range(1, height):
        causal[y] = rf_step(params, values[y], causal[y - 1], w_v[y])
    rows = np.arange(height)
    acc = causal[np.minimum(rows + window - 1, height - 1)].copy()
    for t in range(min(window, height) - 1, 0, -1):
        n = rows[rows + t <= height - 1]
        q = n + t - 1
        acc[n] = rf_step(params, causal[q], acc[n], w_v[q + 1])
    return acc


def output(params, values):
    """Raw ``value_fmt`` to the output integers (round half up)."""
    return resize(values, params.value_fmt, params.output_fmt, Rounding.HALF_UP, Overflow.ERROR)


def filter_frame(params, guide, value, sigma_s_raw, sigma_r_raw, *, vertical=True):
    """The block's output for one frame (``vertical=False``: the horizontal passes only).

    Parameters
    ----------
    params : DtFilterParams
    guide : int array (H, W), 0..255
    value : int array (H, W), 0..2**value_bits - 1
    sigma_s_raw, sigma_r_raw : int
        Register values (raw ``SIGMA_FMT``) latched at the frame's first pixel.
    """
    if not isinstance(params, DtFilterParams):
        raise TypeError(f"params must be a DtFilterParams, not {params!r}")
    guide = UQ(GUIDE_BITS, 0).raw(guide)
    value = params.output_fmt.raw(value)
    if guide.ndim != 2 or guide.shape != value.shape or guide.shape[1] != params.width:
        raise ValueError(f"guide and value must both be (H, {params.width}) arrays, "
                         f"not {guide.shape} and {value.shape}")
    w_h, w_v = frame_weights(params, guide, sigma_s_raw, sigma_r_raw)
    out = horizontal_pass(params, value, w_h)
    if vertical:
        out = vertical_pass(params, out, w_v)
    return output(params, out)


def round_registers(sigma_raw, rounds):
    """A sigma register scaled for each round of :class:`hdl.dt.rounds.DomainTransformRounds`."""
    out = []
    for scale in schedule_scales(rounds):
        product, fmt = mul(np.int64(sigma_raw), SIGMA_FMT, np.int64(scale), SCHEDULE_FMT)
        out.append(int(resize(product, fmt, SIGMA_FMT, Rounding.HALF_UP, Overflow.ERROR)))
    return out


def filter_rounds(params, guide, value, sigma_s_raw, sigma_r_raw, rounds):
    """The output of :class:`hdl.dt.rounds.DomainTransformRounds` for one frame: each
    round is :func:`filter_frame` with the round's registers, on the last round's output."""
    for s_raw, r_raw in zip(round_registers(sigma_s_raw, rounds),
                            round_registers(sigma_r_raw, rounds)):
        value = filter_frame(params, guide, value, s_raw, r_raw)
    return value

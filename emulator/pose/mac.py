"""Bit-accurate model of :class:`hdl.pose.mac.MultiplyAccumulate`."""

import numpy as np

from hdl.fixed import Overflow, QFormat, Rounding, mul, resize

__all__ = ["mac_model"]


def mac_model(params, a, b, last):
    """Sums of products per vector, as raw ``params.out_fmt`` integers.

    ``a``, ``b`` are raw operand integers and ``last`` marks the final pair of each
    vector; pairs after the final ``last`` are an unfinished vector and give no output.
    The accumulator wraps in ``acc_fmt`` at every step, as the hardware does; since
    two's-complement wrap-around is modular, wrapping the exact sum once is identical.
    """
    products, product_fmt = mul(a, params.a_fmt, b, params.b_fmt)
    products = products.astype(object)
    ends = np.flatnonzero(np.asarray(last, dtype=bool))
    starts = np.concatenate([[0], ends[:-1] + 1]).astype(int)
    # Wide enough for any sum of up to 2**64 products: the exact sum before wrapping.
    exact_fmt = QFormat(True, product_fmt.int_bits + 64, product_fmt.frac_bits)
    sums = np.array([products[s:e + 1].sum() for s, e in zip(starts, ends)], dtype=object)
    acc = resize(sums, exact_fmt, params.acc_fmt, Rounding.FLOOR, Overflow.WRAP)
    return resize(acc, params.acc_fmt, params.out_fmt, params.rounding, params.overflow)

"""hdl.fixed: the numpy model and the Amaranth gateware agree bit for bit.

Property tests draw random formats, roundings, overflow modes and operands (always
including each format's extremes), build the gateware once per example and simulate
every operand through it.
"""

import numpy as np
import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator
from hypothesis import given, settings, strategies as st

from hdl.fixed import (Overflow, QFormat, Rounding, SQ, UQ, add, hdl_add, hdl_mul,
                       hdl_mul_constant, hdl_resize, mul, resize)


def formats(max_int=10, max_frac=10):
    return st.tuples(st.booleans(), st.integers(0, max_int), st.integers(0, max_frac)).filter(
        lambda t: t[0] or t[1] + t[2] >= 1,
    ).map(lambda t: QFormat(t[0], t[1] + (1 if t[0] else 0), t[2]))


def operands(fmt, count=40):
    extremes = [fmt.min_raw, fmt.max_raw, 0, min(1, fmt.max_raw), max(-1, fmt.min_raw)]
    return st.lists(st.integers(fmt.min_raw, fmt.max_raw), min_size=count,
                    max_size=count).map(lambda xs: extremes + xs)


def simulate(inputs, output, vectors):
    """Drive each tuple in ``vectors`` onto ``inputs`` and read the combinational output."""
    m = Module()
    m.d.comb += Signal().eq(0)  # a module with no logic of its own still elaborates
    got = []

    async def testbench(ctx):
        for values in vectors:
            for sig, value in zip(inputs, values):
                ctx.set(sig, int(value))
            got.append(ctx.get(output))

    sim = Simulator(m)
    sim.add_testbench(testbench)
    sim.run()
    return got


@settings(max_examples=60, deadline=None)
@given(data=st.data(), src=formats(), dst=formats(),
       rounding=st.sampled_from(Rounding),
       overflow=st.sampled_from([Overflow.WRAP, Overflow.SATURATE]))
def test_resize_hdl_matches_model(data, src, dst, rounding, overflow):
    values = data.draw(operands(src))
    a = Signal(src.shape())
    out = hdl_resize(a, src, dst, rounding, overflow)
    assert out.shape() == dst.shape()
    got = simulate([a], out, [(v,) for v in values])
    expected = resize(values, src, dst, rounding, overflow)
    assert got == [int(x) for x in expected]


@settings(max_examples=40, deadline=None)
@given(data=st.data(), fa=formats(8, 8), fb=formats(8, 8))
def test_add_and_mul_hdl_match_model(data, fa, fb):
    va = data.draw(operands(fa, 20))
    vb = data.draw(operands(fb, 20))
    vb = (vb * 2)[:len(va)]
    a, b = Signal(fa.shape()), Signal(fb.shape())
    for hdl_op, model_op in ((hdl_add, add), (hdl_mul, mul)):
        out, fmt = hdl_op(a, fa, b, fb)
        expected, model_fmt = model_op(va, fa, vb, fb)
        assert fmt == model_fmt and out.shape() == fmt.shape()
        assert simulate([a, b], out, list(zip(va, vb))) == [int(x) for x in expected]


@settings(max_examples=60, deadline=None)
@given(data=st.data(), fa=formats(8, 8), fq=formats(8, 8))
def test_constant_products_match_the_model(data, fa, fq):
    """``hdl_mul_constant`` equals ``mul`` (value and format) for constants at the
    format's extremes, 0, ±1 and every ±2**k it holds (those are shifts, the rest
    multipliers), on operands including the extremes."""
    va = data.draw(operands(fa, 12))
    powers = [s * (1 << k) for k in range(fq.width) for s in (1, -1)]
    constants = {fq.min_raw, fq.max_raw, 0, data.draw(st.integers(fq.min_raw, fq.max_raw)),
                 *(q for q in powers if fq.min_raw <= q <= fq.max_raw)}
    a = Signal(fa.shape())
    for q in sorted(constants):
        out, fmt = hdl_mul_constant(a, fa, q, fq)
        expected, model_fmt = mul(va, fa, [q] * len(va), fq)
        assert fmt == model_fmt and out.shape() == fmt.shape()
        assert simulate([a], out, [(v,) for v in va]) == [int(x) for x in expected], q


@settings(max_examples=200, deadline=None)
@given(fa=formats(12, 12), fb=formats(12, 12), data=st.data())
def test_exact_ops_are_exact(fa, fb, data):
    """add/mul results fit their formats and equal the real-number result."""
    a = data.draw(st.integers(fa.min_raw, fa.max_raw))
    b = data.draw(st.integers(fb.min_raw, fb.max_raw))
    for op, real in ((add, lambda x, y: x + y), (mul, lambda x, y: x * y)):
        raw, fmt = op([a], fa, [b], fb)
        fmt.raw(raw)  # raises if it does not fit
        assert int(raw[0]) * 2.0 ** -fmt.frac_bits == real(a * fa.lsb, b * fb.lsb)


def test_wide_formats_use_exact_python_ints():
    wide = SQ(40, 40)
    big = wide.max_raw
    raw, fmt = mul([big], wide, [big], wide)
    assert fmt.width == 160 and int(raw[0]) == big * big
    assert int(resize(raw, fmt, wide, Rounding.FLOOR, Overflow.SATURATE)[0]) == wide.max_raw


@pytest.mark.parametrize("rounding, expected", [
    (Rounding.FLOOR, [-2, -2, -1, -1, 0, 0, 1, 1, 2]),
    (Rounding.HALF_UP, [-2, -1, -1, 0, 0, 1, 1, 2, 2]),
    (Rounding.HALF_EVEN, [-2, -2, -1, 0, 0, 0, 1, 2, 2]),
])
def test_rounding_of_ties(rounding, expected):
    halves = [-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0]
    src = SQ(4, 1)
    raw = src.quantize(halves)
    assert list(resize(raw, src, SQ(4, 0), rounding, Overflow.ERROR)) == expected
    assert list(SQ(4, 0).quantize(halves, rounding)) == expected


def test_overflow_modes_at_the_extremes():
    src, dst = SQ(8, 0), SQ(4, 0)
    values = [-128, -9, -8, 7, 8, 127]
    assert list(resize(values, src, dst, Rounding.FLOOR, Overflow.SATURATE)) == [-8, -8, -8, 7, 7, 7]
    assert list(resize(values, src, dst, Rounding.FLOOR, Overflow.WRAP)) == [0, 7, -8, 7, -8, -1]
    with pytest.raises(OverflowError, match=r"does not fit SQ\(4, 0\)"):
        resize(values, src, dst, Rounding.FLOOR, Overflow.ERROR)
    # Rounding up past the top of the range is an overflow too.
    assert list(resize([UQ(4, 2).max_raw], UQ(4, 2), UQ(4, 0), Rounding.HALF_UP,
                       Overflow.SATURATE)) == [15]


def test_quantize_refuses_what_does_not_fit():
    fmt = UQ(2, 4)
    assert fmt.min_value == 0 and fmt.max_value == 4 - 1 / 16
    with pytest.raises(OverflowError, match=r"quantized value 64 does not fit UQ\(2, 4\)"):
        fmt.quantize(4.0)
    assert fmt.quantize(4.0, overflow=Overflow.SATURATE) == fmt.max_raw
    with pytest.raises(ValueError, match="non-finite"):
        fmt.quantize(np.nan)


@pytest.mark.parametrize("args, error, message", [
    ((True, 0, 4), ValueError, "int_bits of a signed format must be at least 1"),
    ((False, -1, 4), ValueError, "int_bits must be an integer at least 0, not -1"),
    ((False, 2, 1.5), TypeError, "frac_bits must be an integer, not 1.5"),
    ((False, 0, 0), ValueError, "at least one bit wide"),
])
def test_bad_formats_are_rejected(args, error, message):
    with pytest.raises(error, match=message):
        QFormat(*args)


def test_raw_checks_type_and_range():
    with pytest.raises(TypeError, match="must be integers"):
        SQ(2, 2).raw([0.5])
    with pytest.raises(OverflowError, match="raw value 8 does not fit SQ\\(2, 2\\)"):
        SQ(2, 2).raw([8])


@pytest.mark.parametrize("rounding", list(Rounding))
@pytest.mark.parametrize("overflow", [Overflow.WRAP, Overflow.SATURATE])
def test_resize_hdl_matches_model_exhaustively(rounding, overflow):
    """Every raw value of small formats, so every tie and every overflow is hit."""
    for src in (SQ(4, 3), UQ(3, 3)):
        for dst in (SQ(3, 1), UQ(2, 0), SQ(5, 4)):
            values = list(range(src.min_raw, src.max_raw + 1))
            a = Signal(src.shape())
            got = simulate([a], hdl_resize(a, src, dst, rounding, overflow), [(v,) for v in values])
            assert got == [int(x) for x in resize(values, src, dst, rounding, overflow)], (src, dst)

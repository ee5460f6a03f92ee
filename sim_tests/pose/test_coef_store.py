"""The solver's coefficient store as polynomials in the row (issue 17, memory that fits):
the float fit and its formats (hdl.pose.row_polynomials), the pipeline door's store for
a real rig, and the gateware (hdl.pose.coef_store) against the model in the Amaranth
simulator, with random terms at the formats' extremes and run-time writes."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from golden.rig import preset
from hdl.fixed import SQ, Overflow
from hdl.pipeline_config import COEF_POLYNOMIAL_TOLERANCE_LSB, PipelineConfig
from hdl.pose.coef_store import CoefficientStore
from hdl.pose.coef_term_store import TermStore, second_index
from hdl.pose.params import PoseSolverParams, quantize_coefficients
from hdl.pose.row_polynomials import (evaluate_polynomials, fit_row_polynomials,
                                      polynomial_formats, quantize_polynomials,
                                      shift_polynomials)

SEED = int(os.environ.get("SEED", "17"))
FMTS = (SQ(5, 13), SQ(2, 16), SQ(11, 7))


def _params(degree, rows=40, **changes):
    """A small solver whose terms have the formats the door would pick for its rows."""
    terms = polynomial_formats(np.ones((1, degree + 1, 9)), FMTS, rows)
    fields = {"coef_poly_fmts": terms, **changes}
    return PoseSolverParams(slots=3, rows=rows, coef_t_fmt=FMTS[0], coef_c_fmt=FMTS[1],
                            coef_r_fmt=FMTS[2], **fields)


# --- the model ------------------------------------------------------------------------------

def test_a_linear_table_is_fitted_exactly():
    rows = np.arange(50.0)
    table = np.stack([np.outer(np.ones(4), 0.3 - 0.01 * rows)] * 9, axis=-1)
    poly, residual = fit_row_polynomials(table, 1)
    assert residual.max() < 1e-12
    np.testing.assert_allclose(poly[:, 0], 0.3, atol=1e-12)
    np.testing.assert_allclose(poly[:, 1], -0.01, atol=1e-12)


def test_a_quadratic_table_needs_degree_two():
    y = np.arange(480.0)
    table = np.zeros((2, 480, 9))
    table[..., 6] = 1 + (y / 480) ** 2          # the across-rows store's rotation terms
    assert fit_row_polynomials(table, 1)[1][6] > 0.01
    assert fit_row_polynomials(table, 2)[1][6] < 1e-9


@pytest.mark.parametrize("call, message", [
    (lambda: fit_row_polynomials(np.zeros((2, 5, 8)), 1), "table must have shape"),
    (lambda: fit_row_polynomials(np.zeros((2, 5, 9)), 4), "degree must be an integer between 0 and 3"),
    (lambda: fit_row_polynomials(np.zeros((2, 2, 9)), 2), "degree 2 needs more than 2 rows"),
    (lambda: polynomial_formats(np.zeros((2, 2, 9)), FMTS, 10, guard_bits=-1), "guard_bits must"),
    (lambda: quantize_polynomials(_params(1), np.zeros((3, 3, 9))), "poly must have shape"),
    (lambda: _params(1, coef_poly_fmts=(FMTS,) * 5), "at most 4 terms"),
    (lambda: _params(1, coef_poly_fmts=((SQ(5, 12),) + FMTS[1:],)), "share one fraction width of at least 13"),
    (lambda: _params(1, coef_poly_fmts=(FMTS[:2],)), "tuple of \\(t, c, r\\) format tuples"),
])
def test_bad_inputs_are_named(call, message):
    with pytest.raises((TypeError, ValueError), match=message):
        call()


def test_terms_that_do_not_fit_raise():
    with pytest.raises(OverflowError, match="does not fit"):
        quantize_polynomials(_params(1), np.full((3, 2, 9), 1e4))


def test_shifting_the_terms_moves_the_row_origin_exactly():
    rng = np.random.default_rng(SEED)
    print("seed", SEED)
    params = _params(2, rows=64)
    poly = np.zeros((3, 3, 9))
    for k in range(3):                              # terms of a size the rows keep in range
        poly[:, k] = rng.uniform(-1, 1, (3, 9)) * 64.0 ** -k
    poly = quantize_polynomials(params, poly)
    for first in (0, 1, 17, 63):
        shifted = shift_polynomials(poly, first)
        window = evaluate_polynomials(params, shifted, np.arange(64 - first))
        np.testing.assert_array_equal(window, evaluate_polynomials(params, poly,
                                                                   np.arange(first, 64)))


def test_the_stereo20_store_is_two_terms_within_one_lsb_of_the_row_table():
    """stereo20 at K = 4: 80 slots × 2 terms instead of 80 × 480 rows; every coefficient
    within the tolerance of the per-row store's (measured: 1 LSB on 0.3 % of them)."""
    config = PipelineConfig.for_rig(preset("stereo20"))
    per_row = PipelineConfig.for_rig(preset("stereo20"), coef_degree=None)
    solver = config.top.solver
    assert config.coef_store.shape == (80, 2, 9) and solver.entries == 160
    assert per_row.coef_store.shape == (80, 480, 9) and per_row.coef_error_lsb == 0
    difference = np.abs(config.coef_raw - per_row.coef_raw)
    print("coefficients differing by 1 LSB:", np.mean(difference > 0))
    assert difference.max() == config.coef_error_lsb <= COEF_POLYNOMIAL_TOLERANCE_LSB
    np.testing.assert_array_equal(per_row.coef_raw,
                                  quantize_coefficients(per_row.top.solver, per_row.table))
    # the window a co-simulation loads gives the same coefficients as the full store
    np.testing.assert_array_equal(
        evaluate_polynomials(solver, config.store_window(200, 32), np.arange(32)),
        config.coef_raw[:, 200:232])


def test_a_table_that_is_not_a_polynomial_of_the_degree_is_refused(monkeypatch):
    import hdl.pipeline_config as door
    real = door.coefficient_table

    def bent(rig, lane, scales, axis=0):
        table = real(rig, lane, scales, axis)
        bend = (np.arange(table.shape[1]) / table.shape[1]) ** 2
        return table + 0.05 * bend[None, :, None] * np.abs(table).max(axis=(0, 1))
    monkeypatch.setattr(door, "coefficient_table", bent)
    with pytest.raises(ValueError, match="coef_degree 1: rig 'stereo20'.s coefficients differ"):
        PipelineConfig.for_rig(preset("stereo20"))
    assert PipelineConfig.for_rig(preset("stereo20"), coef_degree=2).coef_error_lsb <= 1


# --- the gateware ---------------------------------------------------------------------------

def _random_terms(params, rng):
    """Raw terms over each format's whole range, a quarter of them at its extremes."""
    out = np.zeros((params.slots, params.coef_terms, 9), dtype=np.int64)
    for t in range(params.coef_terms):
        for k in range(9):
            fmt = params.coef_poly_fmts[t][k // 3]
            values = rng.integers(fmt.min_raw, fmt.max_raw + 1, params.slots)
            edge = rng.random(params.slots) < 0.25
            values[edge] = rng.choice([fmt.min_raw, fmt.max_raw], edge.sum())
            out[:, t, k] = values
    return out


def _run_store(params, contents, reads, writes=()):
    """Present ``reads`` (slot, row) one per clock (``writes`` (clock, addr, index, data)
    at their clocks); returns the data seen ``coef_latency`` clocks after each read."""
    dut = CoefficientStore(params, contents)
    seen = []

    async def bench(ctx):
        pending = dict((c, (a, i, d)) for c, a, i, d in writes)
        for clock in range(len(reads) + params.coef_latency):
            if clock < len(reads):
                ctx.set(dut.slot, reads[clock][0])
                ctx.set(dut.row, reads[clock][1])
            if clock in pending:
                addr, index, data = pending[clock]
                ctx.set(dut.write.addr, addr)
                ctx.set(dut.write.index, index)
                ctx.set(dut.write.data, data)
                ctx.set(dut.write.en, 1)
            await ctx.tick()
            ctx.set(dut.write.en, 0)
            if clock + 1 >= params.coef_latency:
                seen.append([ctx.get(dut.data[k]) for k in range(9)])

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return np.array(seen[:len(reads)])


@pytest.mark.parametrize("degree", [1, 2])
def test_the_gateware_evaluates_the_terms_as_the_model_does(degree):
    """Random terms, extremes included (the result saturates where the model does)."""
    rng = np.random.default_rng(SEED + degree)
    print("seed", SEED + degree)
    params = _params(degree)
    contents = _random_terms(params, rng)
    reads = [(int(rng.integers(params.slots)), int(rng.integers(params.rows)))
             for _ in range(60)]
    seen = _run_store(params, contents, reads)
    table = evaluate_polynomials(params, contents, np.arange(params.rows))
    expected = np.array([table[slot, row] for slot, row in reads])
    np.testing.assert_array_equal(seen, expected)
    coef_max = [f.max_raw for f in FMTS for _ in range(3)]
    assert (np.abs(expected) >= np.array(coef_max)).any(), "no saturation exercised"


def test_the_gateware_serves_the_stereo20_store():
    config = PipelineConfig.for_rig(preset("stereo20"))
    params, contents = config.top.solver, config.coef_store
    rng = random.Random(SEED)
    print("seed", SEED)
    reads = [(rng.randrange(params.slots), rng.randrange(params.rows)) for _ in range(40)]
    seen = _run_store(params, contents, reads)
    np.testing.assert_array_equal(seen, [config.coef_raw[s, r] for s, r in reads])


def test_a_run_time_write_replaces_one_term():
    params = _params(1)
    contents = np.zeros((params.slots, 2, 9), dtype=np.int64)
    # term 1 (the slope) of coefficient 4 of slot 2 := 3 LSB of the coefficient per row
    extra = params.coef_poly_fmts[1][1].frac_bits - FMTS[1].frac_bits
    seen = _run_store(params, contents, [(2, 0)] * 2 + [(2, 10), (1, 10)],
                      writes=[(0, 2 * 2 + 1, 4, 3 << extra)])
    assert seen[:, 4].tolist() == [0, 0, 30, 0]
    assert not np.delete(seen, 4, axis=1).any()


def test_the_per_row_store_reads_in_one_clock():
    params = PoseSolverParams(slots=3, rows=40)
    rng = np.random.default_rng(SEED)
    contents = rng.integers(-1000, 1000, (3, 40, 9))
    reads = [(1, 5), (2, 39), (0, 0)]
    assert params.coef_latency == 1
    np.testing.assert_array_equal(_run_store(params, contents, reads),
                                  [contents[s, r] for s, r in reads])


def test_saturation_is_the_models():
    params = _params(1)
    contents = np.zeros((params.slots, 2, 9), dtype=np.int64)
    contents[0, 1, 0] = params.coef_poly_fmts[1][0].max_raw
    value = evaluate_polynomials(params, contents, [39])[0, 0, 0]
    assert value == FMTS[0].max_raw
    with pytest.raises(OverflowError):
        evaluate_polynomials(params, contents, [39], Overflow.ERROR)


# --- the forecast's across-rows store and its copies -----------------------------------------

def test_the_across_rows_store_is_three_terms_within_one_lsb_of_the_row_table():
    """stereo8-board at K = 4: the displacement across rows is quadratic in the row (the
    ``1 + y²`` of a rotation), so degree 1 is refused and degree 2 (the default) holds
    every coefficient within the tolerance of the per-row store's (measured: 1 LSB)."""
    rig = preset("stereo8-board")
    config = PipelineConfig.for_rig(rig)
    per_row = PipelineConfig.for_rig(rig, row_coef_degree=None)
    store = config.row_store
    assert config.row_coef_store.shape == (32, 3, 9) and store.coef_terms == 3
    assert per_row.row_coef_store.shape == (32, 480, 9) and per_row.row_coef_error_lsb == 0
    np.testing.assert_array_equal(per_row.row_coef_raw,
                                  quantize_coefficients(per_row.row_store, per_row.row_table))
    difference = np.abs(config.row_coef_raw - per_row.row_coef_raw)
    print("across-rows coefficients differing by 1 LSB:", np.mean(difference > 0))
    assert difference.max() == config.row_coef_error_lsb <= COEF_POLYNOMIAL_TOLERANCE_LSB
    assert config.forecast().row_store == store
    np.testing.assert_array_equal(
        evaluate_polynomials(store, config.store_window(200, 32, "row"), np.arange(32)),
        config.row_coef_raw[:, 200:232])
    with pytest.raises(ValueError, match="row_coef_degree 1: rig 'stereo8-board'.s "
                                         "coefficients differ from polynomials"):
        PipelineConfig.for_rig(rig, row_coef_degree=1)
    with pytest.raises(ValueError, match="store must be 'solver' or 'row', not 'x'"):
        config.store_window(0, 1, "x")


@pytest.mark.parametrize("degree", [None, 1, 2])
def test_the_term_store_reads_the_two_coefficients_of_a_term_on_two_ports(degree):
    """The forecast's copy (TermStore): per port a (slot, row, term) in, coefficient
    ``term`` and ``second_index(term)`` out with the store's latency, equal to the model
    (random terms, extremes included: the selected chains round and saturate as the
    nine-chain store does)."""
    rng = np.random.default_rng(SEED)
    print("seed", SEED)
    params = _params(degree) if degree else _params(1, coef_poly_fmts=())
    if degree:
        contents = _random_terms(params, rng)
        table = evaluate_polynomials(params, contents, np.arange(params.rows))
    else:
        contents = rng.integers(-1 << 17, 1 << 17, (params.slots, params.rows, 9))
        table = contents
    dut = TermStore(params, contents, second_read=True)
    assert "write" not in dut.signature.members
    reads = [[(int(rng.integers(params.slots)), int(rng.integers(params.rows)),
               int(rng.integers(6))) for _ in range(60)] for _ in range(2)]
    seen = [[], []]
    q = dut.second_port
    ports = [(dut.slot, dut.row, dut.term, dut.first, dut.second),
             (q.slot, q.row, q.term, q.first, q.second)]

    async def bench(ctx):
        for clock in range(60 + params.coef_latency):
            for (slot, row, term, *_), port in zip(ports, reads):
                if clock < 60:
                    for signal, value in zip((slot, row, term), port[clock]):
                        ctx.set(signal, value)
            await ctx.tick()
            if clock + 1 >= params.coef_latency:
                for (*_, first, second), got in zip(ports, seen):
                    got.append([ctx.get(first), ctx.get(second)])

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    for port, got in zip(reads, seen):
        np.testing.assert_array_equal(np.array(got[:60]), [
            [table[s, r, t], table[s, r, second_index(t)]] for s, r, t in port])
    if degree:
        coef_max = [f.max_raw for f in FMTS for _ in range(3)]
        assert (np.abs(table) >= np.array(coef_max)).any(), "no saturation exercised"


def test_store_contents_that_do_not_fit_name_the_store():
    params = _params(1)
    with pytest.raises(ValueError, match="row_coefficients coefficient 0 term 1 does not fit"):
        contents = np.zeros((3, 2, 9), dtype=np.int64)
        contents[0, 1, 0] = 1 << 40
        CoefficientStore(params, contents, name="row_coefficients")
    with pytest.raises(ValueError, match=r"stores must have shape \(3, 2, 9\)"):
        CoefficientStore(params, np.zeros((3, 40, 9)), name="stores")

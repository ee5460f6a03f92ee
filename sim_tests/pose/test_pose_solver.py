"""hdl.pose_solver: parameters, the engine's program and schedule, and the block against
emulator.pose_solver in the Amaranth simulator (the cocotb bench runs the long mixes)."""

import os
import random

import numpy as np
import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator

from emulator import pose_solver as E
from golden.rig import preset
from emulator.pose.program import split_program
from hdl.fixed import SQ, UQ
from hdl.pose.accumulator import leading_one
from hdl.pose.params import PoseSolverParams, coefficient_formats, quantize_coefficients
from hdl.pose.program import (MAC_LATENCY, NORMALIZER_LATENCY, SEED_LATENCY, build_row_program,
                              schedule)
from hdl.pose.rom import ProgramRom
from hdl.pose_solver import PoseSolver
from hdl.top import board_config
from sim_tests.pose.pose_solver.stimulus import build_case, mixed_rows, random_rows

SEED = int(os.environ.get("SEED", "8"))


# --- parameters -----------------------------------------------------------------------------

@pytest.mark.parametrize("changes, error, message", [
    ({"slots": 0}, ValueError, "slots must be an integer between 1 and 4096, not 0"),
    ({"slots": 2.5}, TypeError, "slots must be an integer, not 2.5"),
    ({"shift_fmt": 3}, TypeError, "shift_fmt must be a QFormat, not 3"),
    ({"cue_fmt": SQ(8, 10)}, ValueError, "cue_fmt must be unsigned"),
    ({"a_fmt": UQ(13, 12)}, ValueError, "a_fmt must be signed"),
    ({"coef_c_fmt": SQ(4, 20)}, ValueError, "must have one width"),
    ({"shift_fmt": SQ(6, 14)}, ValueError, "shift_fmt SQ\\(6, 14\\) must fit a_fmt"),
    ({"engine_width": 70}, ValueError, "engine_width must be an integer between 32 and 64, not 70"),
    ({"pivot_log2": 40}, ValueError, "pivot_log2 must be an integer between 2 and 38, not 40"),
    ({"min_diagonal": 0}, ValueError, "min_diagonal must be a number greater than 0, not 0"),
    ({"min_diagonal": 1e12}, ValueError, "does not fit the normal matrix format"),
    ({"row_bits": 4}, ValueError, "row_bits must be an integer between 9 and 16, not 4"),
    ({"lanes": 0}, ValueError, "lanes must be an integer between 1 and 27, not 0"),
])
def test_params_are_checked(changes, error, message):
    with pytest.raises(error, match=message):
        PoseSolverParams(**changes)


def test_coefficient_formats_follow_the_table():
    table = np.zeros((2, 3, 9))
    table[..., 0:3], table[..., 3:6], table[..., 6:9] = 100.0, 0.3, -900.0
    formats = coefficient_formats(table, 18)
    assert formats == {"coef_t_fmt": SQ(8, 10), "coef_c_fmt": SQ(1, 17),
                       "coef_r_fmt": SQ(11, 7)}
    with pytest.raises(ValueError, match="needs more than width 6 bits"):
        coefficient_formats(table, 6)
    with pytest.raises(ValueError, match="9 coefficients on its last axis"):
        coefficient_formats(np.zeros((2, 8)), 18)


def test_coefficients_are_checked():
    params = PoseSolverParams(slots=2, rows=4, row_bits=2)
    with pytest.raises(ValueError, match="table must have shape \\(2, 4, 9\\)"):
        quantize_coefficients(params, np.zeros((2, 3, 9)))
    with pytest.raises(OverflowError, match="does not fit"):
        quantize_coefficients(params, np.full((2, 4, 9), 1e6))
    with pytest.raises(ValueError, match="coefficients must have shape \\(2, 4, 9\\)"):
        PoseSolver(params, np.zeros((2, 3, 9), dtype=np.int64))
    with pytest.raises(TypeError, match="params must be a PoseSolverParams"):
        PoseSolver("default")


# --- building blocks ------------------------------------------------------------------------

@pytest.mark.parametrize("width", [1, 5, 41, 63])
def test_leading_one_finds_the_highest_set_bit(width):
    rng = random.Random(SEED + width)
    values = [0, 1, (1 << width) - 1] + [rng.getrandbits(rng.randint(1, width)) for _ in range(200)]
    m = Module()
    value, index = Signal(width), Signal(8)
    m.d.comb += index.eq(leading_one(value, width))
    got = []

    async def bench(ctx):
        for v in values:
            ctx.set(value, v)
            got.append(ctx.get(index))

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()
    assert got == [max(v.bit_length() - 1, 0) for v in values]


# --- program and schedule -------------------------------------------------------------------

def test_schedule_respects_every_dependency():
    params = PoseSolverParams()
    program = build_row_program(params)
    plan = schedule(program)
    ops = program.ops
    written = {("input", name): k + NORMALIZER_LATENCY for k, name in enumerate(program.inputs)}
    written.update({("constant", name): 0 for name in program.constants})
    for k, op in enumerate(ops):
        if not op.commit:
            written[(op.dst.bank, op.dst.name)] = plan.writeback[k]
    issue_cycles, write_cycles = [], []
    for k, op in enumerate(ops):
        latency = SEED_LATENCY if op.kind == "seed" else MAC_LATENCY
        assert plan.writeback[k] == plan.issue[k] + op.slots - 1 + latency
        issue_cycles += range(plan.issue[k], plan.issue[k] + op.slots)
        write_cycles.append(plan.writeback[k])
        for source in op.sources:
            if source.bank != "state":
                assert written[(source.bank, source.name)] <= plan.issue[k], (op.dst.name, source.name)
    assert len(set(issue_cycles)) == len(issue_cycles), "two terms issued in one clock"
    assert len(set(write_cycles)) == len(write_cycles), "two write-backs in one clock"
    last_check = max(plan.writeback[k] for k, op in enumerate(ops) if op.checked)
    for k, op in enumerate(ops):
        if op.commit:
            assert plan.writeback[k] > last_check
            for r, reader in enumerate(ops):
                if r != k and op.dst in reader.sources:
                    assert plan.issue[r] + reader.slots - 1 <= plan.writeback[k]


@pytest.mark.parametrize("information", [False, True])
def test_work_registers_are_shared_only_between_values_not_live_together(information):
    """``allocate_work``: a register's values are live (write-back to last read, the read
    of a term at its issue clock) one after the other, a write strictly after the last
    read of the value before; the bank is no deeper than the most values live in one
    clock."""
    rom = ProgramRom(board_config(preset("stereo8-board")).top.solver, information)
    program, plan, register = rom.program, rom.schedule, rom.work_register
    live = {op.dst.name: [plan.writeback[k]] * 2 for k, op in enumerate(program.ops)
            if op.dst.bank == "work"}
    for op, start in zip(program.ops, plan.issue):
        terms = [(op.source, start)] if op.kind == "seed" else [
            (v, start + t) for t, (_, a, b) in enumerate(op.terms) for v in (a, b)]
        for value, cycle in terms + ([(op.init, start)] if op.init is not None else []):
            if value.name in live:
                live[value.name][1] = max(live[value.name][1], cycle)
    by_register = {}
    for name, (write, last) in live.items():
        by_register.setdefault(register[name], []).append((write, last, name))
    for values in by_register.values():
        values.sort()
        for (_, last, before), (write, _, after) in zip(values, values[1:]):
            assert write > last, (before, after)
    most = max(sum(w <= c <= l for w, l in live.values())
               for c in range(plan.length + 1))
    assert rom.work_depth == most < len(program.work)


def test_trace_names_every_solve_value_of_the_program():
    """The model's trace holds every value of the program's solve under its name and
    format, aliases included (the trace test and the benchmark's ranges rely on it)."""
    params, coefficients, _ = build_case("random")
    rows = mixed_rows("random", params, None, np.random.default_rng(SEED), 2)
    trace = E.solve_trace(params, coefficients, rows)
    program = build_row_program(params)
    solve = {name for name in program.work
             if not name.startswith(("R", "theta2", "cubic", "q1", "gain", "px", "py", "pz"))}
    # term-less ops of an operand into its own format are that operand (no register)
    aliases = {"D0", "c0"} | {f"W{i}0" for i in range(1, 6)}
    assert set(program.aliases) == aliases
    assert solve == set(trace) - aliases - set(program.inputs)
    for name in solve:
        assert program.work[name].fmt == trace[name].fmt, name
    for name, operand in program.aliases.items():
        assert trace[name] is trace[operand.name], name


def test_integration_sets_no_flag():
    """The model takes a row's flags from the solve alone and integrates only solved
    rows: no op of the integration (after the step, or reading the slot's pose) may be
    checked or a seed."""
    params, _, _ = build_case("random")
    solve, integration = split_program(build_row_program(params))
    assert {op.dst.name for op in integration} >= {"R00", "theta2", "gain"}
    assert not any(op.checked or op.kind == "seed" for op in integration)
    assert all(not op.commit for op in solve)


# --- the block against the model ------------------------------------------------------------

def _simulate(dut, transfers, count, ready=lambda cycle: True, limit=20000, probe=None,
              start=0, gated=None, pivot_log2=None):
    """Drive ``transfers`` at full rate from cycle ``start`` on (``gated``: per transfer
    the solver's ``gated`` input with it; ``pivot_log2``: per row the register, set
    before the row starts, at reset and as the previous row's record is taken, its
    ``pivot_log2_error`` checked against the model's); returns [(cycle, record)], the
    cycles of the ``last`` transfers, and what ``probe(ctx)`` returned in every cycle up
    to the first record."""
    out, ends, probed = [], [], []

    def set_gate(ctx, row):
        if pivot_log2 is not None and row < len(pivot_log2):
            ctx.set(dut.pivot_log2, int(pivot_log2[row]))
            error = dut.params.pivot_thresholds(pivot_log2[row])[1]
            assert ctx.get(dut.pivot_log2_error) == error, (row, pivot_log2[row])

    async def bench(ctx):
        queue = list(transfers)
        verdicts = list(gated or [0] * len(queue))
        cycle = 0
        set_gate(ctx, 0)
        while len(out) < count and cycle < limit:
            ctx.set(dut.i.valid, int(bool(queue) and cycle >= start))
            if queue:
                ctx.set(dut.i.payload, queue[0])
                ctx.set(dut.gated, verdicts[len(verdicts) - len(queue)])
            ctx.set(dut.o.ready, int(ready(cycle)))
            taken = ctx.get(dut.i.valid) and ctx.get(dut.i.ready)
            if probe is not None and not out:
                probed.append(probe(ctx))
            if ctx.get(dut.o.valid) and ctx.get(dut.o.ready):
                out.append((cycle, ctx.get(dut.o.payload)))
                set_gate(ctx, len(out))
            await ctx.tick()
            if taken:
                ends.extend([cycle] if queue.pop(0)["last"] else [])
            cycle += 1

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return out, ends, probed


def _as_lists(record):
    return {"row": record.row, "time": record.time, "flags": record.flags,
            "q": [record.q[k] for k in range(4)], "p": [record.p[k] for k in range(3)],
            "step": [record.step[k] for k in range(6)]}


@pytest.mark.parametrize("case, count", [("random", 10), ("stereo8", 3), ("radial4", 3)])
def test_records_match_the_model(case, count):
    params, coefficients, rig = build_case(case)
    rows = mixed_rows(case, params, rig, np.random.default_rng(SEED), count)
    model = E.pose_solver_model(params, coefficients, rows)
    dut = PoseSolver(params, coefficients)
    out, ends, _ = _simulate(dut, rows.transfers(), count, start=dut.clear_clocks)
    _assert_records(out, model)
    assert out[0][0] - ends[0] == dut.latency


def _assert_records(out, model):
    assert len(out) == len(model["row"])
    for k, (_, record) in enumerate(out):
        expected = {"row": model["row"][k], "time": model["time"][k], "flags": model["flags"][k],
                    "q": list(model["q"][k]), "p": list(model["p"][k]),
                    "step": list(model["step"][k])}
        assert _as_lists(record) == expected, k


def test_gated_rows_are_flagged_empty():
    """Rows whose last transfer comes with ``gated`` give the records the model gives
    with every confidence of those rows set to 0 (the consistency model's gates): flag
    EMPTY, no step, the slot's pose unchanged; the other rows as before. Rows of two
    frames, a random third of them gated (SEED printed)."""
    print(f"SEED={SEED}")
    params, coefficients, _ = build_case("random")
    rng = np.random.default_rng(SEED)
    rows = random_rows(params, rng, 2 * params.rows, framed=True)[0]
    gate = rng.random(len(rows)) < 0.35
    zeroed = E.PoseRows(slot=rows.slot, shift=rows.shift, cue=rows.cue,
                        conf=np.where(gate[:, None], 0, rows.conf), present=rows.present,
                        row=rows.row, time=rows.time)
    model = E.pose_solver_model(params, coefficients, zeroed)
    ungated = E.pose_solver_model(params, coefficients, rows)
    # the gates change something: gated rows the model would have solved
    assert np.sum(gate & (ungated["flags"] == 0)) >= 5
    assert np.all(model["flags"][gate & (ungated["flags"] != int(E.PoseFlag.OVERRUN))]
                  == int(E.PoseFlag.EMPTY))
    transfers = rows.transfers()
    ends = np.cumsum(rows.counts) - 1
    verdicts = [0] * len(transfers)
    for r in np.flatnonzero(gate):
        verdicts[ends[r]] = 1
    # a gated bit with a row's other transfers means nothing
    for k in range(len(verdicts)):
        if k not in set(ends.tolist()):
            verdicts[k] = int(rng.random() < 0.5)
    dut = PoseSolver(params, coefficients)
    out, _, _ = _simulate(dut, transfers, len(rows), limit=200000, gated=verdicts)
    _assert_records(out, model)


def test_the_conditioning_gate_is_a_run_time_register():
    """``pivot_log2`` changed between rows (random values over its field, those out of
    range included, SEED printed): every record as the model's with the same value per
    row; rows solved at the build's value flip to ILL at a stricter one, others stay
    solved; an out-of-range value is the build's, with ``pivot_log2_error``."""
    print(f"SEED={SEED}")
    params, coefficients, _ = build_case("random")
    rng = np.random.default_rng(SEED)
    rows = random_rows(params, rng, params.rows, framed=True)[0]
    values = rng.integers(0, 1 << params.pivot_log2_bits, size=len(rows))
    model = E.pose_solver_model(params, coefficients, rows, pivot_log2=values)
    built = E.pose_solver_model(params, coefficients, rows)["flags"]
    strict = params.pivot_thresholds(values)[0] > params.pivot_thresholds()[0]
    ill = int(E.PoseFlag.ILL)
    assert np.sum((built == 0) & (model["flags"] == ill)) >= 5, "no row flipped to ILL"
    assert np.sum(strict & (model["flags"] == 0)) >= 5, "a stricter gate solved nothing"
    assert np.any(params.pivot_thresholds(values)[1]), "no value out of range"
    dut = PoseSolver(params, coefficients)
    assert dut.pivot_log2.init == params.pivot_log2
    out, _, _ = _simulate(dut, rows.transfers(), len(rows), limit=200000, pivot_log2=values)
    _assert_records(out, model)
    with pytest.raises(ValueError, match="pivot_log2 must be integers from 0 to 31, not 32"):
        params.pivot_thresholds(32)


def test_row_slots_carry_poses_across_frames():
    """Two frames of 64 rows in frame order (three run in the cocotb bench), then rows of one slot back to back (the
    slot written in the clock before the next row starts). The first row has one
    measurement and is sent at once after reset: it waits for the ring to be cleared
    (uncleared slots read zero, not the reset pose). Every record as the model's."""
    params, coefficients, _ = build_case("random")
    rng = np.random.default_rng(SEED)
    frames = random_rows(params, rng, 2 * params.rows, framed=True)[0]
    repeats = random_rows(params, rng, 6)[0]
    joined = {name: np.concatenate([getattr(frames, name), getattr(repeats, name)])
              for name in ("slot", "shift", "cue", "conf", "present", "time")}
    joined["present"][0, 1:] = False
    rows = E.PoseRows(**joined, row=np.concatenate([frames.row, np.full(6, frames.row[-1])]))
    model = E.pose_solver_model(params, coefficients, rows)
    assert np.sum(model["flags"][-6:] == 0) >= 2
    dut = PoseSolver(params, coefficients)
    out, ends, _ = _simulate(dut, rows.transfers(), len(rows), limit=100000)
    _assert_records(out, model)
    # the row was done before the clear ended, and started in the clock after it
    assert ends[0] + dut._accumulator.tail < dut.clear_clocks
    assert out[0][0] == dut.clear_clocks + dut._engine.length + 1


def _collapse(values):
    """``values`` without repeats of the value before."""
    return [v for k, v in enumerate(values) if k == 0 or v != values[k - 1]]


def _is_subsequence(part, whole):
    rest = iter(whole)
    return all(any(v == w for w in rest) for v in part)


def test_engine_registers_match_the_model_trace():
    """Every solve intermediate of a row, read out of the engine's register bank while the
    row runs: the values sharing a register (``allocate_work``) pass through it in the
    order they are written, each the model's."""
    params, coefficients, _ = build_case("random")
    rows = mixed_rows("random", params, None, np.random.default_rng(SEED), 1)
    trace = E.solve_trace(params, coefficients, rows)
    dut = PoseSolver(params, coefficients)
    engine = dut._engine
    register = engine._words.work_register
    names = [n for n in trace if n in engine.program.work]
    depth = engine._words.work_depth
    _, _, history = _simulate(dut, rows.transfers(), 1,     # the banks exist once elaborated
                              probe=lambda ctx: [ctx.get(engine._banks[1].data[r])
                                                 for r in range(depth)])
    writes = dict(zip((op.dst.name for op in engine.program.ops),
                      engine._words.schedule.writeback))
    missing = []
    for r in sorted({register[n] for n in names}):
        held = sorted((writes[n], n) for n in names if register[n] == r)
        expected = _collapse([int(np.asarray(trace[n].raw, dtype=object)[0]) for _, n in held])
        seen = _collapse([cycle[r] for cycle in history])
        if not _is_subsequence(expected, seen):
            missing.append((r, [n for _, n in held]))
    assert len({register[n] for n in names}) < len(names), "registers must be shared"
    assert not missing, f"registers whose values differ from the model's: {missing[:3]}"


def test_backpressure_holds_the_record_and_the_next_row():
    params, coefficients, _ = build_case("random")
    rows = mixed_rows("random", params, None, np.random.default_rng(SEED), 3)
    model = E.pose_solver_model(params, coefficients, rows)
    dut = PoseSolver(params, coefficients)
    out, _, _ = _simulate(dut, rows.transfers(), 3, ready=lambda cycle: cycle % 300 == 299)
    assert [_as_lists(r)["step"] for _, r in out] == [list(s) for s in model["step"]]
    assert [_as_lists(r)["q"] for _, r in out] == [list(q) for q in model["q"]]

"""The per-row program of the pose solver's engine, and its static schedule.

The engine (:mod:`hdl.pose.engine`) is a single-issue multiply-accumulate machine with
a seed unit for inverse square roots. Its program for one row — the Cholesky solve and
the pose integration of ``docs/pose/pose_solver.md`` — is written here once, as a list of ops on named
values, and scheduled at build time into one instruction word per clock. The schedule is
static, so the block's latency is known exactly (and read by the benches).

An op is ``dst = round(init + 2**scale · Σ ±a·b)``: the sum is exact and rounded once
(half-even, saturating) into the destination's format, so the order of the terms does
not matter. The bit-accurate model (:mod:`emulator.pose_solver`) executes this same op
list, so the engine and the model share one description of the algorithm.

Operands live in
* ``input``: the scaled system N̂ (21, upper triangle row by row), b̂ (6) and the scales
  ``2**-e`` (6), written by the normalizer at one per clock from the program's start;
* ``work``: everything the program computes; a value is named once (``Operand.index``
  numbers the values), and the scheduled program keeps it in a register only from its
  write to its last read (:func:`allocate_work`: registers are reused, the bank holds
  the values live at once);
* ``constant``: the program's few constants, a table in the engine;
* ``state``: the pose of the row's slot (q_w, q_x, q_y, q_z, p_x, p_y, p_z), registers
  loaded from the engine's pose ring when the row starts and written only by *commit*
  ops, which take effect only when the row raised no flag.
"""

import heapq
from dataclasses import dataclass, field, replace

from hdl.fixed import QFormat

__all__ = ["Operand", "Op", "RowProgram", "build_row_program", "build_gain_program",
           "cholesky_solve", "Schedule", "schedule", "allocate_work",
           "UPPER", "MAC_LATENCY", "SEED_LATENCY", "NORMALIZER_LATENCY", "STATE_NAMES"]

#: (i, j) entries of the upper triangle of N̂, in normalizer order.
UPPER = tuple((i, j) for i in range(6) for j in range(i, 6))
#: State registers, in record order.
STATE_NAMES = ("qw", "qx", "qy", "qz", "px", "py", "pz")

#: Clocks from the issue of an op's last term to its write-back (one register read,
#: two multiplier stages, the accumulator, the rounding).
MAC_LATENCY = 5
#: Clocks from a seed op's issue to its write-back.
SEED_LATENCY = 7
#: Clocks from the normalizer's n-th output to its write into the input bank.
NORMALIZER_LATENCY = 3


@dataclass(frozen=True)
class Operand:
    """A value's home: ``bank`` is "input", "work" or "state"."""
    name: str
    bank: str
    index: int
    fmt: QFormat


@dataclass(frozen=True)
class Op:
    """One instruction of the program (see the module docstring).

    ``kind`` "mac" or "seed" (the seed unit: ``dst ≈ source^-1/2`` and the pivot check).
    ``checked``: a saturation sets the row's SATURATED flag (``group`` "row") or the
    information gain's own flag (``group`` "gain", :func:`build_gain_program`'s ops, whose
    seeds' pivot checks are the gain's too). ``commit``: writes state.
    """
    kind: str
    dst: Operand
    terms: tuple = ()
    init: Operand = None
    scale_log2: int = 0
    checked: bool = False
    source: Operand = None
    group: str = "row"

    @property
    def commit(self):
        return self.dst.bank == "state"

    @property
    def sources(self):
        out = [a for _, a, b in self.terms] + [b for _, a, b in self.terms]
        return out + [v for v in (self.init, self.source) if v is not None]

    @property
    def slots(self):
        """Issue clocks the op occupies."""
        return max(1, len(self.terms))

    @property
    def product_frac(self):
        """Fraction bits of the products (equal for every term, checked)."""
        fracs = {a.fmt.frac_bits + b.fmt.frac_bits - self.scale_log2 for _, a, b in self.terms}
        if len(fracs) != 1:
            raise ValueError(f"op {self.dst.name}: terms have different product formats {fracs}")
        return fracs.pop()

    @property
    def init_shift(self):
        """Left shift that aligns ``init`` to the products."""
        return self.product_frac - self.init.fmt.frac_bits if self.init is not None else 0

    @property
    def out_shift(self):
        """Fraction bits dropped when the sum is rounded into ``dst``."""
        return self.product_frac - self.dst.fmt.frac_bits


@dataclass
class RowProgram:
    """The ops of one row with the register map.

    Members
    -------
    ops : list of Op
        In dependency order.
    inputs, work, state : dict name -> Operand
    constants : dict name -> (Operand, float)
        The constants (bank "constant") and their values.
    step : tuple of Operand
        The six step values (captured into the pose record).
    gain_step : tuple of Operand
        The information gain's six moves (``build_row_program(..., information=True)``;
        empty otherwise).
    aliases : dict name -> Operand
        Values that need no op (a term-less op of an operand into its own format): the
        operand they stand for, so that every value of the algorithm has its name.
    """
    ops: list = field(default_factory=list)
    inputs: dict = field(default_factory=dict)
    work: dict = field(default_factory=dict)
    state: dict = field(default_factory=dict)
    constants: dict = field(default_factory=dict)
    step: tuple = ()
    gain_step: tuple = ()
    aliases: dict = field(default_factory=dict)

    def _new(self, table, bank, name, fmt):
        if name in table:
            raise ValueError(f"value {name} is defined twice")
        table[name] = Operand(name, bank, len(table), fmt)
        return table[name]

    def work_value(self, name, fmt):
        return self._new(self.work, "work", name, fmt)

    def constant(self, name, fmt, value):
        """A constant operand of value ``value`` (quantized into ``fmt`` by its users)."""
        if name in self.constants:
            raise ValueError(f"constant {name} is defined twice")
        operand = Operand(name, "constant", len(self.constants), fmt)
        self.constants[name] = (operand, value)
        return operand

    def mac(self, name, fmt, init=None, terms=(), scale_log2=0, checked=False, dst=None):
        """Append ``dst = round(init + 2**scale_log2 · Σ ±a·b)``; a term-less op of an
        operand into its own format is the operand itself (no op)."""
        if not terms and dst is None and init is not None and init.fmt == fmt:
            self.aliases[name] = init
            return init
        dst = dst or self.work_value(name, fmt)
        op = Op("mac", dst, tuple(terms), init, scale_log2, checked)
        op.product_frac  # check the terms agree
        if op.init_shift < 0 or op.out_shift <= 0:
            raise ValueError(f"op {name}: formats need a right shift of the sum and a left "
                             f"shift of init, not {op.out_shift} and {op.init_shift}")
        self.ops.append(op)
        return dst

    @property
    def work_depth(self):
        return len(self.work)


def build_row_program(params, information=False):
    """The op list of one row for ``params`` (a PoseSolverParams): what the engine's ROM
    is built from and what ``emulator.pose_solver`` executes. ``information``: the
    information gain's ops follow (:func:`build_gain_program`; their result is
    ``gain_step``), for the engine's ROM."""
    prog = RowProgram()
    qf, sf, pf = params.quat_fmt, params.step_fmt, params.position_fmt
    n, rhs, scales = _system_inputs(prog, params)
    for name in STATE_NAMES:
        prog._new(prog.state, "state", name, qf if name.startswith("q") else pf)
    for name, value, fmt in (("three_halves", 1.5, params.unit_fmt),
                             ("three_halves_q", 1.5, qf), ("one", 1.0, qf),
                             ("third", 1 / 3, qf)):
        prog.constant(name, fmt, value)

    x = cholesky_solve(prog, params, lambda i, j: n[f"N{i}{j}"], rhs)
    step = [prog.mac(f"Y{j}", sf, terms=[(1, x[j], scales[j])], checked=True) for j in range(6)]
    prog.step = tuple(step)

    # Integration: R(q) of the pose before the step (known from the start),
    # q ⊗ (1 − |θ|²/12, θ/2) with one Newton step of the normalization, p + R(q) T.
    s = prog.state
    qw, qx, qy, qz = (s[k] for k in ("qw", "qx", "qy", "qz"))
    tx, ty, tz, ax, ay, az = step
    one = prog.constants["one"][0]
    rotation = [
        prog.mac("R00", qf, one, [(-1, qy, qy), (-1, qz, qz)], 1),
        prog.mac("R01", qf, terms=[(1, qx, qy), (-1, qw, qz)], scale_log2=1),
        prog.mac("R02", qf, terms=[(1, qx, qz), (1, qw, qy)], scale_log2=1),
        prog.mac("R10", qf, terms=[(1, qx, qy), (1, qw, qz)], scale_log2=1),
        prog.mac("R11", qf, one, [(-1, qx, qx), (-1, qz, qz)], 1),
        prog.mac("R12", qf, terms=[(1, qy, qz), (-1, qw, qx)], scale_log2=1),
        prog.mac("R20", qf, terms=[(1, qx, qz), (-1, qw, qy)], scale_log2=1),
        prog.mac("R21", qf, terms=[(1, qy, qz), (1, qw, qx)], scale_log2=1),
        prog.mac("R22", qf, one, [(-1, qx, qx), (-1, qy, qy)], 1)]
    first = [prog.mac("q1w", qf, qw, [(-1, qx, ax), (-1, qy, ay), (-1, qz, az)], -1),
             prog.mac("q1x", qf, qx, [(1, qw, ax), (1, qy, az), (-1, qz, ay)], -1),
             prog.mac("q1y", qf, qy, [(1, qw, ay), (1, qz, ax), (-1, qx, az)], -1),
             prog.mac("q1z", qf, qz, [(1, qw, az), (1, qx, ay), (-1, qy, ax)], -1)]
    # the third-order term − q·|θ|²/12, one single-term op per component once |θ|² is
    # known, so the first-order ops above run beside its chain; |θ|²/4 < 3/4 at the step
    # format's extremes
    square = prog.mac("theta2", qf, terms=[(1, a, a) for a in (ax, ay, az)], scale_log2=-2)
    cubic = prog.mac("cubic", qf, terms=[(1, square, prog.constants["third"][0])])
    q1 = [prog.mac(c.name + "_c", qf, c, [(-1, v, cubic)])
          for c, v in zip(first, (qw, qx, qy, qz))]
    gain = prog.mac("gain", qf, prog.constants["three_halves_q"][0],
                    [(-1, c, c) for c in q1], -1)
    # T_x comes last out of the back substitution: the T_y, T_z terms go first
    for k, name in enumerate(("px", "py", "pz")):
        early = prog.mac(name + "_yz", pf, s[name], [(1, rotation[3 * k + 1], ty),
                                                     (1, rotation[3 * k + 2], tz)])
        prog.mac(name + "'", pf, early, [(1, rotation[3 * k], tx)], dst=s[name])
    for name, c in zip(("qw", "qx", "qy", "qz"), q1):
        prog.mac(name + "'", qf, terms=[(1, c, gain)], dst=s[name])
    if information:
        prog.gain_step = _gain_ops(prog, params, n, rhs)
    return prog


def _system_inputs(prog, params):
    """The normalizer's inputs N̂ (21, upper triangle), b̂ (6) and the scales ``2**-e``
    (6), in that order: (input table, b̂ operands, scale operands)."""
    for (i, j) in UPPER:
        prog._new(prog.inputs, "input", f"N{i}{j}", params.unit_fmt)
    rhs = [prog._new(prog.inputs, "input", f"b{i}", params.solution_fmt) for i in range(6)]
    scales = [prog._new(prog.inputs, "input", f"s{i}", params.scale_fmt) for i in range(6)]
    return prog.inputs, rhs, scales


def build_gain_program(params):
    """The op list of the information gain's solve (issue 16, docs/pose/information_gain.md)
    for ``params`` (a PoseSolverParams): the level update ``d = (N + Λ)⁻¹ N (Y − p)`` of
    the motion filter, with ``N`` the row's normal matrix, ``Λ`` the prior information
    (:mod:`emulator.pose.information_gain`) and ``p`` the filter's prediction; ``step``
    is ``d``. :func:`build_row_program` with ``information=True`` appends the same ops
    to the row's (the engine's ROM); the model runs them apart."""
    prog = RowProgram()
    n, rhs, _ = _system_inputs(prog, params)
    prog.constant("three_halves", params.unit_fmt, 1.5)
    prog.step = _gain_ops(prog, params, n, rhs)
    return prog


def _gain_ops(prog, params, n, rhs):
    """Append the gain's inputs and ops (group "gain") to ``prog``; returns ``d``.

    Inputs, after the row program's own (N̂, b̂, ``s = 2**-e`` from the Jacobi exponents
    ``e`` of N): ``M̂ = S_M (N + Λ) S_M`` with the exponents ``e_M`` of ``N + Λ``, the
    prediction ``f = p·2**e`` in N's scaled unknowns, ``ratio = 2**(e − e_M)`` and
    ``sM = 2**-e_M``. Since ``N Y = r``, ``S_N N (Y − p) = b̂ − N̂ f`` needs no step: the
    solve runs beside the row's own. ``S_M N (Y − p)`` is that times ``ratio``; the
    Cholesky solve of M̂ gives ``S_M⁻¹ d``, and ``d = sM · S_M⁻¹ d``."""
    unit, sol = params.unit_fmt, params.solution_fmt
    for (i, j) in UPPER:
        prog._new(prog.inputs, "input", f"M{i}{j}", unit)
    forecast = [prog._new(prog.inputs, "input", f"f{i}", sol) for i in range(6)]
    ratio = [prog._new(prog.inputs, "input", f"ratio{i}", params.scale_fmt) for i in range(6)]
    scales = [prog._new(prog.inputs, "input", f"sM{i}", params.scale_fmt) for i in range(6)]
    first = len(prog.ops)

    def entry(i, j):
        return n[f"N{min(i, j)}{max(i, j)}"]

    innovation = [prog.mac(f"v{i}", sol, rhs[i], [(-1, entry(i, j), forecast[j])
                                                  for j in range(6)], checked=True)
                  for i in range(6)]
    scaled = [prog.mac(f"vM{i}", sol, terms=[(1, v, k)], checked=True)
              for i, (v, k) in enumerate(zip(innovation, ratio))]
    x = cholesky_solve(prog, params, lambda i, j: n[f"M{i}{j}"], scaled, prefix="g")
    d = tuple(prog.mac(f"d{j}", params.step_fmt, terms=[(1, x[j], scales[j])], checked=True)
              for j in range(6))
    prog.ops[first:] = [replace(op, group="gain") for op in prog.ops[first:]]
    return d


def cholesky_solve(prog, params, entry, rhs, prefix=""):
    """Append the ops that solve ``A x = rhs`` for a scaled symmetric ``A`` (``entry(i, j)``,
    ``i ≤ j``, in ``unit_fmt``; ``rhs`` six ``solution_fmt`` operands): the Cholesky
    ``A = G Gᵀ`` with the forward substitution carried along, ``D^-1/2`` a seed and one
    Newton step ``ρ = seed·(3/2 − D·seed²/2)``, then the back substitution. Every value is
    named with ``prefix`` (a second solve in one program). Returns the six unknowns."""
    unit, lower, sol = params.unit_fmt, params.lower_fmt, params.solution_fmt
    three_halves = prog.constants["three_halves"][0]
    g, low, rho, z = {}, {}, [], []
    for j in range(6):
        pivot = prog.mac(f"{prefix}D{j}", unit, entry(j, j),
                         [(-1, g[(j, k)], g[(j, k)]) for k in range(j)], checked=True)
        seed = prog.work_value(f"{prefix}seed{j}", params.seed_fmt)
        prog.ops.append(Op("seed", seed, source=pivot))
        root = prog.mac(f"{prefix}h{j}", unit, terms=[(1, pivot, seed)], checked=True)
        newton = prog.mac(f"{prefix}e{j}", unit, three_halves, [(-1, root, seed)], -1,
                          checked=True)
        rho.append(prog.mac(f"{prefix}rho{j}", lower, terms=[(1, seed, newton)], checked=True))
        for i in range(j + 1, 6):
            schur = prog.mac(f"{prefix}W{i}{j}", unit, entry(j, i),
                             [(-1, g[(i, k)], g[(j, k)]) for k in range(j)], checked=True)
            product = prog.mac(f"{prefix}P{i}{j}", unit, terms=[(1, schur, seed)],
                               checked=True)
            g[(i, j)] = prog.mac(f"{prefix}G{i}{j}", unit, terms=[(1, product, newton)],
                                 checked=True)
            low[(i, j)] = prog.mac(f"{prefix}L{i}{j}", lower, terms=[(1, g[(i, j)], rho[j])],
                                   checked=True)
        forward = prog.mac(f"{prefix}c{j}", sol, rhs[j],
                           [(-1, g[(j, k)], z[k]) for k in range(j)], checked=True)
        z.append(prog.mac(f"{prefix}z{j}", sol, terms=[(1, forward, rho[j])], checked=True))
    # back substitution, right-looking: one single-term op per unknown on the chain
    partial = [prog.mac(f"{prefix}w{j}", sol, terms=[(1, z[j], rho[j])], checked=True)
               for j in range(6)]
    x = [None] * 6
    for k in reversed(range(6)):
        x[k] = partial[k]
        for j in reversed(range(k)):  # the next unknown first: it is on the chain
            partial[j] = prog.mac(f"{prefix}u{j}_{k}", sol, partial[j],
                                  [(-1, low[(k, j)], x[k])], checked=True)
    return x


# --- scheduling ---------------------------------------------------------------------------

@dataclass
class Schedule:
    """Issue cycle of every op (``issue[k]`` for ``program.ops[k]``) and timing.

    Members
    -------
    issue : list of int
    writeback : list of int
        Cycle in which each op's result is written (readable by an op issued then).
    length : int
        Cycles from the program's start to the last write-back, inclusive.
    input_ready : dict name -> int
        Cycle the normalizer's write of each input value happens.
    """
    issue: list
    writeback: list
    length: int
    input_ready: dict


def _latency(op):
    return SEED_LATENCY if op.kind == "seed" else MAC_LATENCY


def _critical_path(ops):
    """Longest latency from each op to the end of the program (list scheduling priority)."""
    users = {k: [] for k in range(len(ops))}
    producer = {}
    for k, op in enumerate(ops):
        for src in op.sources:
            if (src.bank, src.name) in producer:
                users[producer[(src.bank, src.name)]].append(k)
        producer[(op.dst.bank, op.dst.name)] = k
    path = [0] * len(ops)
    for k in reversed(range(len(ops))):
        path[k] = ops[k].slots - 1 + _latency(ops[k]) + max((path[u] for u in users[k]), default=0)
    return path


def schedule(program):
    """List-schedule ``program``: one term issued per clock, at most one write-back per
    clock, every operand written before it is read (write-back cycle ≤ read cycle; the
    register file reads are transparent). State values are read as they were at the
    row's start: a commit op writes back no earlier than the last read of the state it
    replaces (a state register samples its old value in that clock), and after every
    checked op of the row (the row's flags are final by then; the information gain's
    checks are its own)."""
    ops = program.ops
    ready = {("input", name): k + NORMALIZER_LATENCY for k, name in enumerate(program.inputs)}
    ready.update({("constant", name): 0 for name in program.constants})
    ready.update({("state", name): 0 for name in program.state})
    priority = _critical_path(ops)
    readers = {name: [k for k, op in enumerate(ops) if op.dst.name != name and any(
        s.bank == "state" and s.name == name for s in op.sources)] for name in program.state}
    checked = [k for k, op in enumerate(ops) if op.checked and op.group == "row"]
    issue, writeback = [None] * len(ops), [None] * len(ops)
    busy_issue, busy_write = set(), set()
    pending = set(range(len(ops)))
    cycle = 0
    while pending:
        best = None
        for k in pending if cycle not in busy_issue else ():
            op = ops[k]
            wb = cycle + op.slots - 1 + _latency(op)
            if (any(ready.get((s.bank, s.name), cycle + 1) > cycle for s in op.sources)
                    or any(cycle + t in busy_issue for t in range(op.slots))
                    or wb in busy_write):
                continue
            if op.commit and (any(writeback[c] is None or writeback[c] >= wb for c in checked)
                              or any(issue[r] is None or issue[r] + ops[r].slots - 1 > wb
                                     for r in readers[op.dst.name])):
                continue
            if best is None or (priority[k], -k) > (priority[best[0]], -best[0]):
                best = (k, wb)
        if best is not None:
            k, wb = best
            issue[k], writeback[k] = cycle, wb
            busy_issue.update(cycle + t for t in range(ops[k].slots))
            busy_write.add(wb)
            if not ops[k].commit:
                ready[(ops[k].dst.bank, ops[k].dst.name)] = wb
            pending.discard(k)
        cycle += 1
    return Schedule(issue=issue, writeback=writeback, length=max(writeback) + 1,
                    input_ready={name: ready[("input", name)] for name in program.inputs})


def _work_lifetimes(program, schedule):
    """(write cycle, last read cycle) of every computed work value, in write order; a
    value never read lives for its write cycle only."""
    ops = program.ops
    last = {}
    for op, start in zip(ops, schedule.issue):
        reads = [(op.source, start)] if op.kind == "seed" else [
            (value, start + t) for t, (_, a, b) in enumerate(op.terms) for value in (a, b)]
        if op.init is not None:
            reads.append((op.init, start))      # read with the first term
        for value, cycle in reads:
            if value.bank == "work":
                last[value.name] = max(last.get(value.name, cycle), cycle)
    written = sorted((wb, op.dst.name) for op, wb in zip(ops, schedule.writeback)
                     if op.dst.bank == "work")
    return [(name, wb, max(last.get(name, wb), wb)) for wb, name in written]


def allocate_work(program, schedule):
    """Work-bank registers of ``program`` as scheduled: ``(register, depth)``, register a
    dict name -> index. A computed value takes a free register from its write-back to
    its last read, and a register is free again from the clock after that read (a write
    in the clock of a read would be seen by it: the bank's reads are transparent).
    Linear scan in write order: as many registers as values are live at once, the least
    an interval allocation can do. One register per value took 283 (with the constants)
    for the board's program with the information gain, where 64 are ever live (issue
    17: the bank is distributed RAM, copied per read port)."""
    register = {}
    free, busy = [], []                     # heaps: free registers; (free from, register)
    depth = 0
    for name, write, last in _work_lifetimes(program, schedule):
        while busy and busy[0][0] <= write:
            heapq.heappush(free, heapq.heappop(busy)[1])
        if free:
            index = heapq.heappop(free)
        else:
            index, depth = depth, depth + 1
        register[name] = index
        heapq.heappush(busy, (last + 1, index))
    return register, depth

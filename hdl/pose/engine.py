"""The pose solver's engine: scaling, the 6×6 solve and the pose integration of a row.

It runs the statically scheduled program of :mod:`hdl.pose.program` — one instruction
word per clock from a ROM — on

* a normalizer that reads the accumulator's 27 sums, scales them by the row's Jacobi
  exponents (barrel shift + one half-even rounding) into the ``input`` register bank,
  then writes the six scales ``2**-e``;
* one pipelined multiply-accumulate unit (exact sums, one rounding per op);
* a seed unit for inverse square roots (normalize by an even shift, interpolated
  table, denormalize) that also checks every pivot against ``2**-pivot_log2``, the
  run-time register (:meth:`PoseSolverParams.pivot_thresholds`);
* the ``work`` register bank (LUT RAM, transparent reads) and the pose state registers;
* the pose ring: one pose per row slot (block RAM). A row's step is the rig's motion
  since the same row one frame earlier, so the program reads the old pose from the
  row's slot (read when the row starts, held at the block RAM's output), the commit
  ops write the new pose into the state registers, and those — the record's pose — are
  written back to the slot when the record is taken. After reset the ring is cleared
  to the reset pose, one slot per clock (:attr:`PoseEngine.clear_clocks`).

When the program ends it offers the pose record; the next row starts once the record
is taken.
"""

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.fixed import SQ, UQ, Overflow, Rounding, hdl_add, hdl_mul, hdl_resize, mul_format
from hdl.pose.accumulator import PAIRS, exponent_bits, leading_one
from hdl.pose.params import (DELTA_BITS, MIN_PIVOT_LOG2, SEED_TABLE_FMT, SLOPE_FMT, PoseFlag,
                             PoseSolverParams, solver_source)
from hdl.pose.forecast_filter import gain_layout
from hdl.pose.forecast_params import ForecastParams
from hdl.pose.prior_store import total_fmt
from hdl.pose.program import MAC_LATENCY, NORMALIZER_LATENCY, SEED_LATENCY, STATE_NAMES, UPPER
from hdl.pose.rom import BANKS, ProgramRom, seed_table_contents

__all__ = ["PoseEngine", "record_layout", "counters_layout"]



def record_layout(params):
    """A pose record, one per row: ``row``, ``time``, ``flags``, ``q`` (4), ``p`` (3),
    ``step`` (6) in the solver's formats (:func:`hdl.pose.params.solver_source`)."""
    return solver_source(params).layout()


def counters_layout(params):
    """Status counters (wrap): rows solved, and rows flagged for each reason."""
    return data.StructLayout({name: params.counter_bits for name in
                              ("solved", "empty", "ill", "saturated", "overrun")})


def check_gain(params, gain):
    """``gain``: None, or the forecast's parameters with ``motion_gain="information"`` of
    this solver (the information gain's formats); returned as given."""
    if gain is None:
        return None
    if not isinstance(gain, ForecastParams) or gain.motion_gain != "information":
        raise ValueError(f"gain must be None or a ForecastParams with motion_gain "
                         f"'information', not {gain!r}")
    if gain.solver != params:
        raise ValueError("gain must be the forecast of this solver (gain.solver == params)")
    return gain


def prior_exponent_high(gain):
    """The largest Jacobi exponent of ``N + Λ`` (its format's top bit)."""
    return gain.solver.exponent(total_fmt(gain).width - 1)


def gain_ports(gain):
    """The engine's ports of the information gain: whether ``read_index`` reads one of
    the 21 entries of N this clock, M's entries and exponents in, the filter's prediction
    in, the moves out."""
    p = gain.solver
    low = p.exponent_range[0]
    bits = max(abs(low), abs(prior_exponent_high(gain))).bit_length() + 1
    return {"reading_normal": Out(1),
            "m_index": Out(range(len(UPPER))),
            "m_data": In(total_fmt(gain).shape()),
            "m_exponents": In(data.ArrayLayout(signed(bits), 6)),
            "predicted": In(data.ArrayLayout(gain.motion_fmt.shape(), 6)),
            "gains": Out(stream.Signature(gain_layout(gain)))}


class PoseEngine(wiring.Component):
    """Scaling, Cholesky solve and integration of one row at a time.

    Parameters
    ----------
    params : PoseSolverParams

    Members
    -------
    row_done : In(1)
        The accumulator holds a finished row (with ``exponents``, ``empty``,
        ``overrun``, ``row``, ``time``).
    read_index : Out(range(27)), read_data : In(normal_fmt)
        The accumulator's sums, read one per clock at the start of the program.
    release : Out(1)
        All 27 sums were read.
    o : Out(stream.Signature(record_layout(params)))
        Pose records. The next row starts only once the record was taken.
    counters : Out(counters_layout(params))
    pivot_log2 : In(unsigned(pivot_log2_bits)), reset ``params.pivot_log2``
        The pivot check: a pivot below ``2**-pivot_log2`` flags ILL. Used from the
        next clock; change it between rows. Out of range (below ``MIN_PIVOT_LOG2`` or
        above the build's): the build's, and ``pivot_log2_error`` is set.
    pivot_log2_error : Out(1)

    Latency: :attr:`length` + 1 clocks from a ``row_done`` that finds the engine idle
    to ``o.valid``. Reset: every row slot's pose (1, 0, 0, 0), position 0 (the ring is
    cleared in the first :attr:`clear_clocks` clocks; a row waits for that), counters 0.
    """

    def __init__(self, params, gain=None):
        if not isinstance(params, PoseSolverParams):
            raise TypeError(f"params must be a PoseSolverParams, not {params!r}")
        self.params, self.gain = params, check_gain(params, gain)
        self._words = ProgramRom(params, information=gain is not None)
        eb = exponent_bits(params)
        super().__init__({
            **({} if gain is None else gain_ports(gain)),
            "row_done": In(1),
            "read_index": Out(range(len(PAIRS))),
            "read_data": In(params.normal_fmt.shape()),
            "release": Out(1),
            "exponents": In(data.ArrayLayout(signed(eb), 6)),
            "empty": In(1),
            "overrun": In(1),
            "row": In(params.row_bits),
            "time": In(params.time_bits),
            "o": Out(stream.Signature(record_layout(params))),
            "counters": Out(counters_layout(params)),
            "pivot_log2": In(unsigned(params.pivot_log2_bits), init=params.pivot_log2),
            "pivot_log2_error": Out(1),
        })

    @property
    def length(self):
        """Clocks the program runs (from its first cycle to its last write-back)."""
        return self._words.schedule.length

    @property
    def clear_clocks(self):
        """Clocks after reset before a row can start: one per ring slot."""
        return self.params.rows

    @property
    def program(self):
        return self._words.program

    def elaborate(self, platform):
        p = self.params
        words = self._words
        prog = words.program
        m = Module()
        W = p.engine_width
        raw = signed(W)
        length = words.schedule.length

        # --- control ---------------------------------------------------------------------
        running = Signal()
        pc = Signal(range(length + 1))
        go = Signal()
        cleared = Signal()
        idle_out = ~self.o.valid if self.gain is None else ~self.o.valid & ~self.gains.valid
        m.d.comb += go.eq(self.row_done & ~running & idle_out & cleared)
        exps = Signal.like(self.exponents)
        row, time = Signal.like(self.row), Signal.like(self.time)
        empty, overrun, ill, saturated = Signal(), Signal(), Signal(), Signal()
        with m.If(go):
            m.d.sync += [running.eq(1), pc.eq(0), exps.eq(self.exponents), row.eq(self.row),
                         time.eq(self.time), empty.eq(self.empty), overrun.eq(self.overrun),
                         ill.eq(0), saturated.eq(0)]
        with m.Elif(running):
            m.d.sync += pc.eq(pc + 1)
            with m.If(pc == length - 1):
                m.d.sync += [running.eq(0), self.o.valid.eq(1)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        # The word of program cycle t is on `word` in cycle t (the issue stage): the ROM's
        # registered address is t + 1 in cycle t, and 0 while idle (word 0 is ready).
        rom = Memory(shape=words.layout.size, depth=len(words.words), init=words.words,
                     attrs={"rom_style": "block", "ram_style": "block"})
        m.submodules.rom = rom
        fetch = rom.read_port()
        with m.If(go):
            m.d.sync += fetch.addr.eq(1)
        with m.Elif(running & (pc != length - 1)):
            m.d.sync += fetch.addr.eq(fetch.addr + 1)
        with m.Else():
            m.d.sync += fetch.addr.eq(0)
        word = Signal(words.layout)
        m.d.comb += word.eq(Mux(running, fetch.data, 0))
        stages = [word]
        for k in range(7):
            stage = Signal(words.layout, name=f"ctrl{k + 1}")
            m.d.sync += stage.eq(stages[-1])
            stages.append(stage)

        # --- register banks --------------------------------------------------------------
        depth_in = 1 << (len(prog.inputs) - 1).bit_length()
        # LUT RAM: block RAM is the scarcer resource (reference rows, coefficients)
        distributed = {"ram_style": "distributed"}
        bank_in = Memory(shape=raw, depth=depth_in, init=[], attrs=distributed)
        bank_work = Memory(shape=raw, depth=words.work_depth, init=[], attrs=distributed)
        constants = [Const(int(operand.fmt.quantize(value)), raw)
                     for operand, value in prog.constants.values()]
        m.submodules.bank_in, m.submodules.bank_work = bank_in, bank_work
        self._banks = (bank_in, bank_work)  # for inspection by tests
        w_in, w_work = bank_in.write_port(), bank_work.write_port()
        state = [Signal(raw, name=f"state_{n}",
                        init=int(p.quat_fmt.quantize(1.0)) if n == "qw" else 0)
                 for n in STATE_NAMES]
        old = self._pose_ring(m, state, go, cleared)

        def operand(bank_field, index_field, name):
            """The operand named by an issue-stage word, one clock later."""
            r_in = bank_in.read_port(transparent_for=(w_in,))
            r_work = bank_work.read_port(transparent_for=(w_work,))
            m.d.comb += [r_in.addr.eq(index_field), r_work.addr.eq(index_field)]
            bank = Signal(2, name=f"{name}_bank")
            held = Signal(raw, name=f"{name}_held")       # a state value or a constant
            m.d.sync += [bank.eq(bank_field),
                         held.eq(Mux(bank_field == BANKS["constant"],
                                     Array(constants)[index_field[:(len(constants) - 1).bit_length()]],
                                     Array(old)[index_field[:3]]))]
            value = Signal(raw, name=name)
            m.d.comb += value.eq(Mux(bank == BANKS["input"], r_in.data,
                                     Mux(bank == BANKS["work"], r_work.data, held)))
            return value

        op_a = operand(word.a_bank, word.a, "op_a")
        op_b = operand(word.b_bank, word.b, "op_b")
        op_c = operand(word.c_bank, word.c, "op_c")

        # --- normalizer: cycles 0..26 read and scale the sums, 27..32 write the scales ---
        count_in = len(PAIRS) + 6
        low, high = p.exponent_range
        # (reads past the last sum are ignored: no guard in the index path)
        m.d.comb += [self.read_index.eq(pc),
                     self.release.eq(running & (pc == len(PAIRS) - 1))]
        n_shift = Signal(range(2 * (high - low) + 1))
        n_scale = Signal(range(p.scale_fmt.frac_bits - low + 1))
        n_kind = Signal(2)          # 0: N entry, 1: right-hand side, 2: scale
        n_value = Signal(p.normal_fmt.shape())
        n_valid, n_addr = Signal(), Signal(range(depth_in))
        with m.Switch(pc):
            for k, (i, j) in enumerate(PAIRS):
                with m.Case(k):
                    if j < 6:
                        m.d.sync += [n_shift.eq(2 * high - exps[i] - exps[j]), n_kind.eq(0)]
                    else:
                        m.d.sync += [n_shift.eq(high - exps[i]), n_kind.eq(1)]
            for i in range(6):
                with m.Case(len(PAIRS) + i):
                    m.d.sync += [n_scale.eq(p.scale_fmt.frac_bits - exps[i]), n_kind.eq(2)]
        m.d.sync += [n_value.eq(self.read_data), n_valid.eq(running & (pc < count_in)),
                     n_addr.eq(pc)]

        # one clock for the barrel shift, one for the rounding
        src = p.normal_fmt
        shifted = Signal(signed(src.width + 2 * (high - low) + 1))
        kind2, scale2, valid2, addr2 = (Signal.like(n_kind), Signal.like(n_scale), Signal(),
                                        Signal.like(n_addr))
        m.d.sync += [shifted.eq(n_value << n_shift), kind2.eq(n_kind), scale2.eq(n_scale),
                     valid2.eq(n_valid), addr2.eq(n_addr)]

        def scaled(span, shift_high, dst):
            wide_src = SQ(max(1, src.int_bits + span - shift_high) + 1, src.frac_bits + shift_high)
            return _round_saturating(m, shifted[:wide_src.width], wide_src, dst)

        norm, norm_sat = scaled(2 * (high - low), 2 * high, p.unit_fmt)
        rhs, rhs_sat = scaled(high - low, high, p.solution_fmt)
        scale = Const(1, 1) << scale2
        n_data, n_sat, n_write, n_waddr = Signal(raw), Signal(), Signal(), Signal.like(n_addr)
        m.d.sync += [n_data.eq(Mux(kind2 == 0, norm, Mux(kind2 == 1, rhs, scale))),
                     n_sat.eq(valid2 & Mux(kind2 == 0, norm_sat, Mux(kind2 == 1, rhs_sat, 0))),
                     n_write.eq(valid2), n_waddr.eq(addr2)]
        assert NORMALIZER_LATENCY == 3
        if self.gain is None:
            m.d.comb += [w_in.en.eq(n_write), w_in.addr.eq(n_waddr), w_in.data.eq(n_data)]
        else:
            g_write, g_waddr, g_data, g_sat = self._gain_inputs(m, pc, running, exps, depth_in)
            m.d.comb += [w_in.en.eq(n_write | g_write),
                         w_in.addr.eq(Mux(g_write, g_waddr, n_waddr)),
                         w_in.data.eq(Mux(g_write, g_data, n_data))]

        # --- multiply-accumulate unit -----------------------------------------------------
        # issue t: read; t+1: operands; t+2: multiply; t+3: product aligned to the op's
        # rounding position; t+4: accumulate; t+5: round, saturate, write (the op's last
        # term issued at t). Products and init are shifted left by r_max − out_shift, so
        # the sum always has r_max fraction bits beyond the destination's.
        r_max = words.out_shifts[-1]
        init_max = max(words.init_shifts, default=0)
        span = r_max - words.out_shifts[0]
        acc_width = max(2 * W, W + init_max) + span + (words.max_terms + 2).bit_length() + 1
        mul_a, mul_b = Signal(raw), Signal(raw)
        m.d.sync += [mul_a.eq(op_a), mul_b.eq(op_b)]
        c_aligned = Signal(signed(acc_width))
        m.d.sync += c_aligned.eq(0)
        with m.If(stages[1].has_init):
            with m.Switch(Cat(stages[1].init_code, stages[1].out_code)):
                for (init_code, init_shift), (out_code, out_shift) in words.init_out_pairs:
                    with m.Case(init_code | (out_code << len(stages[1].init_code))):
                        m.d.sync += c_aligned.eq(op_c << (init_shift + r_max - out_shift))
        product_fmt = mul_format(SQ(W, 0), SQ(W, 0))
        product_m = Signal(product_fmt.shape())
        m.d.sync += product_m.eq(hdl_mul(mul_a, SQ(W, 0), mul_b, SQ(W, 0))[0])
        product_p = Signal(signed(acc_width))
        with m.Switch(stages[3].out_code):
            for code, shift in enumerate(words.out_shifts):
                with m.Case(code):
                    m.d.sync += product_p.eq(product_m << (r_max - shift))
        c_aligned3, c_aligned4 = Signal.like(c_aligned), Signal.like(c_aligned)
        m.d.sync += [c_aligned3.eq(c_aligned), c_aligned4.eq(c_aligned3)]
        acc = Signal(signed(acc_width))
        base = Mux(stages[4].first, c_aligned4, acc)
        m.d.sync += acc.eq(Mux(stages[4].negate, base - product_p, base + product_p))
        mac_data, mac_sat = _round_saturating(m, acc, SQ(acc_width - r_max, r_max), SQ(W, 0))
        mac_write = stages[5].issue & ~stages[5].seed & stages[5].last
        assert MAC_LATENCY == 5

        # --- seed unit -----------------------------------------------------------------
        # t+1: pivot in; t+2: ILL check, bit length; t+3: normalize (even shift), table
        # address; t+4: table data, slope·delta; t+5: interpolate; t+6: denormalize;
        # t+7: write. As emulator.pose_solver.rsqrt_seed.
        unit = p.unit_fmt
        built = int(p.pivot_thresholds()[0])
        one = Const(1 << unit.frac_bits)
        threshold = Signal(len(one), init=built)               # raw 2**-pivot_log2
        error = (self.pivot_log2 < MIN_PIVOT_LOG2) | (self.pivot_log2 > p.pivot_log2)
        m.d.comb += self.pivot_log2_error.eq(error)
        m.d.sync += threshold.eq(Mux(error, built, one >> self.pivot_log2))
        pivot1, seed1 = Signal(raw), Signal()
        m.d.sync += [pivot1.eq(op_a), seed1.eq(stages[1].issue & stages[1].seed)]
        if self.gain is None:
            with m.If(seed1 & (pivot1 < threshold)):
                m.d.sync += ill.eq(1)
        else:                   # a gain op's pivot check is the gain's
            gain_ill, gain_saturated = Signal(), Signal()
            with m.If(go):
                m.d.sync += [gain_ill.eq(0), gain_saturated.eq(0)]
            with m.If(seed1 & (pivot1 < threshold)):
                with m.If(stages[2].gain):
                    m.d.sync += gain_ill.eq(1)
                with m.Else():
                    m.d.sync += ill.eq(1)
        # a pivot at or below zero counts as the smallest positive one (the row is ILL);
        # the test runs beside the bit-length tree, not before it
        nonpositive = pivot1[W - 1] | ~pivot1.any()
        clamped, top = Signal(W - 1), Signal(range(W))
        m.d.comb += [clamped.eq(Mux(nonpositive, 1, pivot1)),
                     top.eq(Mux(nonpositive, 0, leading_one(pivot1, W - 1)))]
        # bit length top + 1; excess = F − length ≥ −1, k = floor(excess / 2),
        # m = D·2**(2k): half = k + 1 ≥ 0
        pivot2, half2 = Signal(W - 1), Signal(range(W))
        m.d.sync += [pivot2.eq(clamped), half2.eq((unit.frac_bits + 1 - top) >> 1)]
        # seed = y0·2**k in seed_fmt: a shift by (half − 1) + (seed frac − table frac)
        extra = p.seed_fmt.frac_bits - SEED_TABLE_FMT.frac_bits - 1
        shift3 = Signal(range(W + extra + 1))
        m.d.sync += shift3.eq(half2 + extra)
        mantissa = Signal(p.mantissa_bits)
        m.d.comb += mantissa.eq(pivot2 << (half2 << 1))
        low_bit = p.mantissa_bits - p.seed_bits
        table = Memory(shape=SEED_TABLE_FMT.width + SLOPE_FMT.width, depth=1 << p.seed_bits,
                       init=seed_table_contents(p))
        m.submodules.seed_table = table
        lookup = table.read_port()
        m.d.comb += lookup.addr.eq(mantissa[low_bit:])
        delta_fmt = UQ(0, p.seed_bits + DELTA_BITS)
        delta3 = Signal(DELTA_BITS)
        m.d.sync += delta3.eq(mantissa[low_bit - DELTA_BITS:low_bit])
        slope_fmt = mul_format(SLOPE_FMT, delta_fmt)
        slope4, t0_4, shift4 = (Signal(slope_fmt.shape()), Signal(SEED_TABLE_FMT.width),
                                Signal.like(shift3))
        m.d.sync += [slope4.eq(hdl_mul(lookup.data[SEED_TABLE_FMT.width:], SLOPE_FMT, delta3,
                                       delta_fmt)[0]),
                     t0_4.eq(lookup.data[:SEED_TABLE_FMT.width]), shift4.eq(shift3)]
        total, total_fmt = hdl_add(t0_4, SEED_TABLE_FMT, -slope4,
                                   SQ(slope_fmt.int_bits + 1, slope_fmt.frac_bits))
        y0_5, shift5 = Signal(SEED_TABLE_FMT.shape()), Signal.like(shift3)
        m.d.sync += [y0_5.eq(_round_saturating(m, total, total_fmt, SEED_TABLE_FMT)[0]),
                     shift5.eq(shift4)]
        # (wraps only for pivots below 2**-pivot_log2, which flag ILL)
        seed_data = Signal(raw)
        m.d.sync += seed_data.eq(hdl_resize(y0_5 << shift5,
                                            UQ(SEED_TABLE_FMT.width + W + extra, 0),
                                            SQ(W, 0), Rounding.FLOOR, Overflow.WRAP))
        seed_write = stages[7].issue & stages[7].seed
        assert SEED_LATENCY == 7

        # --- write-back ------------------------------------------------------------------
        wb = Signal(words.layout)
        m.d.comb += wb.eq(Mux(seed_write, stages[7].as_value(), stages[5].as_value()))
        w_data = Signal(raw)
        m.d.comb += w_data.eq(Mux(seed_write, seed_data, mac_data))
        write = seed_write | mac_write
        flagged = overrun | empty | ill | saturated
        m.d.comb += [w_work.en.eq(write & ~wb.dst_state), w_work.addr.eq(wb.dst),
                     w_work.data.eq(w_data)]
        # a flagged row commits its slot's old pose: the record and the ring keep it
        with m.If(write & wb.dst_state):
            m.d.sync += Array(state)[wb.dst[:3]].eq(Mux(flagged, Array(old)[wb.dst[:3]],
                                                        w_data))
        mac_saturated = mac_write & stages[5].checked & mac_sat
        if self.gain is None:
            with m.If(mac_saturated | n_sat):
                m.d.sync += saturated.eq(1)
        else:
            with m.If((mac_saturated & ~stages[5].gain) | n_sat):
                m.d.sync += saturated.eq(1)
            with m.If((mac_saturated & stages[5].gain) | g_sat):
                m.d.sync += gain_saturated.eq(1)
        captured = [Signal(raw, name=f"step{k}") for k in range(6)]
        moves = [] if self.gain is None else [Signal(raw, name=f"move{k}") for k in range(6)]
        with m.If(write):
            with m.Switch(wb.capture):
                for k, target in enumerate(captured + moves):
                    with m.Case(k + 1):
                        m.d.sync += target.eq(w_data)

        # --- record ------------------------------------------------------------------------
        flags = Signal(len(PoseFlag))
        m.d.comb += flags.eq(Mux(overrun, int(PoseFlag.OVERRUN), Mux(empty, int(PoseFlag.EMPTY),
                             Mux(ill, int(PoseFlag.ILL),
                                 Mux(saturated, int(PoseFlag.SATURATED), 0)))))
        rec = self.o.payload
        m.d.comb += [rec.row.eq(row), rec.time.eq(time), rec.flags.eq(flags)]
        m.d.comb += [rec.q[k].eq(state[k]) for k in range(4)]
        m.d.comb += [rec.p[k].eq(state[4 + k]) for k in range(3)]
        m.d.comb += [rec.step[k].eq(Mux(flags == 0, captured[k], 0)) for k in range(6)]
        if self.gain is not None:   # the information gain's moves, beside the record
            with m.If(running & (pc == length - 1)):
                m.d.sync += self.gains.valid.eq(1)
            with m.Elif(self.gains.valid & self.gains.ready):
                m.d.sync += self.gains.valid.eq(0)
            m.d.comb += [self.gains.payload.ok.eq(~gain_ill & ~gain_saturated)]
            m.d.comb += [self.gains.payload.move[k].eq(moves[k]) for k in range(6)]
        # counted on the edge that raises o.valid (the flags are final by then)
        with m.If(running & (pc == length - 1)):
            for name, flag in (("empty", PoseFlag.EMPTY), ("ill", PoseFlag.ILL),
                               ("saturated", PoseFlag.SATURATED),
                               ("overrun", PoseFlag.OVERRUN)):
                with m.If(flags == int(flag)):
                    m.d.sync += getattr(self.counters, name).eq(getattr(self.counters, name) + 1)
            with m.If(flags == 0):
                m.d.sync += self.counters.solved.eq(self.counters.solved + 1)
        return m

    def _gain_inputs(self, m, pc, running, exps, depth_in):
        """The normalizer's share of the information gain (the model's
        :func:`emulator.pose.information_gain.gain_inputs`): after the row's 33 inputs,
        M̂ (21, from ``m_data`` at ``m_index`` with ``m_exponents``), ``f = p·2**e`` (6,
        ``predicted``), ``2**(e − e_M)`` and ``2**−e_M`` (6 each), one per clock with the
        row inputs' latency. Returns (write, address, data, saturated) of the input bank
        write; a saturation is the gain's."""
        p, g = self.params, self.gain
        low, high = p.exponent_range
        high_m = prior_exponent_high(g)
        total, motion, frac = total_fmt(g), g.motion_fmt, p.scale_fmt.frac_bits
        first = len(PAIRS) + 6
        count = len(UPPER) + 18
        kind = Signal(2)            # 0: M entry, 1: prediction, 2: power of two, 3: zero
        m_value, p_value = Signal(total.shape()), Signal(motion.shape())
        m_shift = Signal(range(2 * (high_m - low) + 1))
        p_shift = Signal(range(high + 1))
        scale = Signal(range(frac + 1))
        valid, addr = Signal(), Signal(range(depth_in))
        index = pc - first
        m.d.comb += self.m_index.eq(Mux((pc >= first) & (index < len(UPPER)), index, 0))
        m.d.comb += self.reading_normal.eq(running & (pc < len(UPPER)))
        m_exps = self.m_exponents
        with m.Switch(pc):
            for k, (i, j) in enumerate(UPPER):
                with m.Case(first + k):
                    m.d.sync += [m_shift.eq(2 * high_m - m_exps[i] - m_exps[j]), kind.eq(0)]
            for i in range(6):
                with m.Case(first + len(UPPER) + i):
                    m.d.sync += [p_value.eq(self.predicted[i]), p_shift.eq(exps[i]),
                                 kind.eq(1)]
                with m.Case(first + len(UPPER) + 6 + i):
                    diff = m_exps[i] - exps[i]
                    m.d.sync += [scale.eq(frac - diff), kind.eq(Mux(diff > frac, 3, 2))]
                with m.Case(first + len(UPPER) + 12 + i):
                    m.d.sync += [scale.eq(frac - m_exps[i]), kind.eq(2)]
        m.d.sync += [m_value.eq(self.m_data), valid.eq(running & (pc >= first)
                                                       & (pc < first + count)),
                     addr.eq(pc)]
        # one clock for the shifts, one for the rounding (the row inputs' latency)
        span = 2 * (high_m - low)
        shifted_m = Signal(signed(total.width + span + 1))
        shifted_p = Signal(signed(motion.width + high + 1))
        kind2, scale2, valid2, addr2 = (Signal.like(kind), Signal.like(scale), Signal(),
                                        Signal.like(addr))
        m.d.sync += [shifted_m.eq(m_value << m_shift), shifted_p.eq(p_value << p_shift),
                     kind2.eq(kind), scale2.eq(scale), valid2.eq(valid), addr2.eq(addr)]
        wide_m = SQ(max(1, total.int_bits + span - 2 * high_m) + 1, total.frac_bits + 2 * high_m)
        scaled, scaled_sat = _round_saturating(m, shifted_m[:wide_m.width], wide_m, p.unit_fmt)
        wide_p = SQ(motion.int_bits + high + 1, motion.frac_bits)
        shifted, shifted_sat = _round_saturating(m, shifted_p, wide_p, p.solution_fmt)
        data, saturated = Signal(signed(p.engine_width)), Signal()
        write, waddr = Signal(), Signal.like(addr)
        m.d.sync += [data.eq(Mux(kind2 == 0, scaled, Mux(kind2 == 1, shifted,
                                                          Mux(kind2 == 2, Const(1, 1) << scale2,
                                                              0)))),
                     saturated.eq(valid2 & Mux(kind2 == 0, scaled_sat,
                                               Mux(kind2 == 1, shifted_sat, 0))),
                     write.eq(valid2), waddr.eq(addr2)]
        return write, waddr, data, saturated

    def _pose_ring(self, m, state, go, cleared):
        """The pose ring (one pose per row slot). Reads the starting row's slot on
        ``go`` and holds it at the block RAM's output (the returned old pose, seven
        values, what the program reads as ``state``); writes ``state`` — the record's
        pose — back when the record is taken; clears every slot to the reset pose after
        reset (``cleared`` rises :attr:`clear_clocks` clocks after reset).

        A slot is read in the clock a row starts, never earlier, so a write of the
        previous row (same slot or not) or of the clear is always seen: the read port
        needs no transparency."""
        p = self.params
        ring = Memory(shape=len(STATE_NAMES) * p.engine_width, depth=p.rows, init=[],
                      attrs={"ram_style": "block"})
        m.submodules.pose_ring = ring
        write, read = ring.write_port(), ring.read_port()
        sweep = Signal(range(p.rows + 1))
        clearing = sweep != p.rows
        with m.If(clearing):
            m.d.sync += sweep.eq(sweep + 1)
        # the state registers hold the reset pose until the first row's commits
        m.d.comb += [cleared.eq(~clearing),
                     write.en.eq(clearing | (self.o.valid & self.o.ready)),
                     write.addr.eq(Mux(clearing, sweep, self.o.payload.row)),
                     write.data.eq(Cat(*state)),
                     read.en.eq(go), read.addr.eq(self.row)]
        return [read.data[k * p.engine_width:(k + 1) * p.engine_width]
                for k in range(len(STATE_NAMES))]


def _round_saturating(m, value, src, dst):
    """Half-even rounding of ``value`` (format ``src``) into ``dst``, saturating; returns
    (rounded, saturated) — the engine's one narrowing, as ``emulator.pose_solver._round``."""
    wide_fmt = SQ(max(src.int_bits, dst.int_bits) + 2, dst.frac_bits)
    wide = Signal(wide_fmt.shape())
    m.d.comb += wide.eq(hdl_resize(value, src, wide_fmt, Rounding.HALF_EVEN, Overflow.ERROR))
    saturated = (wide < dst.min_raw) | (wide > dst.max_raw)
    return hdl_resize(wide, wide_fmt, dst, Rounding.FLOOR, Overflow.SATURATE), saturated

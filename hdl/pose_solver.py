"""The pose solver: per image row, the weighted least-squares small-motion step and the
integrated pose, in fixed point.

Measurements (one per camera or row segment) stream in; each row's last measurement
closes the row, and one pose record per row streams out. Inside:

* the coefficient store (:class:`hdl.pose.coef_store.CoefficientStore`: per slot
  every row's coefficients, or their polynomials in the row; initial contents at build
  time, rewritable at run time through ``coef_write``);
* :class:`hdl.pose.accumulator.PoseAccumulator`: the weighted normal equations;
* :class:`hdl.pose.engine.PoseEngine`: Jacobi scaling, the Cholesky solve with its
  pivot check, and the pose integration onto the pose of the same row one frame
  earlier (a ring of one pose per row slot).

The algorithm, formats and error budget are in ``docs/pose/pose_solver.md``; the
bit-accurate model is :mod:`emulator.pose_solver`.
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out, connect

from hdl.pose.coef_store import CoefficientStore, coef_write_signature
from hdl.pose.accumulator import PAIRS, PoseAccumulator, leading_one, measurement_layout
from hdl.pose.engine import PoseEngine, counters_layout, prior_exponent_high, record_layout
from hdl.pose.prior_store import PriorStore, total_fmt
from hdl.pose.program import UPPER
from hdl.pose.params import PoseFlag, PoseSolverParams

__all__ = ["PoseSolver", "PoseSolverParams", "PoseFlag",
           "measurement_layout", "record_layout", "counters_layout", "default_gain_solver"]


class PoseSolver(wiring.Component):
    """Fixed-point weighted least-squares pose update, one per row.

    Parameters
    ----------
    params : PoseSolverParams
    coefficients : ndarray (slots, entries_per_slot, 9) of int, optional
        Initial raw contents of the coefficient store: rows (see
        :func:`hdl.pose.params.quantize_coefficients`) or polynomial terms
        (:func:`hdl.pose.row_polynomials.quantize_polynomials`); zeros if omitted.

    Members
    -------
    i : In(stream.Signature(measurement_layout(params)))
        Measurements, ``last`` on the final one of a row (formats: shift ``shift_fmt``
        pixels, cue ``cue_fmt``, confidence ``conf_fmt``).
    gated : In(1)
        Read with a row's ``last`` transfer: the row failed the consistency stage's gates
        (:class:`hdl.measurement.consistency.ConsistencyStage`'s ``gated``); it is
        flagged EMPTY and gives no step, as the model's all-zero confidences make it.
        0 when no stage is in front.
    o : Out(stream.Signature(record_layout(params)))
        One pose record per row (q ``quat_fmt``, p ``position_fmt`` metres, step
        ``step_fmt`` metres/radians, :class:`PoseFlag` flags).
    coef_write : In(coef_write_signature(params))
        Rewrites one stored coefficient.
    counters : Out(counters_layout(params))
        Rows solved and rows flagged per reason (wrapping).
    pivot_log2 : In(unsigned(params.pivot_log2_bits)), reset ``params.pivot_log2``
        The conditioning gate: a pivot below ``2**-pivot_log2`` flags ILL (change it
        between rows). Out of range (below ``MIN_PIVOT_LOG2`` or above the build's
        ``pivot_log2``, which sets the formats): the build's, with ``pivot_log2_error``.
    pivot_log2_error : Out(1)

    Latency: :attr:`latency` clocks from the transfer of a row's last measurement to
    ``o.valid``, when the solver is idle and ``o`` is not stalled. Throughput: one
    measurement per ``ceil(27 / lanes)`` clocks; one row per :attr:`row_interval`
    clocks when rows come back to back. Backpressure: ``i.ready`` falls while a finished
    row waits for the engine, and the engine waits while ``o`` holds an untaken record.
    Integration: the step of row ``y`` is the rig's motion since row ``y`` of the
    previous frame, so it is composed onto the pose of row slot ``y`` (one pose per
    slot); the record carries the new pose of the slot, or its unchanged pose when the
    row is flagged.

    Reset: every slot's pose (1, 0, 0, 0), position 0 — the ring is cleared in the first
    :attr:`clear_clocks` clocks, and a row finished earlier waits for that —; counters
    0; the coefficient store keeps its contents.
    """

    def __init__(self, params=None, coefficients=None, gain=None):
        params = PoseSolverParams() if params is None else params
        if not isinstance(params, PoseSolverParams):
            raise TypeError(f"params must be a PoseSolverParams, not {params!r}")
        self.params = params
        self._store = CoefficientStore(params, coefficients)
        self.coefficients = self._store.contents
        self._accumulator = PoseAccumulator(params)
        self._engine = PoseEngine(params, gain)
        self.gain = gain
        extra = {}
        if gain is not None:
            self._prior = PriorStore(gain)
            members = self._engine.signature.members
            extra = {"predicted": members["predicted"], "gains": members["gains"],
                     "prior_weight": self._prior.signature.members["prior_weight"],
                     "smoothing": self._prior.signature.members["smoothing"]}
        super().__init__({
            **extra,
            "i": In(stream.Signature(measurement_layout(params))),
            "gated": In(1),
            "o": Out(stream.Signature(record_layout(params))),
            "coef_write": In(coef_write_signature(params)),
            "counters": Out(counters_layout(params)),
            "pivot_log2": self._engine.signature.members["pivot_log2"],
            "pivot_log2_error": self._engine.signature.members["pivot_log2_error"],
        })

    @property
    def latency(self):
        """Clocks from a row's last measurement to its pose record (idle solver)."""
        return self._accumulator.tail + 1 + self._engine.length

    @property
    def clear_clocks(self):
        """Clocks after reset in which the pose ring is cleared (no row starts)."""
        return self._engine.clear_clocks

    @property
    def row_interval(self):
        """Clocks per row when rows of ``slots`` measurements come back to back and
        records are taken at once. Either the engine bounds it (its program, the clock
        the record is taken in, the clock it restarts in), or the accumulation does: a
        row's first measurement is accepted once the engine has read the previous
        row's sums, ``len(PAIRS) + 1`` clocks after that row was done."""
        acc = self._accumulator
        accumulate = acc.tail + len(PAIRS) + 1 + (self.params.slots - 1) * acc.period
        return max(self._engine.length + 2, accumulate)

    def elaborate(self, platform):
        p = self.params
        m = Module()
        m.submodules.accumulator = acc = self._accumulator
        m.submodules.engine = engine = self._engine

        m.submodules.coefficients = store = self._store
        m.d.comb += [store.slot.eq(acc.coef_slot), store.row.eq(acc.coef_row),
                     acc.coef_data.eq(store.data)]
        connect(m, wiring.flipped(self.coef_write), store.write)
        connect(m, wiring.flipped(self.i), acc.i)
        m.d.comb += acc.gated.eq(self.gated)
        connect(m, engine.o, wiring.flipped(self.o))
        m.d.comb += [engine.row_done.eq(acc.done), acc.release.eq(engine.release),
                     acc.read_index.eq(engine.read_index), engine.read_data.eq(acc.read_data),
                     engine.exponents.eq(acc.exponents), engine.empty.eq(acc.empty),
                     engine.overrun.eq(acc.overrun), engine.row.eq(acc.row),
                     engine.time.eq(acc.time), self.counters.eq(engine.counters),
                     engine.pivot_log2.eq(self.pivot_log2),
                     self.pivot_log2_error.eq(engine.pivot_log2_error)]
        if self.gain is not None:
            self._wire_prior(m, acc, engine)
        return m

    def _wire_prior(self, m, acc, engine):
        """The information gain's prior: the engine's reads of the first 21 sums (N) pass
        through the prior store, whose ``M = N + Λ'`` fill a buffer the normalizer reads
        and whose diagonal gives ``M``'s exponents (by cycle 28 of the program, before
        the normalizer reaches M at cycle 33); the record's flags keep or drop ``Λ'``."""
        p, g = self.params, self.gain
        m.submodules.prior = prior = self._prior
        connect(m, wiring.flipped(self.gains), engine.gains)
        m.d.comb += [engine.predicted.eq(self.predicted),
                     prior.prior_weight.eq(self.prior_weight),
                     prior.smoothing.eq(self.smoothing)]
        entries = len(UPPER)
        m.d.comb += [prior.i.valid.eq(engine.reading_normal),
                     prior.i.payload.value.eq(acc.read_data),
                     prior.i.payload.last.eq(engine.read_index == entries - 1),
                     prior.o.ready.eq(1),
                     prior.keep.valid.eq(engine.o.valid & self.o.ready),
                     prior.keep.payload.eq(engine.o.payload.flags == 0)]
        m.submodules.prior_buffer = buffer = Memory(shape=total_fmt(g).shape(), depth=entries,
                                                    init=[])
        write, read = buffer.write_port(), buffer.read_port(domain="comb")
        index = Signal(range(entries))
        with m.If(prior.o.valid):
            m.d.sync += index.eq(Mux(prior.o.payload.last, 0, index + 1))
        m.d.comb += [write.en.eq(prior.o.valid), write.addr.eq(index),
                     write.data.eq(prior.o.payload.value),
                     read.addr.eq(engine.m_index), engine.m_data.eq(read.data)]
        # a diagonal entry's leading one is registered first, its exponent and clamp
        # written a clock later (issue 17: both in one clock were 11 LUT levels)
        low, high = p.exponent_range[0], prior_exponent_high(g)
        frac, width = p.normal_fmt.frac_bits, total_fmt(g).width
        top = Signal(range(width), name="prior_top")
        diagonal = Signal(6, name="prior_diagonal")
        m.d.sync += [top.eq(leading_one(prior.o.payload.value, width)),
                     diagonal.eq(Cat(prior.o.valid & (index == UPPER.index((i, i)))
                                     for i in range(6)))]
        exponent = -((frac - 1 - top) >> 1)
        clamped = Mux(exponent < low, low, Mux(exponent > high, high, exponent))
        for i in range(6):
            with m.If(diagonal[i]):
                m.d.sync += engine.m_exponents[i].eq(clamped)


def default_gain_solver():
    """The closed loop's solver of the board rig (``stereo8-board``, its polynomial store)
    with the information gain (prior store, gain program): the catalog's build, for
    Verilog and synthesis."""
    from golden.rig import preset
    from hdl.pipeline_config import PipelineConfig
    config = PipelineConfig.for_rig(preset("stereo8-board"))
    gain = config.forecast(motion_gain="information")
    return PoseSolver(gain.solver, config.coef_store, gain=gain)

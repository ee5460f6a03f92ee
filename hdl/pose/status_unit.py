"""Tracking status of every pose record (issue 18 item 3): tracking, degraded or lost,
and drifted since a loss, in the record's flags byte — so that a board user sees in the
pose packets when the tracker stopped being trustworthy.

It sits between the pose solver's record stream and the pose output
(:class:`hdl.output.packet.PoseOutput`, whose source must then be
:func:`hdl.pose.status_params.status_source`) and takes, beside every record, the row's
counts from the consistency stage (``row``, one transfer per record, in order). The
rule and every rounding are :class:`emulator.pose.tracking_status.StatusUnitModel`'s
(bit-exact); the golden original is :class:`golden.tracking_status.StatusMonitor`;
``docs/pose/tracking_status.md`` gives the differences.

The window's rows live in a ``max_window``-deep memory (one entry per row: stepped,
formed, ill and the three counts); the window sums are kept incrementally (add the new
row, subtract the one ``window`` rows back once the window is full). The update fraction
has a window of its own over the *determinable* rows only (the row input's
``determinable``, as the golden's): a second ring of one bit (stepped) per such row,
with its row count and sum kept the same way.
"""

from amaranth.hdl import Module, Mux, Signal, Value
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.pose.params import PoseFlag, PoseSolverParams, solver_source
from hdl.pose.status_params import (DRIFTED_BIT, FRACTION_FMT, MEASUREMENTS_FMT,
                                    STATUS_SHIFT, StatusParams, TrackingStatus,
                                    status_source)

__all__ = ["StatusUnit", "default_status_unit"]

COUNTS = ("judged", "outliers", "confident")
BITS = ("stepped", "formed", "ill")

#: The window rules that compare a sum with a run-time fraction of a count: (the
#: setting's name in ``settings``, the operands — left side and count —, the test ``left > fraction·count`` or
#: ``<``). Judged one a clock through one multiplier: six in parallel took six DSP48.
RULES = (("lost_update_fraction", "update", "<"), ("lost_outlier_fraction", "outlier", ">"),
         ("degraded_update_fraction", "update", "<"),
         ("degraded_outlier_fraction", "outlier", ">"),
         ("degraded_ill_fraction", "ill", ">"), ("degraded_measurements", "measurements", "<"))


class StatusUnit(wiring.Component):
    """Annotates each pose record's flags with the tracking status.

    Parameters
    ----------
    params : StatusParams
    solver : PoseSolverParams
        The solver whose records come in (``slots`` must be ``params.slots``).

    Members
    -------
    i : In(stream.Signature(solver_source(solver).layout()))
        The solver's pose records (flags: ``PoseFlag`` bits).
    row : In(stream.Signature(params.row_layout()))
        The counts of each record's row and whether it was determinable, one transfer
        per record, in order; taken together with the record.
    o : Out(stream.Signature(status_source(solver).layout()))
        The same records, flags bits 5:4 the status code
        (:class:`golden.tracking_status.TrackingStatus`), bit 6 drifted since a loss
        (a loss after the unit first saw a TRACKING row).
    settings : In(params.settings_layout()), reset to ``params.raw_settings()``
        Registers, raw: ``window`` (rows, integer), the fractions in ``FRACTION_FMT``
        UQ(1,16), ``degraded_measurements`` in ``MEASUREMENTS_FMT`` UQ(8,4); a change
        of ``window`` restarts the history at the next record.
    clear : In(1)
        A one-clock strobe: before the next record, forget the history, the loss latch,
        drifted and the counters.
    state : Out(params.state_layout())

    Latency: ``o.valid`` rises :attr:`latency` clocks after the clock of a record's
    transfer (take, sum, judge the rules, decide).
    Throughput: one record per :attr:`interval` clocks when ``o`` is ready (a pose
    record comes once per camera row, hundreds of clocks apart). Backpressure: ``o``
    not ready holds the record and stops taking new ones. Reset: empty history, not
    lost, not drifted, counters 0.
    """

    #: take, sum, the rules' products and comparisons (:data:`RULES`), decide
    latency = 3 + len(RULES) + 1
    interval = latency + 1

    def __init__(self, params, solver):
        if not isinstance(params, StatusParams):
            raise TypeError(f"params must be a StatusParams, not {params!r}")
        if not isinstance(solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {solver!r}")
        if solver.slots != params.slots:
            raise ValueError(f"params.slots must be the solver's slots ({solver.slots}), "
                             f"not {params.slots}")
        self.params, self.solver = params, solver
        self.entry_layout = data.StructLayout({**{name: 1 for name in BITS},
                                               **{name: params.row_count_bits
                                                  for name in COUNTS}})
        #: The history (one entry per row); tests may read it.
        self.history = Memory(shape=self.entry_layout, depth=params.max_window, init=[])
        #: Stepped, of each determinable row: the update fraction's own window.
        self.updates = Memory(shape=1, depth=params.max_window, init=[])
        super().__init__({
            "i": In(stream.Signature(solver_source(solver).layout())),
            "row": In(stream.Signature(params.row_layout())),
            "o": Out(stream.Signature(status_source(solver).layout())),
            "settings": In(params.settings_layout(), init=params.raw_settings()),
            "clear": In(1),
            "state": Out(params.state_layout()),
        })

    def elaborate(self, platform):
        p, cfg, state = self.params, self.settings, self.state
        m = Module()
        m.submodules.history = history = self.history
        m.submodules.updates = updates = self.updates
        read, write = history.read_port(), history.write_port()
        u_read, u_write = updates.read_port(), updates.write_port()

        record = Signal(self.i.payload.shape())
        entry, old = Signal(self.entry_layout), read.data
        position = Signal(p.address_bits)
        rows, window, applied = (Signal(p.window_bits) for _ in range(3))
        sums = {name: Signal(p.window_bits) for name in BITS}
        sums.update({name: Signal(p.sum_bits) for name in COUNTS})
        # the determinable rows' window: its position, rows and stepped rows
        determinable, u_position = Signal(), Signal(p.address_bits)
        u_rows, updated = Signal(p.window_bits), Signal(p.window_bits)
        restart, pending_clear = Signal(), Signal()
        # emptied at a clear and at a loss, as the history
        empty_windows = [rows.eq(0), u_rows.eq(0), updated.eq(0),
                         *(s.eq(0) for s in sums.values())]

        # the window rules' comparisons, one a clock through one multiplier (_judge)
        rule = Signal(range(len(RULES) + 1))
        verdicts = Signal(len(RULES))
        asked = cfg.window
        effective = Mux(asked == 0, 1, Mux(asked > p.max_window, p.max_window, asked))
        with m.If(self.clear):
            m.d.sync += pending_clear.eq(1)

        flags = self.i.payload.flags
        incoming = {"stepped": flags == 0, "formed": ~(flags & int(PoseFlag.EMPTY)).any(),
                    "ill": (flags & int(PoseFlag.ILL)).any(),
                    "judged": self.row.payload.judged, "outliers": self.row.payload.outliers,
                    "confident": Mux(flags == 0, self.row.payload.confident, 0)}
        m.d.comb += [read.addr.eq(position - effective),
                     u_read.addr.eq(u_position - effective)]

        # the record waits in `record` until `o` takes it: one copy of its ~600 bits
        for name in record.shape().members:
            if name != "flags":
                m.d.comb += getattr(self.o.payload, name).eq(getattr(record, name))
        with m.FSM():
            with m.State("TAKE"):
                with m.If(pending_clear):
                    m.d.sync += [pending_clear.eq(0), applied.eq(0), state.eq(0),
                                 *empty_windows]
                with m.Else():
                    both = self.i.valid & self.row.valid
                    m.d.comb += [self.i.ready.eq(both), self.row.ready.eq(both)]
                    with m.If(both):
                        m.d.sync += [record.eq(self.i.payload), window.eq(effective),
                                     applied.eq(effective), restart.eq(effective != applied),
                                     state.window_error.eq(effective != asked),
                                     determinable.eq(self.row.payload.determinable),
                                     *(getattr(entry, k).eq(v) for k, v in incoming.items())]
                        m.next = "SUM"
            with m.State("SUM"):
                # the window before this row: emptied by a restart; full: drop the oldest
                before = Mux(restart, 0, rows)
                full = before == window
                for name, total in sums.items():
                    kept = Mux(restart, 0, total)
                    m.d.sync += total.eq(kept + getattr(entry, name)
                                         - Mux(full, getattr(old, name), 0))
                m.d.comb += [write.en.eq(1), write.addr.eq(position), write.data.eq(entry)]
                m.d.sync += [rows.eq(Mux(full, before, before + 1)), position.eq(position + 1)]
                # the determinable rows' window, the same way
                u_before = Mux(restart, 0, u_rows)
                u_full = u_before == window
                with m.If(determinable):
                    m.d.comb += [u_write.en.eq(1), u_write.addr.eq(u_position),
                                 u_write.data.eq(entry.stepped)]
                    m.d.sync += [updated.eq(Mux(restart, 0, updated) + entry.stepped
                                            - Mux(u_full, u_read.data, 0)),
                                 u_rows.eq(Mux(u_full, u_before, u_before + 1)),
                                 u_position.eq(u_position + 1)]
                with m.Elif(restart):
                    m.d.sync += [updated.eq(0), u_rows.eq(0)]
                m.d.sync += rule.eq(0)
                m.next = "JUDGE"
            with m.State("JUDGE"):
                self._judge(m, rule, verdicts, sums, (u_rows, updated))
                with m.If(rule == len(RULES)):
                    m.next = "DECIDE"
            with m.State("DECIDE"):
                self._decide(m, record, verdicts, sums, rows, window, (u_rows, updated),
                             empty_windows)
                m.next = "OUT"
            with m.State("OUT"):
                with m.If(self.o.ready):
                    m.d.sync += self.o.valid.eq(0)
                    m.next = "TAKE"
        return m

    def _judge(self, m, rule, verdicts, sums, updates):
        """One clock of the JUDGE state: rule ``rule``'s product ``fraction × count``
        into a register with its left side, and the previous rule's comparison into
        ``verdicts`` (bit ``k``: rule ``k``'s test of :data:`RULES` holds). The window
        sums stand still meanwhile; ``len(RULES) + 1`` clocks in all."""
        cfg, b = self.settings, FRACTION_FMT.frac_bits
        u_rows, updated = updates
        operands = {
            "update": (updated << b, u_rows), "outlier": (sums["outliers"] << b, sums["judged"]),
            "ill": (sums["ill"] << b, sums["formed"]),
            "measurements": (sums["confident"] << MEASUREMENTS_FMT.frac_bits,
                             sums["stepped"]),
        }
        width = max(len(Value.cast(left)) for left, _ in operands.values())
        left = Signal(width)
        factor = Signal(max(len(getattr(cfg, name)) for name, _, _ in RULES))
        count = Signal(max(len(c) for _, c in operands.values()))
        product = Signal(len(factor) + len(count))
        above = Signal()                    # the rule tests left > product, else <
        judged = Signal(range(len(RULES)))  # the rule in the registers
        loaded = Signal()
        # the operands chosen first: a product per case would be six multipliers again
        with m.Switch(rule):
            for k, (name, operand, test) in enumerate(RULES):
                with m.Case(k):
                    value, of = operands[operand]
                    m.d.comb += [factor.eq(getattr(cfg, name)), count.eq(of)]
                    m.d.sync += [left.eq(value), above.eq(test == ">")]
        m.d.sync += product.eq(factor * count)
        m.d.sync += [judged.eq(rule), loaded.eq(rule != len(RULES)),
                     rule.eq(Mux(rule == len(RULES), 0, rule + 1))]
        with m.If(loaded):
            m.d.sync += verdicts.bit_select(judged, 1).eq(
                Mux(above, left > product, left < product))

    def _verdicts(self, verdicts, sums, rows, window, updates):
        """(lost, degraded) from the window sums and the rules' ``verdicts``, as the
        model's ``verdicts``; ``updates``: the determinable rows' window, (rows,
        stepped)."""
        cfg = self.settings
        u_rows, _ = updates
        v = {name: verdicts[k] for k, (name, _, _) in enumerate(RULES)}

        def few_updates(name):
            return Mux(u_rows == 0, getattr(cfg, name) != 0, v[name])

        lost = (((u_rows == window) & few_updates("lost_update_fraction"))
                | ((rows == window) & v["lost_outlier_fraction"]))
        few = Mux(sums["stepped"] == 0, cfg.degraded_measurements != 0,
                  v["degraded_measurements"])
        degraded = (few_updates("degraded_update_fraction") | v["degraded_outlier_fraction"]
                    | (sums["formed"] == 0) | v["degraded_ill_fraction"] | few)
        return lost, degraded

    def _decide(self, m, record, verdicts, sums, rows, window, updates, empty_windows):
        """The status of the row just summed, the latch, the counters and the output."""
        state = self.state
        lost, degraded = self._verdicts(verdicts, sums, rows, window, updates)
        full = rows == window
        status = Signal(2)
        with m.If(lost):
            m.d.comb += status.eq(TrackingStatus.LOST)
            with m.If(~state.lost):
                m.d.sync += [*empty_windows, state.losses.eq(state.losses + 1)]
            m.d.sync += state.lost.eq(1)
        with m.Elif(state.lost & (~full | degraded)):
            m.d.comb += status.eq(TrackingStatus.LOST)
        with m.Else():
            m.d.sync += state.lost.eq(0)
            m.d.comb += status.eq(Mux(degraded, TrackingStatus.DEGRADED,
                                      TrackingStatus.TRACKING))
        drifted = state.drifted | (state.acquired & (status == TrackingStatus.LOST))
        m.d.sync += [state.status.eq(status), state.drifted.eq(drifted),
                     state.lost_rows.eq(state.lost_rows + (status == TrackingStatus.LOST)),
                     state.degraded_rows.eq(state.degraded_rows
                                            + (status == TrackingStatus.DEGRADED)),
                     self.o.valid.eq(1)]
        with m.If(status == TrackingStatus.TRACKING):
            m.d.sync += state.acquired.eq(1)
        m.d.sync += self.o.payload.flags.eq(record.flags | (status << STATUS_SHIFT)
                                            | (drifted << DRIFTED_BIT))


def default_status_unit():
    """The status unit of the default top (:class:`hdl.top_params.TopParams`): the
    catalog's build, for Verilog and synthesis."""
    from hdl.pose.status_params import top_status_params
    from hdl.top_params import TopParams
    top = TopParams()
    return StatusUnit(top_status_params(top), top.solver)

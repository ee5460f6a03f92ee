"""The forecast's motion filter: Holt–Winters on the solver's steps with the scalar gain
or the information gain's moves (``motion_gain``), and the loop delay (:class:`emulator.pose.forecast.MotionFilter` and
:class:`golden.temporal_filter.DelayedForecast` in gateware, bit for bit).

One pose record per row slot updates the filter (a row without measurements is given a
record with a flag, as the model's ``take(slot, None)``); one query per row slot reads
the forecast ``Ŷ = L_j + k·B_j`` from the newest state ``j`` of a slot at most
``slot − 1 − loop_delay_rows``. Records and queries are paired in order: the ``n``-th
record belongs to the ``n``-th query's slot (a FIFO of the slots queried and not yet
updated). The filter keeps its newest ``loop_delay_rows + 1`` states, the model's
``deque``; ``k`` is one plus the number of rows queried since state ``j``.

Why the pairing: the solver's record does not know the row slot (the row period count
the delay is measured in), the row sequencer that queries does. A query waits while a
record it needs (of a slot at most ``slot − 1 − loop_delay_rows``) is outstanding, so a
solver later than the loop delay stalls the rows instead of forecasting from old states.
"""

from amaranth.hdl import Array, Module, Mux, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import SQ, UQ, Overflow, Rounding, hdl_mul, hdl_resize
from hdl.pose.forecast_params import ForecastParams
from hdl.pose.params import solver_source

__all__ = ["MotionFilter", "DEFAULT_SLOT_BITS", "gain_layout", "track_layout"]

#: Width of the row slot counter (wraps; slots are compared modulo ``2**slot_bits``).
DEFAULT_SLOT_BITS = 16


def outside(value, fmt):
    """Whether the raw ``value`` (same fraction bits as ``fmt``) is beyond ``fmt``'s range."""
    return (value < fmt.min_raw) | (value > fmt.max_raw)


def gain_layout(params):
    """The information gain's move of one record (``motion_gain="information"``): ``move``
    ``d`` per axis (the solver's ``step_fmt``) and ``ok`` (the gain solve raised no flag;
    0: the filter moves by ``α``)."""
    return data.StructLayout({"move": data.ArrayLayout(params.solver.step_fmt.shape(), 6),
                              "ok": 1})


def track_layout(params, slot_bits=DEFAULT_SLOT_BITS):
    """One updated row for the motion track (:class:`hdl.pose.motion_track.MotionTrack`):
    its ``slot``, the filter's ``level`` and ``trend`` before the row's update, the pull's
    ``target`` (the level after it; all ``motion_fmt``) and ``solved`` (0: the row gave
    the filter no step, no pull)."""
    motion = data.ArrayLayout(params.motion_fmt.shape(), 6)
    return data.StructLayout({"slot": unsigned(slot_bits), "level": motion, "trend": motion,
                              "target": motion, "solved": 1})


class MotionFilter(wiring.Component):
    """Holt–Winters on the solved steps (scalar or information gain), with the loop delay.

    Parameters
    ----------
    params : ForecastParams
    slot_bits : int
        Width of a row slot (the slots of rows in flight must differ by less than
        ``2**(slot_bits − 1)``).
    track : bool
        Hand every update to a motion track (the ``track`` stream).

    Members
    -------
    records : In(stream.Signature(PoseSource.layout()))
        The solver's pose records (``step``, ``flags``; the other fields are not read),
        one per queried row slot, in order; a flagged record leaves ``L' = L + B``.
    gains : In(stream.Signature(gain_layout(params))), with ``motion_gain="information"``
        One per record, taken with it: a solved record's level moves by ``move`` when
        ``ok`` (:func:`emulator.pose.information_gain.gain_step`), else by ``α``.
    predicted : Out(ArrayLayout(motion_fmt, 6)), with ``motion_gain="information"``
        ``p = L + B`` of the newest state, saturated (the model's
        :meth:`~emulator.pose.forecast.MotionFilter.predicted`): what the next record's
        gain is solved against; settled :attr:`update_clocks` clocks after a record is
        taken.
    query : In(stream.Signature(unsigned(slot_bits)))
        The row slot whose forecast is wanted, once per row slot, in increasing order.
    motion : Out(ArrayLayout(motion_fmt, 6))
        The forecast ``Ŷ`` of the last query, valid from :attr:`query_latency` clocks
        after its transfer (``motion_valid`` strobes then) until the next query's
        forecast overwrites it, an axis a clock.
    motion_valid : Out(1)
    alpha, beta : In(unsigned(gain_fmt.width))
        Raw gains (``gain_fmt``); reset values ``params.alpha_raw``/``beta_raw``. A
        change applies from the next record.
    initial : In(ArrayLayout(motion_fmt, 6))
        Level loaded by ``restart``.
    restart : In(1)
        Level ← ``initial``, trend 0, no record outstanding, no state but this one (the
        model's construction); a forecast in progress still completes, from the state
        it selected. Reset does the same with ``initial`` = 0.
    track : Out(stream.Signature(track_layout(params, slot_bits))), with ``track=True``
        Every update, offered once its state is the newest: the row's slot, the state
        before it, the level after it and whether it was solved. The next record waits
        until it is taken.
    busy : Out(1)
        A record's update is in progress.
    drained : Out(1)
        Every query's record is taken (none outstanding), its update done and handed
        to the track, and no forecast is in progress: a ``restart`` now drops no record
        and no update.
    saturated : Out(1)
        Strobe: an update in which some value saturated into ``motion_fmt`` (with its
        state's push), or a forecast (with its ``motion_valid``).

    Timing: a record takes :attr:`update_clocks` clocks (one multiplier, shared by the
    six axes and both gains); queries wait while an update runs. A query's forecast
    takes :attr:`query_latency` clocks (a second multiplier, shared by the six axes);
    the next query waits for it, records need not.
    """

    #: Clocks per axis: p and d; α·d; L' and e; β·e; B'.
    PHASES = 5
    #: Clocks from a query's transfer to ``motion_valid`` and to the next query: state
    #: selection, then a clock per axis for k·B, and L + k·B of the last axis.
    query_latency = 1 + 6 + 1

    def __init__(self, params, *, slot_bits=DEFAULT_SLOT_BITS, track=False):
        if not isinstance(params, ForecastParams):
            raise TypeError(f"params must be a ForecastParams, not {params!r}")
        if not isinstance(slot_bits, int) or isinstance(slot_bits, bool) or not 2 <= slot_bits <= 32:
            raise ValueError(f"slot_bits must be an integer from 2 to 32, not {slot_bits!r}")
        if not isinstance(track, bool):
            raise TypeError(f"track must be a bool, not {track!r}")
        self.params, self.slot_bits = params, slot_bits
        self.depth = params.loop_delay_rows + 1
        self.source = solver_source(params.solver)
        motion = data.ArrayLayout(params.motion_fmt.shape(), 6)
        gain = unsigned(params.gain_fmt.width)
        gains = {"gains": In(stream.Signature(gain_layout(params))),
                 "predicted": Out(motion)} if params.motion_gain == "information" else {}
        tracked = {"track": Out(stream.Signature(track_layout(params, slot_bits)))} \
            if track else {}
        super().__init__({
            "records": In(stream.Signature(self.source.layout())),
            **gains, **tracked,
            "query": In(stream.Signature(unsigned(slot_bits))),
            "motion": Out(motion),
            "motion_valid": Out(1),
            "alpha": In(gain, init=params.alpha_raw),
            "beta": In(gain, init=params.beta_raw),
            "initial": In(motion),
            "restart": In(1),
            "busy": Out(1),
            "saturated": Out(1),
            "drained": Out(1),
        })

    @property
    def update_clocks(self):
        """Clocks from a record's transfer until the next record or query is taken."""
        return 6 * self.PHASES + 2

    def elaborate(self, platform):
        p = self.params
        m = Module()
        fmt, depth, bits = p.motion_fmt, self.depth, self.slot_bits
        count_bits = (depth + 1).bit_length() + 1     # k ≤ depth, compared modulo 2**bits

        # --- states, newest last: kind 0 empty, 1 the initial state (slot −∞), 2 a slot
        state = data.StructLayout({"kind": 2, "slot": bits, "count": count_bits,
                                   "level": data.ArrayLayout(fmt.shape(), 6),
                                   "trend": data.ArrayLayout(fmt.shape(), 6)})
        states = [Signal(state, name=f"state{k}", init={"kind": int(k == depth - 1)})
                  for k in range(depth)]
        newest = states[-1]
        staged = Signal(state)                     # the state being computed
        updates = Signal(count_bits)               # records taken (the model's count)
        queries = Signal(count_bits)               # queries taken

        # --- slots queried and not yet updated, oldest first
        pending = [Signal(bits, name=f"pending{k}") for k in range(depth)]
        level = Signal(range(depth + 1))
        head_is_old = Signal()                     # pending[0] ≤ query slot − 1 − delay
        limit = Signal(bits)
        m.d.comb += [limit.eq(self.query.payload - 1 - p.loop_delay_rows),
                     head_is_old.eq((limit - pending[0])[bits - 1] == 0)]

        # --- acceptance: restart first, then a record, then a query
        running, push = Signal(), Signal()    # an update runs; its state is pushed
        idle = Signal()
        forecasting = Signal()                # a query's axes are being computed
        take_record, take_query = Signal(), Signal()
        information = p.motion_gain == "information"
        tracked = "track" in self.signature.members
        handed = ~self.track.valid if tracked else 1       # the last update is with the track
        record_ready = ~self.restart & idle & (level != 0) & handed
        m.d.comb += [
            idle.eq(~running & ~push),
            self.records.ready.eq(record_ready & self.gains.valid if information
                                  else record_ready),
            take_record.eq(self.records.valid & self.records.ready),
            self.query.ready.eq(~self.restart & idle & ~take_record & ~forecasting
                                & (level != depth) & ((level == 0) | ~head_is_old)),
            take_query.eq(self.query.valid & self.query.ready),
            self.busy.eq(~idle),
            self.drained.eq((level == 0) & idle & handed & ~forecasting),
        ]
        if information:     # a gain waits for its record, and goes with it
            m.d.comb += self.gains.ready.eq(record_ready & self.records.valid)
        with m.If(take_query):
            m.d.sync += [Array(pending)[level].eq(self.query.payload), level.eq(level + 1),
                         queries.eq(queries + 1)]
        with m.If(take_record):
            m.d.sync += [pending[k].eq(pending[k + 1]) for k in range(depth - 1)]
            m.d.sync += level.eq(level - 1)

        # --- query: the newest state of a slot ≤ limit, then L + k·B on one multiplier, an
        # axis a clock: the selected trends shift down an axis per product (sel_trend[0] is
        # multiplied), the levels a clock later with the registered product (sel_level[0]
        # is added); the next query waits for the six, a record need not
        chosen = states[0].as_value()
        for s in states[1:]:
            fits = (s.kind == 1) | ((s.kind == 2) & ((limit - s.slot)[bits - 1] == 0))
            chosen = Mux(fits, s.as_value(), chosen)
        chosen = state(chosen)
        sel_level = Signal(data.ArrayLayout(fmt.shape(), 6))
        sel_trend = Signal(data.ArrayLayout(fmt.shape(), 6))
        ahead = Signal(count_bits)
        multiplying, adding = Signal(), Signal()
        factor_axis, sum_axis = Signal(range(6)), Signal(range(6))
        query_clamped = Signal()                   # some axis of this forecast saturated
        scaled, scaled_fmt = hdl_mul(sel_trend[0], fmt, ahead, UQ(count_bits, 0))
        scaled_reg = Signal(scaled_fmt.shape())
        total_fmt = SQ(scaled_fmt.int_bits + 1, fmt.frac_bits)
        total = Signal(total_fmt.shape(), name="forecast")
        m.d.comb += [forecasting.eq(multiplying | adding), total.eq(sel_level[0] + scaled_reg)]
        m.d.sync += [scaled_reg.eq(scaled), adding.eq(multiplying), sum_axis.eq(factor_axis),
                     self.motion_valid.eq(adding & (sum_axis == 5))]
        with m.If(take_query):
            m.d.sync += [sel_level.eq(chosen.level), sel_trend.eq(chosen.trend),
                         ahead.eq(queries + 1 - chosen.count), multiplying.eq(1),
                         factor_axis.eq(0), query_clamped.eq(0)]
        with m.If(multiplying):
            m.d.sync += [sel_trend[i].eq(sel_trend[i + 1]) for i in range(5)]
            m.d.sync += factor_axis.eq(factor_axis + 1)
            with m.If(factor_axis == 5):
                m.d.sync += multiplying.eq(0)
        with m.If(adding):                         # L + k·B saturated into motion_fmt
            m.d.sync += [sel_level[i].eq(sel_level[i + 1]) for i in range(5)]
            m.d.sync += [self.motion[sum_axis].eq(hdl_resize(total, total_fmt, fmt,
                                                             Rounding.FLOOR, Overflow.SATURATE)),
                         query_clamped.eq(query_clamped | outside(total, fmt))]

        # --- update: axis by axis, one multiplier for both gains
        axis = Signal(range(6))
        phase = Signal(range(self.PHASES))
        solved = Signal()
        step = Signal(data.ArrayLayout(self.source.step_fmt.shape(), 6))
        gain = Signal(p.gain_fmt.shape())
        operand = Signal(SQ(fmt.int_bits + 2, fmt.frac_bits).shape())
        product, product_fmt = hdl_mul(gain, p.gain_fmt, operand,
                                       SQ(fmt.int_bits + 2, fmt.frac_bits))
        product_reg = Signal(product_fmt.shape())
        # |gain · (difference of two motion_fmt values)| < 2: one integer bit more
        gained = hdl_resize(product_reg, product_fmt, SQ(fmt.int_bits + 1, fmt.frac_bits),
                            Rounding.HALF_EVEN, Overflow.ERROR)
        predicted = Signal(fmt.shape())
        new_level = Signal(fmt.shape())

        if information:     # the level moves by the gain's move when it stands
            move = Signal(data.ArrayLayout(self.source.step_fmt.shape(), 6))
            use_move = Signal()

            def increment(gained):
                moved = hdl_resize(move[axis], self.source.step_fmt, fmt, Rounding.HALF_EVEN,
                                   Overflow.ERROR)
                return Mux(use_move, moved, gained)
        else:
            def increment(gained):
                return gained

        if information:
            for i in range(6):
                total = newest.level[i] + newest.trend[i]
                m.d.comb += self.predicted[i].eq(
                    hdl_resize(total, SQ(fmt.int_bits + 1, fmt.frac_bits), fmt,
                               Rounding.FLOOR, Overflow.SATURATE))

        level_i, trend_i = newest.level[axis], newest.trend[axis]
        y = hdl_resize(step[axis], self.source.step_fmt, fmt, Rounding.HALF_EVEN,
                       Overflow.ERROR)
        update_clamped = Signal()                  # some value of this update saturated

        def clamp(value, extra):
            """``value`` (``extra`` integer bits wider than motion_fmt) saturated into it,
            noted in ``update_clamped``."""
            m.d.sync += update_clamped.eq(update_clamped | outside(value, fmt))
            return hdl_resize(value, SQ(fmt.int_bits + extra, fmt.frac_bits), fmt,
                              Rounding.FLOOR, Overflow.SATURATE)

        m.d.sync += product_reg.eq(product)
        m.d.sync += push.eq(0)
        with m.If(take_record):
            m.d.sync += [running.eq(1), axis.eq(0), phase.eq(0),
                         solved.eq(self.records.payload.flags == 0),
                         step.eq(self.records.payload.step), updates.eq(updates + 1),
                         update_clamped.eq(0),
                         staged.kind.eq(2), staged.slot.eq(pending[0]),
                         staged.count.eq(updates + 1)]
            if information:
                m.d.sync += [move.eq(self.gains.payload.move),
                             use_move.eq(self.gains.payload.ok & (self.records.payload.flags == 0))]
        with m.Elif(running & ~push):
            m.d.sync += phase.eq(Mux(phase == self.PHASES - 1, 0, phase + 1))
            with m.Switch(phase):
                with m.Case(0):                    # p = L + B, d = y − p (0 if unsolved)
                    p_value = clamp(level_i + trend_i, 1)
                    m.d.sync += [predicted.eq(p_value), gain.eq(self.alpha),
                                 operand.eq(Mux(solved, y - p_value, 0))]
                with m.Case(2):                    # L' = p + α d (or + move), e = L' − p
                    level_new = clamp(predicted + increment(gained), 2)
                    m.d.sync += [new_level.eq(level_new), gain.eq(self.beta),
                                 operand.eq(level_new - predicted)]
                with m.Case(4):                    # B' = B + β e
                    m.d.sync += [staged.level[axis].eq(new_level),
                                 staged.trend[axis].eq(clamp(trend_i + gained, 2)),
                                 axis.eq(axis + 1)]
                    with m.If(axis == 5):
                        m.d.sync += push.eq(1)
        # one strobe per update and per forecast in which some value saturated (they
        # never coincide: a query waits for the update before it, and the update after it
        # pushes update_clocks − 1 clocks after its record, later than the forecast)
        m.d.comb += self.saturated.eq((push & update_clamped)
                                      | (self.motion_valid & query_clamped))

        # the staged state becomes the newest one clock after its last axis
        with m.If(push):
            m.d.sync += running.eq(0)
            m.d.sync += [states[k].eq(states[k + 1]) for k in range(depth - 1)]
            m.d.sync += states[-1].eq(staged)
        if tracked:
            out = self.track
            with m.If(out.valid & out.ready):
                m.d.sync += out.valid.eq(0)
            with m.If(push):
                m.d.sync += [out.valid.eq(1), out.payload.slot.eq(staged.slot),
                             out.payload.level.eq(newest.level),
                             out.payload.trend.eq(newest.trend),
                             out.payload.target.eq(staged.level), out.payload.solved.eq(solved)]

        with m.If(self.restart):
            m.d.sync += [level.eq(0), running.eq(0), push.eq(0), updates.eq(0),
                         queries.eq(0)]
            if tracked:
                m.d.sync += self.track.valid.eq(0)
            m.d.sync += [states[k].kind.eq(0) for k in range(depth - 1)]
            m.d.sync += [newest.kind.eq(1), newest.count.eq(0), newest.level.eq(self.initial),
                         newest.trend.eq(0)]
        return m

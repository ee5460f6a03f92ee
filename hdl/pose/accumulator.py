"""The pose solver's accumulator: measurements in, the weighted normal equations out.

Per measurement it reads the row's nine coefficients, forms the design row
``a = [w a_T, a_R + w a_C]`` (rounded to ``a_fmt``), the weighted row ``c·a`` (exact),
and adds the 27 products ``c a_i a_j`` (i ≤ j) and ``c a_i s`` into exact accumulators.
When a row's last measurement is in, it computes the Jacobi exponents of the diagonal
and holds the sums until the engine has read them (``release``). A row whose last
measurement comes with ``gated`` (the consistency stage's verdict that the row failed its
gates, ``hdl/measurement/consistency.py``) is flagged empty: the model sets every
confidence of such a row to 0, which leaves every diagonal entry 0, below
``min_diagonal`` (at least one raw unit), so the model flags it EMPTY too.
"""

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import Overflow, Rounding, hdl_add, hdl_mul, hdl_resize, mul_format
from hdl.pose.params import PoseSolverParams

__all__ = ["measurement_layout", "PAIRS", "PoseAccumulator", "exponent_bits", "leading_one"]

#: The 27 accumulated products: (i, j) with i ≤ j < 6 for N (row by row), then (i, 6)
#: for the right-hand side (6 stands for the shift).
PAIRS = tuple((i, j) for i in range(6) for j in range(i, 6)) + tuple((i, 6) for i in range(6))


def measurement_layout(params):
    """One shift measurement; a row is the transfers up to the one with ``last``.

    Fields
    ------
    slot : unsigned(slot_bits)
        Camera/segment slot (selects the coefficients with ``row``).
    row : unsigned(row_bits)
        Row index in the frame; ``row`` and ``time`` of the ``last`` transfer label the
        pose record.
    time : unsigned(time_bits)
        Time stamp of the row.
    shift : shift_fmt
        Shift along the row, pixels.
    cue : cue_fmt
        Depth cue (disparity in pixels or scaled inverse depth, see the table).
    conf : conf_fmt
        Confidence weight; zero contributes nothing.
    last : 1
        Closes the row.
    """
    return data.StructLayout({
        "slot": params.slot_bits, "row": params.row_bits, "time": params.time_bits,
        "shift": params.shift_fmt.shape(), "cue": params.cue_fmt.shape(),
        "conf": params.conf_fmt.shape(), "last": 1,
    })


def exponent_bits(params):
    """Width of a signed Jacobi exponent."""
    low, high = params.exponent_range
    return max(abs(low), abs(high)).bit_length() + 1


def leading_one(value, width):
    """Index of the highest set bit of the low ``width`` bits of ``value`` (0 when none
    is set: callers treat a zero value apart): a balanced tree, ``log2(width)`` mux
    levels deep where a priority chain would be ``width`` deep. The bit length of a
    non-zero value is the index plus one."""
    size = 1 << (width - 1).bit_length()
    bits = Cat(value[:width], Const(0, size - width)) if size > width else value[:width]

    def tree(low, count):
        """(any bit set, index of the highest set bit) of bits[low:low + count]."""
        if count == 1:
            return bits[low], Const(0, 0)
        half = count // 2
        any_low, index_low = tree(low, half)
        any_high, index_high = tree(low + half, half)
        return any_low | any_high, Mux(any_high, Cat(index_high, 1), Cat(index_low, 0))

    return tree(0, size)[1]


class PoseAccumulator(wiring.Component):
    """Weighted normal equations of each row of measurements.

    Parameters
    ----------
    params : PoseSolverParams

    Members
    -------
    i : In(stream.Signature(measurement_layout(params)))
        Measurements. One transfer per ``27 / lanes`` clocks at most; held off while a
        finished row waits for the engine.
    gated : In(1)
        Read with the transfer of a row's last measurement: the row is flagged empty
        whatever its sums (no step).
    coef_slot, coef_row : Out
        Slot and row of the transfer being accepted, to the coefficient store
        (:class:`hdl.pose.coef_store.CoefficientStore`).
    coef_data : In(ArrayLayout(signed(coef_width), 9))
        The store's coefficients of that slot and row, ``params.coef_latency`` clocks
        later.
    done : Out(1)
        A row's sums, exponents and flags are valid (until ``release``).
    release : In(1)
        The engine has read the row; the next row may accumulate.
    read_index : In(range(27))
        Entry of :data:`PAIRS` to put on ``read_data``.
    read_data : Out(signed)
        Raw sum of that entry: ``normal_fmt`` (the right-hand side entries are the same
        raw format, aligned to the same fraction bits).
    exponents : Out(ArrayLayout(signed(exponent_bits), 6))
        Jacobi exponents ``e_i`` (clamped to the exponent range).
    empty, overrun : Out(1)
        A diagonal entry is below ``min_diagonal``; the row had more than ``slots``
        measurements.
    row, time : Out
        Of the row's last measurement.

    Latency: the row is ``done`` :attr:`tail` clocks after its last transfer.
    """

    def __init__(self, params):
        if not isinstance(params, PoseSolverParams):
            raise TypeError(f"params must be a PoseSolverParams, not {params!r}")
        self.params = params
        self.period = -(-len(PAIRS) // params.lanes)
        super().__init__({
            "i": In(stream.Signature(measurement_layout(params))),
            "gated": In(1),
            "coef_slot": Out(params.slot_bits),
            "coef_row": Out(params.row_bits),
            "coef_data": In(data.ArrayLayout(signed(params.coef_width), 9)),
            "done": Out(1),
            "release": In(1),
            "read_index": In(range(len(PAIRS))),
            "read_data": Out(params.normal_fmt.shape()),
            "exponents": Out(data.ArrayLayout(signed(exponent_bits(params)), 6)),
            "empty": Out(1),
            "overrun": Out(1),
            "row": Out(params.row_bits),
            "time": Out(params.time_bits),
        })

    @property
    def front(self):
        """Clocks from accepting a measurement to its first product reaching the sums:
        the coefficient store's latency, coef·cue, rounding, c·a, operand select,
        product."""
        return self.params.coef_latency + 5

    @property
    def tail(self):
        """Clocks from a row's last transfer to ``done``: the front, the products, the
        diagonal's bit lengths and the exponents."""
        return self.front + self.period + 2

    def elaborate(self, platform):
        p = self.params
        m = Module()
        lanes, period = p.lanes, self.period
        a_fmt, conf_fmt = p.a_fmt, p.conf_fmt

        # --- acceptance: one measurement per period, none while a row awaits release
        spacing = Signal(range(period + 1))
        waiting = Signal()          # a `last` was accepted and not yet released
        first_of_row = Signal(init=1)
        count = Signal(range(p.slots + 2))
        take = Signal()
        m.d.comb += [self.i.ready.eq((spacing == 0) & ~waiting), take.eq(self.i.valid & self.i.ready)]
        with m.If(take):
            m.d.sync += spacing.eq(period - 1)
        with m.Elif(spacing != 0):
            m.d.sync += spacing.eq(spacing - 1)
        m.d.comb += [self.coef_slot.eq(self.i.payload.slot), self.coef_row.eq(self.i.payload.row)]

        count_next = Mux(first_of_row, 1, Mux(count > p.slots, count, count + 1))
        gated = Signal()            # the row in `waiting` was gated
        with m.If(take):
            m.d.sync += [count.eq(count_next), first_of_row.eq(self.i.payload.last)]
            with m.If(self.i.payload.last):
                m.d.sync += [waiting.eq(1), gated.eq(self.gated), self.row.eq(self.i.payload.row),
                             self.time.eq(self.i.payload.time),
                             self.overrun.eq(count_next > p.slots)]
        with m.If(self.release):
            m.d.sync += [waiting.eq(0), self.done.eq(0)]

        # --- front: stage 1 (coefficients arrive, `coef_latency` clocks after the
        # transfer: the measurement waits alongside), 2 (coef·cue), 3 (a), 4 (c·a); the
        # data of stages 2-4 load only with a measurement, so they hold while the back works.
        stage = data.StructLayout({"valid": 1, "first": 1, "last": 1,
                                   "shift": p.shift_fmt.shape(), "conf": conf_fmt.shape()})
        s2, s3, s4 = (Signal(stage, name=f"s{k}") for k in range(2, 5))
        waiting_coef = data.StructLayout({"stage": stage, "cue": p.cue_fmt.shape()})
        s1 = Signal(waiting_coef)
        m.d.comb += [s1.stage.valid.eq(take), s1.stage.first.eq(first_of_row),
                     s1.stage.last.eq(self.i.payload.last), s1.stage.shift.eq(self.i.payload.shift),
                     s1.stage.conf.eq(self.i.payload.conf), s1.cue.eq(self.i.payload.cue)]
        for k in range(p.coef_latency):
            s1, entered = Signal(waiting_coef, name=f"s1_{k}"), s1
            m.d.sync += s1.eq(entered)
        s1, cue1 = s1.stage, s1.cue
        m.d.sync += [s2.valid.eq(s1.valid), s3.valid.eq(s2.valid), s4.valid.eq(s3.valid)]
        fmts = [p.coef_t_fmt] * 3 + [p.coef_c_fmt] * 3
        products = []
        for k in range(6):
            value, fmt = hdl_mul(self.coef_data[k], fmts[k], cue1, p.cue_fmt)
            products.append((Signal(fmt.shape(), name=f"coef_cue{k}"), fmt))
        rot = [Signal(p.coef_r_fmt.shape(), name=f"coef_r{k}") for k in range(3)]
        with m.If(s1.valid):
            m.d.sync += [products[k][0].eq(hdl_mul(self.coef_data[k], fmts[k], cue1,
                                                   p.cue_fmt)[0]) for k in range(6)]
            m.d.sync += [rot[k].eq(self.coef_data[6 + k]) for k in range(3)]
            m.d.sync += [s2.first.eq(s1.first), s2.last.eq(s1.last), s2.shift.eq(s1.shift),
                         s2.conf.eq(s1.conf)]

        a = [Signal(a_fmt.shape(), name=f"a{k}") for k in range(6)]
        with m.If(s2.valid):
            for k in range(3):
                m.d.sync += a[k].eq(hdl_resize(*products[k], a_fmt, Rounding.HALF_EVEN,
                                               Overflow.SATURATE))
                total, fmt = hdl_add(rot[k], p.coef_r_fmt, *products[3 + k])
                m.d.sync += a[3 + k].eq(hdl_resize(total, fmt, a_fmt, Rounding.HALF_EVEN,
                                                   Overflow.SATURATE))
            m.d.sync += [s3.first.eq(s2.first), s3.last.eq(s2.last), s3.shift.eq(s2.shift),
                         s3.conf.eq(s2.conf)]

        weighted = [Signal(p.weighted_fmt.shape(), name=f"ca{k}") for k in range(6)]
        x = [Signal(a_fmt.shape(), name=f"x{k}") for k in range(7)]
        with m.If(s3.valid):
            m.d.sync += [weighted[k].eq(hdl_mul(s3.conf, conf_fmt, a[k], a_fmt)[0])
                         for k in range(6)]
            m.d.sync += [x[k].eq(a[k]) for k in range(6)]
            m.d.sync += x[6].eq(hdl_resize(s3.shift, p.shift_fmt, a_fmt, Rounding.FLOOR,
                                           Overflow.ERROR))
            m.d.sync += [s4.first.eq(s3.first), s4.last.eq(s3.last)]

        # --- back: `period` clocks per measurement, the first in s4's own clock (so that
        # the next measurement's operands replace these only after the last product);
        # lane l forms the products of pairs l, l + lanes, ... in turn.
        step = Signal(range(period + 1))
        busy, row_first, row_last = Signal(), Signal(), Signal()
        run = s4.valid | busy
        current = Mux(s4.valid, 0, step)
        first_now = Mux(s4.valid, s4.first, row_first)
        last_now = Mux(s4.valid, s4.last, row_last)
        with m.If(s4.valid):
            m.d.sync += [busy.eq(period > 1), step.eq(1), row_first.eq(s4.first),
                         row_last.eq(s4.last)]
        with m.Elif(busy):
            m.d.sync += step.eq(step + 1)
            with m.If(step == period - 1):
                m.d.sync += busy.eq(0)

        acc_fmt = p.normal_fmt
        product_fmt = mul_format(p.weighted_fmt, a_fmt)
        b_valid, b_first, b_end = Signal(), Signal(), Signal()
        m.d.sync += [b_valid.eq(run), b_first.eq(first_now),
                     b_end.eq(run & last_now & (current == period - 1))]
        c_valid, c_first, c_end = Signal(), Signal(), Signal()
        m.d.sync += [c_valid.eq(b_valid), c_first.eq(b_first), c_end.eq(b_end)]
        rings = []
        for lane in range(lanes):
            pairs = [PAIRS[k] if k < len(PAIRS) else None
                     for k in range(lane, lanes * period, lanes)]
            left = Signal(p.weighted_fmt.shape(), name=f"lane{lane}_ca")
            right = Signal(a_fmt.shape(), name=f"lane{lane}_x")
            with m.Switch(current):
                for c, pair in enumerate(pairs):
                    with m.Case(c):
                        if pair is None:
                            m.d.sync += [left.eq(0), right.eq(0)]
                        else:
                            m.d.sync += [left.eq(weighted[pair[0]]), right.eq(x[pair[1]])]
            product = Signal(product_fmt.shape(), name=f"lane{lane}_product")
            m.d.sync += product.eq(hdl_mul(left, p.weighted_fmt, right, a_fmt)[0])
            ring = [Signal(acc_fmt.shape(), name=f"lane{lane}_sum{k}") for k in range(period)]
            head = Mux(c_first, 0, ring[0])
            total, total_fmt = hdl_add(head, acc_fmt, product, product_fmt)
            with m.If(c_valid):
                m.d.sync += [ring[k].eq(ring[k + 1]) for k in range(period - 1)]
                m.d.sync += ring[-1].eq(hdl_resize(total, total_fmt, acc_fmt, Rounding.FLOOR,
                                                   Overflow.WRAP))
            rings.append(ring)

        entries = Array(rings[k % lanes][k // lanes] for k in range(len(PAIRS)))
        m.d.comb += self.read_data.eq(entries[self.read_index])

        # --- row end: bit lengths of the diagonal (one clock), then the exponents and the
        # EMPTY check (the next)
        finished, lengths_ready = Signal(), Signal()
        m.d.sync += [finished.eq(c_end), lengths_ready.eq(finished)]
        low, high = p.exponent_range
        empty = Const(0)
        for i in range(6):
            k = PAIRS.index((i, i))
            diag = rings[k % lanes][k // lanes]
            top = Signal(signed(acc_fmt.width.bit_length() + 2), name=f"top{i}")
            small = Signal(name=f"small{i}")
            with m.If(finished):
                m.d.sync += [top.eq(leading_one(diag, acc_fmt.width)),
                             small.eq(diag < p.min_diagonal_raw)]
            exponent = Signal(signed(top.shape().width + 1), name=f"exponent{i}")
            # ceil((length − F) / 2) = −floor((F − length) / 2) with length = top + 1; a
            # zero diagonal (length 0, not 1) clamps to the same lowest exponent
            m.d.comb += exponent.eq(-((acc_fmt.frac_bits - 1 - top) >> 1))
            clamped = Mux(exponent < low, low, Mux(exponent > high, high, exponent))
            with m.If(lengths_ready):
                m.d.sync += self.exponents[i].eq(clamped)
            empty = empty | small
        with m.If(lengths_ready):
            m.d.sync += [self.done.eq(1), self.empty.eq(empty | gated)]
        return m

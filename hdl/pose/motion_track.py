"""The motion track in gateware: :class:`emulator.pose.motion_track.MotionTrackModel` bit
for bit (``sim_tests/pose/test_motion_track_hdl.py``; docs/pose/motion_track.md).

Per row: the carry ``c = L/P + B/2`` (six products on one multiplier), then each row
period since the last row through the ring: one read of the period's word (the six
axes side by side), ``u = Y − v`` and ``Y = u + v`` axis by axis on one adder (one
clock per axis), one write; the row's own period with the pull ``v = c + a·(m − u −
c)`` (six more products on the same multiplier); ``Y`` out. A restart latches
``frame_rows``, divides ``1/P`` (one bit per clock), fills the ring with the carry of
``initial`` and sets ``Y = P·c`` on the multiplier; reset leaves the built ``P``, its
reciprocal and ``Y = 0``, and clears the ring (its length in clocks, rows waiting), as
the restart from ``initial`` = 0 would: a reset at run time finds no stale increments.
"""

from amaranth.hdl import Module, Mux, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.checks import check_int
from hdl.fixed import SQ, Overflow, Rounding, hdl_mul, hdl_resize
from hdl.pose.forecast_filter import DEFAULT_SLOT_BITS, outside, track_layout
from hdl.pose.forecast_params import ForecastParams

__all__ = ["MotionTrack", "default_motion_track"]


class MotionTrack(wiring.Component):
    """``Y`` of every row, read like golden (b)'s pose track.

    Parameters
    ----------
    params : ForecastParams
    frame_rows : int
        The ring's length: the largest ``P`` it can hold, and ``P`` after reset.
    slot_bits : int
        Width of a row slot (slots compared modulo ``2**slot_bits``).

    Members
    -------
    i : In(stream.Signature(track_layout(params, slot_bits)))
        One per row, slots increasing; the row periods since the previous row's slot are
        carried first (at most ``P``; a difference of 0 counts as ``2**slot_bits``).
    o : Out(stream.Signature(ArrayLayout(motion_fmt, 6)))
        ``Y`` after each row, in order.
    frame_rows : In(unsigned(slot_bits)), reset ``frame_rows``
        ``P``, read at ``restart``. 0 or beyond the ring's length: ``overrange``, and the
        ring's length is used.
    alpha : In(unsigned(gain_fmt.width)), reset ``params.track_alpha_raw``
        The pull ``a``, raw ``gain_fmt``; a change applies from the next row.
    initial : In(ArrayLayout(motion_fmt, 6))
        The motion a restart starts from.
    restart : In(1)
        A strobe: every increment the carry of ``initial``, ``Y`` their sum, the next
        row's period the first. Held until taken between rows (a row in progress
        finishes first; ``initial`` is read then); rows wait meanwhile.
    overrange : Out(1)
        The last restart's ``frame_rows`` was 0 or beyond the ring's length.
    saturated : Out(solver.counter_bits)
        Rows (and restarts) in which a value saturated into ``motion_fmt`` (wraps).
    """

    def __init__(self, params, frame_rows, *, slot_bits=DEFAULT_SLOT_BITS):
        if not isinstance(params, ForecastParams):
            raise TypeError(f"params must be a ForecastParams, not {params!r}")
        check_int("slot_bits", slot_bits, 2, 32)
        check_int("frame_rows", frame_rows, 1, 2 ** slot_bits - 1)
        self.params, self.depth, self.slot_bits = params, frame_rows, slot_bits
        motion = data.ArrayLayout(params.motion_fmt.shape(), 6)
        super().__init__({
            "i": In(stream.Signature(track_layout(params, slot_bits))),
            "o": Out(stream.Signature(motion)),
            "frame_rows": In(unsigned(slot_bits), init=frame_rows),
            "alpha": In(unsigned(params.gain_fmt.width), init=params.track_alpha_raw),
            "initial": In(motion),
            "restart": In(1),
            "overrange": Out(1),
            "saturated": Out(params.solver.counter_bits),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        fmt, bits, rfmt = p.motion_fmt, self.slot_bits, p.reciprocal_fmt
        word = data.ArrayLayout(fmt.shape(), 6)
        rest_fmt = SQ(fmt.int_bits + 1, fmt.frac_bits)                 # u = Y − v
        diff_fmt = SQ(fmt.int_bits + 3, fmt.frac_bits)                 # m − u − c
        pull_fmt = SQ(fmt.int_bits + 4, fmt.frac_bits)                 # a·(m − u − c)

        m.submodules.ring = ring = Memory(shape=word, depth=self.depth, init=[])
        read, write = ring.read_port(), ring.write_port()

        length = Signal(range(self.depth + 1), init=self.depth)       # P
        reciprocal = Signal(rfmt.shape(), init=p.reciprocal_raw(self.depth))
        index = Signal(range(self.depth))
        motion = Signal(word)                                          # Y
        carry = Signal(word)                                           # c
        old = Signal(word)                                             # v(j − P)
        increment = Signal(word)                                       # v(j)
        rest = Signal(rest_fmt.shape())                                # u of one axis
        row = Signal(track_layout(p, bits))
        last_slot = Signal(bits)
        first = Signal(init=1)                     # no row since the last restart
        restarting = Signal()
        periods = Signal(range(self.depth + 1))    # row periods still to carry
        clamped = Signal()                         # a value of this row saturated
        axis = Signal(range(6))

        # one multiplier for 1/P · L, a · (m − u − c) and P · c: a's raw value aligned to
        # the reciprocal's fraction bits (exact), L and c widened to the difference's format
        a_operand = Signal(rfmt.shape())
        b_operand = Signal(diff_fmt.shape())
        product_value, product_fmt = hdl_mul(a_operand, rfmt, b_operand, diff_fmt)
        product = Signal(product_fmt.shape())
        m.d.sync += product.eq(product_value)
        alpha = self.alpha << (rfmt.frac_bits - p.gain_fmt.frac_bits)
        rate = hdl_resize(product, product_fmt, fmt, Rounding.HALF_EVEN, Overflow.ERROR)
        pull = hdl_resize(product, product_fmt, pull_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
        # the pull's rounding (with the axis's c), v = c + pull and Y = u + v each end in
        # a register: one saturating sum per clock, no axis select before it, keeps the
        # paths within 8 LUT levels
        pulled = Signal(pull_fmt.shape())
        carried = Signal(fmt.shape())
        moved = Signal(fmt.shape())
        # P · c: the integer P times c's raw value, a raw value of motion_fmt's fraction
        filled_fmt = SQ(product_fmt.width - fmt.frac_bits, fmt.frac_bits)
        trend = row.trend[axis]
        half_trend = (trend >> 1) + (trend[0] & trend[1])    # B/2, ties to even

        def limit(value, value_fmt):
            """``value`` (raw ``value_fmt``, motion_fmt's fraction) saturated into
            motion_fmt, and whether it was out of range."""
            return (hdl_resize(value, value_fmt, fmt, Rounding.FLOOR, Overflow.SATURATE),
                    outside(value, fmt))

        def wider(extra):
            return SQ(fmt.int_bits + extra, fmt.frac_bits)

        # the restart's divider: q = ⌊2^(F+1) / P⌋ one bit per clock, then (q + 1) >> 1
        q_bits = rfmt.frac_bits + 2
        quotient = Signal(q_bits)
        remainder = Signal(bits + 1)
        bit = Signal(range(q_bits + 1))
        elapsed = Signal(bits)
        m.d.comb += [elapsed.eq(self.i.payload.slot - last_slot),
                     read.addr.eq(index), write.addr.eq(index), write.data.eq(increment),
                     self.o.payload.eq(motion)]
        wrap = Mux(index == length - 1, 0, index + 1)

        requested = Signal()                       # a restart strobed, not yet taken
        restart = self.restart | requested
        with m.If(self.restart):
            m.d.sync += requested.eq(1)
        with m.FSM(init="CLEAR"):
            with m.State("CLEAR"):                 # after reset: increment = 0, index 0
                m.d.comb += write.en.eq(1)
                m.d.sync += index.eq(wrap)
                with m.If(index == self.depth - 1):
                    m.next = "IDLE"
            with m.State("IDLE"):
                m.d.comb += self.i.ready.eq(~restart)
                with m.If(restart):
                    m.d.sync += requested.eq(0)
                    bad = (self.frame_rows == 0) | (self.frame_rows > self.depth)
                    m.d.sync += [self.overrange.eq(bad),
                                 length.eq(Mux(bad, self.depth, self.frame_rows)),
                                 quotient.eq(0), remainder.eq(0), bit.eq(q_bits),
                                 row.level.eq(self.initial), row.trend.eq(0),
                                 restarting.eq(1), clamped.eq(0)]
                    m.next = "DIVIDE"
                with m.Elif(self.i.valid):
                    long = (elapsed == 0) | (elapsed >= length)
                    m.d.sync += [row.eq(self.i.payload), axis.eq(0), clamped.eq(0),
                                 periods.eq(Mux(first, 1, Mux(long, length, elapsed))),
                                 last_slot.eq(self.i.payload.slot), first.eq(0)]
                    m.next = "CARRY"

            with m.State("DIVIDE"):                # 2^(F+1): its one 1 bit comes first
                shifted = (remainder << 1) | (bit == q_bits)
                fits = shifted >= length
                m.d.sync += [remainder.eq(Mux(fits, shifted - length, shifted)),
                             quotient.eq((quotient << 1) | fits), bit.eq(bit - 1)]
                with m.If(bit == 1):
                    m.next = "RECIPROCAL"
            with m.State("RECIPROCAL"):
                m.d.sync += [reciprocal.eq((quotient + 1) >> 1), axis.eq(0)]
                m.next = "CARRY"

            with m.State("CARRY"):                 # c = L/P + B/2, axis by axis
                m.d.sync += [a_operand.eq(reciprocal), b_operand.eq(row.level[axis])]
                m.next = "CARRY_PRODUCT"
            with m.State("CARRY_PRODUCT"):
                m.next = "CARRY_SUM"
            with m.State("CARRY_SUM"):
                value, out = limit(rate + half_trend, wider(1))
                m.d.sync += [carry[axis].eq(value), clamped.eq(clamped | out),
                             axis.eq(axis + 1)]
                with m.If(axis != 5):
                    m.next = "CARRY"
                with m.Elif(restarting):
                    m.d.sync += [index.eq(0), increment.eq(carry), increment[5].eq(value)]
                    m.next = "FILL"
                with m.Else():
                    m.next = "READ"

            with m.State("FILL"):                  # every increment c ...
                m.d.comb += write.en.eq(1)
                m.d.sync += index.eq(wrap)
                with m.If(index == length - 1):
                    m.d.sync += [index.eq(0), axis.eq(0)]
                    m.next = "FILL_PRODUCT"
            with m.State("FILL_PRODUCT"):          # ... and Y = P·c, axis by axis
                m.d.sync += [a_operand.eq(length), b_operand.eq(carry[axis])]
                m.next = "FILL_WAIT"
            with m.State("FILL_WAIT"):
                m.next = "FILL_SUM"
            with m.State("FILL_SUM"):
                value, out = limit(product, filled_fmt)
                m.d.sync += [motion[axis].eq(value), clamped.eq(clamped | out),
                             axis.eq(axis + 1)]
                with m.If(axis == 5):
                    m.d.sync += [first.eq(1), restarting.eq(0)]
                    m.next = "COUNT"
                with m.Else():
                    m.next = "FILL_PRODUCT"

            with m.State("READ"):                  # the ring's word of this period
                m.next = "PERIOD"
            with m.State("PERIOD"):
                m.d.sync += [old.eq(read.data), axis.eq(0)]
                m.next = "AXIS"
            with m.State("AXIS"):                  # u = Y − v(j − P); v = c, Y = u + v
                difference = motion[axis] - old[axis]
                with m.If((periods == 1) & row.solved):
                    m.d.sync += rest.eq(difference)
                    m.next = "PULL"
                with m.Else():
                    value, out = limit(difference + carry[axis], wider(2))
                    m.d.sync += [increment[axis].eq(carry[axis]), motion[axis].eq(value),
                                 clamped.eq(clamped | out), axis.eq(axis + 1)]
                    with m.If(axis == 5):
                        m.next = "WRITE"
            with m.State("PULL"):                  # v = c + a·(m − u − c)
                m.d.sync += [a_operand.eq(alpha), b_operand.eq(row.target[axis] - rest - carry[axis])]
                m.next = "PULL_PRODUCT"
            with m.State("PULL_PRODUCT"):
                m.next = "PULL_ROUND"
            with m.State("PULL_ROUND"):            # a·(m − u − c) rounded, c of the axis
                m.d.sync += [pulled.eq(pull), carried.eq(carry[axis])]
                m.next = "PULL_MOVE"
            with m.State("PULL_MOVE"):             # v = c + pull
                moved_value, moved_out = limit(carried + pulled, wider(5))
                m.d.sync += [moved.eq(moved_value), clamped.eq(clamped | moved_out)]
                m.next = "PULL_SUM"
            with m.State("PULL_SUM"):              # Y = u + v
                value, out = limit(rest + moved, wider(2))
                m.d.sync += [increment[axis].eq(moved), motion[axis].eq(value),
                             clamped.eq(clamped | out), axis.eq(axis + 1)]
                with m.If(axis == 5):
                    m.next = "WRITE"
                with m.Else():
                    m.next = "AXIS"

            with m.State("WRITE"):                 # v(j) into the ring
                m.d.comb += write.en.eq(1)
                m.d.sync += [index.eq(wrap), periods.eq(periods - 1)]
                with m.If(periods == 1):
                    m.next = "OUT"
                with m.Else():
                    m.next = "READ"

            with m.State("OUT"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "COUNT"
            with m.State("COUNT"):                 # a row or restart that saturated
                with m.If(clamped):
                    m.d.sync += self.saturated.eq(self.saturated + 1)
                m.next = "IDLE"
        return m


def default_motion_track():
    """The motion track of the board rig (``stereo8-board``: its forecast's formats, a
    frame of 600 row periods): the catalog's build, for Verilog and synthesis."""
    from golden.rig import preset
    from hdl.pipeline_config import PipelineConfig
    config = PipelineConfig.for_rig(preset("stereo8-board"))
    return MotionTrack(config.forecast(), round(config.frame_rows))

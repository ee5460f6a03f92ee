"""Iterative arithmetic units of the consistency stage: a restoring divider and an integer
square root, ``bits_per_clock`` result bits per clock.

Both are shared, multi-cycle and small: the stage judges one measurement at a time, and
the solver's accumulator takes at most one measurement per nine clocks, so a divider of
two quotient bits per clock keeps up where a pipelined one would cost ~20× the logic.
"""

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from golden.checks import check_int

__all__ = ["SerialDivider", "SerialSqrt"]


def _restoring_step(rem, sub, width=None):
    """``(rem >= sub, rem − sub if so else rem)``, the remainder ``width`` bits (default
    ``rem``'s): one subtraction whose borrow is the comparison, so a step is one carry
    chain and a multiplexer, not a comparison's chain in front of the subtraction's."""
    diff = rem - sub
    ge = ~diff[-1]
    return ge, Mux(ge, diff, rem)[:len(rem) if width is None else width]


class SerialDivider(wiring.Component):
    """``num // den`` and ``num % den`` of unsigned integers whose quotient is below
    ``2**quotient_bits`` (the caller guarantees it; ``den > 0``).

    ``start`` (one clock) loads ``num`` and ``den``; ``busy`` is high for :attr:`steps`
    clocks after it, then ``quotient`` and ``remainder`` hold until the next start.
    """

    def __init__(self, num_width, den_width, quotient_bits, bits_per_clock):
        for name, value in (("num_width", num_width), ("den_width", den_width),
                            ("quotient_bits", quotient_bits),
                            ("bits_per_clock", bits_per_clock)):
            check_int(name, value, 1)
        self.steps = -(-quotient_bits // bits_per_clock)
        self.bits = self.steps * bits_per_clock
        self.per_clock = bits_per_clock
        self._den_width = den_width
        super().__init__({"start": In(1), "num": In(num_width), "den": In(den_width),
                          "busy": Out(1), "quotient": Out(self.bits),
                          "remainder": Out(num_width)})

    def elaborate(self, platform):
        m = Module()
        d = Signal(self._den_width + self.bits)
        count = Signal(range(self.steps + 1))
        rem, q, dd = self.remainder, self.quotient, d
        for _ in range(self.per_clock):            # one restoring step per result bit
            ge, rem = _restoring_step(rem, dd)
            q = Cat(ge, q)[:len(self.quotient)]
            dd = dd >> 1
        m.d.comb += self.busy.eq(count != 0)
        with m.If(self.start):
            m.d.sync += [self.remainder.eq(self.num), self.quotient.eq(0),
                         d.eq(self.den << (self.bits - 1)), count.eq(self.steps)]
        with m.Elif(count != 0):
            m.d.sync += [self.remainder.eq(rem), self.quotient.eq(q), d.eq(dd),
                         count.eq(count - 1)]
        return m


class SerialSqrt(wiring.Component):
    """``⌊√n⌋`` and ``n − ⌊√n⌋²`` of an unsigned ``width``-bit ``n`` (by digits).

    ``start`` loads ``n``; ``busy`` for :attr:`steps` clocks, then ``root`` and
    ``remainder`` hold.
    """

    def __init__(self, width, bits_per_clock):
        check_int("width", width, 1)
        check_int("bits_per_clock", bits_per_clock, 1)
        digits = -(-width // 2)                             # root bits needed
        self.steps = -(-digits // bits_per_clock)
        self.bits = self.steps * bits_per_clock             # root bits
        self.per_clock = bits_per_clock
        super().__init__({"start": In(1), "n": In(width), "busy": Out(1),
                          "root": Out(self.bits), "remainder": Out(self.bits + 2)})

    def elaborate(self, platform):
        m = Module()
        n = Signal(2 * self.bits)
        count = Signal(range(self.steps + 1))
        rem, root, nn = self.remainder, self.root, n
        for _ in range(self.per_clock):
            rem = Cat(nn[-2:], rem)                    # bring down the next two bits
            nn = (nn << 2)[:len(n)]
            trial = Cat(Const(1, 2), root)             # 4·root + 1
            ge, rem = _restoring_step(rem, trial, len(self.remainder))
            root = Cat(ge, root)[:len(self.root)]
        m.d.comb += self.busy.eq(count != 0)
        with m.If(self.start):
            m.d.sync += [n.eq(self.n), self.remainder.eq(0), self.root.eq(0),
                         count.eq(self.steps)]
        with m.Elif(count != 0):
            m.d.sync += [n.eq(nn), self.remainder.eq(rem), self.root.eq(root),
                         count.eq(count - 1)]
        return m

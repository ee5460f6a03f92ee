"""UART transmitter (8N1) with a fractional baud divisor set at run time.

The pose packets leave the fabric on one pin. The bit period is a register holding
system clocks per bit in ``UQ(16, 4)``: at a 100 MHz system clock, 3 Mbaud is 33.3125
clocks per bit (0.06 % fast) where an integer divisor would be 1 % off.
"""

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.output.params import FRAME_BITS, UartParams

__all__ = ["UartTx"]

class UartTx(wiring.Component):
    """Sends bytes as 8N1 frames on ``tx``, back to back while bytes are waiting.

    Bit ``k`` of a frame lasts ``(r_k + d) >> f`` clocks, where ``d`` is the divisor
    (``f`` fraction bits), ``r_0 = 0`` and ``r_{k+1} = (r_k + d) mod 2**f``: the
    fraction carries from bit to bit, so a frame lasts exactly ``(10 d) >> f`` clocks.

    Parameters
    ----------
    params : UartParams

    Members
    -------
    i : In(stream.Signature(8))
        Bytes to send; taken when the line is idle or in the last clock of a stop bit.
    divisor : In(params.divisor_fmt.shape())
        Clocks per bit, raw ``divisor_fmt``; sampled at the start of every bit.
    tx : Out(1)
        The line (idle high).

    Latency: the start bit begins the clock after a byte is taken. Throughput: one
    byte per frame, with no idle time between frames. Reset: line idle, frame dropped.
    """

    def __init__(self, params=UartParams()):
        if not isinstance(params, UartParams):
            raise TypeError(f"params must be a UartParams, not {params!r}")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(8)),
            "divisor": In(params.divisor_fmt.shape()),
            "tx": Out(1, init=1),
        })

    def elaborate(self, platform):
        p = self.params
        frac = p.divisor_fmt.frac_bits
        m = Module()

        busy = Signal()
        shifter = Signal(FRAME_BITS)
        bits_left = Signal(range(FRAME_BITS + 1))
        clocks_left = Signal(p.divisor_fmt.int_bits + 1)
        remainder = Signal(max(frac, 1))

        divisor = Mux(self.divisor < p.min_divisor_raw, p.min_divisor_raw, self.divisor)

        def start_bit(remainder_now):
            total = remainder_now + divisor
            return [clocks_left.eq(total >> frac), remainder.eq(total[:frac] if frac else 0)]

        bit_ends = busy & (clocks_left == 1)
        frame_ends = bit_ends & (bits_left == 1)
        m.d.comb += self.i.ready.eq(~busy | frame_ends)

        # `tx` is a register (a clean pin): it changes with the bit counters.
        with m.If(self.i.valid & self.i.ready):
            m.d.sync += [busy.eq(1), bits_left.eq(FRAME_BITS), self.tx.eq(0),
                         shifter.eq(Cat(Const(0, 1), self.i.payload, Const(1, 1))),
                         *start_bit(Const(0, max(frac, 1)))]
        with m.Elif(frame_ends):
            m.d.sync += [busy.eq(0), self.tx.eq(1)]
        with m.Elif(bit_ends):
            m.d.sync += [shifter.eq(shifter >> 1), bits_left.eq(bits_left - 1),
                         self.tx.eq(shifter[1]), *start_bit(remainder)]
        with m.Elif(busy):
            m.d.sync += clocks_left.eq(clocks_left - 1)
        return m

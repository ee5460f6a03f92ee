"""A pipelined fixed-point multiply-accumulate block.

The smallest complete block of the project: it exercises the shared fixed-point formats
(:mod:`hdl.fixed`), a ``lib.stream`` interface with an end-of-vector marker in the
payload, and the cocotb harness on both simulators. The pose solver's accumulator uses
the same pattern for the normal equations.
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import Overflow, Rounding, hdl_add, hdl_mul, hdl_resize
from hdl.pose.mac_params import MacParams

__all__ = ["MultiplyAccumulate"]


class MultiplyAccumulate(wiring.Component):
    """Sum of products over a vector, one product per clock.

    Each input transfer carries one operand pair; ``last`` closes the vector, and the
    rounded, overflow-handled sum appears on ``o``.

    Parameters
    ----------
    params : MacParams

    Members
    -------
    i : In(stream.Signature(StructLayout(a: a_fmt, b: b_fmt, last: 1)))
        Operand pairs (raw integers of ``a_fmt``/``b_fmt``).
    o : Out(stream.Signature(out_fmt.shape()))
        One sum per vector, raw ``out_fmt``.

    Latency: :attr:`latency` clocks from the cycle ``last`` is transferred to the cycle
    ``o.valid`` rises, when the output is not stalled. Throughput: one operand pair per
    clock. Backpressure: while ``o`` holds an untaken result the pipeline stalls
    (``i.ready`` low). Reset: clears the pipeline and the accumulator.
    """

    #: Register stages from an input transfer to ``o``: operands, product, accumulate+round.
    latency = 3

    def __init__(self, params=MacParams()):
        if not isinstance(params, MacParams):
            raise TypeError(f"params must be a MacParams, not {params!r}")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(params.input_layout())),
            "o": Out(stream.Signature(params.out_fmt.shape())),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()

        stall = self.o.valid & ~self.o.ready
        m.d.comb += self.i.ready.eq(~stall)

        a = Signal(p.a_fmt.shape())
        b = Signal(p.b_fmt.shape())
        s1_valid = Signal()
        s1_last = Signal()
        product = Signal(p.product_fmt.shape())
        s2_valid = Signal()
        s2_last = Signal()
        acc = Signal(p.acc_fmt.shape())

        total, total_fmt = hdl_add(acc, p.acc_fmt, product, p.product_fmt)
        wrapped = hdl_resize(total, total_fmt, p.acc_fmt, Rounding.FLOOR, Overflow.WRAP)

        with m.If(~stall):
            m.d.sync += [
                a.eq(self.i.p.a), b.eq(self.i.p.b),
                s1_valid.eq(self.i.valid), s1_last.eq(self.i.p.last),
                product.eq(hdl_mul(a, p.a_fmt, b, p.b_fmt)[0]),
                s2_valid.eq(s1_valid), s2_last.eq(s1_last),
                self.o.valid.eq(s2_valid & s2_last),
            ]
            with m.If(s2_valid & s2_last):
                m.d.sync += [
                    acc.eq(0),
                    self.o.payload.eq(hdl_resize(wrapped, p.acc_fmt, p.out_fmt,
                                                 p.rounding, p.overflow)),
                ]
            with m.Elif(s2_valid):
                m.d.sync += acc.eq(wrapped)
        return m

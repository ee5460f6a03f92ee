"""A registered ready/valid slice (skid buffer) that cuts a combinational stream chain.

Amaranth streams pass ``ready`` backwards combinationally: a consumer whose ``ready``
depends on its own outputs' ``ready`` chains the logic of every block on the way into
one path (issue 17: 14 LUT levels from the stereo lanes' framers through the row-set
fork and the row aligner into the camera-input FIFO). :class:`RegisterSlice` sits on a
stream and registers everything that crosses it: ``o.valid`` and ``o.payload`` come from
flip-flops, and so does ``i.ready``, so no path goes through it. A second (skid)
register takes the beat that arrives in the clock ``o.ready`` falls, which keeps one
transfer per clock when nothing stalls.
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["RegisterSlice"]


class RegisterSlice(wiring.Component):
    """Full-throughput skid buffer: ``i`` to ``o`` with every port registered.

    Parameters
    ----------
    layout : shape-castable
        The payload layout (``stream.Signature(layout)`` on both sides).

    Members
    -------
    i : In(stream.Signature(layout))
    o : Out(stream.Signature(layout))
        The beats of ``i``, in order and unchanged.

    Latency :attr:`latency` clock (a beat taken from ``i`` at one clock edge is offered on
    ``o`` after it). Throughput one beat per clock while ``o.ready`` is high. Backpressure:
    ``i.ready`` is low only while the skid register holds a beat, i.e. from the clock
    after ``o`` stalled with a beat waiting until ``o`` takes it; ``o.valid`` never
    depends on ``o.ready`` and a beat is held until it is taken. Reset: empty.
    """

    latency = 1

    def __init__(self, layout):
        self.layout = layout
        super().__init__({
            "i": In(stream.Signature(layout)),
            "o": Out(stream.Signature(layout)),
        })

    def elaborate(self, platform):
        m = Module()
        skid_valid = Signal()
        skid = Signal(self.layout)
        i, o = self.i, self.o
        m.d.comb += i.ready.eq(~skid_valid)
        with m.If(o.ready | ~o.valid):
            # The output register is free this clock: it takes the skid beat if there is
            # one (``i.ready`` is low then), else whatever ``i`` offers.
            with m.If(skid_valid):
                m.d.sync += [o.valid.eq(1), o.payload.eq(skid), skid_valid.eq(0)]
            with m.Else():
                m.d.sync += [o.valid.eq(i.valid), o.payload.eq(i.payload)]
        with m.Elif(i.valid & ~skid_valid):
            # ``o`` stalls with a beat: the beat ``i`` transfers now waits in the skid.
            m.d.sync += [skid_valid.eq(1), skid.eq(i.payload)]
        return m

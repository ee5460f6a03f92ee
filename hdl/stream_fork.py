"""A stream sent to several consumers, each taking every beat once, at its own time.

A pose record goes to the forecast (which waits for it before the next rows can be
forecast) and to the tracking-status unit (which takes one every few clocks); a judged
measurement goes to the solver and to the status unit's row counter. Each consumer may
stall independently, and none may miss a beat: :class:`StreamFork` offers the beat on
every output, remembers which outputs took it, and takes the next beat from ``i`` only
once all have. ``o[k].valid`` never depends on any ``ready`` (a registered ``taken``
flag per output), as the stream rules ask.
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from golden.checks import check_int

__all__ = ["StreamFork"]


class StreamFork(wiring.Component):
    """``i`` to ``n`` outputs, every beat to each.

    Parameters
    ----------
    layout : shape-castable
        The payload layout of ``i`` and every output.
    n : int
        Outputs (at least 2).

    Members
    -------
    i : In(stream.Signature(layout))
    o : Out(stream.Signature(layout)).array(n)
        Each output gets every beat of ``i``, in order and unchanged.

    No latency: a beat is offered on every output that has not taken it in the clock it
    arrives. Throughput one beat per clock while every output is ready; a beat leaves ``i``
    in the clock the last output takes it. Reset: no output has taken the beat.
    """

    def __init__(self, layout, n):
        check_int("n", n, 2)
        self.layout, self.n = layout, n
        super().__init__({"i": In(stream.Signature(layout)),
                          "o": Out(stream.Signature(layout)).array(n)})

    def elaborate(self, platform):
        m = Module()
        taken = [Signal(name=f"taken{k}") for k in range(self.n)]
        done = [Signal(name=f"done{k}") for k in range(self.n)]
        for k, o in enumerate(self.o):
            m.d.comb += [o.payload.eq(self.i.payload), o.valid.eq(self.i.valid & ~taken[k]),
                         done[k].eq(taken[k] | o.ready)]
        all_done = done[0]
        for k in range(1, self.n):
            all_done = all_done & done[k]
        m.d.comb += self.i.ready.eq(all_done)
        for k, o in enumerate(self.o):
            with m.If(self.i.valid & all_done):
                m.d.sync += taken[k].eq(0)
            with m.Elif(o.valid & o.ready):
                m.d.sync += taken[k].eq(1)
        return m

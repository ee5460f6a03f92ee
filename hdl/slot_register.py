"""State kept once per stream of a block that serves several streams in turn (issue 17
item 3: one lane for several cameras).

A block that serves ``slots`` interleaved streams round robin, one slot per step (a
bubble when a stream has nothing to give), keeps each piece of per-stream state in a
ring of ``slots`` registers that turns one place per step (C-slow): the register at the
ring's head always belongs to the stream being served, so the logic between the
registers is built once for all streams, and no multiplexer picks a stream's state. A
stage that sits ``d`` steps down the block's pipeline serves the stream of ``d`` steps
ago with its own rings: a ring's contents only ever meet the beats of one stage.

With one slot a :class:`SlotRegister` is one plain register: ``next`` defaults to its
value, which synthesis reads as a clock enable, as it would a conditional assignment.
"""

from amaranth.hdl import Signal

__all__ = ["SlotRegister"]


class SlotRegister:
    """One register per slot, as a ring that turns one place each ``step``.

    Parameters
    ----------
    m : Module
        The module that drives the ring.
    shape : shape-castable
    slots : int
        Streams served in turn (at least 1).
    step : Value
        High when the block moves on to the next slot (beat or bubble).
    name : str
    init : int
        Every slot's value after reset.

    Attributes
    ----------
    head : Signal
        The value of the slot being served.
    next : Signal
        What the served slot's value becomes at ``step``; assign it under conditions
        (``m.d.comb += reg.next.eq(v)``), otherwise the slot keeps ``head``.
    tail : Signal
        The value written at the previous step (that slot's ``next``): what a stage one
        step further down the pipeline reads of the slot it now serves. ``head`` with
        one slot.
    """

    def __init__(self, m, shape, *, slots, step, name, init=0):
        if not isinstance(slots, int) or slots < 1:
            raise ValueError(f"slots must be an integer at least 1, not {slots!r}")
        ring = [Signal(shape, name=name if slots == 1 else f"{name}_slot{k}", init=init)
                for k in range(slots)]
        self.head, self.tail = ring[0], ring[-1]
        self.next = Signal(shape, name=f"{name}_next")
        m.d.comb += self.next.eq(self.head)
        with m.If(step):
            m.d.sync += [ring[-1].eq(self.next)]
            m.d.sync += [a.eq(b) for a, b in zip(ring, ring[1:])]

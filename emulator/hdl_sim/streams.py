"""cocotb drivers for Amaranth ``lib.stream`` ports, with random gaps and backpressure.

A port named ``i`` appears in the Verilog as ``i__valid``, ``i__ready`` and
``i__payload``. Every coroutine here follows one timing discipline so they compose:
after a rising edge they drive, then wait for ``ReadOnly`` and sample; a transfer is
``valid & ready`` as sampled in a cycle and takes effect at the next rising edge.
"""

import cocotb
from cocotb.triggers import ReadOnly, RisingEdge

from emulator.hdl_sim.payload import pack, unpack

__all__ = ["CycleCounter", "StreamSource", "StreamSink"]


class CycleCounter:
    """Counts rising edges of ``clk`` so drivers and monitors can timestamp transfers."""

    def __init__(self, clk):
        self.clk = clk
        self.cycle = 0
        cocotb.start_soon(self._count())

    async def _count(self):
        while True:
            await RisingEdge(self.clk)
            self.cycle += 1


class _StreamPort:
    """The ``valid``/``ready``/``payload`` handles of stream port ``port`` of ``dut``."""

    def __init__(self, dut, port, layout, clock, rng):
        self.valid = getattr(dut, f"{port}__valid")
        self.ready = getattr(dut, f"{port}__ready")
        self.payload = getattr(dut, f"{port}__payload")
        self.layout = layout
        self.clock = clock
        self.rng = rng


class StreamSource(_StreamPort):
    """Drives payloads into a stream port, holding each until it is transferred.

    ``valid_prob`` < 1 inserts random idle cycles (``rng`` is a seeded
    ``random.Random``); ``interval`` > 1 offers a payload at most every ``interval``
    cycles (a source as slow as the block's rate). ``valid`` never waits for ``ready``.
    ``sent`` records ``(cycle, payload)`` of every transfer.
    """

    def __init__(self, dut, port, layout, clock, *, rng=None, valid_prob=1.0, interval=1):
        super().__init__(dut, port, layout, clock, rng)
        self.valid_prob = valid_prob
        self.interval = interval
        self.sent = []
        self.valid.value = 0

    async def send(self, payloads):
        for item in payloads:
            for _ in range(self.interval - 1 if self.sent else 0):
                self.valid.value = 0
                await RisingEdge(self.clock.clk)
            while self.rng is not None and self.rng.random() >= self.valid_prob:
                self.valid.value = 0
                await RisingEdge(self.clock.clk)
            self.payload.value = pack(self.layout, item)
            self.valid.value = 1
            while True:
                await ReadOnly()
                taken = int(self.ready.value)
                cycle = self.clock.cycle
                await RisingEdge(self.clock.clk)
                if taken:
                    self.sent.append((cycle, item))
                    break
        self.valid.value = 0


class StreamSink(_StreamPort):
    """Accepts transfers from a stream port, with random ``ready`` backpressure.

    ``received`` records ``(cycle, payload)`` of every transfer; the payload is unpacked
    with ``layout``.
    """

    def __init__(self, dut, port, layout, clock, *, rng=None, ready_prob=1.0):
        super().__init__(dut, port, layout, clock, rng)
        self.ready_prob = ready_prob
        self.received = []
        self.ready.value = 0
        cocotb.start_soon(self._run())

    async def _run(self):
        while True:
            ready = self.rng is None or self.rng.random() < self.ready_prob
            self.ready.value = int(ready)
            await ReadOnly()
            if ready and int(self.valid.value):
                self.received.append((self.clock.cycle, unpack(self.layout, self.payload.value)))
            await RisingEdge(self.clock.clk)

    async def wait_for(self, count, timeout_cycles):
        """Wait until ``count`` transfers arrived; fail after ``timeout_cycles``."""
        start = self.clock.cycle
        while len(self.received) < count:
            if self.clock.cycle - start > timeout_cycles:
                raise AssertionError(f"timeout: {len(self.received)} of {count} transfers "
                                     f"after {timeout_cycles} cycles")
            await RisingEdge(self.clock.clk)

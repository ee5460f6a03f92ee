"""cocotb side of the row-descriptor benches and tests: play beat streams row by row
(the centre port follows each row), collect measurements, check them against the model
and, at full rate, check every measurement's clock cycle."""

import cocotb
import numpy as np

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.row_stimulus import frame_beats, inject_faults, moving_rows, square_rows
from emulator.hdl_sim.streams import StreamSink, StreamSource

__all__ = ["split_rows", "make_stimulus", "Lane"]


def split_rows(beats):
    """Beat lists from one ``first`` beat to the next (stray beats stay with the row
    before them)."""
    rows = []
    for beat in beats:
        if beat["first"] or not rows:
            rows.append([])
        rows[-1].append(beat)
    return rows


def make_stimulus(params, kind, rng, dataset_rows=None):
    """Beats and the centre of each row for the bench variants.

    ``textured``: moving random texture, frame numbers wrapping; ``faults``: the same
    with short, long, interrupted, flagged rows and stray beats; ``dataset``: rows of
    the golden simulator (``dataset_rows``, (F, H', W') uint8), cropped to the lane;
    ``square``: square waves whose shifts by a multiple of the period cost whole
    segments (:func:`~emulator.hdl_sim.row_stimulus.square_rows`).
    """
    h, w = params.height, params.width
    if kind == "dataset":
        frames = dataset_rows[:, :h, :w]
    elif kind == "square":
        frames = square_rows(3, h, w)
    else:
        frames, _ = moving_rows(rng, 4 if kind == "faults" else 3, h, w)
    beats = frame_beats(frames, frame0=(1 << params.frame_bits) - 2)
    if kind == "faults":
        beats = inject_faults(rng, beats, w, 5)
    rows = split_rows(beats)
    span = params.centre_range + 2                   # also exercise the saturation
    centres = [int(c) for c in rng.integers(-span, span + 1, len(rows))]
    return rows, centres


class Lane:
    """A running lane under test: sources on its input ports, a sink on ``o``."""

    def __init__(self, dut, params, ports, rng, *, busy):
        self.dut, self.params = dut, params
        self.clock = start_clock(dut)
        self.sources = {port: StreamSource(dut, port, params.input_layout(), self.clock,
                                           rng=rng, valid_prob=1.0 if busy else 0.7)
                        for port in ports}
        self.sink = StreamSink(dut, "o", params.measurement_layout(), self.clock, rng=rng,
                               ready_prob=1.0 if busy else 0.4)
        dut.centre.value = 0

    async def start(self):
        await reset(self.dut)

    async def play(self, port, rows, centres=None):
        """Send ``rows`` (lists of beats) into ``port``; the centre port follows when
        ``centres`` is given."""
        for k, row in enumerate(rows):
            if centres is not None:
                self.dut.centre.value = centres[k]
            await self.sources[port].send(row)

    async def play_all(self, streams, centres):
        """Play ``{port: rows}`` concurrently; the first port drives the centre."""
        ports = list(streams)
        tasks = [cocotb.start_soon(self.play(port, streams[port],
                                             centres if port == ports[0] else None))
                 for port in ports]
        for task in tasks:
            await task

    async def check(self, expected, latency, busy, last_cycles=None):
        """Every measurement equals the model's, in order; at full rate measurement k of
        a row leaves exactly ``latency + k`` clocks after the row's last pixel."""
        await self.sink.wait_for(len(expected), timeout_cycles=40 * len(expected) + 5000)
        got = [payload for _, payload in self.sink.received]
        for i, (g, e) in enumerate(zip(got, expected)):
            assert g == e, f"measurement {i}: hardware {g} != model {e}"
        assert len(got) == len(expected)
        if busy and last_cycles is not None:
            k = self.params.segments
            cycles = np.array([c for c, _ in self.sink.received])
            segments = np.array([m["segment"] for m in expected])
            want = np.repeat(last_cycles, k)[:len(cycles)] + latency + segments
            assert np.array_equal(cycles, want), "measurement cycles differ from latency"

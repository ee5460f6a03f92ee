"""hdl/register_slice.py in the Amaranth simulator: every beat through in order, one per
clock at full rate, with and without random valid gaps and ready backpressure; ``i.ready``
and ``o.valid`` never follow the same clock's ``o.ready``.

SEED replays a run (printed).
"""

import os
import random

import pytest
from amaranth.lib import data
from amaranth.sim import Simulator

from hdl.register_slice import RegisterSlice

SEED = int(os.environ.get("SEED", "17"))
LAYOUT = data.StructLayout({"value": 12, "last": 1})


def simulate(beats, rng, valid_prob, ready_prob):
    """Offer ``beats`` on ``i`` and take ``o``; returns (cycles ``i`` took a beat, cycles
    and beats ``o`` gave, the most consecutive clocks ``i.ready`` was low)."""
    dut = RegisterSlice(LAYOUT)
    taken, given = [], []
    record = {"longest_unready": 0}

    async def bench(ctx):
        n, cycle, offering, unready = 0, 0, False, 0
        while len(given) < len(beats):
            assert cycle < 10 * len(beats) + 10, "the slice stopped passing beats"
            offering = n < len(beats) and (offering or rng.random() < valid_prob)
            ctx.set(dut.i.valid, offering)
            if n < len(beats):
                ctx.set(dut.i.payload, beats[n])
            # Registered outputs: flipping o.ready must not move i.ready or o.valid.
            ctx.set(dut.o.ready, 0)
            before = (ctx.get(dut.i.ready), ctx.get(dut.o.valid))
            ctx.set(dut.o.ready, 1)
            assert (ctx.get(dut.i.ready), ctx.get(dut.o.valid)) == before, \
                "i.ready or o.valid follows o.ready"
            ready = rng.random() < ready_prob
            ctx.set(dut.o.ready, ready)
            if ready and ctx.get(dut.o.valid):
                payload = ctx.get(dut.o.payload)
                given.append((cycle, {"value": payload.value, "last": payload.last}))
            took = offering and ctx.get(dut.i.ready)
            unready = 0 if ctx.get(dut.i.ready) else unready + 1
            record["longest_unready"] = max(record["longest_unready"], unready)
            if took:
                taken.append(cycle)
            await ctx.tick()
            cycle += 1
            if took:
                n, offering = n + 1, False

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return taken, given, record["longest_unready"]


def _beats(rng, count):
    return [{"value": rng.randrange(1 << 12), "last": rng.randrange(2)} for _ in range(count)]


def test_full_rate_is_one_beat_per_clock_after_one_clock():
    rng = random.Random(SEED)
    beats = _beats(rng, 50)
    taken, given, longest_unready = simulate(beats, rng, 1.0, 1.0)
    assert [b for _, b in given] == beats
    assert taken == list(range(50))
    assert [c for c, _ in given] == [t + RegisterSlice.latency for t in taken]
    assert longest_unready == 0


@pytest.mark.parametrize("valid_prob,ready_prob", [(0.6, 1.0), (1.0, 0.5), (0.5, 0.5),
                                                   (0.9, 0.2)],
                         ids=["gaps", "backpressure", "both", "mostly_stalled"])
def test_gaps_and_backpressure_keep_every_beat_in_order(valid_prob, ready_prob):
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    beats = _beats(rng, 400)
    taken, given, longest_unready = simulate(beats, rng, valid_prob, ready_prob)
    assert [b for _, b in given] == beats
    assert len(taken) == len(beats)
    # Each beat leaves at least one clock after it entered (registered path).
    assert all(c >= t + RegisterSlice.latency for t, (c, _) in zip(taken, given))
    if ready_prob < 1:
        # The skid is used, and it holds at most two beats: i.ready low only while the
        # skid is full, which ends in the first clock o takes a beat.
        assert longest_unready >= 1
    else:
        assert longest_unready == 0

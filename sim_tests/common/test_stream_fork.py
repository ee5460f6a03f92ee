"""hdl/stream_fork.py in the Amaranth simulator: every beat reaches every output once, in
order, with random valid gaps and independent random backpressure per output; an
output's ``valid`` never follows any ``ready`` of the same clock.

SEED replays a run (printed).
"""

import os
import random

import pytest
from amaranth.lib import data
from amaranth.sim import Simulator

from hdl.stream_fork import StreamFork

SEED = int(os.environ.get("SEED", "23"))
LAYOUT = data.StructLayout({"value": 12, "last": 1})


def simulate(beats, n, rng, valid_prob, ready_probs):
    """Offer ``beats`` on ``i``; per output the beats it took and the cycles ``i`` took."""
    dut = StreamFork(LAYOUT, n)
    got = [[] for _ in range(n)]
    taken = []

    async def bench(ctx):
        sent, cycle, offering = 0, 0, False
        while any(len(g) < len(beats) for g in got):
            assert cycle < 20 * len(beats) + 20, "the fork stopped passing beats"
            offering = sent < len(beats) and (offering or rng.random() < valid_prob)
            ctx.set(dut.i.valid, offering)
            if sent < len(beats):
                ctx.set(dut.i.payload, beats[sent])
            for o in dut.o:
                ctx.set(o.ready, 0)
            before = [ctx.get(o.valid) for o in dut.o]
            for o in dut.o:
                ctx.set(o.ready, 1)
            assert [ctx.get(o.valid) for o in dut.o] == before, "a valid follows a ready"
            for k, o in enumerate(dut.o):
                ready = rng.random() < ready_probs[k]
                ctx.set(o.ready, ready)
                if ready and ctx.get(o.valid):
                    payload = ctx.get(o.payload)
                    got[k].append({"value": payload.value, "last": payload.last})
            took = offering and ctx.get(dut.i.ready)
            if took:
                taken.append(cycle)
            await ctx.tick()
            cycle += 1
            if took:
                sent, offering = sent + 1, False

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return got, taken


@pytest.mark.parametrize("n, valid_prob, ready_probs", [
    (2, 1.0, (1.0, 1.0)), (2, 0.7, (0.5, 0.9)), (3, 0.9, (0.3, 1.0, 0.6)),
])
def test_every_output_gets_every_beat_once_in_order(n, valid_prob, ready_probs):
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    beats = [{"value": rng.randrange(1 << 12), "last": rng.randrange(2)} for _ in range(300)]
    got, taken = simulate(beats, n, rng, valid_prob, ready_probs)
    assert all(g == beats for g in got)
    if valid_prob == 1.0 and min(ready_probs) == 1.0:
        assert taken == list(range(len(beats))), "not one beat per clock at full rate"


def test_n_is_checked():
    with pytest.raises(ValueError, match="n must be an integer"):
        StreamFork(LAYOUT, 1)

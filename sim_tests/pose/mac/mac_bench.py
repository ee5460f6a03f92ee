"""cocotb bench for hdl.pose.mac.MultiplyAccumulate: every output against emulator.pose.mac."""

import random

import cocotb

from emulator.pose.mac import mac_model
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.streams import StreamSink, StreamSource


def _random_vectors(params, rng, count):
    """Random vectors with the extremes of each operand format mixed in."""
    pairs = []
    for _ in range(count):
        length = rng.choice([1, 2, 3, 7, 16, 33])
        for k in range(length):
            a = rng.choice([params.a_fmt.min_raw, params.a_fmt.max_raw, 0,
                            rng.randint(params.a_fmt.min_raw, params.a_fmt.max_raw)])
            b = rng.choice([params.b_fmt.min_raw, params.b_fmt.max_raw, 0,
                            rng.randint(params.b_fmt.min_raw, params.b_fmt.max_raw)])
            pairs.append({"a": a, "b": b, "last": int(k == length - 1)})
    return pairs


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def mac_matches_model(dut, traffic):
    """Random vectors, with or without valid gaps and ready backpressure."""
    params = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    source = StreamSource(dut, "i", params.input_layout(), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", params.out_fmt.shape(), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    await reset(dut)
    pairs = _random_vectors(params, rng, 60)
    expected = mac_model(params, [p["a"] for p in pairs], [p["b"] for p in pairs],
                         [p["last"] for p in pairs])
    await source.send(pairs)
    await sink.wait_for(len(expected), timeout_cycles=20 * len(pairs))
    got = [payload for _, payload in sink.received]
    assert got == [int(x) for x in expected], "MAC output differs from emulator.pose.mac"
    if busy:
        latency = load_sidecar()["latency"]
        last_cycles = [cycle for cycle, p in source.sent if p["last"]]
        out_cycles = [cycle for cycle, _ in sink.received]
        assert [o - l for o, l in zip(out_cycles, last_cycles)] == [latency] * len(expected)

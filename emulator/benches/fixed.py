"""Benchmark of the fixed-point core's MAC block: latency and throughput measured in the
Amaranth simulator, resources from synth_xilinx."""

import numpy as np

from emulator.pose.mac import mac_model
from emulator.synth import XC7Z020, synth_report


def _simulate_mac(params, pairs):
    """Run pairs through the MAC at full rate; returns (outputs, last-transfer cycles,
    output cycles, total cycles)."""
    from amaranth.sim import Simulator
    from hdl.pose.mac import MultiplyAccumulate

    dut = MultiplyAccumulate(params)
    record = {"last_in": [], "out": [], "values": [], "cycles": 0}

    async def testbench(ctx):
        ctx.set(dut.o.ready, 1)
        cycle = 0
        queue = list(pairs)
        while queue or len(record["out"]) < sum(p["last"] for p in pairs):
            if queue:
                ctx.set(dut.i.valid, 1)
                ctx.set(dut.i.payload, queue[0])
            else:
                ctx.set(dut.i.valid, 0)
            in_valid, in_ready = ctx.get(dut.i.valid), ctx.get(dut.i.ready)
            out_valid, out_payload = ctx.get(dut.o.valid), ctx.get(dut.o.payload)
            await ctx.tick()
            if in_valid and in_ready:
                if queue.pop(0)["last"]:
                    record["last_in"].append(cycle)
            if out_valid:
                record["out"].append(cycle)
                record["values"].append(out_payload)
            cycle += 1
        record["cycles"] = cycle

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return record


def measure():
    from hdl.pose.mac import MultiplyAccumulate
    from hdl.pose.mac_params import MacParams
    params = MacParams()
    rng = np.random.default_rng(1)
    length, vectors = 64, 8
    a = rng.integers(params.a_fmt.min_raw, params.a_fmt.max_raw + 1, length * vectors)
    b = rng.integers(params.b_fmt.min_raw, params.b_fmt.max_raw + 1, length * vectors)
    last = (np.arange(length * vectors) % length) == length - 1
    pairs = [{"a": int(x), "b": int(y), "last": int(z)} for x, y, z in zip(a, b, last)]
    record = _simulate_mac(params, pairs)
    expected = [int(v) for v in mac_model(params, a, b, last)]
    if record["values"] != expected:
        raise AssertionError("MAC simulation differs from emulator.pose.mac in the benchmark run")
    latencies = {o - i for o, i in zip(record["out"], record["last_in"])}
    if len(latencies) != 1:
        raise AssertionError(f"MAC latency is not constant at full rate: {sorted(latencies)}")
    first_in = 0
    last_in = record["last_in"][-1]
    figures = {
        "mac.latency_clocks": latencies.pop(),
        "mac.pairs_per_clock": round(len(pairs) / (last_in - first_in + 1), 4),
    }
    synth = synth_report(MultiplyAccumulate(params), "mac")
    figures.update({f"mac.{key}": synth[key] for key in ("lut", "ff", "dsp48", "lut_levels")})
    return figures


def report(figures):
    rows = "\n".join(f"| {key} | {value} |" for key, value in sorted(figures.items()))
    return f"""# Fixed-point core: multiply-accumulate block

`hdl/pose/mac.py` with its default formats (operands SQ(2, 16), accumulator SQ(12, 32), output
SQ(8, 16), convergent rounding, saturation). Latency and throughput come from an Amaranth
simulation of 8 vectors of 64 random pairs at full rate (outputs checked against
`emulator/pose/mac.py`); resources from Yosys `synth_xilinx -family xc7` (capacity of the
xc7z020: {XC7Z020['lut']} LUTs, {XC7Z020['dsp48']} DSP48E1).

| figure | value |
|---|---|
{rows}
"""

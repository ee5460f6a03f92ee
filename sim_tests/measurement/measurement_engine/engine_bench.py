"""cocotb bench for hdl.measurement.engine.MeasurementEngine: golden-simulator rows of a
four-camera rig played as aligned row sets (the ``cfg`` port changes between sets),
every solver transfer and the final counters against emulator.measurement.engine."""

import os
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles

from emulator.measurement.engine import row_set_columns, run_engine
from golden.dataset import Dataset
from hdl.measurement.engine_params import engine_config_layout, engine_status_layout
from hdl.pose_solver import measurement_layout
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.payload import pack, unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource

from sim_tests.measurement.measurement_engine.stimulus import make_stimulus, priming_frame


def _indexed(value):
    """Lists (array fields of the model's dicts) as the index dicts ``pack`` takes."""
    if isinstance(value, dict):
        return {key: _indexed(item) for key, item in value.items()}
    if isinstance(value, list):
        return {k: _indexed(item) for k, item in enumerate(value)}
    return value


def _wrapped(status, bits):
    """The model's unwrapped counters as the hardware shows them (wrapped)."""
    if isinstance(status, dict):
        return {key: _wrapped(value, bits) for key, value in status.items()}
    return status % (1 << bits)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"], faults=[False, True])
async def engine_matches_model(dut, traffic, faults):
    """Clean sets at fixed non-zero centres, or sets with lost cameras and pairs, bad
    rows, ``enable`` 0 and centres changing per set; with a free-running or a random
    source and sink."""
    params = load_params()
    busy = traffic == "full_rate"
    rng = random.Random(cocotb.RANDOM_SEED)
    dataset = Dataset.load(os.environ["ROWTRACK_ME_DATASET"])
    stim = make_stimulus(params, dataset, np.random.default_rng(cocotb.RANDOM_SEED),
                         faults=faults)
    # Reset keeps the reference stores' bits: a priming frame sets them as in the model.
    prime = priming_frame(params)
    skip = len(run_engine(params, prime.row_sets, prime.configs).transfers)
    row_sets, configs = prime.row_sets + stim.row_sets, prime.configs + stim.configs
    expected = run_engine(params, row_sets, configs)
    cfg_layout = engine_config_layout(params)

    clock = start_clock(dut)
    # with shared matchers a column at most every ``matcher_ports`` clocks, the rate
    # the matchers take them at
    source = StreamSource(dut, "rows", params.aligned_layout(), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.8, interval=params.matcher_ports)
    sink = StreamSink(dut, "o", measurement_layout(params.router.solver), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.5)
    dut.cfg.value = pack(cfg_layout, _indexed(configs[0]))
    await reset(dut)
    for row_set, cfg in zip(row_sets, configs):
        dut.cfg.value = pack(cfg_layout, _indexed(cfg))   # sets only change between sets
        await source.send([_indexed(c) for c in row_set_columns(params, row_set)])
    await check_output(dut, params, source, sink, expected, skip, steady=busy and not faults)


async def check_output(dut, params, source, sink, expected, skip, *, steady):
    """Wait for the model's transfers on ``o``; every one after the first ``skip``
    (priming rows, which meet what an earlier test left in the reference stores) and the
    final ``status`` must equal the model's. ``steady``: the row source must not have
    stalled, and every row's latency must be the block's."""
    cycles = [c for c, _ in source.sent]
    await sink.wait_for(len(expected.transfers), timeout_cycles=20 * len(cycles) + 5000)
    await ClockCycles(dut.clk, 500)                       # nothing more may come
    got = [payload for _, payload in sink.received]
    assert len(got) == len(expected.transfers), \
        f"{len(got)} transfers, model {len(expected.transfers)}"
    for n, (g, e) in enumerate(zip(got, expected.transfers)):
        assert n < skip or g == e, f"transfer {n}: hardware {g} != model {e}"
    status = unpack(engine_status_layout(params), dut.status.value)
    assert status == _wrapped(_indexed(expected.status), params.count_bits), \
        f"status {status} != model {expected.status}"
    rate = len(cycles) / (cycles[-1] - cycles[0] + 1)
    dut._log.info(f"{len(got)} transfers ({skip} priming), {len(cycles)} columns at "
                  f"{rate:.3f} columns/clock, status {expected.status}")
    if steady:    # a column every matcher_ports clocks when nothing stalls
        step = params.matcher_ports
        assert cycles == list(range(cycles[0], cycles[0] + step * len(cycles), step)), \
            f"the engine stalled its input: {rate:.3f} columns per clock"
        latency = _row_latencies(source.sent, sink.received)
        dut._log.info(f"latency from a set's last column to its first transfer: "
                      f"{min(latency)} to {max(latency)} clocks")
        assert set(latency) == {load_sidecar()["latency"]}, "latency differs from the block's"


def _row_latencies(sent, received):
    """Clocks from each set's last column to its row's first solver transfer (every set
    routed, as in the clean case)."""
    set_ends = [c for c, column in sent
                if all(lane["last"] or not column["lane_valid"] >> k & 1
                       for k, lane in column["lanes"].items())]
    row_starts = [received[0][0]] + [c for (_, prev), (c, _) in zip(received, received[1:])
                                     if prev["last"]]
    assert len(set_ends) == len(row_starts)
    return [start - end for end, start in zip(set_ends, row_starts)]

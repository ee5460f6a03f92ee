"""cocotb bench for hdl.pose.forecast.Forecast: every output transfer and every row's
forecast Ŷ against emulator.pose.forecast.ForecastModel, in order and bit for bit, the
saturation counters, the latency and the time per row.

Environment: FORECAST_CASE (path of a pickled stimulus case, see
``sim_tests.pose.forecast.stimulus``), FORECAST_ROWS (rows of it to run),
FORECAST_ROW_CLOCKS (the block's ``row_clocks``).
"""

import os
import pickle
import random

import cocotb
from amaranth.lib import data
from cocotb.triggers import ReadOnly, RisingEdge

from hdl.pose.forecast import request_layout
from hdl.pose.forecast_predictor import counters_layout, output_layout
from hdl.pose.params import solver_source
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.payload import pack, unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource

from sim_tests.pose.forecast.stimulus import saturations


def _indexed(payload):
    """Lists of a payload as the index dicts ``pack`` takes for array layouts."""
    if isinstance(payload, dict):
        return {name: _indexed(value) for name, value in payload.items()}
    if isinstance(payload, list):
        return {k: _indexed(value) for k, value in enumerate(payload)}
    return payload


def _case():
    with open(os.environ["FORECAST_CASE"], "rb") as f:
        case = pickle.load(f)
    rows = int(os.environ["FORECAST_ROWS"])
    return (case, [_indexed(r) for r in case["requests"][:rows]],
            [_indexed(r) for r in case["records"][:rows]], case["expected"][:rows],
            case["motion"][:rows])


async def _motion_monitor(dut, params, clock, seen):
    """Ŷ (``motion``) at every transfer of a row's first camera."""
    layout = output_layout(params)
    motion_layout = data.ArrayLayout(params.motion_fmt.shape(), 6)
    while True:
        await ReadOnly()
        if int(dut.o__valid.value) and int(dut.o__ready.value):
            if unpack(layout, dut.o__payload.value)["camera"] == 0:
                value = unpack(motion_layout, dut.motion.value)
                seen.append([value[k] for k in range(6)])
        await RisingEdge(clock.clk)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def forecast_matches_model(dut, traffic):
    """The case's rows: requests and records from two independent sources (the
    hardware pairs them and waits for the records the loop delay needs)."""
    params = load_params()
    case, requests, records, expected, motions = _case()
    rng = random.Random(cocotb.RANDOM_SEED)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    source = StreamSource(dut, "requests", request_layout(params), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    solver = StreamSource(dut, "records", solver_source(params.solver).layout(), clock,
                          rng=rng, valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", output_layout(params), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.4)
    seen = []
    cocotb.start_soon(_motion_monitor(dut, params, clock, seen))
    dut.alpha.value = params.alpha_raw
    dut.beta.value = params.beta_raw
    dut.initial.value = pack(data.ArrayLayout(params.motion_fmt.shape(), 6),
                             _indexed([int(v) for v in case["initial"]]))
    dut.restart.value = 0
    await reset(dut)
    dut.restart.value = 1
    await RisingEdge(dut.clk)
    dut.restart.value = 0
    cocotb.start_soon(solver.send(records))
    await source.send(requests)
    cameras = params.cameras
    sidecar = load_sidecar()
    await sink.wait_for(len(expected) * cameras,
                        timeout_cycles=len(expected) * 20 * sidecar["latency"] * cameras)
    got = [payload for _, payload in sink.received]
    flat = [o for outs in expected for o in outs]
    for n, (g, e) in enumerate(zip(got, flat)):
        assert g == e, f"transfer {n} (row {n // cameras}): hardware {g} != model {e}"
    assert len(got) == len(flat)
    assert seen == motions, "forecast Ŷ differs from the model"
    counters = unpack(counters_layout(params), dut.counters.value)
    assert counters == saturations(flat), counters
    saturated = sum(o["centre_saturated"] + o["row_saturated"] for o in flat)
    dut._log.info(f"{traffic}: {len(requests)} rows, {len(got)} transfers bit-exact; "
                  f"{saturated} saturation flags; clocks {sink.received[-1][0]}")
    if busy:
        _check_latency(dut, source, sink, cameras, sidecar["latency"],
                       int(os.environ["FORECAST_ROW_CLOCKS"]))


def _check_latency(dut, source, sink, cameras, latency, row_clocks):
    """A request taken by an idle block has its first output ``latency`` clocks later
    and its last ``row_clocks`` clocks later (outputs taken at once)."""
    starts = [cycle for cycle, _ in source.sent]
    firsts = [cycle for cycle, _ in sink.received[::cameras]]
    lasts = [cycle for cycle, _ in sink.received[cameras - 1::cameras]]
    idle = [n for n in range(len(starts)) if n == 0 or lasts[n - 1] < starts[n]]
    assert idle, "no request found the block idle"
    measured = sorted({firsts[n] - starts[n] for n in idle})
    assert measured == [latency], f"latency {measured}, expected {latency}"
    rows = [lasts[n] - starts[n] for n in range(len(starts))]
    assert set(rows) == {row_clocks}, f"request to last output {sorted(set(rows))}, expected {row_clocks}"
    dut._log.info(f"latency {latency} clocks; request to last output {min(rows)}..{max(rows)} "
                  f"clocks; requests {min(b - a for a, b in zip(starts, starts[1:]))}.."
                  f"{max(b - a for a, b in zip(starts, starts[1:]))} clocks apart")

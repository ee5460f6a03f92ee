"""cocotb bench for hdl.pose.tracking_loop.TrackingLoop: fed the measurement stream of a
real closed-loop emulator run, every forecast transfer, every pose record and the motion
track's ``Y`` of every row against the loop's model (emulator.pose.tracking_loop.TrackingLoopModel through
emulator.pipeline.run), bit for bit and in order, and the consistency stage's counters;
at full rate and with random gaps and backpressure. A restart case strobes ``restart``
mid-frame (:func:`sim_tests.pose.tracking_loop.stimulus.restart_after`); the model
restarted before the next frame, nothing is mismatched, and ``counters.restart_pending``
is set from the write until that frame boundary.

Environment: LOOP_CASE (path of a pickled case, sim_tests/pose/tracking_loop/stimulus.py).
"""

import os
import pickle
import random

import cocotb
from amaranth.lib import data
from cocotb.triggers import ClockCycles, RisingEdge

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.payload import pack, unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource
from hdl.measurement.consistency import counts_layout, settings_init, settings_layout
from hdl.pose.forecast_predictor import output_layout
from hdl.pose.row_counter import verdict_layout
from hdl.pose.tracking_loop import loop_counters_layout
from hdl.pose_solver import measurement_layout, record_layout

from sim_tests.pose.forecast.forecast_bench import _indexed
from sim_tests.pose.tracking_loop.stimulus import restart_after


async def _restart(dut, sink, case, motion_layout, timeout_cycles):
    """``initial`` ← the case's restart motion and a one-clock ``restart`` strobe once
    the sink has :func:`restart_after` forecast transfers; ``counters.restart_pending``
    then holds until the frame boundary: it clears with every forecast transfer before
    the restarted frame out and none of it."""
    await sink.wait_for(restart_after(case), timeout_cycles=timeout_cycles)
    dut.initial.value = pack(motion_layout, _indexed([int(v) for v in case["restart"][1]]))
    dut.restart.value = 1
    await RisingEdge(dut.clk)
    dut.restart.value = 0
    layout = loop_counters_layout(case["params"])
    for cycle in range(timeout_cycles):
        await RisingEdge(dut.clk)
        if not unpack(layout, dut.counters.value)["restart_pending"]:
            break
    assert cycle > 0, "restart_pending was not set after the write"
    boundary = case["restart"][0] * case["params"].height * case["params"].cameras
    assert len(sink.received) == boundary, (len(sink.received), boundary)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def loop_matches_model(dut, traffic):
    with open(os.environ["LOOP_CASE"], "rb") as f:
        case = pickle.load(f)
    params, stage = case["params"], case["stage"]
    s = params.solver
    rng = random.Random(cocotb.RANDOM_SEED)
    busy = traffic == "full_rate"
    clock = start_clock(dut)
    dut.settings.value = pack(settings_layout(stage), settings_init(stage))
    dut.alpha.value, dut.beta.value = params.alpha_raw, params.beta_raw
    if params.motion_gain == "information":
        dut.prior_weight.value, dut.smoothing.value = params.prior_raw, params.smoothing_raw
    dut.pivot_log2.value = s.pivot_log2
    dut.frame_rows.value = int(stage.frame_rows)
    motion = data.ArrayLayout(params.motion_fmt.shape(), 6)
    dut.initial.value = pack(motion, _indexed([int(v) for v in case["initial"]]))
    dut.restart.value = 0
    source = StreamSource(dut, "i", measurement_layout(s), clock, rng=rng,
                          valid_prob=1.0 if busy else 0.6)
    sink = StreamSink(dut, "o", output_layout(params), clock, rng=rng,
                      ready_prob=1.0 if busy else 0.4)
    records = StreamSink(dut, "records", record_layout(s), clock, rng=rng,
                         ready_prob=1.0 if busy else 0.5)
    verdicts = StreamSink(dut, "verdicts", verdict_layout(), clock, rng=rng,
                          ready_prob=1.0 if busy else 0.7)
    dut.track_alpha.value = params.track_alpha_raw
    track = StreamSink(dut, "track", motion, clock, rng=rng, ready_prob=1.0 if busy else 0.5)
    await reset(dut)
    dut.restart.value = 1
    await RisingEdge(dut.clk)
    dut.restart.value = 0
    cocotb.start_soon(source.send(case["inputs"]))
    timeout = 2000 * len(case["expected"])
    restart = None
    if restart_after(case) is not None:
        restart = cocotb.start_soon(_restart(dut, sink, case, motion, timeout))
    flat = [o for outs in case["expected"] for o in outs]
    await sink.wait_for(len(flat), timeout_cycles=timeout)
    await records.wait_for(len(case["records"]), timeout_cycles=timeout)
    if restart is not None:
        await restart                        # its checks of restart_pending
    await ClockCycles(dut.clk, 100)          # the last scale update is counted, Y out
    got = [payload for _, payload in sink.received]
    for n, (g, e) in enumerate(zip(got, flat)):
        assert g == e, f"forecast transfer {n} (row {n // params.cameras}): hardware {g}, model {e}"
    extra = got[len(flat):]
    assert len(extra) <= (params.loop_delay_rows + 1) * params.cameras, len(extra)
    assert len(records.received) == len(case["records"])
    assert len(verdicts.received) == len(case["inputs"]), "one verdict per measurement"
    for n, ((_, g), e) in enumerate(zip(records.received, case["records"])):
        assert g == _indexed(e), f"record {n}: hardware {g}, model {e}"
    ys = [[y[k] for k in range(6)] for _, y in track.received]
    assert len(ys) == len(case["track"]), (len(ys), len(case["track"]))
    for n, (g, e) in enumerate(zip(ys, case["track"])):
        assert g == e, f"track row {n}: hardware {g}, model {e}"
    assert unpack(motion, dut.track_y.value) == _indexed(case["track"][-1])
    counts = unpack(counts_layout(), dut.counts.value)
    assert counts == case["counts"], counts
    counters = unpack(loop_counters_layout(params), dut.counters.value)
    assert counters["mismatched"] == 0, counters
    assert counters["track_overrange"] == 0, counters
    assert counters["track_saturated"] == case["track_saturated"], counters
    if params.motion_gain == "information":
        assert counters["gain_flagged"] == case["gain_flagged"], counters
    solved = sum(r["flags"] == 0 for r in case["records"])
    dut._log.info(f"{traffic}: {len(case['inputs'])} measurements, {len(flat)} forecast "
                  f"transfers, {len(records.received)} records ({solved} solved) bit-exact, "
                  f"{len(verdicts.received)} verdicts, {len(ys)} track rows; counts {counts}; "
                  f"last record at clock "
                  f"{records.received[-1][0]}")

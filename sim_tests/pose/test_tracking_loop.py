"""The back half of the closed loop in gateware (hdl/pose/tracking_loop.py) in the Amaranth
simulator, bit-exact with the loop's model: fed the measurement stream of a real
closed-loop run (stereo20 cut to three pairs and 8 rows, three frames, loop delay 1 and
2), every forecast transfer, every pose record and the motion track's ``Y`` of every row
equal the model's, with and without
valid gaps and ready backpressure (SEED printed); the model's row slots are the
generator's; a ``restart`` written while rows are forecast takes effect at the next
frame boundary, as the model's restart there (nothing mismatched), with
``counters.restart_pending`` set from the write until then; the latency; the parameter
checks; MeasuredShift's predicted shift and translation part of every measurement
as the model's (the depth weight's inputs). The longer runs are the cocotb bench's
(sim_tests/pose/tracking_loop/)."""

import os
import random

import numpy as np
import pytest
from amaranth.sim import Simulator

from emulator.measurement.consistency import ConsistencyModel
from hdl.measurement.consistency import COUNTS
from hdl.pose.tracking_loop import TrackingLoop
from sim_tests.pose.tracking_loop.stimulus import closed_loop_case, restart_after

SEED = int(os.environ.get("SEED", "1"))
OUT_FIELDS = ("camera", "row", "centre", "source_row", "centre_saturated", "row_saturated",
              "shift_saturated", "across_saturated", "segment_rows_saturated", "last")


def build(case):
    return TrackingLoop(case["params"], case["stage"], case["coefficients"],
                        case["row_coefficients"], case["solver_store"], track_stream=True)


def record_dict(record):
    return {"row": record.row, "time": record.time, "flags": record.flags,
            "q": [record.q[k] for k in range(4)], "p": [record.p[k] for k in range(3)],
            "step": [record.step[k] for k in range(6)]}


def run_loop(case, *, seed, gaps, limit=400000):
    """The case's inputs through the gateware; returns the forecast transfers and the
    records (each with its clock), the clocks of the input transfers, the counters, the
    clocks ``counters.restart_pending`` was set and those a restart took effect in.
    With the case's ``restart`` (frame, motion) ``initial`` is set to the motion and
    ``restart`` strobed after :func:`restart_after` forecast transfers."""
    dut = build(case)
    rng = random.Random(seed)
    prob = 0.6 if gaps else 1.0
    want_out = sum(len(e) for e in case["expected"])
    got = {"o": [], "records": [], "inputs": [], "lasts": [], "requests": [], "judged": [],
           "predicted": [], "shifts": [], "verdicts": [], "counts": None, "pending": [],
           "restarting": [], "track": []}
    requests, judged, predicted = dut._requests.o, dut._stage.i, dut._shift.o

    restart_at = restart_after(case)

    async def bench(ctx):
        ctx.set(dut.initial, [int(v) for v in case["initial"]])
        ctx.set(dut.restart, 1)
        await ctx.tick()
        ctx.set(dut.restart, 0)
        queue, cycle = list(case["inputs"]), 0
        valid = was_shown = False
        while (len(got["o"]) < want_out or len(got["records"]) < len(case["records"])):
            strobe = len(got["o"]) == restart_at and "restart" not in got
            if strobe:
                got["restart"] = cycle
                ctx.set(dut.initial, [int(v) for v in case["restart"][1]])
            ctx.set(dut.restart, strobe)
            if ctx.get(dut.counters.restart_pending):
                got["pending"].append(cycle)
            if ctx.get(dut._requests.restarting):
                got["restarting"].append(cycle)
            if not valid and queue and rng.random() < prob:
                ctx.set(dut.i.payload, queue[0])
                valid = True
            ctx.set(dut.i.valid, valid)
            ready = rng.random() < prob
            ctx.set(dut.o.ready, ready)
            if valid and ctx.get(dut.i.ready):
                got["inputs"].append(cycle)
                got["lasts"] += [cycle] if queue.pop(0)["last"] else []
                valid = False
            if ctx.get(requests.valid) and ctx.get(requests.ready):
                got["requests"].append(cycle)
            if ctx.get(judged.valid) and ctx.get(judged.ready):
                got["judged"].append(cycle)
                shift = ctx.get(judged.payload)
                got["shifts"].append((shift.predicted, shift.translation))
            shown = ctx.get(predicted.valid)
            if shown and not was_shown:
                got["predicted"].append(cycle)     # the clock a result appeared
            was_shown = shown and not ctx.get(predicted.ready)
            if ready and ctx.get(dut.o.valid):
                payload = ctx.get(dut.o.payload)
                fields = {n: getattr(payload, n) for n in OUT_FIELDS}
                fields["segment_rows"] = {n: payload.segment_rows[n]
                                          for n in range(len(payload.segment_rows))}
                got["o"].append((cycle, fields))
            taking = [rng.random() < prob for _ in range(2)]
            ctx.set(dut.verdicts.ready, taking[0])
            ctx.set(dut.records.ready, taking[1])
            if taking[0] and ctx.get(dut.verdicts.valid):
                verdict = ctx.get(dut.verdicts.payload)
                got["verdicts"].append((verdict.judged, verdict.outliers, verdict.confident,
                                        verdict.last))
            track_ready = rng.random() < prob
            ctx.set(dut.track.ready, track_ready)
            if track_ready and ctx.get(dut.track.valid):
                got["track"].append([int(v) for v in ctx.get(dut.track.payload)])
            if taking[1] and ctx.get(dut.records.valid):
                got["records"].append((cycle, record_dict(ctx.get(dut.records.payload))))
            await ctx.tick()
            cycle += 1
            assert cycle < limit, (f"loop hung: {len(got['o'])} forecast transfers, "
                                   f"{len(got['records'])} records")
        ctx.set(dut.i.valid, 0)
        ctx.set(dut.o.ready, 0)
        ctx.set(dut.track.ready, 1)
        for _ in range(100):                   # the last scale update counted, Y out
            if ctx.get(dut.track.valid):
                got["track"].append([int(v) for v in ctx.get(dut.track.payload)])
            await ctx.tick()
        got["counts"] = {n: ctx.get(getattr(dut.counts, n)) for n in COUNTS}
        got["counters"] = {n: ctx.get(getattr(dut.counters, n))
                           for n in ("mismatched", "predicted_saturated", "restart_pending",
                                     "track_saturated", "track_overrange")}

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return dut, got


def check(case, got):
    """Every forecast transfer and record as the model's; beyond the case's rows only the
    forecasts of the next rows the loop delay allows (the model stops there)."""
    flat = [o for outs in case["expected"] for o in outs]
    params = case["params"]
    extra = [g for _, g in got["o"][len(flat):]]
    assert len(extra) <= (params.loop_delay_rows + 1) * params.cameras
    assert [g["row"] for g in extra] == [k // params.cameras for k in range(len(extra))]
    for n, ((_, g), e) in enumerate(zip(got["o"], flat)):
        assert g == e, f"forecast transfer {n}: hardware {g}, model {e}"
    assert len(got["records"]) == len(case["records"])
    for n, ((_, g), e) in enumerate(zip(got["records"], case["records"])):
        assert g == e, f"record {n}: hardware {g}, model {e}"
    assert got["counts"] == case["counts"]
    assert len(got["track"]) == len(case["track"])
    for n, (g, e) in enumerate(zip(got["track"], case["track"])):
        assert g == e, f"track row {n}: hardware {g}, model {e}"
    # MeasuredShift's predicted shift and its translation part (the depth weight's
    # input) of every measurement as the model's; most of them weighed below one, so
    # the records above cover the weight
    assert got["shifts"] == case["judged"]
    stage = ConsistencyModel(case["stage"])
    weights = stage.depth_weight([t["cue"] for t in case["inputs"]],
                                 [tr for _, tr in case["judged"]])
    one = 1 << case["stage"].ratio_fmt.frac_bits
    print(f"depth weights {weights.min() / one:.3f} … {weights.max() / one:.3f}, "
          f"{np.mean(weights < one):.0%} below one")
    assert np.mean(weights < one) > 0.25
    # one verdict per measurement; the outliers are the stage's count
    verdicts = np.array(got["verdicts"])
    assert len(verdicts) == len(case["inputs"])
    assert verdicts[:, 1].sum() == case["counts"]["outliers"]
    assert verdicts[:, 3].tolist() == [t["last"] for t in case["inputs"]]
    assert np.all(verdicts[:, 2] <= verdicts[:, 0])          # confident only if judged
    assert got["counters"] == {"mismatched": 0, "predicted_saturated": 0,
                               "restart_pending": 0, "track_overrange": 0,
                               "track_saturated": case["track_saturated"]}


@pytest.mark.parametrize("gaps, delay, restart", [(False, 1, None), (True, 1, None),
                                                  (True, 2, None), (False, 1, 1),
                                                  (True, 2, 2)])
def test_small_closed_loop_bit_exact(gaps, delay, restart):
    print(f"SEED={SEED}")
    case = closed_loop_case(rows=8, frames=3, delay=delay, restart=restart)
    first = 0 if restart is None else restart * case["params"].height
    slots = list(range(first)) + list(range(len(case["slots"]) - first))
    assert case["slots"] == slots       # f·frame_rows + r, counted again from a restart
    _, got = run_loop(case, seed=SEED, gaps=gaps)
    check(case, got)
    start = got["o"][0][0]
    assert got["restarting"][0] < start        # the reset's restart, before any forecast
    late = [c for c in got["pending"] if c > start]
    if restart is None:
        assert late == []
    else:
        cams = case["params"].cameras
        strobe = got["restart"]
        assert 0 < strobe < got["o"][first * cams][0]
        took = min(c for c in got["restarting"] if c > strobe)
        assert got["o"][first * cams - 1][0] < took < got["o"][first * cams][0]
        assert took > strobe + 1, "the restart did not wait for its boundary"
        # restart_pending from the clock after the write until the one it took effect in
        assert late == list(range(strobe + 1, took + 1))
    flags = [r["flags"] for r in case["records"]]
    print(f"{len(got['o'])} forecast transfers, {len(flags)} records "
          f"({flags.count(0)} solved) bit-exact; counts {got['counts']}")
    assert flags.count(0) > 0 and case["counts"]["gated_rows"] > 0


def test_loop_latency():
    """At full rate: clocks from a request's transfer to its first forecast transfer
    (the forecast's ``latency`` whenever it was idle), from a row's last measurement to
    its record, and from a record to the first forecast transfer of the row that waited
    for it (``loop_delay_rows + 1`` rows later)."""
    case = closed_loop_case(rows=8, frames=3)
    dut, got = run_loop(case, seed=SEED, gaps=False)
    check(case, got)
    p = case["params"]
    cams, delay = p.cameras, p.loop_delay_rows
    firsts = [c for c, _ in got["o"][::cams]]
    lasts = [c for c, _ in got["o"][cams - 1::cams]]
    starts = got["requests"][:len(firsts)]
    idle = [n for n in range(len(starts)) if n == 0 or lasts[n - 1] < starts[n]]
    request_to_out = sorted({firsts[n] - starts[n] for n in idle})
    records = [c for c, _ in got["records"]]
    measure_to_record = [r - m for m, r in zip(got["lasts"], records)]
    waited = [n for n in range(delay + 1, len(firsts))
              if starts[n] > max(records[n - delay - 1], lasts[n - 1])]
    record_to_out = [firsts[n] - records[n - delay - 1] for n in waited]
    # each measurement's prediction: ready ``MeasuredShift.latency`` clocks after its
    # transfer; then the clocks it waited for the stage (the unit's latency is hidden
    # where the stage was still busy with the previous measurement)
    waits = [j - r for r, j in zip(got["predicted"], got["judged"])]
    assert [r - i for i, r in zip(got["inputs"], got["predicted"])] == \
        [dut._shift.latency] * len(got["inputs"])
    firsts_of_rows = [0] + [k + 1 for k, t in enumerate(case["inputs"][:-1]) if t["last"]]
    lasts_of_rows = [k for k, t in enumerate(case["inputs"]) if t["last"]]
    solver = dut._solver
    print(f"prediction waited for the stage: first measurement of a row "
          f"{min(waits[k] for k in firsts_of_rows)}…{max(waits[k] for k in firsts_of_rows)}, "
          f"last {min(waits[k] for k in lasts_of_rows)}…{max(waits[k] for k in lasts_of_rows)}, "
          f"all {min(waits)}…{max(waits)} clocks")
    print(f"request → first forecast transfer: {request_to_out} clocks "
          f"(forecast latency {dut._forecast.latency}, row {dut._forecast.row_clocks}); "
          f"last measurement → record: {min(measure_to_record)}…{max(measure_to_record)} "
          f"(solver latency {solver.latency}, stage {dut._stage.latency}, shift "
          f"{dut._shift.latency}); record → forecast of the row that waited: "
          f"{sorted(set(record_to_out))}; rows {len(firsts)} in {firsts[-1]} clocks")
    assert request_to_out == [dut._forecast.latency]
    assert waited and min(measure_to_record) >= solver.latency


def _checks():
    from hdl.fixed import SQ
    from hdl.pose.loop_requests import RequestGenerator
    from hdl.pose.measured_shift import MeasuredShift
    case = closed_loop_case(rows=8, frames=2)
    p, stage = case["params"], case["stage"]
    stores = (case["coefficients"], case["row_coefficients"], case["solver_store"])
    return [
        (lambda: TrackingLoop("nope", stage, *stores), TypeError,
         "params must be a ForecastParams, not 'nope'"),
        (lambda: TrackingLoop(p, "nope", *stores), TypeError,
         "stage must be a ConsistencyParams, not 'nope'"),
        (lambda: TrackingLoop(p, stage.replace(segments=2), *stores), ValueError,
         "stage must have the forecast's solver and segments"),
        (lambda: TrackingLoop(p, stage.replace(frame_rows=8.5), *stores), ValueError,
         "the stage's frame_rows must be a whole number of row periods"),
        (lambda: RequestGenerator(p.replace(loop_delay_rows=7), 8), ValueError,
         "height 8 must be at least loop_delay_rows \\+ 2 = 9"),
        (lambda: RequestGenerator(p, 7), ValueError,
         "frame_rows must be an integer between 8 and 65535, not 7"),
        (lambda: RequestGenerator("nope", 8), TypeError,
         "params must be a ForecastParams, not 'nope'"),
        (lambda: MeasuredShift(p, stage.replace(predicted_fmt=SQ(9, 8))), ValueError,
         "the stage's predicted_fmt .* must be the forecast's displacement_fmt"),
    ]


@pytest.mark.parametrize("index", range(8))
def test_parameter_checks(index):
    build_it, error, message = _checks()[index]
    with pytest.raises(error, match=message):
        build_it()

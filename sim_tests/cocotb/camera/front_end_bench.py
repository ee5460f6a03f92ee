"""cocotb bench of hdl.camera_sync.CameraFrontEnd: cameras with their own PCLKs play
rows (synthetic or from a golden simulator dataset) into the front end; every row set,
skew and counter is checked against emulator.camera_sync cycle by cycle, and against
what the cameras sent.

Environment: ``ROWTRACK_DATASET`` (a dataset .npz to play instead of random images),
``RUN_SLOW=1`` (the long randomized run), ``ROWTRACK_FIGURES`` (where the performance
test writes its figures).
"""

import json
import os
import random

import cocotb

from hdl.streams import RowFlag
from sim_tests.common.cocotb_env import load_params
from sim_tests.common.dvp import DvpTiming, Fault, FAULT_KINDS
from sim_tests.cocotb.camera.harness import (SYS_PS, FrontEndRun, Scenario, dataset_images,
                                             row_runs, write_time)

TIMING = DvpTiming(width=16, height=6, hblank=6, hblank_jitter=3)
PERIOD = 240


def _scenario(params, **changes):
    n = params.n_cameras
    base = dict(n_frames=3, timing=TIMING, periods_ps=(10_400, 10_800, 11_200, 10_400)[:n],
                phases_ps=(3_001, 7_777, 1_235, 5_555)[:n], delays=(0, 3, 6, 2)[:n],
                period=PERIOD, jitter_ps=400, skew_threshold=40)
    base.update(changes)
    return Scenario(**base)


def _rng():
    return random.Random(cocotb.RANDOM_SEED)


def _all_rows(run):
    """(camera, frame, row) of every row the cameras were asked to send."""
    return {(k, f, y) for k in range(run.p.n_cameras) for f in range(run.sc.n_frames)
            for y in range(run.sc.timing.height)}


def check_rows(run, sets, expected_good):
    """Good rows carry their pixels bit-exact; flagged rows carry a prefix of theirs;
    every row in ``expected_good`` arrives good, in a set with its own frame and row."""
    good = set()
    for s in sets:
        for k, lane in s["lanes"].items():
            assert (lane["frame"], lane["row"]) == (s["frame"], s["row"])
            frame, row = lane["frame"], lane["row"]
            if frame >= run.sc.n_frames or row >= run.sc.timing.height:
                continue
            truth = [int(v) for v in run.images[k, frame, row]]
            if lane["flags"] == 0:
                assert lane["pixels"] == truth, f"camera {k} frame {frame} row {row} differs"
                good.add((k, frame, row))
            else:
                assert lane["pixels"] == truth[:len(lane["pixels"])], (
                    f"flagged row camera {k} frame {frame} row {row} is not a prefix")
    missing = expected_good - good
    assert not missing, f"good rows that did not arrive: {sorted(missing)[:10]}"
    return good


#: Clocks by which two row starts must be apart for their order as the camera sync sees
#: it to be certain (each crosses into the system clock one to two clocks after its
#: PCLK edge).
ORDER_MARGIN = 2


def pairable_rows(pk, pm, run_k, run_m, offset, height):
    """Camera ``k``'s rows of one frame that the sync must pair with the master's and
    those it may pair. It pairs row y when neither camera has started row y + 1 before
    the other's row y (``hdl.camera_sync``: the latest unpaired row start of each side is
    kept), so a skew of about a row period or more leaves a row unpaired; starts within
    ``ORDER_MARGIN`` clocks of each other may go either way."""
    def start(player, runs, y):
        return player.times[runs[y][0] + offset] / SYS_PS if y < height else float("inf")
    certain, possible = set(), set()
    for y in range(height):
        margin = min(start(pm, run_m, y + 1) - start(pk, run_k, y),
                     start(pk, run_k, y + 1) - start(pm, run_m, y))
        if margin > ORDER_MARGIN:
            certain.add(y)
        if margin > -ORDER_MARGIN:
            possible.add(y)
    return certain, possible


def check_skews(run, frames, tolerance=1):
    """Measured skews equal the skews between the PCLK edges that wrote the events into
    the crossings, within ``tolerance`` clocks, for every frame and for the rows the sync
    pairs (:func:`pairable_rows`). Returns the largest error against those edges and
    against the edges that sampled the events at the pins (the two differ by
    ``glitch_pclks + 1`` times the difference of the cameras' PCLK periods)."""
    g = run.p.glitch_pclks
    master = run.p.master
    height = run.sc.timing.height
    runs = [row_runs(pl, g) for pl in run.players]
    worst = {"write": 0.0, "pin": 0.0}
    for k in range(run.p.n_cameras):
        if k == master:
            continue
        pk, pm = run.players[k], run.players[master]
        measured_f = [s["frame_skew"] for c, cam, s in run.skews if cam == k and s["frame_valid"]]
        assert len(measured_f) == len(frames)
        measured_r = {}             # frame index -> {row: skew}; a new frame when rows restart
        f, last = 0, -1
        for c, cam, s in run.skews:
            if cam == k and s["row_valid"]:
                f, last = (f + 1, s["row"]) if s["row"] <= last else (f, s["row"])
                measured_r.setdefault(f, {})[s["row"]] = s["row_skew"]
        for i, f in enumerate(frames):
            certain, possible = pairable_rows(pk, pm, runs[k][f], runs[master][f], g + 1,
                                              height)
            rows = set(measured_r.get(i, {}))
            assert certain <= rows <= possible, (
                f"camera {k} frame {f}: rows paired {sorted(rows)}, must be "
                f"{sorted(certain)}, may be {sorted(possible)}")
        for edge, offset in (("write", g + 1), ("pin", 0)):
            for i, f in enumerate(frames):
                pairs = [(measured_f[i], pk.times[pk.frame_starts[f] + offset]
                          - pm.times[pm.frame_starts[f] + offset])]
                pairs += [(skew, pk.times[runs[k][f][y][0] + offset]
                           - pm.times[runs[master][f][y][0] + offset])
                          for y, skew in sorted(measured_r.get(i, {}).items())]
                errors = [abs(m - t / SYS_PS) for m, t in pairs]
                worst[edge] = max([worst[edge]] + errors)
    assert worst["write"] <= tolerance, (
        f"skew measured {worst['write']:.2f} clocks away from the injected skew")
    return worst


def check_timestamps(run, sets):
    """Each time stamp is the system cycle in which its word was read from the crossing:
    one to two clocks after the PCLK edge that wrote it."""
    g = run.p.glitch_pclks
    runs = [row_runs(pl, g) for pl in run.players]
    for s in sets:
        for k, lane in s["lanes"].items():
            if lane["flags"]:
                continue
            first, last = runs[k][lane["frame"]][lane["row"]]
            for stamp, sample in ((lane["t_first"], first), (lane["t_last"], last)):
                d = run.t0 + stamp * SYS_PS - write_time(run.players[k], sample, g)
                assert SYS_PS < d < 2 * SYS_PS, (
                    f"camera {k} frame {lane['frame']} row {lane['row']}: time stamp "
                    f"{stamp} is {d / SYS_PS:.2f} clocks after its pixel was written")


def latencies(run, sets):
    """Per set, clocks from the latest camera's last pixel at its input register (the
    PCLK edge that samples it) to the edge that takes the set's last pixel from ``o``."""
    g = run.p.glitch_pclks
    runs = [row_runs(pl, g) for pl in run.players]
    out = []
    for s in sets:
        pin = max(run.players[k].times[runs[k][lane["frame"]][lane["row"]][1]]
                  for k, lane in s["lanes"].items())
        out.append((run.t0 + (s["last_cycle"] + 1) * SYS_PS - pin) / SYS_PS)
    return out


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def clean_cluster(dut, traffic):
    """Three cameras with their own PCLK period, phase, jitter and row jitter: every row
    arrives bit-exact, in full sets, with the right indices, time stamps and skews."""
    await _clean_run(dut, ready=1.0 if traffic == "full_rate" else 0.6)


@cocotb.test(skip=not os.environ.get("ROWTRACK_DATASET"))
async def dataset_playback(dut):
    """The cameras play the rows of a golden simulator dataset (``ROWTRACK_DATASET``)."""
    params = load_params()
    images = dataset_images(os.environ["ROWTRACK_DATASET"], params.n_cameras,
                            TIMING.width, TIMING.height, 3)
    await _clean_run(dut, ready=0.8, images=images)


async def _clean_run(dut, ready, images=None):
    params = load_params()
    rng = _rng()
    busy = ready == 1.0
    run = FrontEndRun(dut, params, _scenario(params, ready=ready, images=images), rng)
    await run.run()
    run.check_model()
    sets = run.sets()
    check_rows(run, sets, _all_rows(run))
    assert all(s["missing"] == 0 and len(s["lanes"]) == params.n_cameras for s in sets)
    check_timestamps(run, sets)
    worst = check_skews(run, range(3))
    dut._log.info(f"largest skew error {worst['write']:.2f} clocks at the crossing, "
                  f"{worst['pin']:.2f} at the pins")
    status = run.status
    assert all(status["inputs"][k]["bad_rows"] == 0 for k in range(params.n_cameras))
    assert status["sync"]["desync"] == 0 and status["sync"]["lost"] == 0
    if busy:
        worst_latency = max(latencies(run, sets))
        dut._log.info(f"largest latency {worst_latency:.2f} clocks")
        assert worst_latency <= 16


@cocotb.test()
async def desync_flagged(dut):
    """A camera triggered too late is flagged out of sync in every frame, with skews
    equal to its delay, while its rows still join their sets. (PCLKs of one frequency
    here: row skews are paired by row index, so they must stay under a row period.)"""
    params = load_params()
    rng = _rng()
    n = params.n_cameras
    delays = (0, 3, 16, 2)[:n]
    timing = DvpTiming(width=16, height=6, hblank=6)
    run = FrontEndRun(dut, params, _scenario(params, timing=timing, delays=delays,
                                             periods_ps=(10_400,) * n, skew_threshold=10),
                      rng)
    await run.run()
    run.check_model()
    check_rows(run, run.sets(), _all_rows(run))
    check_skews(run, range(3))
    sync = run.status["sync"]
    assert sync["desync_count"][2] == 3 and sync["desync_count"][1] == 0
    assert sync["desync"] >> 2 & 1


#: camera -> faults, frame by frame; camera 0 (the master) stays clean.
FAULTS = {
    1: (Fault("short", 0, 1, 3), Fault("long", 0, 3, 2), Fault("glitch", 1, 2, 2),
        Fault("stall", 3, 2, 900_000)),
    2: (Fault("dropout", 1, 3, 2), Fault("extra_vsync", 2, 3), Fault("no_vsync", 4)),
}


@cocotb.test()
async def faults_flagged(dut):
    """Every injected fault is flagged with its reason and counted; good rows around it
    stay bit-exact; each camera is back in step at the next frame."""
    params = load_params()
    rng = _rng()
    height = TIMING.height
    run = FrontEndRun(dut, params, _scenario(params, n_frames=5, faults=FAULTS, period=340,
                                             pclk_timeout=30, align_timeout=30), rng)
    await run.run()
    run.check_model()
    sets = run.sets()
    # Rows a fault touches: the faulty row, the rest of a frame whose VSYNC went wrong,
    # and the rest of the frame a stalled camera now lags behind in.
    touched = ({(1, 0, 1), (1, 0, 3), (2, 1, 3)} | {(1, 3, y) for y in range(2, height)}
               | {(2, 2, y) for y in range(3, height)} | {(2, 4, y) for y in range(height)})
    check_rows(run, sets, _all_rows(run) - touched)
    flags = {(k, s["frame"], s["row"]): lane["flags"] for s in sets
             for k, lane in s["lanes"].items()}
    assert flags[1, 0, 1] == RowFlag.SHORT
    assert flags[1, 0, 3] == RowFlag.LONG
    assert flags[2, 1, 3] == RowFlag.SHORT          # the first piece; the second is stale
    assert flags[1, 3, 2] == RowFlag.STALL
    inputs = run.status["inputs"]
    assert inputs[1]["glitches"] == 1 and inputs[2]["glitches"] == 0
    assert inputs[1]["bad_rows"] == 3
    assert inputs[1]["reasons"] == RowFlag.SHORT | RowFlag.LONG | RowFlag.STALL
    # Camera 2: two dropout pieces, three rows after the extra VSYNC, a frame of overrun.
    assert inputs[2]["bad_rows"] == 2 + (height - 3) + height
    assert inputs[2]["reasons"] == (RowFlag.SHORT | RowFlag.SPLIT | RowFlag.FRAME
                                    | RowFlag.OVERRUN)
    assert inputs[0]["bad_rows"] == 0
    stale = run.status["align"]["stale_count"]
    assert stale[2] == 1 + (height - 3) + height
    # Back in step: the frame after each fault is complete and good.
    for frame, cam in ((3, 2), (4, 1)):
        assert all((cam, frame, y) in flags and flags[cam, frame, y] == 0
                   for y in range(height))


@cocotb.test()
async def lost_camera(dut):
    """A camera that stops sending is reported lost; rows keep flowing for the others
    after a single time-out."""
    params = load_params()
    rng = _rng()
    run = FrontEndRun(dut, params, _scenario(params, faults={2: (Fault("stop", 1),)},
                                             lost_timeout=200), rng)
    await run.run()
    run.check_model()
    sets = run.sets()
    others = {(k, f, y) for k, f, y in _all_rows(run) if k != 2 or f == 0}
    check_rows(run, sets, others)
    later = [s for s in sets if s["frame"] >= 1]
    assert all(s["missing"] == 0b100 and 2 not in s["lanes"] for s in later)
    sync = run.status["sync"]
    assert sync["lost"] >> 2 & 1 and sync["lost_count"][2] == 1
    assert run.status["align"]["missing_count"][2] == len(later)


@cocotb.test()
async def downstream_overflow(dut):
    """Downstream stops taking rows for a long while: rows that do not fit are closed
    early (OVERFLOW) or dropped, counted, and the rows after it arrive good."""
    params = load_params()
    rng = _rng()
    run = FrontEndRun(dut, params, _scenario(params, n_frames=4, stall=(PERIOD + 40, 300)),
                      rng)
    await run.run()
    run.check_model()
    sets = run.sets()
    inputs = run.status["inputs"]
    hurt = sum(inputs[k]["bad_rows"] + inputs[k]["dropped_rows"] for k in range(3))
    assert hurt > 0
    assert all(inputs[k]["reasons"] in (0, RowFlag.OVERFLOW) for k in range(3))
    assert any(RowFlag.OVERFLOW in RowFlag(lane["flags"]) for s in sets
               for lane in s["lanes"].values()) or sum(
        inputs[k]["dropped_rows"] for k in range(3)) > 0
    last_frame = {(k, 3, y) for k in range(3) for y in range(TIMING.height)}
    check_rows(run, sets, last_frame)


@cocotb.test()
async def random_no_deadlock(dut):
    """Random faults, jitter and backpressure (RUN_SLOW=1: many more frames): the front
    end matches the model cycle by cycle and drains completely."""
    params = load_params()
    rng = _rng()
    n_frames = 200 if os.environ.get("RUN_SLOW") else 4
    faults = {}
    for f in range(n_frames):
        for _ in range(rng.randint(0, 2)):
            kind = rng.choice([k for k in FAULT_KINDS if k != "stop"])
            arg = {"short": rng.randint(1, 10), "long": rng.randint(1, 4),
                   "glitch": rng.randint(1, 2), "dropout": rng.randint(1, 3),
                   "stall": 2 * rng.randint(100_000, 600_000)}.get(kind, 0)
            cam = rng.randrange(params.n_cameras)
            faults.setdefault(cam, []).append(Fault(kind, f, rng.randrange(TIMING.height), arg))
    scenario = _scenario(params, n_frames=n_frames, faults=faults,
                         ready=rng.uniform(0.3, 1.0), jitter_ps=2 * rng.randint(0, 300),
                         skew_threshold=rng.randint(5, 40))
    run = FrontEndRun(dut, params, scenario, rng)
    await run.run(extra_cycles=1200)
    model = run.check_model()
    assert all(inp.pixels.level == 0 and not inp.row_open for inp in model.inputs), \
        "rows are stuck in the front end"
    assert not model.aligner.streaming


@cocotb.test(skip=not os.environ.get("ROWTRACK_FIGURES"))
async def performance(dut):
    """Full rate, PCLK as fast as the system clock: pixels per clock per camera and the
    latency from a row's last pixel at the pins to its last pixel out of the aligner."""
    params = load_params()
    rng = _rng()
    n = params.n_cameras
    width = params.max_width
    timing = DvpTiming(width=width, height=4, hblank=8)
    periods = tuple([SYS_PS] * n)
    phases = tuple(1_001 + 2_222 * k for k in range(n))
    frame = timing.frame_pclks + 40
    run = FrontEndRun(dut, params, Scenario(
        n_frames=2, timing=timing, periods_ps=periods, phases_ps=phases,
        delays=tuple(k % 3 for k in range(n)), period=frame, skew_threshold=100,
        align_timeout=200), rng)
    await run.run()
    run.check_model()
    sets = run.sets()
    check_rows(run, sets, _all_rows(run))
    rates = []
    for s in sets:
        first = min(lane["first_cycle"] for lane in s["lanes"].values())
        rates.append(width / (s["last_cycle"] - first + 1))
    figures = {"cameras": n, "width": width, "sets": len(sets),
               "px_per_clock": min(rates), "latency_clocks": max(latencies(run, sets)),
               "skew_error_clocks": check_skews(run, range(2))["write"]}
    dut._log.info(f"performance: {figures}")
    path = os.environ.get("ROWTRACK_FIGURES")
    if path:
        with open(path, "w") as f:
            json.dump(figures, f)

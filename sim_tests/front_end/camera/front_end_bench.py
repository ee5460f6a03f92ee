"""cocotb bench of hdl.front_end.camera_sync.CameraFrontEnd: cameras with their own PCLKs play
rows (synthetic or from a golden simulator dataset) into the front end; every row set,
skew and counter is checked against emulator.front_end.camera_sync cycle by cycle, and against
what the cameras sent.

Environment: ``ROWTRACK_DATASET`` (a dataset .npz to play instead of random images),
``RUN_SLOW=1`` (the long randomized run). The full-rate figures of the benchmark are
``emulator/benches/camera_cocotb.py``.
"""

import os
import random

import cocotb

from emulator.hdl_sim.camera_harness import (FrontEndRun, Scenario, all_rows, check_rows,
                                             check_skews, check_timestamps, dataset_images,
                                             latencies)
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.dvp import FAULT_KINDS, DvpTiming, Fault
from hdl.streams import RowFlag

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
    check_rows(run, sets, all_rows(run))
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
    check_rows(run, run.sets(), all_rows(run))
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
    check_rows(run, sets, all_rows(run) - touched)
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
    others = {(k, f, y) for k, f, y in all_rows(run) if k != 2 or f == 0}
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

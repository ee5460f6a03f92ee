"""hdl.front_end.camera_input: parameter checks, and the block against emulator.front_end.camera_input cycle
by cycle in the Amaranth simulator (faults, backpressure, a PCLK faster than the system
clock)."""

import gc
import os
import random
import warnings
from contextlib import contextmanager

import numpy as np
import pytest
from amaranth.hdl import ClockDomain, Module, UnusedElaboratable
from amaranth.sim import Simulator

from emulator.front_end.camera_input import CameraInputModel, SystemClock, capture_words
from hdl.front_end.camera_input import CameraInput
from hdl.front_end.params import CameraParams
from hdl.streams import RowFlag
from emulator.hdl_sim.dvp import DvpPlayer, DvpTiming, Fault, drive_amaranth

SEED = int(os.environ.get("SEED", "6"))
SYS_PS = 10_000
SMALL = CameraParams(n_cameras=2, max_width=16, max_height=8, frame_bits=8,
                     timestamp_bits=20, timer_bits=12, count_bits=8, buffer_depth=40,
                     row_queue_depth=3)


@pytest.mark.parametrize("name, value, error, message", [
    ("n_cameras", 0, ValueError, "n_cameras must be an integer between 1 and 32, not 0"),
    ("n_cameras", 2.0, TypeError, "n_cameras must be an integer, not 2.0"),
    ("max_width", 1, ValueError, "max_width must be an integer at least 2, not 1"),
    ("pixel_bits", 17, ValueError, "pixel_bits must be an integer between 1 and 16"),
    ("cdc_depth", 12, ValueError, "cdc_depth must be a power of two, not 12"),
    ("buffer_depth", 3, ValueError, "buffer_depth must be an integer at least 4, not 3"),
    ("row_queue_depth", 1, ValueError, "row_queue_depth must be an integer at least 2"),
    ("glitch_pclks", -1, ValueError, "glitch_pclks must be an integer between 0 and 16"),
    ("master", 8, ValueError, "master must be an integer between 0 and 7, not 8"),
    ("skew_bits", 40, ValueError, "skew_bits must be an integer between 2 and 32, not 40"),
])
def test_params_reject_bad_values(name, value, error, message):
    with pytest.raises(error, match=message):
        CameraParams(**{name: value})


@contextmanager
def rejected_components():
    """Components whose constructor raised are never elaborated; collect them here
    instead of letting Amaranth warn about them in some later test."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)
        yield
        gc.collect()


def test_constructor_rejects_bad_arguments():
    with rejected_components():
        with pytest.raises(TypeError, match="params must be a CameraParams, not 3"):
            CameraInput(3)
        with pytest.raises(ValueError, match="camera must be an integer between 0 and 1, not 2"):
            CameraInput(SMALL, camera=2)
        with pytest.raises(ValueError, match="domain must be the camera's own pixel clock"):
            CameraInput(SMALL, domain="sync")


def simulate_input(params, cfg, player, cycles, ready, frame_of):
    """Run one CameraInput; returns per-cycle (offer, event) and the final status."""
    dut = CameraInput(params, camera=1, domain="pclk")
    m = Module()
    m.domains.pclk = pclk = ClockDomain("pclk")
    m.submodules.dut = dut
    record = {"offers": [], "events": [], "status": None}

    async def system(ctx):
        ctx.set(dut.cfg, cfg)
        for c in range(cycles):
            await ctx.tick()
            ctx.set(dut.now, c)
            ctx.set(dut.frame, frame_of(c))
            ctx.set(dut.o.ready, ready(c))
            valid = ctx.get(dut.o.valid)
            record["offers"].append(_fields(ctx.get(dut.o.payload)) if valid else None)
            record["events"].append(_fields(ctx.get(dut.event)))
        record["status"] = _fields(ctx.get(dut.status))

    async def camera(ctx):
        await drive_amaranth(ctx, pclk.clk, dut.dvp, player, until_ps=(cycles + 2) * SYS_PS)

    sim = Simulator(m)
    sim.add_clock(SYS_PS * 1e-12)
    sim.add_testbench(system)
    sim.add_testbench(camera, background=True)
    sim.run()
    return record


def _fields(view):
    return {name: int(getattr(view, name)) for name, _ in view.shape()}


def model_input(params, cfg, player, cycles, ready, frame_of):
    clock = SystemClock(t0=SYS_PS // 2, period=SYS_PS)
    words = dict(capture_words(params, player.samples, player.times, clock, cfg["width"]))
    model = CameraInputModel(params, 1, cfg)
    offers, events = [], []
    for c in range(cycles):
        offer = model.offer()
        offers.append(offer)
        events.append(dict(model.event))
        model.step(words.get(c), c, frame_of(c), offer is not None and bool(ready(c)))
    return {"offers": offers, "events": events, "status": model.status}


def rows_of(offers, ready):
    """Rows transferred: list of (frame, row, flags, pixels)."""
    rows, pixels = [], []
    for c, beat in enumerate(offers):
        if beat is None or not ready(c):
            continue
        pixels.append(beat["data"])
        if beat["last"]:
            rows.append((beat["frame"], beat["row"], beat["flags"], pixels))
            pixels = []
    return rows


def _compare(got, expected, cycles):
    for c in range(cycles):
        assert got["offers"][c] == expected["offers"][c], f"o differs in cycle {c}"
        ev_got, ev_exp = got["events"][c], expected["events"][c]
        for strobe, fields in (("frame_start", ("frame", "frame_time")),
                               ("row_start", ("row", "row_time"))):
            assert ev_got[strobe] == ev_exp[strobe], f"event.{strobe} differs in cycle {c}"
            if ev_got[strobe]:
                assert [ev_got[f] for f in fields] == [ev_exp[f] for f in fields], c
    assert got["status"] == expected["status"]


def _cfg(params, timing, pclk_timeout=60):
    return {"width": timing.width, "height": timing.height, "pclk_timeout": pclk_timeout}


FAULTS = (Fault("short", 0, 1, 3), Fault("long", 0, 2, 2), Fault("glitch", 0, 3, 2),
          Fault("dropout", 1, 2, 1), Fault("extra_vsync", 1, 4), Fault("no_vsync", 3),
          Fault("stall", 4, 1, 900_000))
S, L, P, F, O, T = (RowFlag.SHORT, RowFlag.LONG, RowFlag.SPLIT, RowFlag.FRAME,
                    RowFlag.OVERRUN, RowFlag.STALL)
#: (row, flags) of every row the faults above leave, frame after frame.
EXPECTED_ROWS = (
    [(0, 0), (1, S), (2, L), (3, 0), (4, 0), (5, 0)]
    + [(0, 0), (1, 0), (2, S), (2, S | P), (3, 0), (0, F), (1, F)]
    + [(y, 0) for y in range(6)]
    + [(y, O) for y in range(6, 12)]
    + [(0, 0), (1, T)] + [(y, 0) for y in range(2, 6)])
ROWS_PER_FRAME = (6, 7, 6, 6, 6)


@pytest.mark.parametrize("backpressure", [False, True])
def test_camera_input_matches_model_with_faults(backpressure):
    rng = random.Random(SEED)
    print(f"SEED={SEED}")
    timing = DvpTiming(width=12, height=6, hblank=6, hblank_jitter=2)
    frames = np.random.default_rng(SEED).integers(0, 256, (5, 6, 12))
    player = DvpPlayer(frames=frames, timing=timing, period_ps=10_400, phase_ps=3_001,
                       jitter_ps=400, rng=rng, faults=FAULTS, free_run=150)
    cycles = 1100
    ready_bits = [rng.random() < (0.5 if backpressure else 1.0) for _ in range(cycles)]
    ready = ready_bits.__getitem__
    frame_of = lambda c: c // 150
    cfg = _cfg(SMALL, timing)
    got = simulate_input(SMALL, cfg, player, cycles, ready, frame_of)
    expected = model_input(SMALL, cfg, player, cycles, ready, frame_of)
    _compare(got, expected, cycles)

    rows = rows_of(got["offers"], ready)
    assert got["status"]["glitches"] == 1
    if backpressure:
        # Rows come in faster than half of them can leave: the buffer overflows.
        assert got["status"]["reasons"] & RowFlag.OVERFLOW
        assert got["status"]["bad_rows"] + got["status"]["dropped_rows"] > len(EXPECTED_ROWS) // 4
        return
    assert [(row, RowFlag(flags)) for _, row, flags, _ in rows] == EXPECTED_ROWS
    assert got["status"]["bad_rows"] == sum(1 for _, f in EXPECTED_ROWS if f)
    assert got["status"]["dropped_rows"] == 0
    # Good rows carry their pixels bit-exact, in frames numbered as they were started.
    frame_numbers = [frame for frame, _, _, _ in rows]
    assert frame_numbers == sorted(frame_numbers)
    dataset_frame = np.repeat(np.arange(5), ROWS_PER_FRAME)
    for (_, row, flags, pixels), i in zip(rows, dataset_frame):
        if not flags:
            assert pixels == [int(v) for v in frames[i, row]]


@pytest.mark.parametrize("pixel_bits", [8, 10])
def test_good_rows_arrive_bit_exact_at_full_rate(pixel_bits):
    """No faults, no backpressure: every row arrives whole, with its pixels and indices."""
    rng = random.Random(SEED)
    params = SMALL.replace(pixel_bits=pixel_bits)
    timing = DvpTiming(width=16, height=4, hblank=2)
    frames = np.random.default_rng(SEED + 1).integers(0, 1 << pixel_bits, (2, 4, 16))
    player = DvpPlayer(frames=frames, timing=timing, period_ps=10_000, phase_ps=2_345,
                       rng=rng, free_run=120)
    cycles = 400
    ready = lambda c: True
    frame_of = lambda c: 7 + max(0, c - 100) // 120
    cfg = _cfg(params, timing)
    got = simulate_input(params, cfg, player, cycles, ready, frame_of)
    _compare(got, model_input(params, cfg, player, cycles, ready, frame_of), cycles)
    rows = rows_of(got["offers"], ready)
    assert [(f, r, fl) for f, r, fl, _ in rows] == [(7 + i, y, 0) for i in range(2)
                                                    for y in range(4)]
    for (frame, row, _, pixels) in rows:
        assert pixels == [int(v) for v in frames[frame - 7, row]]
    # One pixel per clock out when PCLK runs at the system clock.
    beats = [c for c, b in enumerate(got["offers"]) if b is not None]
    first_row = beats[:16]
    assert first_row[-1] - first_row[0] == 15
    # A row's last pixel is offered `latency` clocks after the word that closes it is
    # read from the crossing.
    clock = SystemClock(t0=SYS_PS // 2, period=SYS_PS)
    ends = [c for c, w in capture_words(params, player.samples, player.times, clock, 16)
            if w["end"]]
    lasts = [c for c, b in enumerate(got["offers"]) if b is not None and b["last"]]
    assert [c - e for c, e in zip(lasts, ends)] == [CameraInput.latency] * len(rows)


def test_fast_pclk_overflows_the_crossing():
    """PCLK faster than the system clock: the crossing fills, rows are flagged OVERFLOW
    and the block recovers; the model predicts it exactly."""
    rng = random.Random(SEED)
    timing = DvpTiming(width=16, height=3, hblank=1)
    frames = np.random.default_rng(SEED + 2).integers(0, 256, (2, 3, 16))
    params = SMALL.replace(cdc_depth=4)
    player = DvpPlayer(frames=frames, timing=timing, period_ps=4_000, phase_ps=1_111,
                       rng=rng, free_run=400)
    cycles = 450
    ready = lambda c: True
    frame_of = lambda c: 0
    cfg = _cfg(params, timing)
    got = simulate_input(params, cfg, player, cycles, ready, frame_of)
    _compare(got, model_input(params, cfg, player, cycles, ready, frame_of), cycles)
    assert got["status"]["reasons"] & RowFlag.OVERFLOW

"""cocotb bench for hdl.top.RowtrackTop, the PS side played by cocotbext-axi:

* identification and error responses through the register window;
* cameras with their own pixel clocks, configured and observed through registers
  (time base, per-camera counters after an injected fault, the row sets the front end
  hands to the measurement engine and the engine's row-set counter).

The pose path (engine → solver → UART and PS FIFO) against the emulator is the
co-simulated slice, ``emulator/hdl_sim/cosim_bench.py``.
"""

import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles

from emulator.hdl_sim.dvp import DvpPlayer, DvpTiming, Fault, drive_cocotb
from emulator.hdl_sim.payload import unpack
from emulator.hdl_sim.top_harness import engine_input, start_top
from hdl.streams import RowFlag


@cocotb.test()
async def identification_and_error_responses(dut):
    params, regmap, regs, clock = await start_top(dut)
    assert await regs.read_register("ident", "magic") == 0x5257544B
    assert await regs.read_register("ident", "map_crc") == regmap.layout_crc()
    cameras = await regs.read_register("ident", "cameras")
    assert cameras & 0xFF == params.camera.n_cameras
    assert await regs.read_register("ident", "clk_khz") == params.clk_hz // 1000
    for address in (regmap.base + 0xFFC, regmap.base + 0x3, regmap.base + regmap.size):
        assert not (await regs.read(address))[1]
        assert not await regs.write(address, 1)
    # The bus still answers after the errors.
    assert await regs.read_register("ident", "magic") == 0x5257544B


@cocotb.test()
async def cameras_run_and_their_counters_are_visible(dut):
    """Two frames from every camera (one short row injected on camera 1): every row
    reaches the measurement engine, which counts the row sets; time base, frame number,
    skews and the bad-row counter read back. Rows are as wide as the engine's lanes
    (``max_width``): a narrower row is padded by the lanes' framers to their width, so
    rows would arrive faster than the engine takes them."""
    params, regmap, regs, clock = await start_top(dut)
    cam = params.camera
    rng = random.Random(cocotb.RANDOM_SEED)
    timing = DvpTiming(width=cam.max_width, height=4, hblank=6)
    n_frames, period = 2, timing.frame_pclks * 12 // 10
    images = np.array([[[[rng.randrange(1 << cam.pixel_bits) for _ in range(timing.width)]
                         for _ in range(timing.height)] for _ in range(n_frames)]
                       for _ in range(cam.n_cameras)])
    faults = {1: (Fault("short", frame=1, row=2, arg=3),)}
    players = [DvpPlayer(frames=images[k], timing=timing, period_ps=10_400 + 400 * k,
                         phase_ps=3_001 + 2_222 * k, rng=rng, faults=faults.get(k, ()))
               for k in range(cam.n_cameras)]
    for k, player in enumerate(players):
        cocotb.start_soon(drive_cocotb(dut, f"dvp__{k}", f"pclk{k}_clk", player,
                                       trigger=lambda k=k: int(dut.fsin.value) >> k & 1))
    monitor = engine_input(dut, clock)
    await regs.write_register("camera", "input", {"width": timing.width,
                                                  "height": timing.height,
                                                  "pclk_timeout": 200})
    await regs.write_register("camera", "align", {"enable": (1 << cam.n_cameras) - 1,
                                                  "timeout": 60})
    sync = {"trigger_enable": 1, "period": period, "pulse": 4, "exposure": 20,
            "delay": {k: 2 * k for k in range(cam.n_cameras)}, "skew_threshold": 100,
            "lost_timeout": 0}
    before = await regs.read_register("camera", "time")
    await regs.write_register("camera", "sync", sync)
    await ClockCycles(dut.clk, n_frames * period)
    while any(player.busy for player in players):
        await ClockCycles(dut.clk, 50)
    await regs.write_register("camera", "sync", {**sync, "trigger_enable": 0})
    await ClockCycles(dut.clk, 200)

    time = unpack(regmap.find("camera", "time").register.shape,
                  await regs.read_register("camera", "time"))
    assert time["now"] > unpack(regmap.find("camera", "time").register.shape, before)["now"]
    assert time["frame"] >= n_frames - 1
    inputs = [unpack(cam.input_status_layout(), await regs.read_register("camera", "inputs", k))
              for k in range(cam.n_cameras)]
    assert [s["bad_rows"] for s in inputs] == [0, 1] + [0] * (cam.n_cameras - 2)
    assert inputs[1]["reasons"] & RowFlag.SHORT
    rows = set()
    for _, column in monitor.columns:
        beat = unpack(cam.aligned_layout(), column)
        rows |= {(k, beat["lanes"][k]["frame"], beat["lanes"][k]["row"])
                 for k in range(cam.n_cameras)
                 if beat["lane_valid"] >> k & 1 and beat["lanes"][k]["last"]}
    expected = {(k, f, y) for k in range(cam.n_cameras) for f in range(n_frames)
                for y in range(timing.height)}
    assert rows == expected, f"rows out: missing {sorted(expected - rows)[:5]}"
    engine = unpack(regmap.find("engine", "status").register.shape,
                    await regs.read_register("engine", "status"))
    assert engine["row_sets"] == n_frames * timing.height and engine["dropped"] == 0, engine
    dut._log.info(f"{len(rows)} camera rows into the engine; counters {inputs}, "
                  f"engine {engine}")

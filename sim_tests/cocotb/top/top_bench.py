"""cocotb bench for hdl.top.RowtrackTop, the PS side played by cocotbext-axi:

* identification and error responses through the register window;
* cameras with their own pixel clocks, configured and observed through registers
  (time base, per-camera counters after an injected fault, aligned rows out);
* the pose path: solver coefficients loaded through registers, measurement rows in,
  pose packets on the UART line compared byte for byte with the emulator (solver model
  → packet model), the same records read from the PS FIFO through registers, and the
  counters read back.
"""

import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge

from emulator import packets
from emulator.pose_solver import pose_solver_model
from hdl.pose_solver import measurement_layout
from hdl.streams import RowFlag
from sim_tests.cocotb.pose_solver.stimulus import build_case, mixed_rows
from sim_tests.cocotb.regs.access import Registers
from sim_tests.cocotb.uart.uart_bench import UartMonitor, wait_idle
from sim_tests.common.clocking import reset, start_clock
from sim_tests.common.cocotb_env import load_params
from sim_tests.common.dvp import DvpPlayer, DvpTiming, Fault, drive_cocotb
from sim_tests.common.payload import unpack
from sim_tests.common.streams import StreamSource

#: The coefficient-store case the top is built with (see test_top.py).
SOLVER_CASE = "random"
#: UART divisor for the bench: one clock per bit keeps packets short.
DIVISOR = 16


async def _start(dut, *, rows_ready=True):
    """Clock, quiet inputs, reset; returns (params, regmap, registers, clock)."""
    params = load_params()
    regmap = params.regmap()
    clock = start_clock(dut)
    dut.rows__ready.value = int(rows_ready)
    dut.measurements__valid.value = 0
    for k in range(params.camera.n_cameras):
        getattr(dut, f"pclk{k}_rst").value = 1
        getattr(dut, f"pclk{k}_clk").value = 0
        for pin in ("vsync", "href", "data"):
            getattr(dut, f"dvp__{k}__{pin}").value = 0
    regs = Registers(dut, regmap, rng=random.Random(cocotb.RANDOM_SEED))
    await reset(dut)
    for k in range(params.camera.n_cameras):
        getattr(dut, f"pclk{k}_rst").value = 0
    return params, regmap, regs, clock


@cocotb.test()
async def identification_and_error_responses(dut):
    params, regmap, regs, _ = await _start(dut)
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
    """Two frames from every camera (one short row injected on camera 1): rows leave on
    ``rows``; time base, frame number, skews and the bad-row counter read back."""
    params, regmap, regs, _ = await _start(dut)
    cam = params.camera
    rng = random.Random(cocotb.RANDOM_SEED)
    timing = DvpTiming(width=12, height=4, hblank=6)
    n_frames, period = 2, 300
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
    rows = set()

    async def collect():
        layout = cam.aligned_layout()
        while True:
            await RisingEdge(dut.clk)
            await ReadOnly()
            if int(dut.rows__valid.value):
                beat = unpack(layout, dut.rows__payload.value)
                for k in range(cam.n_cameras):
                    lane = beat["lanes"][k]
                    if beat["lane_valid"] >> k & 1 and lane["last"]:
                        rows.add((k, lane["frame"], lane["row"]))

    cocotb.start_soon(collect())
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
    expected = {(k, f, y) for k in range(cam.n_cameras) for f in range(n_frames)
                for y in range(timing.height)}
    assert rows == expected, f"rows out: missing {sorted(expected - rows)[:5]}"
    dut._log.info(f"{len(rows)} camera rows out; counters {inputs}")


def _case_coefficients(params, rows):
    """The case's coefficients of the table rows ``rows`` uses (the rest stay zero)."""
    _, coefficients, _ = build_case(SOLVER_CASE)
    loaded = np.zeros_like(coefficients)
    used = sorted({int(r) for r in rows.row})
    loaded[:, used] = coefficients[:, used]
    return loaded, used


@cocotb.test()
async def poses_through_registers_solver_uart_and_fifo(dut):
    params, regmap, regs, clock = await _start(dut)
    solver, po = params.solver, params.pose_output
    rng = np.random.default_rng(cocotb.RANDOM_SEED)
    rows = mixed_rows(SOLVER_CASE, solver, None, rng, 24)
    coefficients, used = _case_coefficients(solver, rows)
    for row in used:
        for slot in range(solver.slots):
            for index in range(9):
                await regs.write_register("solver", "coef", {
                    "addr": slot * solver.rows + row, "index": index,
                    "data": int(coefficients[slot, row, index])})
    await regs.write(regs.address(regmap.find("pose_out", "uart_divisor")), DIVISOR)
    monitor = UartMonitor(dut, params.uart, DIVISOR, line="uart_tx")
    source = StreamSource(dut, "measurements", measurement_layout(solver), clock)

    packet_clocks = po.packet.packet_bytes * packets.uart_byte_clocks(params.uart, DIVISOR)
    transfers = rows.transfers()
    for r in range(len(rows)):
        count = int(np.sum(rows.present[r]))
        await source.send(transfers[:count])
        del transfers[:count]
        await ClockCycles(dut.clk, packet_clocks + 200)
    await wait_idle(dut, monitor, 100)

    model = pose_solver_model(solver, coefficients, rows)
    poses = [{"t_row": int(model["time"][k]), "row": int(model["row"][k]),
              "flags": int(model["flags"][k]), "position": [int(v) for v in model["p"][k]],
              "quaternion": [int(v) for v in model["q"][k]]} for k in range(len(rows))]
    expected = [record for _, record in packets.keep_poses(po, poses, 1)]
    assert bytes(monitor.received) == b"".join(packets.encode_packet(po.packet, r)
                                               for r in expected), "UART bytes differ"
    assert monitor.framing_errors == 0

    flags = np.bincount(model["flags"], minlength=9)
    counters = unpack(regmap.find("solver", "counters").register.shape,
                      await regs.read_register("solver", "counters"))
    assert counters["solved"] == int(flags[0]) and counters["ill"] == int(flags[2])
    status = unpack(po.status_layout(), await regs.read_register("pose_out", "status"))
    assert (status["poses"], status["packets"], status["uart_dropped"], status["fifo_level"]) \
        == (len(rows), len(rows), 0, len(rows))

    pop = regmap.find("pose_out", "fifo_pop")
    for record in expected:
        head = unpack(po.packet.record_layout(), await regs.read_register("pose_out",
                                                                         "fifo_head"))
        head = {k: [v[i] for i in sorted(v)] if isinstance(v, dict) else v
                for k, v in head.items()}
        assert head == record, f"FIFO record {record['seq']} differs"
        assert await regs.write(regs.address(pop), 1)
    status = unpack(po.status_layout(), await regs.read_register("pose_out", "status"))
    assert status["fifo_level"] == 0
    dut._log.info(f"{len(expected)} pose records bit-exact on the UART and in the FIFO; "
                  f"solver flags {flags.tolist()}")

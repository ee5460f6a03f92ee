"""Benchmark of the SoC integration: each board's closed-loop top (resources, pins, pose
rate, latency), the UART link's packet rate measured in simulation, and the host tool on
a faulty pseudo-terminal link.

Figures (prefixed ``top.`` by the registry), per board rig ``<rig>``: ``cameras``,
``lut``, ``ff``, ``bram36``, ``dsp48``, their share of the xc7z020 (``*_pct``),
``lut_levels``, ``io_pins``, ``io_pins_left``, ``clk_hz``, ``pose_rate_hz`` (delivered),
``capacity_hz``, ``latency_clocks``, ``latency_us`` (co-simulated);
``link.clocks_per_packet`` and ``link.packets_per_s`` at the board top's baud and clock;
``host.packets_ok``, ``host.packets_bad`` (damaged packets the host counted),
``host.packets_sent``, ``host.packets_damaged`` (what the emulator damaged) and ``host.decoder_packets_per_s``
(the decoder alone on the same bytes: whether the host keeps up with the link).
"""

import time

import numpy as np

from emulator.output import packets
from emulator.synth import XC7Z020, synth_report

#: Packets played into the pseudo-terminal, and the fault probabilities per packet.
HOST_PACKETS = 2000
FAULTS = {"flip": 0.04, "drop": 0.04, "truncate": 0.04}
SEED = 2026


def _link_clocks_per_packet(params, divisor, count=3):
    """Clocks between the start bits of back-to-back packets on the PoseLink's line."""
    from amaranth.sim import Simulator
    from hdl.output.link import PoseLink

    dut = PoseLink(params)
    po = params.pose_output
    starts = []
    frame = sum(packets.uart_bit_clocks(params.uart, divisor))
    packet_bytes = po.packet.packet_bytes

    async def testbench(ctx):
        ctx.set(dut.cfg, {"uart_enable": 1, "fifo_enable": 0, "decimation": 1,
                          "rate_window": 0})
        ctx.set(dut.divisor, divisor)
        ctx.set(dut.pose.valid, 1)                 # a pose every clock: the link is the limit
        previous, cycle, since = 1, 0, frame
        while len(starts) < count * packet_bytes:
            line = ctx.get(dut.tx)
            if previous and not line and since >= frame:
                starts.append(cycle)               # a start bit (not a 0 data bit)
                since = 0
            previous, cycle, since = line, cycle + 1, since + 1
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    packet_starts = starts[::packet_bytes]
    gaps = set(np.diff(packet_starts).tolist())
    if len(gaps) != 1:
        raise AssertionError(f"packets are not evenly spaced on a saturated link: {gaps}")
    return gaps.pop()


def _host_on_pty(params):
    """The host tool on a pseudo-terminal fed with damaged packets."""
    import serial
    from emulator.output.host import PacketDecoder, PtyLink, run_host

    rng = np.random.default_rng(SEED)
    packet = params.pose_output.packet
    records = [{"seq": k & 0xFFFF, "skipped": 0, "t_row": int(rng.integers(0, 2**32)),
                "row": int(rng.integers(0, 480)), "flags": 0,
                "position": [int(v) for v in rng.integers(-2**31, 2**31, 3)],
                "quaternion": [int(v) for v in rng.integers(-2**15, 2**15, 4)]}
               for k in range(HOST_PACKETS)]
    data, intact = packets.damaged_stream(packet, records, rng, **FAULTS)
    with PtyLink(data) as link:
        port = serial.Serial(link.path, params.baud, timeout=0.05)
        try:
            link.play()
            stats = run_host(port, count=len(intact), seconds=120, live=False)
        finally:
            port.close()
    # Can the host keep up with the link? The decoder alone on the same bytes.
    decoder = PacketDecoder(packet)
    start = time.perf_counter()
    for at in range(0, len(data), 4096):
        decoder.feed(data[at:at + 4096])
    decode_rate = HOST_PACKETS / (time.perf_counter() - start)
    if stats.packets_ok != len(intact):
        raise AssertionError(f"the host decoded {stats.packets_ok} of {len(intact)} intact "
                             f"packets")
    return {"host.packets_sent": HOST_PACKETS, "host.packets_damaged": HOST_PACKETS - len(intact),
            "host.packets_ok": stats.packets_ok, "host.packets_bad": stats.packets_lost,
            "host.crc_errors": stats.crc_errors,
            "host.decoder_packets_per_s": round(decode_rate)}


EXTRA_PREFIXES = ("host",)
#: Boards whose closed-loop top is measured (their rig's build, ``rowtrack build``); the
#: figures are keyed by the board's rig.
BOARDS = ("microzed-7020",)
#: The co-simulated slice of the board rig that gives the latency and the clocks per row
#: set: rows around the optical centre, frames (frame 0 and one tracked frame).
SLICE_ROWS, SLICE_FRAMES, SLICE_SEED = 8, 2, 1


def _synthesis(rig):
    """Resources and LUT levels of ``rig``'s closed-loop top against the xc7z020 (in
    ``rowtrack synth-report``'s ``top_closed`` directory: its result is reused when the
    Verilog is the same)."""
    from hdl.top import closed_loop_top
    synth = synth_report(closed_loop_top(rig), "top_closed")
    figures = {key: synth[key] for key in ("lut", "ff", "bram36", "dsp48", "lut_levels")}
    for key, capacity in XC7Z020.items():
        figures[f"{key}_pct"] = round(100 * synth[key] / capacity, 2)
    return figures


def _slice_timing(rig_name):
    """Latency (last pixel at the pins → PS FIFO record) and clocks per row set of a
    co-simulated slice of ``rig_name``'s closed-loop top (Verilator), rows at the rig's
    row period; raises when the slice differs from the emulator."""
    from golden.rig import preset
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    from emulator.cosim_loop import closed_loop_cosim, cut_rig
    rig = preset(rig_name)
    cut = cut_rig(rig, SLICE_ROWS)
    dataset = simulate(cut, default_scene_spec(SLICE_SEED), make_trajectory("paper"),
                       SLICE_FRAMES / cut.cameras[0].fps, seed=SLICE_SEED)
    result = closed_loop_cosim(dataset, row_period_s=rig.cameras[0].t_r,
                               frames=SLICE_FRAMES, sim="verilator", seed=SLICE_SEED,
                               build_dir=f"build/bench_top_{rig_name}", progress=True)
    if result.all_mismatches or not result.rows_match:
        raise AssertionError(f"the {rig_name} slice differs from the emulator: "
                             f"{result.first_mismatch}")
    return result


def measure_board(board_name):
    """``top.<rig>.*`` of a board's closed-loop build (module docstring)."""
    from golden.rig import preset
    from hdl import board
    from hdl.top import board_config
    spec = board.board(board_name)
    rig = preset(spec.rig)
    config = board_config(rig)
    cam = rig.cameras[0]
    timing = _slice_timing(spec.rig)
    figures = {"cameras": len(rig.cameras), **_synthesis(spec.rig),
               "io_pins": len(spec.pins_used()), "io_pins_left": len(spec.pins_left()),
               "clk_hz": config.top.clk_hz,
               "pose_rate_hz": round(cam.fps * cam.height),
               "capacity_hz": round(timing.clk_hz / timing.clocks_per_row_set),
               "latency_clocks": timing.latency_clocks,
               "latency_us": round(1e6 * timing.latency_clocks / timing.clk_hz, 3)}
    return {f"{spec.rig}.{key}": value for key, value in figures.items()}


def measure():
    from hdl import board
    from hdl.top import board_config
    from golden.rig import preset
    figures = {}
    for name in BOARDS:
        figures.update(measure_board(name))
    params = board_config(preset(board.board(BOARDS[0]).rig)).top
    divisor = params.uart.divisor_raw(params.clk_hz, params.baud)
    clocks = _link_clocks_per_packet(params, divisor)
    figures["link.clocks_per_packet"] = clocks
    figures["link.packets_per_s"] = round(params.clk_hz / clocks, 1)
    figures.update(_host_on_pty(params))
    return figures


def report(figures):
    from hdl import board
    from hdl.top import board_config
    from golden.rig import preset
    sections = []
    for name in BOARDS:
        spec = board.board(name)
        params = board_config(preset(spec.rig)).top
        cam = preset(spec.rig).cameras[0]
        keys = sorted(k for k in figures if k.startswith(spec.rig + "."))
        rows = "\n".join(f"| {k[len(spec.rig) + 1:]} | {figures[k]} |" for k in keys)
        sections.append(f"""## `{spec.rig}` on the {name}

`rowtrack build --board {name}`'s top: `hdl.top.closed_loop_top("{spec.rig}")`,
{params.camera.n_cameras} cameras in {len(params.pairs)} stereo pairs,
{cam.width}×{cam.height} at {cam.fps:g} fps, the measurement engine with
{params.camera.n_cameras} temporal lanes of {params.segments} segments,
{len(params.pairs)} stereo lanes and the router, the closed loop (forecast,
consistency, tracking status), the pose solver with {params.solver.slots} slots, pose
output and register file; no PS7, pins or GP0 bridge.

* Resources (`lut`, `ff`, `bram36`, `dsp48`, `*_pct` of the xc7z020: {XC7Z020['lut']}
  LUTs, {XC7Z020['ff']} FFs, {XC7Z020['bram36']} BRAM36, {XC7Z020['dsp48']} DSP48E1) and
  `lut_levels` (the deepest path): Yosys `synth_xilinx -family xc7`.
* `io_pins`: package pins the cameras and the UART take on the board, `io_pins_left` of
  its user pins free.
* `pose_rate_hz`: pose updates the cameras deliver, one per row set: fps × rows
  ({cam.fps:g} × {cam.height}; no staggered triggers yet). `capacity_hz`: `clk_hz` / the
  clocks the engine takes per row set in the co-simulated slice, what the hardware could
  take.
* `latency_clocks`, `latency_us`: the largest time from a row set's last pixel at the
  pins to its record in the PS FIFO, at `clk_hz`, in a Verilator co-simulation of the
  closed-loop top ({SLICE_ROWS} rows around the optical centre × {SLICE_FRAMES} frames,
  seed {SLICE_SEED}, rows at the rig's row period), equal to the emulator record by record
  (checked).

| figure | value |
|---|---|
{rows}
""")
    rest = "\n".join(f"| {k} | {figures[k]} |" for k in sorted(figures)
                      if k.split(".", 1)[0] in ("link", "host"))
    return f"""# SoC integration: the board tops' resources, latency and rate; UART link; host tool

The board rigs' closed-loop tops (issue 17). stereo20 on a larger Zynq-7000 has no
synthesized top yet. Per-block figures: [resources.md](resources.md).

{chr(10).join(sections)}
## UART link and host tool

* Link: Amaranth simulation of the pose output and UART at the board top's baud rate and
  clock with a pose every clock (the link saturated): clocks between packet starts, and
  the packet rate it gives.
* Host: {HOST_PACKETS} packets from the emulator, each damaged with probability
  {FAULTS['flip']} (1–3 bit flips), {FAULTS['drop']} (1–3 bytes dropped) or
  {FAULTS['truncate']} (cut short), written into a pseudo-terminal and read by
  `emulator.output.host.run_host` through pyserial. `host.packets_ok` must equal the intact
  packets (checked) and `host.packets_bad` counts the damaged ones from the sequence
  numbers. `host.decoder_packets_per_s` is the decoder alone on the same bytes (this
  machine, shared with other jobs): it must exceed `link.packets_per_s` for the host to
  keep up with the link.

| figure | value |
|---|---|
{rest}
"""

"""Benchmark of the SoC integration: the closed-loop tops of issue 17's two targets
(:mod:`emulator.top_targets`: resources on their devices, pins, pose rate, latency), the
UART link's packet rate measured in simulation, and the host tool on a faulty
pseudo-terminal link.

Figures (prefixed ``top.`` by the registry), per target rig ``<rig>``: ``cameras``,
``lut``, ``ff``, ``bram36``, ``dsp48``, their share of the target's device (``*_pct``),
``fits`` (LUT, BRAM36 and DSP48 within 80 %), ``lut_levels``, ``io_pins`` (and
``io_pins_left`` on a board), ``clk_hz``, ``pose_rate_hz`` (delivered), ``capacity_hz``,
``latency_clocks``, ``latency_us`` (co-simulated); ``partition_check.*`` (the board top
synthesized whole and in partitions); ``link.clocks_per_packet`` and
``link.packets_per_s`` at the board top's baud and clock; ``host.packets_ok``,
``host.packets_bad`` (damaged packets the host counted), ``host.packets_sent``,
``host.packets_damaged`` (what the emulator damaged) and ``host.decoder_packets_per_s``
(the decoder alone on the same bytes: whether the host keeps up with the link).
"""

import time
from dataclasses import replace

import numpy as np

from emulator.output import packets
from emulator.top_targets import DEVICES, FIT_PCT, TARGETS, top_resources

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
#: The co-simulated slice of a rig that gives the latency and the clocks per row set: rows
#: around the optical centre, frames (frame 0 and one tracked frame).
SLICE_ROWS, SLICE_FRAMES, SLICE_SEED = 8, 2, 1


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


def _io_pins(top_target, cameras):
    """``io_pins`` (and ``io_pins_left`` on a board): package pins the cameras and the
    UART take on the target's board; without a board, the pins they need (each camera's
    :data:`hdl.board.spec.PINS_PER_CAMERA`, and the UART's TXD)."""
    from hdl import board
    from hdl.board.spec import PINS_PER_CAMERA
    if top_target.board is None:
        return {"io_pins": cameras * PINS_PER_CAMERA + 1}
    spec = board.board(top_target.board)
    return {"io_pins": len(spec.pins_used()), "io_pins_left": len(spec.pins_left())}


def measure_target(top_target):
    """The figures of a target's closed-loop top (module docstring), without the
    ``<rig>.`` prefix."""
    from golden.rig import preset
    from hdl.top import board_config
    rig = preset(top_target.rig)
    config = board_config(rig)
    cam = rig.cameras[0]
    timing = _slice_timing(top_target.rig)
    resources = top_resources(top_target, progress=lambda line: print(f"[synth] {line}",
                                                                      flush=True))
    return {"cameras": len(rig.cameras), **resources,
            **_io_pins(top_target, len(rig.cameras)),
            "clk_hz": config.top.clk_hz,
            "pose_rate_hz": round(cam.fps * cam.height),
            "capacity_hz": round(timing.clk_hz / timing.clocks_per_row_set),
            "latency_clocks": timing.latency_clocks,
            "latency_us": round(1e6 * timing.latency_clocks / timing.clk_hz, 3)}


def partition_check(top_target, whole):
    """The partitioned synthesis of a target that also synthesizes whole (``whole``: its
    :func:`~emulator.top_targets.top_resources`, already measured): each figure of both
    and the difference in per cent (``partition_check.*``), what summing partitions
    misses."""
    parts = top_resources(replace(top_target, partitioned=True))
    figures = {}
    for key in ("lut", "ff", "bram36", "dsp48", "lut_levels"):
        figures[f"{key}_whole"], figures[f"{key}_parts"] = whole[key], parts[key]
    for key in ("lut", "ff"):
        figures[f"{key}_diff_pct"] = round(100 * (parts[key] - whole[key]) / whole[key], 2)
    return {f"partition_check.{key}": value for key, value in figures.items()}


def measure():
    from hdl.top import board_config
    from golden.rig import preset
    figures = {}
    measured = {}
    for top_target in TARGETS:
        measured[top_target.rig] = measure_target(top_target)
        figures.update({f"{top_target.rig}.{key}": value
                        for key, value in measured[top_target.rig].items()})
    figures.update(partition_check(TARGETS[0], measured[TARGETS[0].rig]))
    params = board_config(preset(TARGETS[0].rig)).top
    divisor = params.uart.divisor_raw(params.clk_hz, params.baud)
    clocks = _link_clocks_per_packet(params, divisor)
    figures["link.clocks_per_packet"] = clocks
    figures["link.packets_per_s"] = round(params.clk_hz / clocks, 1)
    figures.update(_host_on_pty(params))
    return figures


def _target_section(top_target, figures):
    from golden.rig import preset
    from hdl.board.spec import PINS_PER_CAMERA
    from hdl.top import board_config
    params = board_config(preset(top_target.rig)).top
    cam = preset(top_target.rig).cameras[0]
    capacity = DEVICES[top_target.device]
    rig = top_target.rig
    keys = sorted(k for k in figures if k.startswith(rig + "."))
    rows = "\n".join(f"| {k[len(rig) + 1:]} | {figures[k]} |" for k in keys)
    if top_target.board:
        where = (f"`rowtrack build --board {top_target.board}`'s top: "
                 f"`hdl.top.closed_loop_top(\"{rig}\")`")
        pins = ("`io_pins`: package pins the cameras and the UART take on the board, "
                "`io_pins_left` of its user pins free.")
    else:
        where = (f"`hdl.top.closed_loop_top(\"{rig}\")` (no supported board carries its "
                 f"cameras: [board_rig.md](../board_rig.md), \"The two targets' fit\")")
        pins = (f"`io_pins`: package pins its cameras ({PINS_PER_CAMERA} DVP signals each) "
                f"and the UART need; no board, so none are assigned.")
    how = ("synthesized in partitions (`emulator.synth_partitions`: one temporal lane and "
           "one stereo lane synthesized alone and counted per copy, the rest with the "
           "lanes as black boxes; the 4 GiB WebAssembly Yosys cannot flatten this top; "
           "`lut_levels` is the deepest path within a partition). `partition_check` below "
           "measures what the sum misses on the board rig's top"
           if top_target.partitioned else "flattened")
    return f"""## `{rig}` on the {top_target.device}

{where},
{params.camera.n_cameras} cameras in {len(params.pairs)} stereo pairs,
{cam.width}×{cam.height} at {cam.fps:g} fps, the measurement engine with
{params.camera.n_cameras} temporal lanes of {params.segments} segments,
{len(params.pairs)} stereo lanes and the router, the closed loop (forecast,
consistency, tracking status), the pose solver with {params.solver.slots} slots, pose
output and register file; no PS7, pins or GP0 bridge.

* Resources (`lut`, `ff`, `bram36`, `dsp48`, `*_pct` of the {top_target.device}:
  {capacity['lut']} LUTs, {capacity['ff']} FFs, {capacity['bram36']} BRAM36,
  {capacity['dsp48']} DSP48E1) and `lut_levels` (the deepest path). `lut` counts what
  the device's LUT capacity counts (Vivado's Slice LUTs): `lut_logic`, LUTs as logic,
  plus `lut_memory`, LUTs as distributed RAM and shift registers. Yosys
  `synth_xilinx -family xc7`, {how}. `fits`: LUT, BRAM36 and DSP48 each at most
  {FIT_PCT:g} % of the device.
* {pins}
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
"""


def report(figures):
    sections = "\n".join(_target_section(t, figures) for t in TARGETS)
    check = "\n".join(f"| {k.split('.', 1)[1]} | {figures[k]} |" for k in sorted(figures)
                       if k.startswith("partition_check."))
    rest = "\n".join(f"| {k} | {figures[k]} |" for k in sorted(figures)
                      if k.split(".", 1)[0] in ("link", "host"))
    return f"""# SoC integration: the closed-loop tops' resources, latency and rate; UART link; host tool

Issue 17's two targets from the one parameterised top (`emulator.top_targets`): the
board rig on the xc7z020 and stereo20 on the xc7z045. Per-block figures:
[resources.md](resources.md).

{sections}
## Partitioned against whole synthesis

`{TARGETS[0].rig}`'s top synthesized both ways: flattened (`*_whole`) and in partitions
as stereo20's is (`*_parts`); `*_diff_pct` = (parts − whole) / whole.

| figure | value |
|---|---|
{check}

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

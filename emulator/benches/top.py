"""Benchmark of the SoC integration: resources of the pipeline top, the UART link's
packet rate measured in simulation, and the host tool on a faulty pseudo-terminal link.

Figures (prefixed ``top.`` by the registry): ``lut``, ``ff``, ``bram36``, ``dsp48``,
``lut_levels`` and their share of the xc7z020; ``link.clocks_per_packet`` and
``link.packets_per_s`` at 3 Mbaud and 100 MHz; ``host.packets_ok``,
``host.packets_bad`` (damaged packets the host counted), ``host.packets_sent``,
``host.packets_damaged`` (what the emulator damaged) and ``host.decoder_packets_per_s``
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


def measure():
    from hdl.top import RowtrackTop
    from hdl.top_params import TopParams
    params = TopParams()
    figures = {}
    synth = synth_report(RowtrackTop(params), "top")
    for key in ("lut", "ff", "bram36", "dsp48", "lut_levels"):
        figures[key] = synth[key]
    for key, capacity in XC7Z020.items():
        figures[f"{key}_percent"] = round(100 * synth[key] / capacity, 2)
    divisor = params.uart.divisor_raw(params.clk_hz, params.baud)
    clocks = _link_clocks_per_packet(params, divisor)
    figures["link.clocks_per_packet"] = clocks
    figures["link.packets_per_s"] = round(params.clk_hz / clocks, 1)
    figures.update(_host_on_pty(params))
    return figures


def report(figures):
    from hdl.top_params import TopParams
    params = TopParams()
    rows = "\n".join(f"| {key} | {value} |" for key, value in sorted(figures.items()))
    return f"""# SoC integration: top-level resources, UART link, host tool

* Resources: Yosys `synth_xilinx -family xc7` of `hdl.top.RowtrackTop` with its default
  parameters ({params.camera.n_cameras} cameras in {len(params.pairs)} stereo pairs,
  {params.camera.max_width}×{params.camera.max_height}, the measurement engine with
  {params.camera.n_cameras} temporal lanes of {params.segments} segments,
  {len(params.pairs)} stereo lanes and the router, the pose solver with
  {params.solver.slots} slots, pose output and register file; no PS7, pins or GP0
  bridge), against the xc7z020 ({XC7Z020['lut']} LUTs, {XC7Z020['ff']} FFs,
  {XC7Z020['bram36']} BRAM36, {XC7Z020['dsp48']} DSP48E1). Per-block figures:
  [resources.md](resources.md).
* Link: Amaranth simulation of the pose output and UART at {params.baud:,} baud and
  {params.clk_hz / 1e6:g} MHz with a pose every clock (the link saturated): clocks between
  packet starts, and the packet rate it gives.
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
{rows}
"""

"""cocotb bench for hdl.measurement.cue_map.CueMapper: each pair's mapped cues of both
cameras against :func:`emulator.measurement.cue_map.pair_cues`, bit for bit, and the
clocks from ``start`` to ``busy`` falling against the block's latency.

The rows come from ``CUE_MAP_STIMULUS`` (a pickle of rows of stereo cues written by the
pytest file: real ones from the emulator's stereo lanes) or, without it, from
:func:`stimulus.random_rows` seeded by ``cocotb.RANDOM_SEED`` (CUE_MAP_ROWS of them).
A mapper of P pairs maps P consecutive rows per start (the last group wraps round to
the first rows).
"""

import os
import pickle

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge

from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar

from sim_tests.measurement.cue_map.stimulus import expected, random_rows


def _rows(cue_map):
    path = os.environ.get("CUE_MAP_STIMULUS")
    if path:
        with open(path, "rb") as f:
            return pickle.load(f)
    return random_rows(cue_map, np.random.default_rng(cocotb.RANDOM_SEED),
                       int(os.environ.get("CUE_MAP_ROWS", "200")))


def _pairs(cue_map):
    """The pairs the mapper under test maps per start, from its ``cues`` port."""
    width = next(port["width"] for port in load_sidecar()["ports"] if port["name"] == "cues")
    return width // (cue_map.stereo_segments * cue_map.cue_fmt.width)


def _outputs(dut, cue_map, pair):
    """``(camera A's, camera B's)`` mapped cues of ``pair`` on the outputs, None where
    unusable."""
    width, count = cue_map.cue_fmt.width, cue_map.segments
    out = []
    for role in ("a", "b"):
        cues = int(getattr(dut, f"cue_{role}").value) >> (pair * count * width)
        usable = int(getattr(dut, f"usable_{role}").value) >> (pair * count)
        out.append([cues >> (k * width) & ((1 << width) - 1) if usable >> k & 1 else None
                    for k in range(count)])
    return tuple(out)


@cocotb.test()
async def mapped_cues_match_model(dut):
    cue_map = load_params()
    latency = load_sidecar()["latency"]
    pairs = _pairs(cue_map)
    rows = _rows(cue_map)
    want = expected(cue_map, rows)
    width, ks = cue_map.cue_fmt.width, cue_map.stereo_segments
    start_clock(dut)
    dut.start.value, dut.cues.value, dut.usable.value = 0, 0, 0
    await reset(dut)
    mismatches = []
    for n in range(0, len(rows), pairs):
        group = [i % len(rows) for i in range(n, n + pairs)]
        await RisingEdge(dut.clk)
        dut.cues.value = sum((c or 0) << ((p * ks + j) * width)
                             for p, i in enumerate(group) for j, c in enumerate(rows[i]))
        dut.usable.value = sum((c is not None) << (p * ks + j)
                               for p, i in enumerate(group) for j, c in enumerate(rows[i]))
        dut.start.value = 1
        await RisingEdge(dut.clk)
        dut.start.value = 0
        clocks = 1
        while True:
            await ReadOnly()
            if not int(dut.busy.value):
                break
            await RisingEdge(dut.clk)
            clocks += 1
        assert clocks == latency, f"row {n}: busy fell after {clocks} clocks, not {latency}"
        for p, i in enumerate(group):
            got = _outputs(dut, cue_map, p)
            if got != want[i]:
                mismatches.append((i, p, rows[i], want[i], got))
    await ClockCycles(dut.clk, 2)
    dut._log.info(f"{len(rows)} rows, {pairs} pairs per start, {len(mismatches)} mismatches")
    assert not mismatches, \
        f"first mismatch (row, pair, cues, want, got): {mismatches[0]}"

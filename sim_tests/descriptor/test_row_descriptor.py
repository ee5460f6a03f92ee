"""Row-descriptor lanes: parameters, the bit-accurate model, and the gateware against the
model in the Amaranth simulator (every measurement, and the latency at full rate).

The cocotb benches (``sim_tests/descriptor/row_descriptor/``) repeat the gateware checks on
the generated Verilog; the comparison with the golden float matcher is in
``test_row_descriptor_golden.py``.
"""

import os
import random

import numpy as np
import pytest
from amaranth.hdl import Fragment, Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.sim import Simulator

from emulator.row_descriptor import StereoLaneModel, TemporalLaneModel
from emulator.descriptor.framer import frame_rows
from emulator.descriptor.matcher import descriptor_bits, hamming_costs, measure_segments
from golden.descriptor import STEREO_MATCH, MatchParams, segment_bounds
from hdl.fixed import SQ, UQ
from hdl.descriptor.matcher import SerialDivider
from hdl.descriptor.fir import DescriptorFIR
from hdl.row_descriptor import RowDescriptor, StereoRowDescriptor, connect_shared_bits
from hdl.descriptor.params import STEREO_640X480, TEMPORAL_640X480, RowDescriptorParams
from emulator.hdl_sim.row_stimulus import (frame_beats, inject_faults, square_rows,
                                                      moving_rows, row_beats)
from emulator.hdl_sim.payload import pack, unpack

SEED = int(os.environ.get("SEED", 20261124))

#: Small lanes for simulation: 160-pixel rows, 2 segments, centre ±4.
SMALL = RowDescriptorParams(width=160, height=3, centre_range=4,
                            match=MatchParams(segments=2))
SMALL_STEREO = RowDescriptorParams(width=160, height=4, centre_range=4, match=STEREO_MATCH)


def simulate(dut, streams, centres, expected, *, seed, valid_prob=1.0, ready_prob=1.0,
             final=None, half_widths=None):
    """Drive beat lists into the named input ports of a lane and collect its outputs.

    ``streams`` maps port name → beats (sources hold each beat until it is taken and,
    with ``valid_prob`` < 1, idle at random between beats); ``centres`` gives the
    centre port's value with each beat of the first stream (``None`` for a following
    lane, whose beats carry it). Returns ``(outputs, accepted)``:
    ``[(cycle, measurement dict)]`` and, per port, the cycle of every transfer; the
    names in the dict ``final`` get the values of those ports of ``dut`` at the end.
    ``half_widths`` gives the half-width port's value with each beat of the first
    stream, like ``centres`` (default: the port stays 0, read as the built maximum).
    """
    rng = random.Random(seed)
    out_layout = dut.o.payload.shape()
    names = list(streams)
    accepted = {name: [] for name in names}
    outputs = []
    limit = 4 * sum(len(b) for b in streams.values()) + 4000

    async def testbench(ctx):
        offering = {name: False for name in names}
        for cycle in range(limit):
            if len(outputs) >= expected and all(len(accepted[n]) == len(streams[n])
                                                for n in names):
                for name in final or {}:
                    final[name] = ctx.get(getattr(dut, name))
                return
            for name in names:
                port, idx = getattr(dut, name), len(accepted[name])
                if not offering[name] and idx < len(streams[name]):
                    offering[name] = rng.random() < valid_prob
                ctx.set(port.valid, offering[name])
                if idx < len(streams[name]):
                    ctx.set(port.payload.as_value(),
                            pack(port.payload.shape(), streams[name][idx]))
            if centres is not None:
                ctx.set(dut.centre, centres[min(len(accepted[names[0]]), len(centres) - 1)])
            if half_widths is not None:
                ctx.set(dut.half_width, half_widths[min(len(accepted[names[0]]),
                                                        len(half_widths) - 1)])
            ready = rng.random() < ready_prob
            ctx.set(dut.o.ready, ready)
            taken = {name: ctx.get(getattr(dut, name).valid) and ctx.get(getattr(dut, name).ready)
                     for name in names}
            out_valid, payload = ctx.get(dut.o.valid), ctx.get(dut.o.payload.as_value())
            await ctx.tick()
            for name in names:
                if taken[name]:
                    accepted[name].append(cycle)
                    offering[name] = False
            if out_valid and ready:
                outputs.append((cycle, unpack(out_layout, payload)))
        raise AssertionError(f"timeout: {len(outputs)} of {expected} measurements "
                             f"(SEED={seed})")

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return outputs, accepted


def check_latency(outputs, accepted_last, dut):
    """At full rate measurement k of a row leaves ``latency + k`` clocks after the
    row's last pixel."""
    k = dut.params.segments
    for i, (cycle, meas) in enumerate(outputs):
        assert cycle == accepted_last[i // k] + dut.latency + meas["segment"], (i, meas)


# --- parameters -------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, error, message", [
    ({"width": 7}, ValueError, "width must be an integer at least 8, not 7"),
    ({"height": "480"}, TypeError, "height must be an integer"),
    ({"descriptor": 2.0}, TypeError, "descriptor must be a DescriptorParams"),
    ({"match": None}, TypeError, "match must be a MatchParams"),
    ({"coeff_frac_bits": 1}, ValueError, "coeff_frac_bits must be an integer between 2 and 20"),
    ({"subpixel_frac_bits": 0}, ValueError, "subpixel_frac_bits must be an integer between"),
    ({"confidence_fmt": SQ(2, 6)}, ValueError, "confidence_fmt must be unsigned, not SQ"),
    ({"confidence_fmt": 8}, TypeError, "confidence_fmt must be a QFormat, not 8"),
    ({"confidence_fmt": UQ(1, 6)}, ValueError, "cannot hold peak_ratio_cap 2.0"),
    ({"centre_range": -1}, ValueError, "centre_range must be an integer at least 0, not -1"),
    ({"scan_lanes": 0}, ValueError, "scan_lanes must be an integer between 1 and 16"),
    ({"row_bits": 8}, ValueError, "row_bits 8 cannot index 480 rows"),
    ({"match": MatchParams(shift_min=0, shift_max=2)}, ValueError, "at least 4 shifts"),
    ({"width": 60}, ValueError, "leaves 0 columns to compare at centre -32"),
    ({"match": MatchParams(segments=16)}, ValueError, "shorter than the"),
])
def test_bad_params(kwargs, error, message):
    with pytest.raises(error, match=message):
        RowDescriptorParams(**kwargs)


def test_bad_block_arguments():
    with pytest.raises(TypeError, match="params must be a RowDescriptorParams"):
        RowDescriptor(MatchParams())
    with pytest.raises(TypeError, match="params must be a RowDescriptorParams"):
        DescriptorFIR(MatchParams())


def test_quantized_kernel():
    for sigma in (0.5, 1.3, 2.0, 4.0):
        p = TEMPORAL_640X480.replace(descriptor=TEMPORAL_640X480.descriptor.replace(sigma=sigma))
        k = np.array(p.kernel_raw())
        assert len(k) == 2 * p.radius + 1 and k.sum() == 0 and (k == k[::-1]).all()
        from golden.descriptor import dog2_kernel
        err = np.abs(p.coeff_fmt.to_float(k) - dog2_kernel(p.descriptor))
        assert err[np.arange(len(k)) != p.radius].max() <= p.coeff_fmt.lsb / 2
        assert err[p.radius] <= len(k) * p.coeff_fmt.lsb / 2


@pytest.mark.parametrize("params", [
    SMALL, SMALL_STEREO, TEMPORAL_640X480, STEREO_640X480,
    SMALL.replace(match=MatchParams(segments=1)),
    SMALL.replace(centre_range=0, match=MatchParams(shift_min=-3, shift_max=5, segments=3)),
    TEMPORAL_640X480.replace(width=511, match=MatchParams(segments=3)),
    TEMPORAL_640X480.replace(centre_range=200, match=MatchParams(segments=1)),
])
def test_cost_format_holds_the_longest_segment(params):
    """``max_segment_cost`` is the longest segment golden cuts at any centre the lane
    uses (so it is reached: the square-wave test below), and ``cost_fmt``'s all-ones
    ``top`` lies above it, so no counter wraps and no cost ties with ``top``."""
    r = params.centre_range
    longest = max(hi - lo for c in range(-r, r + 1)
                  for lo, hi in segment_bounds(params.width, params.descriptor,
                                               params.match, c))
    assert params.max_segment_cost == longest
    assert (1 << params.cost_fmt.width) - 1 > longest
    assert (1 << (params.cost_fmt.width - 1)) - 1 <= longest      # no wider than needed


@pytest.mark.parametrize("params, lane", [(TEMPORAL_640X480, RowDescriptor),
                                           (STEREO_640X480, StereoRowDescriptor)])
def test_default_lanes_fit_the_latency_budget(params, lane):
    """Last pixel to last measurement of a row ≤ 64 clocks (elaborated, so the
    sub-blocks the latency comes from are the ones built)."""
    dut = lane(params)
    Fragment.get(dut, None)
    assert dut.latency + params.segments - 1 <= 64


# --- model ------------------------------------------------------------------------------

def test_framer_model_pads_drops_and_flags():
    p = SMALL
    rng = np.random.default_rng(SEED)
    good = [row_beats(rng.integers(0, 256, p.width), camera=1, frame=5, row=y, t_first=y)
            for y in range(3)]
    short = good[0][:50]
    short[-1] = dict(short[-1], last=1)
    long_row = good[1] + [dict(good[1][-1], first=0)]
    long_row[-2] = dict(long_row[-2], last=0)
    interrupted = [dict(b, last=0) for b in good[2][:30]]
    stray = [dict(good[0][3], first=0)]
    flagged = [dict(b) for b in good[2]]
    flagged[-1]["flags"] = 4
    beats = stray + short + long_row + stray + interrupted + good[0] + flagged
    rows = frame_rows(beats, [9] * len(beats), p)
    assert [r.row for r in rows] == [0, 1, 2, 0, 2]
    assert [r.bad for r in rows] == [True, True, True, False, True]
    assert [r.padded for r in rows] == [True, False, True, False, False]
    assert all(len(r.pixels) == p.width and r.centre == p.centre_range for r in rows)
    assert (rows[0].pixels[50:] == 0).all()
    assert rows[0].pixels[:50].tolist() == [b["data"] for b in good[0][:50]]
    assert rows[3].pixels.tolist() == [b["data"] for b in good[0]]


def test_model_recovers_known_shifts_and_flags():
    p = TEMPORAL_640X480.replace(height=4)
    rng = np.random.default_rng(SEED)
    frames, steps = moving_rows(rng, 2, 4, p.width, textureless_rows=(3,))
    beats = frame_beats(frames)
    out = TemporalLaneModel(p).run(beats, [0] * len(beats))
    first, second = out[:16], out[16:]
    assert all(m["no_reference"] and m["confidence"] == 0 for m in first)
    for m in second[:12]:
        true = steps[1, m["row"]]
        shift = m["shift"] + p.subpixel_fmt.to_float(m["subpixel"])
        assert abs(shift - true) < 0.25 and m["confidence"] > p.confidence_fmt.quantize(1.3)
    assert all(m["textureless"] and m["confidence"] == 0 for m in second[12:])


def test_model_confidence_rules():
    """c₁ = 0 < c₂ gives the cap, c₁ = c₂ = 0 gives 0, the cap bounds the ratio."""
    p = TEMPORAL_640X480.replace(match=MatchParams(segments=1))
    rng = np.random.default_rng(SEED)
    bits = rng.random(p.width) < 0.5
    exact = measure_segments(bits, bits, 0, p)
    assert exact["confidence"][0] == p.cap_raw() and exact["shift"][0] == 0
    zeros = np.zeros(p.width, dtype=bool)
    flat = measure_segments(zeros, zeros, 0, p)
    assert flat["confidence"][0] == 0 and flat["textureless"][0] == 1
    assert measure_segments(bits, bits, 0, p, bad=True)["confidence"][0] == 0


# --- gateware against the model ---------------------------------------------------------

def test_serial_divider():
    rng = random.Random(SEED)
    div = SerialDivider(12, 6, 5)
    cases = [(0, 0), (5, 0), (0, 7), (4095, 1), (31, 1), (32, 1), (100, 3), (63, 63)]
    cases += [(rng.randrange(4096), rng.randrange(64)) for _ in range(60)]
    got = []

    async def testbench(ctx):
        for num, den in cases:
            ctx.set(div.num, num)
            ctx.set(div.den, den)
            ctx.set(div.start, 1)
            await ctx.tick()
            ctx.set(div.start, 0)
            await ctx.tick().repeat(5)
            assert not ctx.get(div.busy)
            got.append(ctx.get(div.quotient))

    sim = Simulator(div)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    assert got == [min(n // d, 31) if d else 31 for n, d in cases]


def _temporal_stimulus(params, seed, n_frames=3, faults=0):
    rng = np.random.default_rng(seed)
    frames, _ = moving_rows(rng, n_frames, params.height, params.width)
    beats = frame_beats(frames, frame0=65534)        # frame numbers wrap
    if faults:
        beats = inject_faults(rng, beats, params.width, faults)
    centres = [int(c) for c in rng.integers(-6, 7, len(beats))]
    return beats, centres


@pytest.mark.parametrize("traffic", ["full_rate", "gaps_and_backpressure"])
def test_temporal_lane_matches_model(traffic):
    busy = traffic == "full_rate"
    beats, centres = _temporal_stimulus(SMALL, SEED)
    if busy:   # one centre per row, so the cycle check can use row boundaries
        centres = [centres[i - i % SMALL.width] for i in range(len(beats))]
    expected = TemporalLaneModel(SMALL).run(beats, centres)
    dut = RowDescriptor(SMALL)
    outputs, accepted = simulate(dut, {"i": beats}, centres, len(expected), seed=SEED,
                                 valid_prob=1.0 if busy else 0.7,
                                 ready_prob=1.0 if busy else 0.4)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"
    if busy:
        lasts = [c for c, b in zip(accepted["i"], beats) if b["last"]]
        check_latency(outputs, lasts, dut)
        assert accepted["i"] == list(range(accepted["i"][0], accepted["i"][0] + len(beats)))


def test_temporal_lane_at_the_largest_cost():
    """Square-wave rows moving by half a period per frame: the shifts that are multiples
    of the period cost whole segments, the largest cost ``cost_fmt`` holds; the lane
    still matches the model (a narrower counter would wrap to a false minimum)."""
    frames = square_rows(3, SMALL.height, SMALL.width)
    bits, _ = descriptor_bits(frames, SMALL)
    costs = hamming_costs(bits[1], bits[0], 0, SMALL)
    assert costs.max() == SMALL.max_segment_cost
    beats = frame_beats(frames, frame0=65534)
    centres = [0] * len(beats)
    expected = TemporalLaneModel(SMALL).run(beats, centres)
    outputs, _ = simulate(RowDescriptor(SMALL), {"i": beats}, centres, len(expected),
                          seed=SEED, valid_prob=0.8, ready_prob=0.7)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"


def test_temporal_lane_bad_input():
    beats, centres = _temporal_stimulus(SMALL, SEED + 1, n_frames=4, faults=5)
    expected = TemporalLaneModel(SMALL).run(beats, centres)
    assert any(m["bad"] for m in expected)
    outputs, _ = simulate(RowDescriptor(SMALL), {"i": beats}, centres, len(expected),
                          seed=SEED, valid_prob=0.8, ready_prob=0.7)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"


def test_stereo_lane_matches_model():
    p = SMALL_STEREO
    rng = np.random.default_rng(SEED)
    frames, _ = moving_rows(rng, 2, p.height, p.width + 60)
    left = frame_beats(frames[:, :, 20:p.width + 20])
    right = frame_beats(frames[:, :, 60:])                  # disparity 40
    # camera b loses row 1 of frame 0; camera a reports a bad row
    right = right[:p.width] + right[2 * p.width:]
    left[3 * p.width - 1] = dict(left[3 * p.width - 1], flags=2)
    centres = [0] * len(left)
    expected = StereoLaneModel(p).run(left, centres, right)
    assert len(expected) == 2 * p.height - 1
    good = [m for m in expected if not m["bad"]]
    assert good and all(m["shift"] in (39, 40, 41) for m in good)
    outputs, accepted = simulate(StereoRowDescriptor(p), {"a": left, "b": right}, centres,
                                 len(expected), seed=SEED, valid_prob=0.8, ready_prob=0.6)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"


def test_stereo_lane_samples_the_centre_with_the_rows_first_beat():
    """Camera a's row 1 breaks off after three beats (no ``last``; the next row's first
    beat, with its own centre on the port, follows at once) while its first columns
    are still in the filter: the lane matches that row at the centre the port held at
    its first beat, as the model does, not at the one it holds when the pair's first
    columns reach the join (a CI failure, SEED=169708397, before the fix)."""
    p = SMALL_STEREO
    rng = np.random.default_rng(SEED)
    frames, _ = moving_rows(rng, 1, p.height, p.width + 60)
    left = frame_beats(frames[:, :, 20:p.width + 20])
    right = frame_beats(frames[:, :, 60:])                  # disparity 40
    left = left[:p.width + 3] + left[2 * p.width:]
    row_centres = [-4, 3, -2, 4]
    centres = [row_centres[beat["row"]] for beat in left]
    expected = StereoLaneModel(p).run(left, centres, right)
    at_pairing = [row_centres[2] if beat["row"] == 1 else c for beat, c in zip(left, centres)]
    assert StereoLaneModel(p).run(left, at_pairing, right) != expected
    outputs, _ = simulate(StereoRowDescriptor(p), {"a": left, "b": right}, centres,
                          len(expected), seed=SEED)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"


class SharedPair(wiring.Component):
    """The measurement engine's pair: two paired temporal lanes at their own centre
    ``TEMPORAL_CENTRE`` and narrowest half-width, their bits into a shared stereo lane
    (``centre`` is the stereo lane's); the temporal measurements are drained."""

    TEMPORAL_CENTRE = -3

    def __init__(self, stereo, temporal):
        self.params = stereo
        self.lanes = [RowDescriptor(temporal, paired=True) for _ in "ab"]
        self.stereo = StereoRowDescriptor(stereo, shared=True)
        beat = stream.Signature(temporal.input_layout(paired=True))
        super().__init__({"a": In(beat), "b": In(beat),
                          "centre": In(stereo.centre_fmt.shape()),
                          "o": Out(stream.Signature(stereo.measurement_layout()))})

    @property
    def latency(self):
        return self.lanes[0].bits_latency + self.stereo.latency

    def elaborate(self, platform):
        m = Module()
        m.submodules.stereo = self.stereo
        for name, lane, to in zip("ab", self.lanes, (self.stereo.a, self.stereo.b)):
            m.submodules[name] = lane
            wiring.connect(m, wiring.flipped(getattr(self, name)), lane.i)
            m.d.comb += [lane.centre.eq(self.TEMPORAL_CENTRE), lane.o.ready.eq(1),
                         lane.half_width.eq(lane.params.min_half_width)]
            connect_shared_bits(m, lane.bits, to)
        m.d.comb += self.stereo.centre.eq(self.centre)
        wiring.connect(m, self.stereo.o, wiring.flipped(self.o))
        return m


def test_shared_stereo_lane_keeps_its_own_centre_and_window():
    """Rows of a pair's temporal lanes, some without their partner (a row set missing
    camera b, another missing camera a: those rows are not ``paired``), into a stereo
    lane on their bits: its measurements are the stereo model's on the paired rows at
    the stereo centres (per row, saturation included) and the stereo window; the
    temporal lanes' centre and half-width would move the shifts."""
    p = SMALL_STEREO
    temporal = SMALL.replace(height=p.height)
    rng = np.random.default_rng(SEED)
    frames, _ = moving_rows(rng, 3, p.height, p.width + 60)
    left = frame_beats(frames[:, :, 20:p.width + 20])
    right = frame_beats(frames[:, :, 60:], camera=1)          # disparity 40
    rows_a = [left[n:n + p.width] for n in range(0, len(left), p.width)]
    rows_b = [right[n:n + p.width] for n in range(0, len(right), p.width)]
    rows_a[6][-1] = dict(rows_a[6][-1], flags=2)             # a bad row of a pair
    lone_a, lone_b = 5, 9                                    # b, then a, missing
    a, b, centres, paired_a, paired_b, model_centres = [], [], [], [], [], []
    for n, (row_a, row_b) in enumerate(zip(rows_a, rows_b)):
        centre = int(rng.integers(-6, 7))
        if n != lone_b:
            paired = int(n != lone_a)
            a += [dict(beat, paired=paired) for beat in row_a]
            centres += [centre] * len(row_a)
            if paired:
                paired_a += row_a
                model_centres += [centre] * len(row_a)
        if n != lone_a:
            paired = int(n != lone_b)
            b += [dict(beat, paired=paired) for beat in row_b]
            if paired:
                paired_b += row_b
    expected = StereoLaneModel(p).run(paired_a, model_centres, paired_b)
    assert len(expected) == len(rows_a) - 2 and any(m["bad"] for m in expected)
    good = [m for m in expected if not m["bad"]]
    assert good and all(m["shift"] in (39, 40, 41) for m in good)
    for traffic in ("full_rate", "gaps_and_backpressure"):
        busy = traffic == "full_rate"
        outputs, _ = simulate(SharedPair(p, temporal), {"a": a, "b": b}, centres,
                              len(expected), seed=SEED, valid_prob=1.0 if busy else 0.8,
                              ready_prob=1.0 if busy else 0.6)
        assert [m for _, m in outputs] == expected, f"{traffic}, SEED={SEED}"

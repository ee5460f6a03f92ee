"""Cue map model (emulator/measurement/cue_map.py, constants in
hdl/measurement/cue_map_params.py): against the float interpolation it stands for,
exact at the ends and at the formats' extremes, the usable-cue rules and the parameter
checks. SEED replays the random cues (printed)."""

import dataclasses
import os

import numpy as np
import pytest

from golden.descriptor import STEREO_MATCH, segment_bounds
from hdl.descriptor.params import RowDescriptorParams
from hdl.fixed import SQ, UQ
from hdl.measurement.cue_map_params import B_PASSES, WEIGHT_FMT, CueMap
from emulator.measurement.cue_map import map_cue, pair_cues

SEED = int(os.environ.get("SEED", "1"))
CUE = UQ(8, 10)


def lanes(segments, stereo_segments, width=640):
    temporal = RowDescriptorParams(width=width, height=8, match=dataclasses.replace(
        RowDescriptorParams().match, segments=segments))
    stereo = RowDescriptorParams(width=width, height=8, match=dataclasses.replace(
        STEREO_MATCH, segments=stereo_segments))
    return temporal, stereo


def float_cue(temporal, stereo, column, cues):
    """The float map: linear between the stereo segment centres around ``column``,
    clamped to the end centres, the one usable cue alone, None without one."""
    centres = [(lo + hi - 1) / 2 for lo, hi in segment_bounds(
        stereo.width, stereo.descriptor, stereo.match)]
    if len(centres) == 1:
        return cues[0]
    x = min(max(column, centres[0]), centres[-1])
    j = min(int(np.searchsorted(centres, x, side="right")) - 1, len(centres) - 2)
    w = (x - centres[j]) / (centres[j + 1] - centres[j])
    near, far = cues[j], cues[j + 1]
    if near is None or far is None:
        return far if near is None else near
    return near + w * (far - near)


def float_covered(stereo, column):
    """Whether ``column`` (camera A's) is within the stereo lane's compared columns."""
    bounds = segment_bounds(stereo.width, stereo.descriptor, stereo.match)
    return bounds[0][0] <= column <= bounds[-1][1] - 1


@pytest.mark.parametrize("segments, stereo_segments", [(8, 8), (4, 4), (4, 2), (2, 8),
                                                       (8, 1), (1, 3)])
def test_matches_the_float_interpolation(segments, stereo_segments):
    print(f"SEED={SEED}")
    temporal, stereo = lanes(segments, stereo_segments)
    cue_map = CueMap.for_lanes(temporal, stereo, CUE)
    centres = [(lo + hi - 1) / 2 for lo, hi in segment_bounds(
        temporal.width, temporal.descriptor, temporal.match)]
    rng = np.random.default_rng(SEED)
    worst = 0.0
    for _ in range(300):
        values = rng.uniform(0, CUE.max_value, stereo_segments)
        raw = [None if rng.random() < 0.25 else int(CUE.quantize(v)) for v in values]
        own, moved = pair_cues(cue_map, raw)
        floats = [None if r is None else CUE.to_float(r) for r in raw]
        for k, column in enumerate(centres):
            want = float_cue(temporal, stereo, column, floats)
            held = map_cue(cue_map, cue_map.temporal[k] << CUE.frac_bits, raw)
            assert (want is None) == (held is None)
            assert own[k] == (held if float_covered(stereo, column) else None)
            if want is None:
                assert moved[k] is None
                continue
            usable = [f for f in floats if f is not None]
            # rounding to the cue step, the weight's step and the reciprocal's floor
            bound = CUE.lsb / 2 + (max(usable) - min(usable)) * (2 * WEIGHT_FMT.lsb)
            pairs = [(held, want)]
            cue = held                      # camera B's passes, each against the float
            for _ in range(B_PASSES):
                position = column + CUE.to_float(cue)
                expect = float_cue(temporal, stereo, position, floats)
                cue = map_cue(cue_map, (cue_map.temporal[k] << CUE.frac_bits) + 2 * cue, raw)
                assert (expect is None) == (cue is None)
                if cue is None:
                    break
                pairs.append((cue, expect))
            assert moved[k] == (cue if float_covered(stereo, position) else None)
            for got, expect in pairs:
                assert abs(CUE.to_float(got) - expect) <= bound
                worst = max(worst, abs(CUE.to_float(got) - expect))
    print(f"worst error {worst:.2e} px")


def test_ends_take_the_end_cue_exactly_and_equal_cues_stay_exact():
    temporal, stereo = lanes(8, 8)
    cue_map = CueMap.for_lanes(temporal, stereo, CUE)
    f = CUE.frac_bits
    cues = list(range(1000, 9000, 1000))
    assert map_cue(cue_map, 0, cues) == 1000                   # left of the first centre
    assert map_cue(cue_map, cue_map.position_fmt.max_raw, cues) == 8000
    for j, centre in enumerate(cue_map.stereo):                 # at a centre: its cue
        assert map_cue(cue_map, centre << f, cues) == cues[j]
    centres = [(lo + hi - 1) / 2 for lo, hi in segment_bounds(
        temporal.width, temporal.descriptor, temporal.match)]

    def covered(value, shift):
        return [value if float_covered(stereo, c + shift) else None for c in centres]
    flat = [CUE.max_raw] * 8
    assert pair_cues(cue_map, flat) == (covered(CUE.max_raw, 0),
                                        covered(CUE.max_raw, CUE.max_value))
    assert pair_cues(cue_map, [0] * 8) == (covered(0, 0), covered(0, 0))


def test_segments_outside_the_stereo_columns_have_no_cue():
    """stereo20's lanes (K = K_s = 8): camera A's segment 0 (columns 26–98) lies mostly
    left of the stereo lane's first compared column (76) and gets no cue; camera B's
    segment 0, which sees those points 30 px further right, keeps one, moved by A's
    clamped cue; a cue large enough to move B's last segment past the lane's last
    column drops it."""
    temporal, stereo = lanes(8, 8)
    cue_map = CueMap.for_lanes(temporal, stereo, CUE)
    assert (cue_map.first, cue_map.last) == (2 * 76, 2 * 633)
    thirty = int(CUE.quantize(30.0))
    own, moved = pair_cues(cue_map, [thirty] * 8)
    assert own == [None] + [thirty] * 7
    assert moved == [thirty] * 8
    far = int(CUE.quantize(100.0))
    own, moved = pair_cues(cue_map, [far] * 8)
    assert own == [None] + [far] * 7
    assert moved == [far] * 7 + [None]                  # centre 576.5 + 100 > 633


def test_extremes_do_not_overflow():
    """Alternating 0 and the format's maximum, camera B moved by the largest cue: every
    result lies between its two cues (the model raises on an overflow)."""
    temporal, stereo = lanes(8, 8)
    cue_map = CueMap.for_lanes(temporal, stereo, CUE)
    for cues in ([0, CUE.max_raw] * 4, [CUE.max_raw, 0] * 4):
        own, moved = pair_cues(cue_map, cues)
        assert all(0 <= c <= CUE.max_raw for c in own + moved if c is not None)
    top = (cue_map.temporal[-1] << CUE.frac_bits) + 2 * CUE.max_raw
    assert top <= cue_map.position_fmt.max_raw
    assert max(b - a for a, b in zip(cue_map.stereo, cue_map.stereo[1:])) << CUE.frac_bits \
        <= cue_map.distance_fmt.max_raw


def test_usable_cue_rules():
    temporal, stereo = lanes(4, 2)
    cue_map = CueMap.for_lanes(temporal, stereo, CUE)
    assert pair_cues(cue_map, [None, None]) == ([None] * 4, [None] * 4)
    assert pair_cues(cue_map, [None, 5000]) == ([5000] * 4, [5000] * 4)
    assert pair_cues(cue_map, [7000, None]) == ([7000] * 4, [7000] * 4)
    own, moved = pair_cues(cue_map, [4000, 8000])
    assert own == sorted(own) and moved == sorted(moved)     # disparity grows rightwards
    assert all(b >= a for a, b in zip(own, moved))            # B's columns: further right


def test_parameter_checks():
    temporal, stereo = lanes(4, 2)
    with pytest.raises(TypeError, match="temporal"):
        CueMap.for_lanes(None, stereo, CUE)
    with pytest.raises(TypeError, match="stereo"):
        CueMap.for_lanes(temporal, "stereo", CUE)
    with pytest.raises(ValueError, match="cue_fmt"):
        CueMap.for_lanes(temporal, stereo, SQ(8, 10))
    with pytest.raises(ValueError, match="cues must hold 2"):
        pair_cues(CueMap.for_lanes(temporal, stereo, CUE), [1, 2, 3])

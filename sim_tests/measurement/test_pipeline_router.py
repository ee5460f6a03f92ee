"""Measurement router model (emulator/measurement/router.py): slots, shifts, cues,
confidences, zero-weight rules, row framing and parameter checks."""

import dataclasses
import os
import random

import pytest

from golden.descriptor import STEREO_MATCH
from emulator.measurement.cue_map import pair_cues
from emulator.measurement.router import RouterParams, pose_rows, route, route_row, usable_cues
from hdl.fixed import SQ, UQ
from hdl.pose.params import PoseSolverParams
from hdl.descriptor.params import RowDescriptorParams

DESC = RowDescriptorParams(width=320, height=8)          # K = 4, subpixel SQ(1, 6)
#: Two stereo segments: temporal segments 0, 1 take stereo segment 0; 2, 3 segment 1.
STEREO = RowDescriptorParams(width=320, height=8,
                             match=dataclasses.replace(STEREO_MATCH, segments=2))
SOLVER = PoseSolverParams(slots=16, rows=8, shift_fmt=SQ(6, 12), cue_fmt=UQ(8, 10),
                          conf_fmt=UQ(2, 8))
PARAMS = RouterParams(cameras=4, pairs=((0, 1), (2, 3)), temporal=DESC, stereo=STEREO,
                      solver=SOLVER)
F = DESC.subpixel_frac_bits


def meas(camera, segment, *, shift=3, subpixel=0, confidence=96, edge_hit=0, frame=1,
         row=5, t_first=1000):
    """A lane measurement dict (only the fields the router reads, plus metadata)."""
    return {"camera": camera, "frame": frame, "row": row, "t_first": t_first,
            "segment": segment, "shift": shift, "subpixel": subpixel,
            "confidence": confidence, "textureless": 0, "edge_hit": edge_hit, "bad": 0,
            "no_reference": 0}


def full_row(**changes):
    temporal = [meas(c, k, **changes) for c in range(4) for k in range(4)]
    stereo = [meas(a, k, shift=20, subpixel=16) for a in (0, 2) for k in range(2)]
    return temporal, stereo


def test_slots_order_last_and_time():
    temporal, stereo = full_row()
    for m in temporal:
        m["t_first"] += 7 * m["camera"]    # camera 0, whatever the order, gives the time
    rng = random.Random(int(os.environ.get("SEED", "1")))
    rng.shuffle(temporal)
    out = route_row(PARAMS, temporal, stereo)
    assert [t["slot"] for t in out] == list(range(16))
    assert [t["last"] for t in out] == [0] * 15 + [1]
    assert {t["time"] for t in out} == {1000}
    assert {t["row"] for t in out} == {5}


def test_shift_is_sum_of_integer_and_subpixel_in_solver_format():
    temporal, stereo = full_row(shift=-4, subpixel=-(1 << (F - 1)) + 1)   # −4.484375 px
    out = route_row(PARAMS, temporal, stereo)
    expected = (-4 * (1 << F) - (1 << (F - 1)) + 1) << (12 - F)
    assert all(t["shift"] == expected for t in out)


def test_shift_saturates_to_solver_format():
    narrow = dataclasses.replace(SOLVER, shift_fmt=SQ(3, 12))
    params = dataclasses.replace(PARAMS, solver=narrow)
    temporal, stereo = full_row(shift=30)
    out = route_row(params, temporal, stereo)
    assert all(t["shift"] == SQ(3, 12).max_raw for t in out)


def test_cue_is_the_pairs_disparity_mapped_to_each_cameras_segment_centres():
    temporal, stereo = full_row()
    for m in stereo:
        m["shift"] = 10 + m["camera"] * 5 + 3 * m["segment"]      # distinct per (pair, k)
    out = route_row(PARAMS, temporal, stereo)
    for a, b in PARAMS.pairs:
        raw = [round((10 + a * 5 + 3 * j + 16 / (1 << F)) * (1 << 10)) for j in range(2)]
        own, moved = pair_cues(PARAMS.cue_map, raw)
        for camera, cues in ((a, own), (b, moved)):
            got = out[4 * camera:4 * camera + 4]
            # a segment the stereo lane does not cover has no cue (0) and no weight
            assert [t["cue"] for t in got] == [c or 0 for c in cues]
            assert [t["conf"] for t in got] == [0 if c is None else 96 << 2   # UQ(2, 6) →
                                                for c in cues]                # UQ(2, 8)
        assert moved != own             # camera B's columns sit further right in A's
        assert own[0] is None and None not in own[1:]   # A's first segment: uncovered


def _spoil(stereo, temporal, spoil, segments):
    """Make pair (2, 3)'s stereo ``segments`` unusable (or, ``temporal_edge``, camera
    2's temporal segment 0)."""
    for m in stereo:
        if m["camera"] != 2 or m["segment"] not in segments:
            continue
        if spoil == "stereo_zero_conf":
            m["confidence"] = 0
        elif spoil == "stereo_edge":
            m["edge_hit"] = 1
        elif spoil == "negative_disparity":
            m["shift"], m["subpixel"] = 0, -1
    if spoil == "no_stereo":
        stereo[:] = [m for m in stereo if not (m["camera"] == 2 and m["segment"] in segments)]
    if spoil == "temporal_edge":
        next(m for m in temporal if m["camera"] == 2 and m["segment"] == 0)["edge_hit"] = 1


#: Camera A's first segment of each pair: left of the stereo lane's first compared column
#: (the cue map's coverage test), no cue and no weight in every row.
UNCOVERED = {4 * a for a, _ in PARAMS.pairs}


def test_segments_outside_the_stereo_columns_get_no_weight():
    temporal, stereo = full_row()
    out = route_row(PARAMS, temporal, stereo)
    assert {t["slot"] for t in out if t["conf"] == 0} == UNCOVERED
    assert all(t["cue"] == 0 for t in out if t["slot"] in UNCOVERED)


@pytest.mark.parametrize("spoil", ["no_stereo", "stereo_zero_conf", "stereo_edge",
                                   "negative_disparity", "temporal_edge"])
def test_unusable_measurements_get_zero_weight_but_are_sent(spoil):
    temporal, stereo = full_row()
    _spoil(stereo, temporal, spoil, (0, 1))
    out = route_row(PARAMS, temporal, stereo)
    assert len(out) == 16
    zero = {t["slot"] for t in out if t["conf"] == 0}
    # no usable stereo segment left in pair (2, 3): cameras 2 and 3 get no weight
    assert zero == UNCOVERED | ({2 * 4} if spoil == "temporal_edge" else set(range(8, 16)))
    assert all(t["cue"] == 0 for t in out if t["slot"] >= 8) != (spoil == "temporal_edge")


@pytest.mark.parametrize("spoil", ["no_stereo", "stereo_zero_conf", "stereo_edge",
                                   "negative_disparity"])
def test_one_unusable_stereo_segment_lends_its_neighbours_cue(spoil):
    temporal, stereo = full_row()
    stereo[3]["shift"] = 24                    # pair (2, 3), stereo segment 1
    _spoil(stereo, temporal, spoil, (0,))
    out = route_row(PARAMS, temporal, stereo)
    assert all(t["conf"] for t in out if t["slot"] not in UNCOVERED)
    assert {t["cue"] for t in out[8:] if t["slot"] not in UNCOVERED} == \
        {(24 << 10) + (16 << 10 >> F)}


def test_missing_camera_and_missing_row():
    temporal, stereo = full_row()
    temporal = [m for m in temporal if m["camera"] != 0]
    out = route_row(PARAMS, temporal, stereo)
    assert [t["slot"] for t in out] == list(range(4, 16))
    assert out[0]["time"] == 1000
    assert route_row(PARAMS, [], stereo) == []


def test_route_groups_rows_and_pose_rows_round_trip():
    row5, stereo5 = full_row(row=5)
    row6, stereo6 = full_row(row=6, shift=-2)
    row6 = [m for m in row6 if m["camera"] != 3]            # camera 3 lost row 6
    transfers = route(PARAMS, row5 + row6, stereo6 + stereo5)
    assert sum(t["last"] for t in transfers) == 2
    rows = pose_rows(PARAMS, transfers)
    assert list(rows.counts) == [16, 12]
    assert list(rows.row) == [5, 6]
    assert rows.transfers() == transfers


def test_pose_rows_rejects_unterminated_stream():
    temporal, stereo = full_row()
    transfers = route_row(PARAMS, temporal, stereo)[:-1]
    with pytest.raises(ValueError, match="last"):
        pose_rows(PARAMS, transfers)


@pytest.mark.parametrize("changes, error, message", [
    ({"cameras": 2.0}, TypeError, "cameras must be an integer"),
    ({"cameras": 0}, ValueError, "cameras must be an integer at least 1"),
    ({"cameras": 5}, ValueError, "solver.slots must be cameras × segments = 20"),
    ({"pairs": ((0, 1),)}, ValueError, r"cameras \[2, 3\] have none"),
    ({"pairs": ((0, 1), (1, 2), (3, 0))}, ValueError, "camera 1 is in more than one pair"),
    ({"pairs": ((0, 0), (2, 3))}, ValueError, r"pairs\[0\] must be two different cameras"),
    ({"pairs": ((0, 1), (2, 4))}, ValueError, r"pairs\[1\] names camera 4"),
    ({"temporal": None}, TypeError, "temporal must be a RowDescriptorParams"),
    ({"stereo": 3}, TypeError, "stereo must be a RowDescriptorParams"),
    ({"solver": None}, TypeError, "solver must be a PoseSolverParams"),
])
def test_parameter_checks(changes, error, message):
    kwargs = {"cameras": 4, "pairs": ((0, 1), (2, 3)), "temporal": DESC, "stereo": STEREO,
              "solver": SOLVER, **changes}
    with pytest.raises(error, match=message):
        RouterParams(**kwargs)


def test_a_failed_stereo_segment_takes_the_fallback_cue():
    """Depth per segment (issue 16 item 4): where the pair's stereo match of a segment is
    unusable, the stored cue of the same row (the previous frame's) stands in before the
    map; a usable stereo measurement wins over the store; a pair with neither gives its
    cameras no weight."""
    temporal, stereo = full_row()
    for m in stereo:
        if (m["camera"], m["segment"]) in ((0, 1), (2, 0), (2, 1)):
            m["confidence"] = 0
    fallback = {(0, 0): 999, (0, 1): 12345}
    assert set(usable_cues(PARAMS, stereo)) == {(0, 0)}
    out = route_row(PARAMS, temporal, stereo, fallback)
    own = round((20 + 16 / (1 << F)) * (1 << 10))
    a, b = pair_cues(PARAMS.cue_map, [own, 12345])
    assert [t["cue"] for t in out[:8]] == [c or 0 for c in a + b]
    assert all((t["conf"] > 0) == (t["slot"] not in UNCOVERED) for t in out[:8])
    assert all(t["cue"] == 0 and t["conf"] == 0 for t in out[8:])

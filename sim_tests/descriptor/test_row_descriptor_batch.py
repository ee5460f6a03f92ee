"""The batched row-descriptor lane models (``process_rows`` / ``process_pairs``) against
the same lanes fed one row at a time, and their fast parts (FIR, packed Hamming costs)
against ``golden.descriptor``'s integer definitions.

The gateware is checked against the model in ``test_row_descriptor.py``; these tests make
sure a batch (a whole frame, several frames, or a random cut of the stream) gives the
same dicts in the same order as the per-row calls. SEED replays a run (printed).
"""

import dataclasses
import os

import numpy as np
import pytest

from emulator.descriptor.framer import FramedRow, frame_rows
from emulator.row_descriptor import StereoLaneModel, TemporalLaneModel, stereo_pairs
from emulator.descriptor.matcher import descriptor_bits, hamming_costs, measure_rows
from golden.dataset import Dataset
from golden.descriptor import STEREO_MATCH, MatchParams, describe, response, strength
from golden.descriptor import hamming_costs as golden_costs
from hdl.descriptor.params import STEREO_640X480, TEMPORAL_640X480, RowDescriptorParams
from emulator.hdl_sim.row_stimulus import (frame_beats, inject_faults,
                                                      moving_rows, simulator_dataset)
from emulator.hdl_sim.runner import BUILD_ROOT

SEED = int(os.environ.get("SEED", 20261123))

#: 160-pixel rows: segments and windows small enough for many rows per test.
SMALL = RowDescriptorParams(width=160, height=6, centre_range=8,
                            match=MatchParams(segments=2))
SMALL_STEREO = RowDescriptorParams(width=160, height=6, centre_range=8, match=STEREO_MATCH)


def rng_for(offset):
    print(f"SEED={SEED}")
    return np.random.default_rng(SEED + offset)


def row_by_row(lane, rows):
    return [m for row in rows for m in lane.process_row(row)]


def random_cuts(rng, items):
    """``items`` cut into consecutive batches of random sizes (some of one row)."""
    cuts = np.sort(rng.choice(np.arange(1, len(items)), size=min(6, len(items) - 1),
                              replace=False))
    return [items[a:b] for a, b in zip([0, *cuts], [*cuts, len(items)])]


def temporal_rows(rng, params, n_frames, faults):
    """Framed rows of moving textured frames with flat rows, frame numbers wrapping,
    ``faults`` bad rows, and random centres up to beyond the centre range."""
    frames, _ = moving_rows(rng, n_frames, params.height, params.width,
                            textureless_rows=(params.height - 1,))
    beats = inject_faults(rng, frame_beats(frames, frame0=65534), params.width, faults)
    wide = params.centre_range + 4                       # some centres saturate
    centres = [int(c) for c in rng.integers(-wide, wide + 1, len(beats))]
    return frame_rows(beats, centres, params)


def fields(measurements, key):
    return {m[key] for m in measurements}


# --- the fast parts against golden.descriptor -------------------------------------------

@pytest.mark.parametrize("sigma, pixel_bits", [(0.5, 8), (2.0, 8), (3.3, 8), (2.0, 16)])
def test_descriptor_bits_equal_golden(sigma, pixel_bits):
    """One integer FIR pass (int32 where it cannot overflow, int64 at 16-bit pixels)
    gives golden's bits and strong columns with the quantized kernel."""
    p = TEMPORAL_640X480.replace(pixel_bits=pixel_bits,
                                 descriptor=TEMPORAL_640X480.descriptor.replace(sigma=sigma))
    rng = rng_for(1)
    top = (1 << pixel_bits) - 1
    frames, _ = moving_rows(rng, 1, 40, p.width)
    pixels = np.concatenate([frames[0].astype(np.int64) * (top // 255),
                             rng.integers(0, top + 1, (20, p.width)),
                             np.full((2, p.width), top), np.zeros((2, p.width), int)])
    kernel = np.array(p.kernel_raw())
    bits, strong = descriptor_bits(pixels, p)
    np.testing.assert_array_equal(bits, describe(pixels, p.descriptor, kernel=kernel))
    np.testing.assert_array_equal(strong, strength(pixels, p.descriptor, kernel=kernel,
                                                   threshold=p.strong_raw()))
    assert bits.any() and strong.any() and not strong.all()
    # a threshold some column's response magnitude equals exactly (≥, not >)
    tie = int(np.abs(response(pixels[:1], p.descriptor, kernel=kernel)).max())
    tied = p.replace(descriptor=p.descriptor.replace(
        strong_response=tie / 2 ** p.coeff_frac_bits))
    assert tied.strong_raw() == tie
    np.testing.assert_array_equal(descriptor_bits(pixels, tied)[1],
                                  strength(pixels, p.descriptor, kernel=kernel, threshold=tie))


@pytest.mark.parametrize("params", [TEMPORAL_640X480, STEREO_640X480, SMALL,
                                    TEMPORAL_640X480.replace(match=MatchParams(segments=7))],
                         ids=["temporal", "stereo", "small", "temporal_k7"])
def test_packed_hamming_costs_equal_golden(params):
    """Every centre of the range (the compared columns move with it); random rows, and
    rows whose reference is the current row moved by the window's third shift (cost 0
    there)."""
    rng = rng_for(2)
    cur = rng.random((12, params.width)) < 0.5
    ref = rng.random((12, params.width)) < 0.5
    for centre in range(-params.centre_range, params.centre_range + 1):
        shift = centre + params.match.shift_min + 2
        ref[-2:] = np.roll(cur[-2:], -shift, axis=-1)      # cur[x] = ref[x − shift]
        expected = golden_costs(cur, ref, params.descriptor, params.match, centre)
        np.testing.assert_array_equal(hamming_costs(cur, ref, centre, params), expected,
                                      err_msg=f"centre {centre}, SEED={SEED}")
        assert (expected[-2:, :, 2] == 0).all() and (expected[:-2] > 0).all()


# --- batches against one row at a time --------------------------------------------------

@pytest.mark.parametrize("batching", ["one_batch", "per_frame", "random_cuts"])
def test_temporal_batches_equal_row_by_row(batching):
    """Textured and flat rows, bad rows (short, long, interrupted, reason bits), rows
    without reference (first frame, after a bad row), window-edge hits, centres ≠ 0
    (some saturated), frame numbers wrapping; several frames in one batch exercise the
    store within a batch."""
    p = SMALL
    rng = rng_for(3)
    rows = temporal_rows(rng, p, n_frames=5, faults=6)
    expected = row_by_row(TemporalLaneModel(p), rows)
    if batching == "one_batch":
        batches = [rows]
    elif batching == "per_frame":
        batches = [[r for r in rows if r.frame == f] for f in dict.fromkeys(r.frame for r in rows)]
    else:
        batches = random_cuts(rng, rows)
    lane = TemporalLaneModel(p)
    got = [m for batch in batches for m in lane.process_rows(batch)]
    assert got == expected, f"SEED={SEED}"
    # the stream holds what the test claims to cover
    assert {0, 1} <= fields(expected, "bad") and {0, 1} <= fields(expected, "edge_hit")
    assert {0, 1} <= fields(expected, "textureless")
    clean_missing = [m for m in expected if m["no_reference"] and not m["bad"]]
    assert any(m["frame"] != 65534 for m in clean_missing)      # after a bad row
    assert len(fields(expected, "shift")) > 10 and max(fields(expected, "confidence")) > 0
    assert len({r.centre for r in rows}) > 5 and {-p.centre_range, p.centre_range} & {
        r.centre for r in rows}


def test_temporal_batch_with_row_indices_outside_the_frame():
    """Rows whose index is outside the frame have no reference and store nothing."""
    p = SMALL
    rng = rng_for(4)
    frames, _ = moving_rows(rng, 3, p.height + 2, p.width)
    beats = frame_beats(frames)
    rows = frame_rows(beats, [3] * len(beats), p)
    assert {r.row for r in rows} >= {p.height, p.height + 1}
    expected = row_by_row(TemporalLaneModel(p), rows)
    assert TemporalLaneModel(p).process_rows(rows) == expected, f"SEED={SEED}"
    outside = [m for m in expected if m["row"] >= p.height]
    assert outside and all(m["no_reference"] and m["bad"] for m in outside)


def test_temporal_batches_on_simulator_rows():
    """Full-width rows of the golden simulator (radial4 yawing, three frames), a frame
    of a camera per batch, against row by row."""
    data = Dataset.load(simulator_dataset(BUILD_ROOT / "row_descriptor-yaw-dataset.npz"))
    p = TEMPORAL_640X480
    rng = rng_for(5)
    for camera in (0, 1):
        pixels = data.cameras[camera].rows[:, 200:240]
        rows = [[FramedRow(pixels=pixels[f, y].astype(np.int64), camera=camera, frame=f,
                           row=200 + y, t_first=y, centre=int(rng.integers(-4, 5)),
                           bad=False, padded=False) for y in range(pixels.shape[1])]
                for f in range(pixels.shape[0])]
        expected = row_by_row(TemporalLaneModel(p), [r for frame in rows for r in frame])
        lane = TemporalLaneModel(p)
        assert [m for frame in rows for m in lane.process_rows(frame)] == expected, \
            f"camera {camera}, SEED={SEED}"
        later = [m for m in expected if m["frame"] > 0]
        assert later and not any(m["no_reference"] for m in later)
        assert max(m["confidence"] for m in later) == p.cap_raw()


@pytest.mark.parametrize("params", [SMALL_STEREO, STEREO_640X480.replace(height=8)],
                         ids=["small", "640"])
def test_stereo_batches_equal_pair_by_pair(params):
    """Joined pairs with a lost row, bad rows on either camera, centres ≠ 0, disparities
    on and off the window edge."""
    p = params
    rng = rng_for(6)
    frames, _ = moving_rows(rng, 3, p.height, p.width + 80)
    disparity = rng.integers(8, 79, p.height)             # 8, 9, 71…78: off the window
    right = np.stack([[row[d:d + p.width] for row, d in zip(frame, disparity)]
                      for frame in frames])
    beats_a = inject_faults(rng, frame_beats(frames[:, :, :p.width]), p.width, 2)
    beats_b = frame_beats(right)
    beats_b = beats_b[:p.width] + beats_b[2 * p.width:]    # camera B loses a row
    beats_b[5 * p.width - 1] = dict(beats_b[5 * p.width - 1], flags=1)
    centres = [int(c) for c in rng.integers(-p.centre_range, p.centre_range + 1,
                                            len(beats_a))]
    pairs = stereo_pairs(frame_rows(beats_a, centres, p),
                         frame_rows(beats_b, [0] * len(beats_b), p), p.frame_bits)
    lane = StereoLaneModel(p)
    expected = [m for a, b in pairs for m in lane.process_pair(a, b)]
    for batch in ([pairs], random_cuts(rng, pairs)):
        got = [m for cut in batch
               for m in lane.process_pairs([a for a, _ in cut], [b for _, b in cut])]
        assert got == expected, f"SEED={SEED}"
    assert lane.run(beats_a, centres, beats_b) == expected
    assert {0, 1} <= fields(expected, "bad") and {0, 1} <= fields(expected, "edge_hit")
    assert len({a.centre for a, _ in pairs}) > 3 and max(fields(expected, "confidence")) > 0


# --- batch arguments ---------------------------------------------------------------------

def test_empty_batches():
    assert TemporalLaneModel(SMALL).process_rows([]) == []
    assert StereoLaneModel(SMALL_STEREO).process_pairs([], []) == []


def test_bad_batch_arguments():
    rng = rng_for(7)
    row = FramedRow(pixels=rng.integers(0, 256, SMALL.width), camera=0, frame=0, row=0,
                    t_first=0, centre=0, bad=False, padded=False)
    with pytest.raises(ValueError, match="rows_a and rows_b must pair up, not 2 and 1 rows"):
        StereoLaneModel(SMALL_STEREO).process_pairs([row, row], [row])
    short = FramedRow(**{**row.__dict__, "pixels": row.pixels[:100]})
    with pytest.raises(ValueError, match="rows must hold rows of 160 pixels, not 100"):
        TemporalLaneModel(SMALL).process_rows([short])
    with pytest.raises(ValueError, match="rows_b must hold rows of 160 pixels, not 100"):
        StereoLaneModel(SMALL_STEREO).process_pairs([row], [short])
    bits = np.zeros((3, SMALL.width), dtype=bool)
    with pytest.raises(ValueError, match="centres must hold one value or one per row "
                                         r"\(3\), not 2"):
        measure_rows(bits, bits, [0, 1], SMALL)
    with pytest.raises(ValueError, match="bad must hold one value or one per row"):
        measure_rows(bits, bits, 0, SMALL, bad=[True, False])


# --- the followed-row store (closed loop) -------------------------------------------------

def test_following_the_own_row_is_the_plain_lane():
    """A following lane told to read each row's own index gives the plain lane's dicts
    (bad rows, wrapping frame numbers, saturated centres included)."""
    rows = temporal_rows(rng_for(10), SMALL, 4, faults=3)
    plain = TemporalLaneModel(SMALL).process_rows(rows)
    following = TemporalLaneModel(SMALL, follow=True)
    followed = [m for row in rows
                for m in following.process_rows([row], [[row.row] * SMALL.segments])]
    assert followed == plain


def test_a_followed_row_is_the_previous_frames_row_even_after_this_frame_wrote_it():
    """Row 4 of frame 1 reads row 1 of frame 0, which frame 1's row 1 would already
    have replaced in a same-row store: the ring keeps it; a source outside the frame or a
    row of the wrong frame gives no reference."""
    rng = rng_for(11)
    p = SMALL
    pixels = rng.integers(0, 256, (2, p.height, p.width))
    rows = [FramedRow(pixels=pixels[f, y], camera=0, frame=f, row=y, t_first=0, centre=0,
                      bad=False, padded=False) for f in range(2) for y in range(p.height)]
    store_lane = TemporalLaneModel(p, follow=True)
    k = p.segments
    store_lane.process_rows(rows[:p.height], [[y] * k for y in range(p.height)])  # frame 0
    store = store_lane.store
    bits, _ = descriptor_bits(pixels[1], p)
    sources = [[y] * k for y in (0, 1, 2, 3, 1, -1)]
    reference, none = store.exchange(rows[p.height:], bits, sources)
    expected, _ = descriptor_bits(pixels[0], p)
    kept = p.width - p.radius
    np.testing.assert_array_equal(reference[4, :kept], expected[1, :kept])
    assert list(none) == [False] * 5 + [True]
    late = [dataclasses.replace(rows[0], frame=3)]        # frame 2 was never stored
    _, none = store.exchange(late, bits[:1], [[0] * k])
    assert none[0]


def test_sources_must_match_the_lane_kind():
    row = temporal_rows(rng_for(12), SMALL, 1, faults=0)[0]
    with pytest.raises(ValueError, match="sources must be given exactly when"):
        TemporalLaneModel(SMALL).process_rows([row], [0])
    with pytest.raises(ValueError, match="sources must be given exactly when"):
        TemporalLaneModel(SMALL, follow=True).process_rows([row])

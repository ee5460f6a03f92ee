"""The followed reference store (a ring of ``height + D + 1`` rows): the model against
the two-bank specification it replaces, its served range and flags, and the following
lane's gateware (``RowDescriptor(params, follow=True)``) against the model in the
Amaranth simulator. The cocotb bench on the generated Verilog is
``row_descriptor/followed_bench.py``. SEED replays a run (printed).
"""

import os

import numpy as np
import pytest

from emulator.descriptor.framer import FramedRow, frame_rows
from emulator.descriptor.matcher import descriptor_bits
from emulator.hdl_sim.row_stimulus import frame_beats, inject_faults, moving_rows
from emulator.row_descriptor import FollowedReferenceStoreModel, TemporalLaneModel
from golden.descriptor import DescriptorParams, MatchParams
from hdl.descriptor.params import REFERENCE_WORD_BITS, RowDescriptorParams
from hdl.descriptor.store import ReferenceStore
from hdl.row_descriptor import RowDescriptor
from sim_tests.descriptor.test_row_descriptor import check_latency, simulate

SEED = int(os.environ.get("SEED", 20261202))

#: 160-pixel rows, 8 rows a frame, D = 2: a ring of 11 rows, so requests leave the
#: served range often.
RING = RowDescriptorParams(width=160, height=8, centre_range=4, max_row_displacement=2,
                           match=MatchParams(segments=2))


def rng_for(offset):
    print(f"SEED={SEED}")
    return np.random.default_rng(SEED + offset)


class TwoBanks:
    """The specification the ring replaces (the former model): two banks of ``height``
    rows, frame ``f`` written into bank ``f mod 2``, any row of the previous frame
    readable until its frame ends; each stored word from its segment's row."""

    def __init__(self, params):
        self.params = params
        self.bits = np.zeros((2, params.height, params.width), dtype=bool)
        self.valid = np.zeros((2, params.height), dtype=bool)
        self.frame = np.zeros((2, params.height), dtype=np.int64)

    def exchange(self, rows, bits, sources):
        p, kept = self.params, self.params.width - self.params.radius
        reference = np.zeros((len(rows), p.width), dtype=bool)
        none = np.ones(len(rows), dtype=bool)
        for i, (row, segment_sources) in enumerate(zip(rows, sources)):
            bank, previous = row.frame % 2, (row.frame - 1) % 2
            served = True
            for q, k in enumerate(p.word_segments(row.centre)):
                source = segment_sources[k]
                if not 0 <= source < p.height:
                    served = False
                    continue
                columns = slice(REFERENCE_WORD_BITS * q, REFERENCE_WORD_BITS * (q + 1))
                reference[i, columns] = self.bits[previous, source, columns]
                served &= bool(self.valid[previous, source] and self.frame[previous, source]
                               == (row.frame - 1) % (1 << p.frame_bits))
            none[i] = not served
            self.bits[bank, row.row, :kept] = bits[i, :kept]
            self.valid[bank, row.row], self.frame[bank, row.row] = not row.bad, row.frame
        return reference, none


def random_sources(rng, params, row_indices):
    """K source rows per row index, each: uniform inside the served range, on its upper
    boundary (d = D + 1), just beyond it (d = D + 2), or far outside (−1, height, the
    largest row index), each a quarter of the time (the boundary cases where they
    exist); a third of the rows name one row for every segment."""
    out = []
    for y in row_indices:
        lo = y - params.row_displacement - 1
        row = []
        for _ in range(params.segments):
            kind = rng.integers(4)
            if kind == 0 or (kind in (1, 2) and lo - (kind == 2) < 0):
                row.append(int(rng.integers(max(lo, 0), params.height)))
            elif kind in (1, 2):
                row.append(int(lo - (kind == 2)))
            else:
                row.append(int(rng.choice([-1, params.height, (1 << params.row_bits) - 1])))
        out.append(row if rng.random() > 1 / 3 else [row[0]] * params.segments)
    return out


def row_served(params, row, sources):
    """Whether the ring serves every segment ``row`` (a FramedRow) reads."""
    return all(params.source_in_range(row.row, sources[k])
               for k in set(params.word_segments(row.centre)))


def textured_rows(rng, params, n_frames, faults=0, frame0=65534):
    frames, _ = moving_rows(rng, n_frames, params.height, params.width)
    beats = inject_faults(rng, frame_beats(frames, frame0=frame0), params.width, faults)
    centres = [int(c) for c in rng.integers(-6, 7, len(beats))]
    return frame_rows(beats, centres, params)


# --- the model ----------------------------------------------------------------------------

@pytest.mark.parametrize("faults", [0, 6])
def test_ring_equals_two_banks_inside_the_range_and_flags_the_rest(faults):
    """Random sources over five frames (frame numbers wrapping, bad rows): every row the
    ring serves gives the two banks' bits and flag; every other one is flagged and
    counted, its out-of-range segments reading zeros."""
    rng = rng_for(faults)
    p = RING
    rows = textured_rows(rng, p, 5, faults)
    sources = random_sources(rng, p, [r.row for r in rows])
    bits, _ = descriptor_bits(np.array([r.pixels for r in rows]), p)
    ring = FollowedReferenceStoreModel(p)
    got, got_none = ring.exchange(rows, bits, sources)
    want, want_none = TwoBanks(p).exchange(rows, bits, sources)
    served = np.array([row_served(p, r, s) for r, s in zip(rows, sources)])
    assert 0.1 < served.mean() < 0.95 and (~want_none[served]).sum() > 10
    np.testing.assert_array_equal(got[served], want[served])
    np.testing.assert_array_equal(got_none[served], want_none[served])
    assert got_none[~served].all()
    for i in np.flatnonzero(~served):           # out-of-range segments read zeros
        for q, k in enumerate(p.word_segments(rows[i].centre)):
            columns = slice(REFERENCE_WORD_BITS * q, REFERENCE_WORD_BITS * (q + 1))
            inside = p.source_in_range(rows[i].row, sources[i][k])
            np.testing.assert_array_equal(got[i, columns],
                                          want[i, columns] if inside else False)
    assert ring.out_of_range == (~served).sum()


def test_the_served_range_is_exact():
    """Row y of frame 1 against frame 0: sources y − D − 1 … height − 1 are frame 0's
    rows; y − D − 2, −1 and height are not."""
    p = RING
    d = p.row_displacement
    pixels = rng_for(2).integers(0, 256, (2, p.height, p.width))
    bits = [descriptor_bits(pixels[f], p)[0] for f in range(2)]
    kept = p.width - p.radius
    for y in range(p.height):
        for source in range(-1, p.height + 1):
            store = FollowedReferenceStoreModel(p)
            rows = [FramedRow(pixels=pixels[f, r], camera=0, frame=f, row=r, t_first=0,
                              centre=0, bad=False, padded=False)
                    for f, r in [(0, r) for r in range(p.height)] + [(1, r) for r in
                                                                     range(y + 1)]]
            stack = np.concatenate([bits[0], bits[1][:y + 1]])
            ref, none = store.exchange(rows, stack, [[0, 0]] * (p.height + y) +
                                       [[source, source]])
            inside = 0 <= source < p.height and y - source <= d + 1
            assert p.source_in_range(y, source) == inside
            assert none[-1] == (not inside), (y, source)
            if inside:
                np.testing.assert_array_equal(ref[-1, :kept], bits[0][source, :kept])


def test_a_lost_row_or_frame_is_flagged_never_replaced():
    """Frame 1 lost its row 3 and frame 3 never came: row 3 of frame 1 is not served to
    frame 2 (its ring slot holds another row), and frame 4 has no reference at all."""
    p = RING
    pixels = rng_for(3).integers(0, 256, (5, p.height, p.width))
    rows = [FramedRow(pixels=pixels[f, y], camera=0, frame=f, row=y, t_first=0, centre=0,
                      bad=False, padded=False)
            for f in (0, 1, 2, 4) for y in range(p.height) if (f, y) != (1, 3)]
    bits, _ = descriptor_bits(np.array([r.pixels for r in rows]), p)
    sources = [[r.row] * p.segments for r in rows]
    _, none = FollowedReferenceStoreModel(p).exchange(rows, bits, sources)
    flagged = {(r.frame, r.row) for r, n in zip(rows, none) if n}
    assert flagged == ({(0, y) for y in range(p.height)} | {(2, 3)} |
                       {(4, y) for y in range(p.height)})


@pytest.mark.parametrize("centre", [-4, 0, 4])
def test_each_word_is_read_from_its_segment_s_row(centre):
    """Row 4 of frame 1 names row 1 for segment 0 and row 6 for segment 1 (both served,
    D = 2): the words whose middle column plus the centre lies in segment 0 come from
    frame 0's row 1, the others from its row 6, and the row has a reference."""
    p = RING
    pixels = rng_for(4).integers(0, 256, (2, p.height, p.width))
    bits = np.concatenate([descriptor_bits(pixels[f], p)[0] for f in range(2)])
    rows = [FramedRow(pixels=pixels[f, y], camera=0, frame=f, row=y, t_first=0,
                      centre=centre, bad=False, padded=False)
            for f in range(2) for y in range(p.height)]
    sources = [[y, y] for y in range(p.height)] * 2
    sources[p.height + 4] = [1, 6]
    ref, none = FollowedReferenceStoreModel(p).exchange(rows, bits, sources)
    assert not none[p.height + 4]
    segments = p.word_segments(centre)
    assert set(segments) == {0, 1}
    kept = p.width - p.radius
    for q, k in enumerate(segments):
        columns = slice(REFERENCE_WORD_BITS * q, min(REFERENCE_WORD_BITS * (q + 1), kept))
        np.testing.assert_array_equal(ref[p.height + 4, columns], bits[[1, 6][k], columns])
    middle = REFERENCE_WORD_BITS * np.arange(len(segments)) + REFERENCE_WORD_BITS // 2
    start = p.segment_starts[0]
    assert segments == tuple(int(x + centre >= start) for x in middle)


def test_the_default_ring_fills_nine_block_rams_at_640x480():
    p = RowDescriptorParams()
    words = p.ring_rows * ReferenceStore(p, follow=True).words_per_row
    assert (p.row_displacement, p.ring_rows, words) == (31, 512, 9 * 1024)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"max_row_displacement": -1}, ValueError,
     "max_row_displacement must be an integer between 0 and 1024, not -1"),
    ({"max_row_displacement": 2.0}, TypeError, "max_row_displacement must be an integer"),
])
def test_bad_max_row_displacement(kwargs, error, message):
    with pytest.raises(error, match=message):
        RowDescriptorParams(**kwargs)


def test_bad_store_arguments():
    with pytest.raises(TypeError, match="follow must be a bool, not 1"):
        ReferenceStore(RING, 1)
    thin = RowDescriptorParams(width=160, height=8, descriptor=DescriptorParams(sigma=0.5),
                               centre_range=4, match=MatchParams(segments=2))
    with pytest.raises(ValueError, match="needs a descriptor radius of at least 3 .* not 2"):
        RowDescriptor(thin, follow=True)
    RowDescriptor(thin)                     # the same-row lane has no such limit


# --- the gateware ---------------------------------------------------------------------------

def followed_beats(rng, params, n_frames, faults=0):
    """Beats carrying each row's centre and source (random, some outside the served
    range and the centre range), and the model's measurements of them."""
    frames, _ = moving_rows(rng, n_frames, params.height, params.width)
    beats = inject_faults(rng, frame_beats(frames, frame0=65534), params.width, faults)
    firsts = [i for i, b in enumerate(beats) if b["first"]]
    sources = [[s % (1 << params.row_bits) for s in row]        # the port is unsigned
               for row in random_sources(rng, params, [beats[i]["row"] for i in firsts])]
    centres = [int(c) for c in rng.integers(-params.centre_range - 2,
                                            params.centre_range + 3, len(firsts))]
    per_beat, k = [], -1
    for i, beat in enumerate(beats):
        k += beat["first"]
        beat.update(centre=centres[max(k, 0)], source=sources[max(k, 0)])
        per_beat.append(beat["centre"])
    model = TemporalLaneModel(params, follow=True)
    expected = model.process_rows(frame_rows(beats, per_beat, params), sources)
    return beats, expected, model.store.out_of_range


@pytest.mark.parametrize("traffic", ["full_rate", "gaps_and_backpressure"])
def test_following_lane_matches_model(traffic):
    busy = traffic == "full_rate"
    rng = rng_for(10 + busy)
    beats, expected, out_of_range = followed_beats(rng, RING, 4)
    d = RING.row_displacement
    displacements = {b["row"] - s for b in beats if b["first"] for s in b["source"]}
    assert {d + 1, d + 2} <= displacements, "the stimulus misses the range's edge"
    assert out_of_range > 0 and any(not m["no_reference"] for m in expected)
    dut = RowDescriptor(RING, follow=True)
    final = {"out_of_range": None}
    outputs, accepted = simulate(dut, {"i": beats}, None, len(expected), seed=SEED,
                                 valid_prob=1.0 if busy else 0.7,
                                 ready_prob=1.0 if busy else 0.4, final=final)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"
    assert final["out_of_range"] == out_of_range
    if busy:
        lasts = [c for c, b in zip(accepted["i"], beats) if b["last"]]
        check_latency(outputs, lasts, dut)
        assert accepted["i"] == list(range(accepted["i"][0], accepted["i"][0] + len(beats)))


def test_following_lane_with_bad_rows():
    rng = rng_for(12)
    beats, expected, _ = followed_beats(rng, RING, 4, faults=5)
    assert any(m["bad"] for m in expected)
    outputs, _ = simulate(RowDescriptor(RING, follow=True), {"i": beats}, None,
                          len(expected), seed=SEED, valid_prob=0.8, ready_prob=0.7)
    assert [m for _, m in outputs] == expected, f"SEED={SEED}"


# --- block RAM (RUN_SLOW=1: three Yosys runs, a few minutes) -----------------------------

@pytest.mark.skipif(not os.environ.get("RUN_SLOW"), reason="synthesis: set RUN_SLOW=1")
def test_block_ram_of_the_stores_at_640x480():
    """Yosys synth_xilinx of the store alone at 640×480: the same-row store, the ring
    with the default D = 31, and two frames' worth of rows (the ring with D = height − 1
    = 2 × height slots, which serves every row the two banks served). The ring costs
    the same-row store's block RAM; two frames cost about twice."""
    from emulator.synth import synth_report
    p = RowDescriptorParams()
    stores = {"store_same_row": ReferenceStore(p),
              "store_ring_d31": ReferenceStore(p, follow=True),
              "store_two_frames": ReferenceStore(
                  p.replace(max_row_displacement=p.height - 1), follow=True)}
    figures = {name: synth_report(store, name) for name, store in stores.items()}
    for name, f in figures.items():
        print(f"{name}: {f['bram36']} BRAM36, {f['lut']} LUT, {f['ff']} FF, "
              f"{f['lutram']} LUTRAM, {f['lut_levels']} LUT levels")
    same, ring, two = (figures[n]["bram36"] for n in stores)
    assert ring == same
    assert two >= 1.8 * same

"""Bit-accurate model of the row-descriptor lanes (``hdl/row_descriptor.py``).

Integers only, from the same :class:`hdl.descriptor.params.RowDescriptorParams` as
the gateware. The conventions (borders, shift sign, compare range, segments, first
minimum, second minimum at distance ≥ 2) are :mod:`golden.descriptor`'s, and so are the
integer parts of the computation: the bit changes and the cost peaks are called
directly; the descriptor (quantized kernel) and the Hamming costs are recomputed here
for speed, one FIR pass and 64-bit popcounts, and tested equal to golden's. What is the
hardware's own is modelled here: row framing of the camera stream (padding of short
rows, dropping of stray pixels), the reference store with its frame tags, the
fixed-point sub-pixel and confidence divisions, and the flags.

A lane model takes camera beats (dicts of ``hdl.streams.camera_pixel_layout`` fields)
and returns measurement dicts (fields of the measurement layout) in output order.

Speed: everything after the framer works on batches of rows (numpy over rows, segments
and shifts; rows grouped by their run-time centre, which sets the compared columns), so
a whole frame of a camera costs a few dozen array operations instead of a Python pass
per row. The per-row methods are batches of one; :meth:`TemporalLaneModel.process_rows`
and :meth:`StereoLaneModel.process_pairs` give the same dicts in the same order as one
call per row.
"""

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from golden.descriptor import (cost_peaks, describe, match, segment_bounds, strength,
                               textureless)
from hdl.fixed import UQ, Overflow, Rounding, resize

__all__ = ["FramedRow", "frame_rows", "descriptor_bits", "hamming_costs", "measure_rows",
           "measure_segments", "ReferenceStoreModel", "TemporalLaneModel",
           "StereoLaneModel", "stereo_pairs", "against_golden", "subpixel_errors",
           "confidences"]


@dataclass
class FramedRow:
    """A row as the framer hands it on: exactly ``width`` pixels and its metadata.

    ``bad`` is the row's final verdict (reason bits, short, long, or interrupted row, row
    index outside the frame); ``centre`` is the saturated centre sampled with its first
    pixel; ``padded`` says the framer filled the row's end with zero pixels.
    """
    pixels: np.ndarray
    camera: int
    frame: int
    row: int
    t_first: int
    centre: int
    bad: bool
    padded: bool

    def meta(self):
        return {"camera": self.camera, "frame": self.frame, "row": self.row,
                "t_first": self.t_first}


def frame_rows(beats, centres, params):
    """The framer: a camera beat stream to rows of exactly ``params.width`` pixels.

    ``centres[i]`` is the centre port's value when beat ``i`` is accepted (only the one
    with a row's ``first`` beat is used). A ``first`` beat opens a row (and pads the end
    of a row left incomplete); beats outside an open row are dropped; a row whose
    ``last`` comes early is padded with zeros, one whose pixel ``width − 1`` lacks
    ``last`` is complete there and the rest is dropped. All those rows are bad.
    """
    width, rows, cur = params.width, [], None

    def close(row, pixels):
        row.padded = len(pixels) < width
        row.bad |= row.padded
        row.pixels = np.array(pixels + [0] * (width - len(pixels)), dtype=np.int64)
        rows.append(row)

    pixels = []
    for beat, centre in zip(beats, centres):
        if beat["first"]:
            if cur is not None:
                close(cur, pixels)
            cur, pixels = FramedRow(
                pixels=None, camera=beat["camera"], frame=beat["frame"], row=beat["row"],
                t_first=beat["t_first"], centre=params.clamp_centre(centre),
                bad=beat["row"] >= params.height, padded=False), []
        elif cur is None:
            continue
        pixels.append(beat["data"])
        cur.bad |= bool(beat["flags"])
        if len(pixels) == width:
            cur.bad |= not beat["last"]
            close(cur, pixels)
            cur = None
        elif beat["last"]:
            close(cur, pixels)
            cur = None
    return rows  # a row still open at the end waits for its last beat or the next first


@lru_cache(maxsize=32)
def _constants(params):
    """``(kernel taps, strong threshold, confidence cap)`` raw, quantized once per
    parameter set rather than once per batch (it dominates batches of one row)."""
    kernel = np.array(params.kernel_raw(), dtype=np.int64)
    kernel.setflags(write=False)
    return kernel, params.strong_raw(), params.cap_raw()


def descriptor_bits(pixels, params):
    """Descriptor bits and strong columns of rows ``(..., width)``: ``golden.descriptor``'s
    ``describe`` and ``strength`` with the quantized kernel and threshold, from one
    integer FIR pass (int32 where no sum can overflow it: several times faster)."""
    pixels = np.asarray(pixels, dtype=np.int64)
    kernel, threshold, _ = _constants(params)
    largest = int(np.abs(kernel).sum()) * int(np.abs(pixels).max(initial=0))
    rows = pixels.astype(np.int32 if largest < 2 ** 31 else np.int64)
    r, width = params.radius, pixels.shape[-1]
    interior = width - 2 * r
    response = np.zeros(rows.shape[:-1] + (interior,), dtype=rows.dtype)
    for j, tap in enumerate(kernel.astype(rows.dtype)):
        response += tap * rows[..., j:j + interior]
    bits, strong = np.zeros(pixels.shape, dtype=bool), np.zeros(pixels.shape, dtype=bool)
    bits[..., r:width - r] = response > 0
    strong[..., r:width - r] = np.abs(response) >= threshold
    return bits, strong


def _rounded_quotient(num, den, quotient_bits, fmt):
    """``floor(num / den)`` saturated to ``quotient_bits`` bits (den = 0 saturates), as the
    restoring divider computes it, then rounded half-up to ``fmt`` (one fraction bit
    fewer), saturating."""
    num, den = np.asarray(num, dtype=np.int64), np.asarray(den, dtype=np.int64)
    top = (1 << quotient_bits) - 1
    q = np.where(den > 0, num // np.maximum(den, 1), top)
    q = np.minimum(q, top)
    src = UQ(fmt.int_bits, fmt.frac_bits + 1)
    return resize(q, src, fmt, Rounding.HALF_UP, Overflow.SATURATE)


def _packed_words(bits):
    """Bits ``(..., L)`` packed into little-endian 64-bit words ``(..., ceil(L / 64))``,
    zero-padded (padding never counts: it is zero in every operand)."""
    packed = np.packbits(bits, axis=-1, bitorder="little")
    words = np.zeros(packed.shape[:-1] + (-(-bits.shape[-1] // 64) * 8,), dtype=np.uint8)
    words[..., :packed.shape[-1]] = packed
    return words.view(np.uint64)


def hamming_costs(cur_bits, ref_bits, centre, params):
    """``golden.descriptor.hamming_costs`` of rows ``(N, W)`` at one (clamped) centre,
    ``(N, K, n_shifts)``, as 64-bit popcounts: each segment's columns of the current rows
    and of every shifted reference row are packed into words, XORed and counted
    (``np.bitwise_count``), instead of one pass over the columns per shift."""
    m = params.match
    bounds = segment_bounds(params.width, params.descriptor, m, centre)
    lo, hi = bounds[0][0], bounds[-1][1]
    first, n = centre + m.shift_min, params.n_shifts
    # shift first + i compares cur[x] with ref[x - first - i], x in [lo, hi)
    shifted = sliding_window_view(ref_bits[:, lo - first - n + 1:hi - first], hi - lo,
                                  axis=-1)[:, ::-1]
    costs = np.empty((len(cur_bits), len(bounds), n), dtype=np.int64)
    for k, (a, b) in enumerate(bounds):
        diff = _packed_words(shifted[..., a - lo:b - lo])
        diff ^= _packed_words(cur_bits[:, None, a:b])
        costs[:, k] = np.bitwise_count(diff).sum(axis=-1)
    return costs


def _per_row(name, values, n):
    """``values`` as one entry per row of ``n`` (a single value is repeated)."""
    values = np.asarray(values)
    if values.size not in (1, n):
        raise ValueError(f"{name} must hold one value or one per row ({n}), not "
                         f"{values.size}")
    return np.broadcast_to(values.reshape(-1), (n,))


def _cost_facts(cur_bits, ref_bits, centres, params, cur_strong):
    """:func:`golden.descriptor.cost_peaks` and the textureless flags of rows ``(N, W)``
    at clamped ``centres`` ``(N,)``: one batched call per distinct centre (it sets the
    compared columns and the shifts)."""
    n, k = len(cur_bits), params.segments
    facts = {name: np.zeros((n, k), dtype=np.int64)
             for name in ("best", "c0", "c2", "cm", "cp", "edge", "flat")}
    d, m = params.descriptor, params.match
    for c in np.unique(centres):
        at = centres == c
        costs = hamming_costs(cur_bits[at], ref_bits[at], int(c), params)
        for name, value in cost_peaks(costs)._asdict().items():
            facts[name][at] = value
        strong = None if cur_strong is None else cur_strong[at]
        facts["flat"][at] = textureless(cur_bits[at], d, m, int(c), strong)
    return facts


def measure_rows(cur_bits, ref_bits, centres, params, *, cur_strong=None, bad=False,
                 no_reference=False):
    """Per-segment results of ``N`` rows, each field an int array of shape ``(N, K)``.

    ``cur_bits``, ``ref_bits`` (and ``cur_strong``, the current rows' strong columns, see
    ``golden.descriptor.textureless``): ``(N, W)``; ``centres``, ``bad``,
    ``no_reference``: one per row (or one for all). Fields: ``shift`` (d*),
    ``subpixel`` (raw ``subpixel_fmt``: |δ| = floor(|C₋ − C₊|·2^f / D) rounded half-up
    on the magnitude, D = C₋ − 2C₀ + C₊; 0 on the window edge), ``confidence`` (raw
    ``confidence_fmt``: (c₂ + κ)/(c₁ + κ) floored to one extra fraction bit, saturated,
    rounded half-up, capped; cap when c₁ + κ = 0 < c₂ + κ; 0 when both are 0, and 0 when
    textureless, bad or without reference), and the flags.
    """
    cur_bits, ref_bits = np.asarray(cur_bits, dtype=bool), np.asarray(ref_bits, dtype=bool)
    n, k, m = len(cur_bits), params.segments, params.match
    centres = _per_row("centres", [params.clamp_centre(c) for c in np.ravel(centres)], n)
    bad = _per_row("bad", np.asarray(bad, dtype=bool), n)[:, None]
    no_reference = _per_row("no_reference", np.asarray(no_reference, dtype=bool), n)[:, None]
    if cur_strong is not None:
        cur_strong = np.asarray(cur_strong, dtype=bool)
    f = _cost_facts(cur_bits, ref_bits, centres, params, cur_strong)
    c0, cm, cp, edge = f["c0"], f["cm"], f["cp"], f["edge"].astype(bool)
    sub = params.subpixel_frac_bits
    den = np.where(edge, 1, cm - 2 * c0 + cp)
    mag = _rounded_quotient(np.abs(cm - cp) << sub, den, params.subpixel_quotient_bits,
                            UQ(1, sub))
    subpixel = np.where(edge, 0, np.where(cm < cp, -mag, mag))
    cf, kappa = params.confidence_fmt, m.peak_ratio_offset
    best_k, second_k = c0 + kappa, f["c2"] + kappa
    ratio = _rounded_quotient(second_k << (cf.frac_bits + 1), best_k,
                              params.ratio_quotient_bits, cf)
    ratio = np.minimum(ratio, _constants(params)[2])
    ratio = np.where((best_k == 0) & (second_k == 0), 0, ratio)
    ratio = np.where((f["flat"] != 0) | bad | no_reference, 0, ratio)
    full = lambda flag: np.repeat(flag.astype(np.int64), k, axis=1)
    return {"segment": np.tile(np.arange(k), (n, 1)),
            "shift": centres[:, None] + m.shift_min + f["best"], "subpixel": subpixel,
            "confidence": ratio, "textureless": f["flat"], "edge_hit": f["edge"],
            "bad": full(bad), "no_reference": full(no_reference)}


def measure_segments(cur_bits, ref_bits, centre, params, *, cur_strong=None, bad=False,
                     no_reference=False):
    """:func:`measure_rows` of one row: each field an int array of shape ``(K,)``."""
    strong = None if cur_strong is None else np.asarray(cur_strong)[None]
    results = measure_rows(np.asarray(cur_bits)[None], np.asarray(ref_bits)[None], centre,
                           params, cur_strong=strong, bad=bad, no_reference=no_reference)
    return {key: value[0] for key, value in results.items()}


def against_golden(cur, ref, centre, params):
    """The golden float matcher and this model on the same rows (current and reference
    pixels, ``(W,)``): returns ``(golden MatchResult, model results, model shift in
    pixels)``; level 2 of the three levels of truth."""
    c = params.clamp_centre(centre)
    d, m = params.descriptor, params.match
    cur_f, ref_f = np.asarray(cur, dtype=np.float64), np.asarray(ref, dtype=np.float64)
    golden = match(describe(cur_f, d), describe(ref_f, d), d, m, c,
                   cur_strong=strength(cur_f, d))
    cur_bits, cur_strong = descriptor_bits(cur, params)
    ref_bits, _ = descriptor_bits(ref, params)
    model = measure_segments(cur_bits, ref_bits, c, params, cur_strong=cur_strong)
    return golden, model, model["shift"] + params.subpixel_fmt.to_float(model["subpixel"])


def subpixel_errors(cur_rows, ref_rows, centres, params, min_ratio=1.5):
    """``|model − golden|`` shift (pixels) of every well-textured segment of the row
    pairs: golden finds it textured, off the window edge, with peak ratio ≥
    ``min_ratio``."""
    errors = []
    for cur, ref, centre in zip(cur_rows, ref_rows, centres):
        golden, _, shift = against_golden(cur, ref, centre, params)
        good = ~golden.textureless & ~golden.edge_hit & (golden.peak_ratio >= min_ratio)
        errors += list(np.abs(shift - golden.shift)[good])
    return np.array(errors)


def confidences(cur_rows, ref_rows, params):
    """Golden peak ratios and the model's confidences (as numbers) of every segment of
    the row pairs, centre 0: two flat arrays, for comparing their order."""
    golden_ratio, model_ratio = [], []
    for cur, ref in zip(cur_rows, ref_rows):
        golden, model, _ = against_golden(cur, ref, 0, params)
        golden_ratio += list(golden.peak_ratio)
        model_ratio += list(params.confidence_fmt.to_float(model["confidence"]))
    return np.array(golden_ratio), np.array(model_ratio)


def _records(rows, results):
    """Measurement dicts of rows and their :func:`measure_rows` results, in output order
    (row by row, segment 0 first)."""
    columns = [(key, value.tolist()) for key, value in results.items()]
    segments = range(results["segment"].shape[1])
    return [{**row.meta(), **{key: column[n][s] for key, column in columns}}
            for n, row in enumerate(rows) for s in segments]


def _pixels(rows, params, name):
    """The pixels of framed rows as one ``(N, width)`` array."""
    pixels = np.array([row.pixels for row in rows], dtype=np.int64).reshape(len(rows), -1)
    if pixels.shape[1] != params.width:
        raise ValueError(f"{name} must hold rows of {params.width} pixels, not "
                         f"{pixels.shape[1]}")
    return pixels


class ReferenceStoreModel:
    """The reference store: one descriptor row per row index, tagged with its frame.

    A row reads the bits stored at its row index (the previous write there) while its
    own bits replace them; the reference is valid when the stored row came from frame
    ``frame − 1`` (modulo ``2**frame_bits``) and was not bad.
    """

    def __init__(self, params):
        self.params = params
        self.bits = np.zeros((params.height, params.width), dtype=bool)
        self.tag_valid = np.zeros(params.height, dtype=bool)
        self.tag_frame = np.zeros(params.height, dtype=np.int64)

    def exchange(self, rows, bits):
        """Store each row's ``bits`` ``(N, width)`` in turn, as the rows arrive; returns
        ``(reference bits (N, width), no_reference (N,))``. A row may read the bits of
        an earlier row of the same batch (same row index, an earlier frame).

        Only the frame tags are followed row by row; the bits move in a few array
        operations. The last ``R`` columns are never written (they are border bits,
        always 0), so a reference is the writer's bits with those columns cleared.
        """
        p, n = self.params, len(rows)
        kept = p.width - p.radius
        ys = np.array([row.row for row in rows], dtype=np.int64)
        no_reference = np.ones(n, dtype=bool)
        source = np.full(n, -1)       # the batch row a reference comes from, -1: the store
        writer = {}                   # row index -> last batch row written there
        for i, row in enumerate(rows):
            y = row.row
            if y >= p.height:
                continue
            j = writer.get(y, -1)
            valid, frame = ((self.tag_valid[y], self.tag_frame[y]) if j < 0
                            else (not rows[j].bad, rows[j].frame))
            no_reference[i] = not (valid and frame == (row.frame - 1) % (1 << p.frame_bits))
            source[i], writer[y] = j, i
        reference = np.zeros((n, p.width), dtype=bool)
        stored = (source < 0) & (ys < p.height)
        reference[stored] = self.bits[ys[stored]]
        batch = source >= 0
        reference[batch, :kept] = bits[source[batch], :kept]
        last = np.array(list(writer.values()), dtype=np.int64)
        self.bits[ys[last], :kept] = bits[last, :kept]
        self.tag_valid[ys[last]] = [not rows[i].bad for i in last]
        self.tag_frame[ys[last]] = [rows[i].frame for i in last]
        return reference, no_reference


class TemporalLaneModel:
    """One camera: each row matched against the same row of the previous frame."""

    def __init__(self, params):
        self.params = params
        self.store = ReferenceStoreModel(params)

    def process_rows(self, rows):
        """Measurements of framed rows (any number, e.g. a whole frame), in order.

        Parameters
        ----------
        rows : sequence of FramedRow
            In arrival order; each row's reference is what the store holds at its row
            index when it arrives (so a row may reference an earlier row of the batch).

        Returns
        -------
        list of dict
            The same dicts, in the same order, as :meth:`process_row` called on each
            row in turn: row by row, ``K`` segments each.
        """
        if not rows:
            return []
        p = self.params
        bits, strong = descriptor_bits(_pixels(rows, p, "rows"), p)
        reference, no_reference = self.store.exchange(rows, bits)
        return _records(rows, measure_rows(
            bits, reference, [row.centre for row in rows], p, cur_strong=strong,
            bad=[row.bad for row in rows], no_reference=no_reference))

    def process_row(self, row):
        """Measurements of one framed row (:meth:`process_rows` of one)."""
        return self.process_rows([row])

    def run(self, beats, centres):
        """Measurements of a beat stream (see :func:`frame_rows`)."""
        return self.process_rows(frame_rows(beats, centres, self.params))


def stereo_pairs(rows_a, rows_b, frame_bits):
    """The stereo join: pair rows with the same (frame, row); an unmatched row is the
    older of the two heads and is dropped (frame order modulo ``2**frame_bits``)."""
    half = 1 << (frame_bits - 1)
    pairs, ia, ib = [], 0, 0
    while ia < len(rows_a) and ib < len(rows_b):
        a, b = rows_a[ia], rows_b[ib]
        if (a.frame, a.row) == (b.frame, b.row):
            pairs.append((a, b))
            ia, ib = ia + 1, ib + 1
            continue
        dframe = (a.frame - b.frame) % (1 << frame_bits)
        a_older = dframe >= half or (dframe == 0 and a.row < b.row)
        ia, ib = (ia + 1, ib) if a_older else (ia, ib + 1)
    return pairs


class StereoLaneModel:
    """A stereo pair: camera A's row matched against camera B's row of the same time.

    ``cur[x] ≈ ref[x − d]``: A is the camera in which the scene appears ``d`` pixels
    further right (the left camera of a rectified pair, B the right one).
    """

    def __init__(self, params):
        self.params = params

    def process_pairs(self, rows_a, rows_b):
        """Measurements of joined row pairs (any number), in order.

        Parameters
        ----------
        rows_a, rows_b : sequence of FramedRow
            Camera A's and camera B's rows, ``rows_a[i]`` paired with ``rows_b[i]`` (as
            :func:`stereo_pairs` joins them); A's centre is used.

        Returns
        -------
        list of dict
            The same dicts, in the same order, as :meth:`process_pair` called on each
            pair in turn; a pair is bad when either row is.

        Raises
        ------
        ValueError
            If ``rows_a`` and ``rows_b`` differ in length.
        """
        if len(rows_a) != len(rows_b):
            raise ValueError(f"rows_a and rows_b must pair up, not {len(rows_a)} and "
                             f"{len(rows_b)} rows")
        if not rows_a:
            return []
        p = self.params
        cur, strong = descriptor_bits(_pixels(rows_a, p, "rows_a"), p)
        ref, _ = descriptor_bits(_pixels(rows_b, p, "rows_b"), p)
        results = measure_rows(cur, ref, [a.centre for a in rows_a], p, cur_strong=strong,
                               bad=[a.bad or b.bad for a, b in zip(rows_a, rows_b)])
        return _records(rows_a, results)

    def process_pair(self, row_a, row_b):
        """Measurements of one row pair (:meth:`process_pairs` of one)."""
        return self.process_pairs([row_a], [row_b])

    def run(self, beats_a, centres, beats_b):
        """Measurements of two beat streams (camera B's centre port is not used)."""
        rows_a = frame_rows(beats_a, centres, self.params)
        rows_b = frame_rows(beats_b, [0] * len(beats_b), self.params)
        pairs = stereo_pairs(rows_a, rows_b, self.params.frame_bits)
        return self.process_pairs([a for a, _ in pairs], [b for _, b in pairs])

"""Bit-accurate model of the row-descriptor lanes (``hdl/row_descriptor.py``).

Integers only, from the same :class:`hdl.row_descriptor_params.RowDescriptorParams` as
the gateware. The conventions (borders, shift sign, compare range, segments, first
minimum, second minimum at distance ≥ 2) are :mod:`golden.descriptor`'s, and so are the
integer parts of the computation, called directly: the descriptor with the quantized
kernel, the Hamming costs, the bit changes and the cost peaks. What is the hardware's
own is modelled here: row framing of the camera stream (padding of short rows, dropping
of stray pixels), the reference store with its frame tags, the fixed-point sub-pixel and
confidence divisions, and the flags.

A lane model takes camera beats (dicts of ``hdl.streams.camera_pixel_layout`` fields)
and returns measurement dicts (fields of the measurement layout) in output order.
"""

from dataclasses import dataclass

import numpy as np

from golden.descriptor import (cost_peaks, describe, hamming_costs, match, strength,
                               textureless)
from hdl.fixed import UQ, Overflow, Rounding, resize

__all__ = ["FramedRow", "frame_rows", "descriptor_bits", "measure_segments",
           "ReferenceStoreModel", "TemporalLaneModel", "StereoLaneModel", "stereo_pairs",
           "against_golden", "subpixel_errors", "confidences"]


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


def descriptor_bits(pixels, params):
    """Descriptor bits and strong columns of rows ``(..., width)`` with the quantized
    kernel and threshold (exact integers)."""
    pixels = np.asarray(pixels, dtype=np.int64)
    kernel = np.array(params.kernel_raw(), dtype=np.int64)
    return (describe(pixels, params.descriptor, kernel=kernel),
            strength(pixels, params.descriptor, kernel=kernel, threshold=params.strong_raw()))


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


def measure_segments(cur_bits, ref_bits, centre, params, *, cur_strong=None, bad=False,
                     no_reference=False):
    """Per-segment results of one row, each field an int array of shape ``(K,)``.

    ``shift`` (d*), ``subpixel`` (raw ``subpixel_fmt``: |δ| = floor(|C₋ − C₊|·2^f / D)
    rounded half-up on the magnitude, D = C₋ − 2C₀ + C₊; 0 on the window edge),
    ``confidence`` (raw ``confidence_fmt``: (c₂ + κ)/(c₁ + κ) floored to one extra
    fraction bit, saturated, rounded half-up, capped; cap when c₁ + κ = 0 < c₂ + κ; 0
    when both are 0, and 0 when textureless, bad or without reference), and the flags. ``cur_strong``: the
    current row's strong columns (see ``golden.descriptor.textureless``).
    """
    c = params.clamp_centre(centre)
    m = params.match
    costs = hamming_costs(cur_bits, ref_bits, params.descriptor, m, c)
    best, c0, c2, cm, cp, edge = cost_peaks(costs)
    f = params.subpixel_frac_bits
    den = np.where(edge, 1, cm - 2 * c0 + cp)
    mag = _rounded_quotient(np.abs(cm - cp) << f, den, params.subpixel_quotient_bits,
                            UQ(1, f))
    subpixel = np.where(edge, 0, np.where(cm < cp, -mag, mag))
    cf, kappa = params.confidence_fmt, m.peak_ratio_offset
    best_k, second_k = c0 + kappa, c2 + kappa
    ratio = _rounded_quotient(np.asarray(second_k) << (cf.frac_bits + 1), best_k,
                              params.ratio_quotient_bits, cf)
    ratio = np.minimum(ratio, params.cap_raw())
    ratio = np.where((best_k == 0) & (second_k == 0), 0, ratio)
    flat = textureless(cur_bits, params.descriptor, m, c, cur_strong)
    ratio = np.where(flat | bad | no_reference, 0, ratio)
    k = params.segments
    return {"segment": np.arange(k), "shift": c + m.shift_min + best, "subpixel": subpixel,
            "confidence": ratio, "textureless": flat.astype(int),
            "edge_hit": edge.astype(int), "bad": np.full(k, int(bad)),
            "no_reference": np.full(k, int(no_reference))}


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


def _records(row, results):
    """Measurement dicts of one row, in output order (segment 0 first)."""
    return [{**row.meta(), **{key: int(val[s]) for key, val in results.items()}}
            for s in range(len(results["segment"]))]


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

    def exchange(self, row, bits):
        """Store ``bits`` for ``row``; returns ``(reference bits, no_reference)``."""
        p = self.params
        if row.row >= p.height:
            return np.zeros(p.width, dtype=bool), True
        y = row.row
        previous = (row.frame - 1) % (1 << p.frame_bits)
        no_reference = not (self.tag_valid[y] and self.tag_frame[y] == previous)
        reference = self.bits[y].copy()
        self.bits[y, :p.width - p.radius] = bits[:p.width - p.radius]
        self.tag_valid[y], self.tag_frame[y] = not row.bad, row.frame
        return reference, no_reference


class TemporalLaneModel:
    """One camera: each row matched against the same row of the previous frame."""

    def __init__(self, params):
        self.params = params
        self.store = ReferenceStoreModel(params)

    def process_row(self, row):
        bits, strong = descriptor_bits(row.pixels, self.params)
        reference, no_reference = self.store.exchange(row, bits)
        return _records(row, measure_segments(bits, reference, row.centre, self.params,
                                              cur_strong=strong, bad=row.bad,
                                              no_reference=no_reference))

    def run(self, beats, centres):
        """Measurements of a beat stream (see :func:`frame_rows`)."""
        return [m for row in frame_rows(beats, centres, self.params)
                for m in self.process_row(row)]


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

    def process_pair(self, row_a, row_b):
        p = self.params
        cur, strong = descriptor_bits(row_a.pixels, p)
        ref, _ = descriptor_bits(row_b.pixels, p)
        results = measure_segments(cur, ref, row_a.centre, p, cur_strong=strong,
                                   bad=row_a.bad or row_b.bad)
        return _records(row_a, results)

    def run(self, beats_a, centres, beats_b):
        """Measurements of two beat streams (camera B's centre port is not used)."""
        rows_a = frame_rows(beats_a, centres, self.params)
        rows_b = frame_rows(beats_b, [0] * len(beats_b), self.params)
        return [m for a, b in stereo_pairs(rows_a, rows_b, self.params.frame_bits)
                for m in self.process_pair(a, b)]

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

The framer is :mod:`emulator.descriptor.framer`, the arithmetic
:mod:`emulator.descriptor.matcher`; this module holds the reference store and the lanes.
A lane model takes camera beats (dicts of ``hdl.streams.camera_pixel_layout`` fields)
and returns measurement dicts (fields of the measurement layout) in output order.

Speed: everything after the framer works on batches of rows (numpy over rows, segments
and shifts; rows grouped by their run-time centre, which sets the compared columns), so
a whole frame of a camera costs a few dozen array operations instead of a Python pass
per row. The per-row methods are batches of one; :meth:`TemporalLaneModel.process_rows`
and :meth:`StereoLaneModel.process_pairs` give the same dicts in the same order as one
call per row.
"""


import numpy as np


from emulator.descriptor.framer import frame_rows
from emulator.descriptor.matcher import descriptor_bits, measure_rows

__all__ = ["ReferenceStoreModel", "FollowedReferenceStoreModel", "TemporalLaneModel", "StereoLaneModel", "stereo_pairs"]


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


class FollowedReferenceStoreModel:
    """A reference store that serves rows of the previous frame chosen per row and
    segment (issue 16's followed rows): a ring of ``ring_rows = height + D + 1``
    descriptor rows (``params.row_displacement`` = D), the gateware's
    ``ReferenceStore(params, follow=True)``.

    Row ``y`` of a frame goes to slot ``(base + y) mod ring_rows``, where ``base``
    advances by ``height`` (mod ``ring_rows``) whenever a row's frame number differs from
    the previous row's (the frame's absolute first row index, modulo the ring; it follows
    the frames seen, so a wrapping frame counter does not break it). The previous frame's
    row ``s`` is read from ``(previous base + s) mod ring_rows``. That slot is rewritten by
    row ``s + D + 1`` of this frame, which reads it first, so row ``y`` is served every
    ``s`` with ``0 ≤ s < height`` and ``y − s ≤ D + 1``
    (:meth:`~hdl.descriptor.params.RowDescriptorParams.source_in_range`).

    Each row names one source row per segment; stored word ``q`` is read from the source
    of segment ``params.word_segments(centre)[q]``. A segment whose request is outside
    the served range reads zeros, and the row is counted once in :attr:`out_of_range`;
    the row has a reference when every segment it reads is in range and its slot's tag
    says it holds that row of frame ``frame − 1`` (modulo ``2**frame_bits``), not bad.
    The bits read are the slots', whatever the tags.
    """

    def __init__(self, params):
        self.params = params
        size = params.ring_rows
        self.bits = np.zeros((size, params.width), dtype=bool)
        self.tag_valid = np.zeros(size, dtype=bool)
        self.tag_frame = np.zeros(size, dtype=np.int64)
        self.tag_row = np.zeros(size, dtype=np.int64)
        self.reset()

    def reset(self):
        """What the gateware's reset does: the ring's bases, the frame seen and the
        :attr:`out_of_range` count restart; the memories keep their contents."""
        self.frame, self.base, self.previous_base, self.out_of_range = 0, 0, 0, 0

    def exchange(self, rows, bits, sources):
        """Store each row's ``bits`` in its ring slot and read, for each row, the
        previous frame's rows ``sources[i]`` (K integers, one per segment); returns
        ``(reference bits (N, width), no_reference (N,))``, one row after the other as
        they arrive."""
        p, n = self.params, len(rows)
        size, kept = p.ring_rows, p.width - p.radius
        sources = np.asarray(sources, dtype=np.int64).reshape(n, p.segments)
        reference = np.zeros((n, p.width), dtype=bool)
        no_reference = np.ones(n, dtype=bool)
        for i, row in enumerate(rows):
            if row.frame != self.frame:
                self.frame, self.previous_base = row.frame, self.base
                self.base = (self.base + p.height) % size
            if row.row >= p.height:
                continue
            pick = np.array(p.column_segments(row.centre)[:kept])      # each column's
            inside = np.array([p.source_in_range(row.row, int(s)) for s in sources[i]])
            slots = (self.previous_base + sources[i]) % size
            read = np.unique(pick)                                     # the segments read
            reference[i, :kept] = inside[pick] & self.bits[slots[pick], np.arange(kept)]
            no_reference[i] = not all(
                inside[k] and self.tag_valid[slots[k]] and self.tag_row[slots[k]] == sources[i, k]
                and self.tag_frame[slots[k]] == (row.frame - 1) % (1 << p.frame_bits)
                for k in read)
            self.out_of_range += not inside[read].all()
            slot = (self.base + row.row) % size
            self.bits[slot, :kept] = bits[i, :kept]
            self.tag_valid[slot], self.tag_frame[slot] = not row.bad, row.frame
            self.tag_row[slot] = row.row
        return reference, no_reference


def _half_width(row, params):
    """A framed row's run-time half-width (``None``: the built maximum)."""
    return params.max_half_width if row.half_width is None else row.half_width


class TemporalLaneModel:
    """One camera: each row matched against the same row of the previous frame, or with
    ``follow=True`` against rows of the previous frame chosen per row and segment (the
    forecast's row addresses, :class:`FollowedReferenceStoreModel`, a ring of
    ``height + row_displacement + 1`` rows)."""

    def __init__(self, params, follow=False):
        self.params = params
        self.store = FollowedReferenceStoreModel(params) if follow \
            else ReferenceStoreModel(params)

    def process_rows(self, rows, sources=None):
        """Measurements of framed rows (any number, e.g. a whole frame), in order.

        Parameters
        ----------
        rows : sequence of FramedRow
            In arrival order; each row's reference is what the store holds at its row
            index when it arrives (so a row may reference an earlier row of the batch).
        sources : (N, K) ints, optional
            With ``follow=True`` (and only then): the previous frame's row each segment
            of each row is compared with.

        Returns
        -------
        list of dict
            The same dicts, in the same order, as :meth:`process_row` called on each
            row in turn: row by row, ``K`` segments each.
        """
        if not rows:
            return []
        p = self.params
        if (sources is None) != isinstance(self.store, ReferenceStoreModel):
            raise ValueError("sources must be given exactly when the lane follows rows")
        bits, strong = descriptor_bits(_pixels(rows, p, "rows"), p)
        reference, no_reference = (self.store.exchange(rows, bits) if sources is None
                                   else self.store.exchange(rows, bits, sources))
        return _records(rows, measure_rows(
            bits, reference, [row.centre for row in rows], p, cur_strong=strong,
            bad=[row.bad for row in rows], no_reference=no_reference,
            half_widths=[_half_width(row, p) for row in rows]))

    def process_row(self, row):
        """Measurements of one framed row (:meth:`process_rows` of one)."""
        return self.process_rows([row])

    def run(self, beats, centres, half_widths=None):
        """Measurements of a beat stream (see :func:`frame_rows`)."""
        return self.process_rows(frame_rows(beats, centres, self.params, half_widths))


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

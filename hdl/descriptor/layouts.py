"""Stream layouts inside a row-descriptor lane (framer → FIR → store → matcher).

Every item is one column of a framed row: a row is exactly ``width`` items, ``pos`` is
the pixel column ``0 … width − 1``, ``first``/``last`` mark ``pos == 0``/``width − 1``,
and the row's metadata rides along with every item.
"""

from amaranth.lib import data

__all__ = ["meta_layout", "framed_layout", "descriptor_layout", "pair_layout"]


def meta_layout(params):
    """Row metadata: the camera beat's indices, the saturated centre (``centre_fmt``),
    the saturated run-time half-width of the shift window (``half_width_fmt``),
    the previous frame's rows the reference store reads (``source``, one per segment:
    the row itself in a same-row lane, the forecast's row addresses in a following
    one), ``bad``, sticky
    within the row (final on the row's last item), and ``paired``: a temporal lane's
    row also goes to its pair's stereo lane (``RowDescriptor(paired=True)``; 0 in
    every other lane)."""
    return data.StructLayout({
        "camera": params.camera_bits, "frame": params.frame_bits, "row": params.row_bits,
        "t_first": params.timestamp_bits, "centre": params.centre_fmt.shape(),
        "half_width": params.half_width_fmt.shape(),
        "source": data.ArrayLayout(params.row_bits, params.segments), "bad": 1, "paired": 1,
    })


def _column(params, payload):
    return data.StructLayout({
        **payload, "pos": (params.width - 1).bit_length(), "first": 1, "last": 1,
        "meta": meta_layout(params),
    })


def framed_layout(params, channels):
    """A framed pixel of ``channels`` cameras in lock step (raw ``UQ(pixel_bits, 0)``)."""
    return _column(params, {"pixels": data.ArrayLayout(params.pixel_bits, channels)})


def descriptor_layout(params, channels):
    """Descriptor bits of column ``pos − R`` (0 for ``pos < 2R``: border or not yet
    defined), one per channel, and whether the column is strong (``|response| ≥
    strong_raw``)."""
    return _column(params, {"bits": channels, "strong": channels})


def pair_layout(params):
    """What the matcher compares: the current bit and the reference bit of column
    ``pos − R``, whether the current column is strong, and whether the row has a valid
    reference."""
    return _column(params, {"cur": 1, "ref": 1, "strong": 1, "no_reference": 1})

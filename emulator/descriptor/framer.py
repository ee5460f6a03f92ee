"""Row framing of the lanes' model (:mod:`emulator.row_descriptor`; gateware
:mod:`hdl.descriptor.framer`): rows of exactly ``width`` pixels out of camera beats, short
rows padded, stray pixels dropped, each row with its run-time centre and bad flag."""

from dataclasses import dataclass

import numpy as np


__all__ = ["FramedRow", "frame_rows"]


@dataclass
class FramedRow:
    """A row as the framer hands it on: exactly ``width`` pixels and its metadata.

    ``bad`` is the row's final verdict (reason bits, short, long, or interrupted row, row
    index outside the frame); ``centre`` is the saturated centre sampled with its first
    pixel; ``padded`` says the framer filled the row's end with zero pixels;
    ``half_width`` is the saturated run-time half-width of the shift window (``None``:
    the built maximum, ``RowDescriptorParams.max_half_width``).
    """
    pixels: np.ndarray
    camera: int
    frame: int
    row: int
    t_first: int
    centre: int
    bad: bool
    padded: bool
    half_width: int = None

    def meta(self):
        return {"camera": self.camera, "frame": self.frame, "row": self.row,
                "t_first": self.t_first}


def frame_rows(beats, centres, params, half_widths=None):
    """The framer: a camera beat stream to rows of exactly ``params.width`` pixels.

    ``centres[i]`` (and ``half_widths[i]``, default the built maximum) is the centre
    (half-width) port's value when beat ``i`` is accepted (only the one with a row's
    ``first`` beat is used; the half-width saturated by ``params.saturate_half_width``). A ``first`` beat opens a row (and pads the end
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
    if half_widths is None:
        half_widths = [params.max_half_width] * len(beats)
    for beat, centre, half_width in zip(beats, centres, half_widths):
        if beat["first"]:
            if cur is not None:
                close(cur, pixels)
            cur, pixels = FramedRow(
                pixels=None, camera=beat["camera"], frame=beat["frame"], row=beat["row"],
                t_first=beat["t_first"], centre=params.clamp_centre(centre),
                bad=beat["row"] >= params.height, padded=False,
                half_width=params.saturate_half_width(half_width)[0]), []
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

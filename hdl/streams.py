"""Shared stream layouts and port signatures of the rowtrack pipeline.

Every block that passes data to another one describes the payload here, once, so that the
producer, the consumer, the emulator and the cocotb benches agree on field names and
widths. Layouts are built by functions because their widths are parameters of the design.

Camera front end
----------------
The camera front end (:mod:`hdl.front_end.camera_input`, :mod:`hdl.front_end.row_aligner`,
:mod:`hdl.front_end.camera_sync`) delivers image rows *cut-through*: one pixel per transfer, the
first pixel of a row going downstream before the last one has reached the pins. Fields
known when a row starts are valid on every beat of the row; fields that are only known
when it ends (the time of the last pixel, the reason bits) are valid on the beat that
carries ``last`` and are zero on the others.
"""

import enum

from amaranth.lib import data, wiring
from amaranth.lib.wiring import Out

from hdl.fixed import SQ

__all__ = ["RowFlag", "ROW_FLAG_BITS", "dvp_signature", "camera_pixel_layout",
           "aligned_row_layout", "camera_event_layout", "skew_measurement_layout"]


class RowFlag(enum.IntFlag):
    """Reason bits of a bad row (``flags`` field). A row with no bit set is good.

    The bits are independent: a row can be, say, both ``SHORT`` and ``SPLIT``.
    """
    #: Fewer pixels than the configured row width (HREF fell early, or an HREF dropout).
    SHORT = 1 << 0
    #: More pixels than the row width; the row was cut to the width.
    LONG = 1 << 1
    #: HREF rose again less than one row width after this row slot began (an HREF
    #: dropout split the row): the piece repeats the previous piece's row index.
    SPLIT = 1 << 2
    #: The frame is not in step: rows before the first VSYNC after reset, and rows after
    #: a VSYNC that came in the middle of a frame (until the next VSYNC).
    FRAME = 1 << 3
    #: Row index at or beyond the frame height: a VSYNC was missing.
    OVERRUN = 1 << 4
    #: The pixel clock stopped in the middle of the row; the row was closed by timeout.
    STALL = 1 << 5
    #: Pixels were lost to a full buffer (downstream backpressure or a pixel clock faster
    #: than the system clock); the row was closed early.
    OVERFLOW = 1 << 6


#: Width of the ``flags`` field.
ROW_FLAG_BITS = len(RowFlag)


def dvp_signature(pixel_bits):
    """A DVP-style parallel camera port, as driven by the camera.

    Members: ``vsync`` (frame sync, high between frames), ``href`` (high while a row's
    pixels are on ``data``), ``data`` (one pixel per PCLK rising edge, raw unsigned
    ``UQ(pixel_bits, 0)``). The pixel clock is the clock of the domain the receiving
    block is told to use, not a member.
    """
    return wiring.Signature({"vsync": Out(1), "href": Out(1), "data": Out(pixel_bits)})


def camera_pixel_layout(*, pixel_bits, camera_bits, frame_bits, row_bits, timestamp_bits):
    """One pixel of one camera's row, with the row's metadata.

    Fields
    ------
    data : UQ(pixel_bits, 0)
        The pixel, as read at the pins.
    first, last : 1
        Start- and end-of-row markers. A row is the beats from ``first`` to ``last``.
    camera : unsigned(camera_bits)
        Camera index (fixed per input block).
    frame : unsigned(frame_bits)
        Frame number: the camera_sync trigger count current when the camera's VSYNC
        was seen (wraps).
    row : unsigned(row_bits)
        Row index within the frame (saturates; see :attr:`RowFlag.OVERRUN`).
    t_first : unsigned(timestamp_bits)
        System-clock time stamp of the row's first pixel (cycle counter, wraps).
    t_last : unsigned(timestamp_bits)
        Time stamp of the row's last pixel; valid with ``last``, zero otherwise.
    flags : unsigned(ROW_FLAG_BITS)
        :class:`RowFlag` reason bits; valid with ``last``, zero otherwise.
    """
    return data.StructLayout({
        "data": pixel_bits, "first": 1, "last": 1, "camera": camera_bits,
        "frame": frame_bits, "row": row_bits, "t_first": timestamp_bits,
        "t_last": timestamp_bits, "flags": ROW_FLAG_BITS,
    })


def aligned_row_layout(pixel_layout, n_cameras):
    """One column of a row set: the same row from every camera, one pixel per lane.

    Fields
    ------
    lanes : ArrayLayout(pixel_layout, n_cameras)
        Lane ``k`` carries camera ``k``'s beat when ``lane_valid[k]`` is set, and zeros
        otherwise.
    lane_valid : n_cameras
        Lanes carrying a beat in this transfer. Lanes advance in lock step; a lane whose
        row ended (``last``) drops out for the rest of the set.
    missing : n_cameras
        Enabled cameras that have no row in this set (lost, late past the timeout, or
        ahead because their copy of the row was lost). Constant over a set.
    """
    return data.StructLayout({
        "lanes": data.ArrayLayout(pixel_layout, n_cameras),
        "lane_valid": n_cameras,
        "missing": n_cameras,
    })


def camera_event_layout(*, frame_bits, row_bits, timestamp_bits):
    """Frame and row syncs one camera input reports to camera_sync (a strobe per cycle).

    Fields
    ------
    frame_start : 1
        The camera's VSYNC rose; ``frame`` is the frame number it starts and
        ``frame_time`` when it was seen.
    frame : unsigned(frame_bits)
    frame_time : unsigned(timestamp_bits)
    row_start : 1
        A row of an in-step frame started (split pieces are not reported); ``row`` and
        ``row_time`` (the time stamp of its first pixel) describe it.
    row : unsigned(row_bits)
    row_time : unsigned(timestamp_bits)
    """
    return data.StructLayout({
        "frame_start": 1, "frame": frame_bits, "frame_time": timestamp_bits,
        "row_start": 1, "row": row_bits, "row_time": timestamp_bits,
    })


def skew_measurement_layout(*, row_bits, skew_bits):
    """Skews of one camera against the master, measured this cycle (strobes).

    Fields
    ------
    frame_valid : 1
        ``frame_skew`` holds a new measurement.
    frame_skew : SQ(skew_bits, 0)
        This camera's frame start minus the master's, in system clocks (saturating).
    row_valid : 1
        ``row_skew`` holds a new measurement for row ``row``.
    row : unsigned(row_bits)
    row_skew : SQ(skew_bits, 0)
        This camera's row start minus the master's for the same row (saturating).
    """
    return data.StructLayout({
        "frame_valid": 1, "frame_skew": SQ(skew_bits, 0).shape(),
        "row_valid": 1, "row": row_bits, "row_skew": SQ(skew_bits, 0).shape(),
    })


# --- row descriptor measurements (issue 7, hdl/row_descriptor.py) -----------------------

def row_measurement_layout(*, camera_bits, frame_bits, row_bits, timestamp_bits,
                           segment_bits, shift_fmt, subpixel_fmt, confidence_fmt):
    """One measurement of one row segment (what the pose solver consumes).

    Fields
    ------
    camera, frame, row, t_first
        The row's metadata as it arrived (``t_first``: time stamp of its first pixel).
    segment : unsigned(segment_bits)
        Segment (virtual camera) index, 0 … K − 1; a row's K measurements come in order.
    shift : shift_fmt, SQ(s, 0)
        Integer shift d* in pixels (window centre included).
    subpixel : subpixel_fmt, SQ(1, f)
        Parabola refinement δ; the measured shift is ``shift + subpixel``.
    confidence : confidence_fmt, UQ(i, f)
        Offset peak ratio min((c₂ + κ)/(c₁ + κ), cap); 0 when textureless, bad or
        without reference.
    textureless, edge_hit, bad, no_reference : 1
        Too few bit changes or strong columns in the segment; d* on the window edge
        (δ = 0); the input row was bad (reason bits, short, long or interrupted row;
        the same for all K measurements of the row); no valid reference row.
    """
    return data.StructLayout({
        "camera": camera_bits, "frame": frame_bits, "row": row_bits,
        "t_first": timestamp_bits, "segment": segment_bits,
        "shift": shift_fmt.shape(), "subpixel": subpixel_fmt.shape(),
        "confidence": confidence_fmt.shape(),
        "textureless": 1, "edge_hit": 1, "bad": 1, "no_reference": 1,
    })


__all__ += ["row_measurement_layout"]


def followed_pixel_layout(*, centre_fmt, segments, **camera):
    """A camera pixel (:func:`camera_pixel_layout`, same keyword arguments) with the
    forecast for its row, for a lane that follows rows (``RowDescriptor(follow=True)``).

    Fields (besides the camera pixel's)
    ------
    centre : centre_fmt, SQ(c, 0)
        The row's shift-window centre in pixels (saturated by the lane).
    source : ArrayLayout(unsigned(row_bits), segments)
        The previous frame's row each segment of this row is compared with.

    Both are sampled with the row's ``first`` beat, like the row's metadata.
    """
    return data.StructLayout({**camera_pixel_layout(**camera).members,
                              "centre": centre_fmt.shape(),
                              "source": data.ArrayLayout(camera["row_bits"], segments)})


__all__ += ["followed_pixel_layout"]

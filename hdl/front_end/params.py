"""Parameters of the camera front end (:mod:`hdl.front_end.camera_input`, :mod:`hdl.front_end.camera_sync`,
:mod:`hdl.front_end.row_aligner`), without gateware.

No Amaranth at import time: the layouts are built when a method is called, so the
emulator and the configuration (:mod:`hdl.pipeline_config`) read the parameters without
loading the HDL.
"""

from dataclasses import dataclass, replace

from golden.checks import check_int

__all__ = ["CameraParams"]


@dataclass(frozen=True, kw_only=True)
class CameraParams:
    """Elaboration-time parameters of the camera front end (no Amaranth here).

    Parameters
    ----------
    n_cameras : int
        Cameras in the cluster (1 to 32).
    max_width : int
        Largest row width in pixels; the run-time ``width`` register may be smaller.
    max_height : int
        Largest frame height in rows; the run-time ``height`` register may be smaller.
    pixel_bits : int
        Width of the DVP data bus (8 or 10 for the sensors in mind; 1 to 16).
    frame_bits, timestamp_bits : int
        Widths of the frame number and of the system-clock time stamps (both wrap).
    timer_bits : int
        Width of every programmable interval in system clocks (frame period, exposure,
        trigger pulse, delays, time-outs).
    skew_bits : int
        Width of a measured skew, ``SQ(skew_bits, 0)`` system clocks, saturating.
    count_bits : int
        Width of the event counters (they wrap).
    cdc_depth : int
        Entries of each clock-crossing FIFO (a power of two, at least 4).
    buffer_depth : int
        Pixels each camera can buffer while the aligner waits for a later camera or the
        downstream stalls.
    row_queue_depth : int
        Row records each camera can buffer (rows started but not yet sent downstream).
    glitch_pclks : int
        HREF pulses of at most this many PCLKs are glitches, not rows (0: none are).
    master : int
        Index of the master camera, the reference of every skew.
    """
    n_cameras: int = 8
    max_width: int = 640
    max_height: int = 480
    pixel_bits: int = 8
    frame_bits: int = 16
    timestamp_bits: int = 32
    timer_bits: int = 24
    skew_bits: int = 16
    count_bits: int = 16
    cdc_depth: int = 8
    buffer_depth: int = 1024
    row_queue_depth: int = 4
    glitch_pclks: int = 2
    master: int = 0

    def __post_init__(self):
        check_int("n_cameras", self.n_cameras, 1, 32)
        check_int("max_width", self.max_width, 2)
        check_int("max_height", self.max_height, 1)
        check_int("pixel_bits", self.pixel_bits, 1, 16)
        check_int("frame_bits", self.frame_bits, 1, 32)
        check_int("timestamp_bits", self.timestamp_bits, 8, 64)
        check_int("timer_bits", self.timer_bits, 4, 32)
        check_int("skew_bits", self.skew_bits, 2, self.timestamp_bits)
        check_int("count_bits", self.count_bits, 1, 32)
        check_int("cdc_depth", self.cdc_depth, 4)
        if self.cdc_depth & (self.cdc_depth - 1):
            raise ValueError(f"cdc_depth must be a power of two, not {self.cdc_depth}")
        check_int("buffer_depth", self.buffer_depth, 4)
        check_int("row_queue_depth", self.row_queue_depth, 2)
        check_int("glitch_pclks", self.glitch_pclks, 0, 16)
        check_int("master", self.master, 0, self.n_cameras - 1)

    replace = replace

    # --- derived widths ----------------------------------------------------------------

    @property
    def row_bits(self):
        """Bits of a row index; indices past ``max_height`` saturate at the top value."""
        return self.max_height.bit_length()

    @property
    def width_bits(self):
        """Bits of a pixel count up to ``max_width + 1`` (one past a full row)."""
        return (self.max_width + 1).bit_length()

    @property
    def camera_bits(self):
        return max(1, (self.n_cameras - 1).bit_length())

    def skew_rows_held(self, width):
        """Whole rows of trigger skew between cameras the row aligner absorbs at rows of
        ``width`` pixels. A row set of row ``y`` streams once every camera has shown row
        ``y``; a camera ``s`` rows ahead has meanwhile read ``s`` more rows, which wait in
        its ``buffer_depth`` pixels, and has ``s + 1`` rows started in its
        ``row_queue_depth`` records (docs/front_end/camera.md, "Aligner": size the buffer
        for the skew between cameras)."""
        check_int("width", width, 1, self.max_width)
        return min(self.buffer_depth // width, self.row_queue_depth - 1)

    # --- stream layouts ----------------------------------------------------------------

    def pixel_layout(self):
        """Layout of one camera's pixel stream (:func:`hdl.streams.camera_pixel_layout`)."""
        from hdl.streams import camera_pixel_layout
        return camera_pixel_layout(pixel_bits=self.pixel_bits, camera_bits=self.camera_bits,
                                   frame_bits=self.frame_bits, row_bits=self.row_bits,
                                   timestamp_bits=self.timestamp_bits)

    def aligned_layout(self):
        from hdl.streams import aligned_row_layout
        return aligned_row_layout(self.pixel_layout(), self.n_cameras)

    def event_layout(self):
        from hdl.streams import camera_event_layout
        return camera_event_layout(frame_bits=self.frame_bits, row_bits=self.row_bits,
                                   timestamp_bits=self.timestamp_bits)

    def skew_layout(self):
        from hdl.streams import skew_measurement_layout
        return skew_measurement_layout(row_bits=self.row_bits, skew_bits=self.skew_bits)

    # --- run-time registers --------------------------------------------------------------

    def input_config_layout(self):
        """Registers of every :class:`~hdl.front_end.camera_input.CameraInput` (shared by all cameras).

        ``width``: row width in pixels (2 to ``max_width``); ``height``: rows per frame
        (1 to ``max_height``); ``pclk_timeout``: a row whose pixel clock has been silent
        for more than this many system clocks is closed as ``STALL`` (0 disables).
        Change them only while the cameras are idle: they cross into the PCLK domains
        through plain synchronizers.
        """
        from amaranth.lib import data
        return data.StructLayout({"width": self.width_bits, "height": self.row_bits,
                                  "pclk_timeout": self.timer_bits})

    def input_status_layout(self):
        """Counters of one :class:`~hdl.front_end.camera_input.CameraInput` (wrapping) and its sticky reason bits."""
        from amaranth.lib import data

        from hdl.streams import ROW_FLAG_BITS
        return data.StructLayout({
            "bad_rows": self.count_bits, "dropped_rows": self.count_bits,
            "glitches": self.count_bits, "reasons": ROW_FLAG_BITS,
        })

    def align_config_layout(self):
        """Registers of :class:`~hdl.front_end.row_aligner.RowAligner`: ``enable`` (cameras taking
        part) and ``timeout`` (system clocks to wait for a camera at each row)."""
        from amaranth.lib import data
        return data.StructLayout({"enable": self.n_cameras, "timeout": self.timer_bits})

    def align_status_layout(self):
        """Per-camera counters of :class:`~hdl.front_end.row_aligner.RowAligner` (wrapping)."""
        from amaranth.lib import data
        counters = data.ArrayLayout(self.count_bits, self.n_cameras)
        return data.StructLayout({"missing_count": counters, "stale_count": counters})

    def cdc_word_layout(self):
        """One capture event crossing from the PCLK domain into the system clock.

        ``pixel``/``data``: a pixel; ``first``/``row``/``split``: it opens a row piece with
        this index, repeating the previous slot's index if ``split``; ``end``/``short``/
        ``long``: the open piece ended (before this word's pixel), shorter or longer than
        the width; ``frame_start``: VSYNC rose (after ``end``, before the pixel);
        ``glitch``: an HREF glitch was dropped; ``lost``: words were lost to a full FIFO
        since the previous word.
        """
        from amaranth.lib import data
        return data.StructLayout({
            "data": self.pixel_bits, "pixel": 1, "first": 1, "split": 1,
            "row": self.row_bits, "end": 1, "short": 1, "long": 1,
            "frame_start": 1, "glitch": 1, "lost": 1,
        })

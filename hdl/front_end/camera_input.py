"""One camera's DVP port: capture in the pixel clock, cross, assemble stamped rows.

The front end of the FPGA receives each rolling-shutter camera's rows as they are read
out (thesis, "Hardware implementation: A sketch"). :class:`CameraInput` is the part that
belongs to one camera:

1. *Capture* (camera's PCLK domain): registers VSYNC, HREF and the pixel bus, looks
   ``glitch_pclks`` samples ahead to drop HREF pulses too short to be rows, gives each
   row piece its row index (a new row slot only when HREF rises at least one row width
   after the current slot began, so an HREF dropout does not shift the rest of the
   frame), cuts long rows to the width, and writes one word per event into an
   :class:`~amaranth.lib.fifo.AsyncFIFO`.
2. *Assembly* (system clock): reads the crossing every cycle, time-stamps each word with
   the system cycle counter, holds one pixel back so the end-of-row marker and the
   reason bits ride on the row's last pixel, and writes rows cut-through into an output
   buffer. Bad input is flagged (:class:`~hdl.streams.RowFlag`), counted, and never
   stalls the block; the next VSYNC re-arms it.

:class:`CameraParams` describes the whole camera front end and is shared by
:mod:`hdl.front_end.row_aligner` and :mod:`hdl.front_end.camera_sync`.
"""

from amaranth.hdl import Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.fifo import AsyncFIFO, SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from golden.checks import check_int

from hdl.front_end.params import CameraParams
from hdl.streams import ROW_FLAG_BITS, RowFlag, dvp_signature

__all__ = ["CameraInput", "saturating_increment", "wire"]


_SHORT, _LONG, _SPLIT, _FRAME, _OVERRUN, _STALL, _OVERFLOW = (
    int(flag) for flag in (RowFlag.SHORT, RowFlag.LONG, RowFlag.SPLIT, RowFlag.FRAME,
                           RowFlag.OVERRUN, RowFlag.STALL, RowFlag.OVERFLOW))


def saturating_increment(value, top):
    """``value + 1``, held at ``top``."""
    return Mux(value >= top, top, value + 1)


def wire(m, value, name):
    """``value`` as a named combinational signal. Amaranth re-emits an expression at
    every use; naming the ones used more than once keeps the netlist linear."""
    sig = Signal(value.shape(), name=name)
    m.d.comb += sig.eq(value)
    return sig


class CameraInput(wiring.Component):
    """One camera's DVP receiver: PCLK-domain capture, AsyncFIFO crossing, stamped rows.

    Parameters
    ----------
    params : CameraParams
    camera : int
        This camera's index, stamped into every pixel.
    domain : str
        The camera's pixel clock domain (its clock is PCLK; reset it from the system
        reset through a reset synchronizer).

    Members
    -------
    dvp : In(dvp_signature(pixel_bits)), in ``domain``
        The port; ``data`` is ``UQ(pixel_bits, 0)``.
    now : In(unsigned(timestamp_bits))
        The system time base (camera_sync's cycle counter).
    frame : In(unsigned(frame_bits))
        The frame number a VSYNC seen now starts (camera_sync's trigger count).
    cfg : In(params.input_config_layout())
        Run-time registers.
    o : Out(stream.Signature(params.pixel_layout()))
        This camera's rows, one pixel per transfer, cut-through.
    event : Out(params.event_layout())
        Frame and row syncs for camera_sync, one cycle after the word that carries them.
    status : Out(params.input_status_layout())

    Latency: a word written into the crossing at a PCLK edge is stamped two or three
    system clocks later (two synchronizer stages and the read), the capture adds
    ``glitch_pclks + 2`` PCLKs from the pins, and the output buffer two system clocks;
    :attr:`latency` counts the system-clock part. Throughput: one pixel per PCLK as long
    as PCLK is not faster than the system clock. Backpressure: rows wait in the output
    buffer; when it fills, the row being received is closed early (``OVERFLOW``) and the
    rest of it dropped, and a row that finds the buffer full is dropped whole and counted.
    Reset: the PCLK domain's reset empties the crossing; hold both resets together.
    """

    #: System clocks from the cycle a word is readable from the crossing to the cycle
    #: its pixel (or the row's last pixel it closes) is offered on ``o``.
    latency = 2

    def __init__(self, params=CameraParams(), *, camera=0, domain="pclk"):
        if not isinstance(params, CameraParams):
            raise TypeError(f"params must be a CameraParams, not {params!r}")
        check_int("camera", camera, 0, params.n_cameras - 1)
        if not isinstance(domain, str) or not domain:
            raise TypeError(f"domain must be a non-empty string, not {domain!r}")
        if domain == "sync":
            raise ValueError("domain must be the camera's own pixel clock domain, not 'sync'")
        self.params = params
        self.camera = camera
        self.domain = domain
        #: The clock domains it uses without defining them, in port order
        #: (:func:`hdl.verilog.to_verilog`).
        self.clock_domains = ("sync", domain)
        super().__init__({
            "dvp": In(dvp_signature(params.pixel_bits)),
            "now": In(params.timestamp_bits),
            "frame": In(params.frame_bits),
            "cfg": In(params.input_config_layout()),
            "o": Out(stream.Signature(params.pixel_layout())),
            "event": Out(params.event_layout()),
            "status": Out(params.input_status_layout()),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        word_layout = p.cdc_word_layout()
        m.submodules.cdc = cdc = AsyncFIFO(width=word_layout.size, depth=p.cdc_depth,
                                           r_domain="sync", w_domain=self.domain)
        self._capture(m, cdc, word_layout)
        self._assemble(m, data.View(word_layout, cdc.r_data), cdc)
        return m

    # --- PCLK domain -------------------------------------------------------------------

    def _capture(self, m, cdc, word_layout):
        p = self.params
        cd = m.d[self.domain]
        width = Signal.like(self.cfg.width, name="width_pclk")
        m.submodules.width_cdc = FFSynchronizer(self.cfg.width, width, o_domain=self.domain)

        # taps[0] is the newest sample; the capture decides on taps[-1] with the
        # glitch_pclks samples after it in view.
        sample = data.StructLayout({"vsync": 1, "href": 1, "data": p.pixel_bits})
        taps = [Signal(sample, name=f"tap{j}") for j in range(p.glitch_pclks + 1)]
        cd += [taps[0].vsync.eq(self.dvp.vsync), taps[0].href.eq(self.dvp.href),
               taps[0].data.eq(self.dvp.data)]
        for newer, older in zip(taps, taps[1:]):
            cd += older.eq(newer)
        cur = taps[-1]
        prev_vsync = Signal()
        prev_href = Signal()
        cd += [prev_vsync.eq(cur.vsync), prev_href.eq(cur.href)]

        in_piece = Signal()     # a row piece is open
        length = Signal(p.width_bits)      # pixels of the open piece, saturating
        have_slot = Signal()    # a row slot began in this frame
        slot = Signal(p.row_bits)
        since = Signal(p.width_bits)       # PCLKs since the slot began, saturating
        lost = Signal()

        vsync_rise = wire(m, cur.vsync & ~prev_vsync, "vsync_rise")
        run_start = wire(m, cur.href & (~prev_href | vsync_rise), "run_start")
        ahead_high = Const(1)
        for tap in taps[:-1]:
            ahead_high &= tap.href
        glitch = wire(m, run_start & ~ahead_high, "glitch")
        start = wire(m, run_start & ~glitch, "start")
        cont = wire(m, in_piece & cur.href & ~vsync_rise, "cont")
        end = wire(m, in_piece & (~cur.href | vsync_rise), "end")

        fresh_frame = wire(m, ~have_slot | vsync_rise, "fresh_frame")
        slot_over = wire(m, since >= width, "slot_over")
        new_slot = wire(m, fresh_frame | slot_over, "new_slot")
        index = wire(m, Mux(fresh_frame, 0, Mux(slot_over, saturating_increment(
            slot, 2 ** p.row_bits - 1), slot)), "index")
        keep_pixel = wire(m, start | (cont & (length < width)), "keep_pixel")

        word = Signal(word_layout)
        m.d.comb += [
            word.data.eq(cur.data),
            word.pixel.eq(keep_pixel),
            word.first.eq(start),
            word.split.eq(start & ~new_slot),
            word.row.eq(index),
            word.end.eq(end),
            word.short.eq(end & (length < width)),
            word.long.eq(end & (length > width)),
            word.frame_start.eq(vsync_rise),
            word.glitch.eq(glitch),
            word.lost.eq(lost),
            cdc.w_data.eq(word.as_value()),
            cdc.w_en.eq(keep_pixel | end | vsync_rise | glitch),
        ]
        with m.If(cdc.w_en):
            cd += lost.eq(~cdc.w_rdy)

        cd += [
            in_piece.eq(start | cont),
            since.eq(saturating_increment(since, p.max_width)),
        ]
        with m.If(start):
            cd += [length.eq(1), slot.eq(index), have_slot.eq(1)]
            with m.If(new_slot):
                cd += since.eq(1)
        with m.Elif(cont):
            cd += length.eq(saturating_increment(length, p.max_width + 1))
        with m.Elif(vsync_rise):
            cd += have_slot.eq(0)

    # --- system clock ------------------------------------------------------------------

    def _assemble(self, m, w, cdc):
        p = self.params
        flag_bits = ROW_FLAG_BITS
        meta_layout = data.StructLayout({"frame": p.frame_bits, "row": p.row_bits,
                                         "t_first": p.timestamp_bits})
        end_layout = data.StructLayout({"t_last": p.timestamp_bits, "flags": flag_bits})
        beat_layout = data.StructLayout({"data": p.pixel_bits, "first": 1, "last": 1})
        m.submodules.pixels = pixels = SyncFIFOBuffered(width=beat_layout.size,
                                                        depth=p.buffer_depth)
        m.submodules.starts = starts = SyncFIFOBuffered(width=meta_layout.size,
                                                        depth=p.row_queue_depth)
        m.submodules.ends = ends = SyncFIFOBuffered(width=end_layout.size,
                                                    depth=p.row_queue_depth)
        m.d.comb += cdc.r_en.eq(1)
        wv = cdc.r_rdy

        # Row being received. ``pend_*`` is the held-back pixel.
        row_open = Signal()
        pend_data = Signal(p.pixel_bits)
        pend_first = Signal()
        pend_t = Signal(p.timestamp_bits)
        cur_frame = Signal(p.frame_bits)
        cur_row = Signal(p.row_bits)
        cur_t_first = Signal(p.timestamp_bits)
        cur_flags = Signal(flag_bits)
        # Frame state.
        synced = Signal()
        rows_seen = Signal(p.row_bits + 1)
        frame_num = Signal(p.frame_bits)
        idle = Signal(p.timer_bits)

        # VSYNC: a VSYNC in the middle of an in-step frame puts the next frame out of
        # step; any VSYNC in an out-of-step frame re-arms.
        early = synced & (rows_seen != 0) & (rows_seen < self.cfg.height)
        fs = wire(m, wv & w.frame_start, "fs")
        synced_now = wire(m, Mux(fs, ~(synced & early), synced), "synced_now")
        frame_now = wire(m, Mux(fs, self.frame, frame_num), "frame_now")
        with m.If(fs):
            m.d.sync += [synced.eq(synced_now), frame_num.eq(self.frame), rows_seen.eq(0)]

        new_row = wire(m, wv & w.pixel & w.first, "new_row")
        more = wire(m, wv & w.pixel & ~w.first & row_open, "more")
        closes = wire(m, wv & row_open & (w.end | w.first | w.frame_start), "closes")
        timeout = self.cfg.pclk_timeout
        stalled = wire(m, row_open & ~wv & (timeout != 0) & (idle >= timeout), "stalled")
        lost_flag = wire(m, Mux(w.lost, _OVERFLOW, 0), "lost_flag")
        end_flags = (Mux(w.end & w.short, _SHORT, 0) | Mux(w.end & w.long, _LONG, 0)
                     | Mux(w.end, 0, _OVERFLOW) | lost_flag)

        # Room rules keep one slot for the row's last pixel and its end record.
        room_more = pixels.level <= p.buffer_depth - 3
        room_last = pixels.level <= p.buffer_depth - 2
        room_row = starts.level <= p.row_queue_depth - 2
        ok_more = wire(m, room_more & (~pend_first | room_row), "ok_more")
        ok_last = wire(m, room_last & (~pend_first | room_row), "ok_last")

        write = Signal()
        write_last = Signal()
        last_flags = Signal(flag_bits)
        drop_row = Signal()
        close_now = Signal()
        with m.If(more & ok_more):
            m.d.comb += write.eq(1)
        with m.Elif(more | closes | stalled):
            m.d.comb += close_now.eq(1)
            with m.If(ok_last):
                m.d.comb += [write.eq(1), write_last.eq(1)]
            with m.Else():
                m.d.comb += drop_row.eq(1)
            with m.If(more):
                m.d.comb += last_flags.eq(cur_flags | _OVERFLOW | lost_flag)
            with m.Elif(closes):
                m.d.comb += last_flags.eq(cur_flags | end_flags)
            with m.Else():
                m.d.comb += last_flags.eq(cur_flags | _STALL)

        beat_in = Signal(beat_layout)
        meta_in = Signal(meta_layout)
        tail_in = Signal(end_layout)
        m.d.comb += [
            beat_in.data.eq(pend_data), beat_in.first.eq(pend_first),
            beat_in.last.eq(write_last),
            meta_in.frame.eq(cur_frame), meta_in.row.eq(cur_row),
            meta_in.t_first.eq(cur_t_first),
            tail_in.t_last.eq(pend_t), tail_in.flags.eq(last_flags),
            pixels.w_en.eq(write), pixels.w_data.eq(beat_in.as_value()),
            starts.w_en.eq(write & pend_first), starts.w_data.eq(meta_in.as_value()),
            ends.w_en.eq(write_last), ends.w_data.eq(tail_in.as_value()),
        ]

        with m.If(more & ok_more):
            m.d.sync += [pend_data.eq(w.data), pend_first.eq(0), pend_t.eq(self.now),
                         cur_flags.eq(cur_flags | lost_flag)]
        with m.If(close_now):
            m.d.sync += row_open.eq(0)
        with m.If(new_row):
            row_flags = (Mux(synced_now, 0, _FRAME) |
                         Mux(w.row >= self.cfg.height, _OVERRUN, 0) |
                         Mux(w.split, _SPLIT, 0) | lost_flag)
            m.d.sync += [
                row_open.eq(1), pend_data.eq(w.data), pend_first.eq(1), pend_t.eq(self.now),
                cur_frame.eq(frame_now), cur_row.eq(w.row), cur_t_first.eq(self.now),
                cur_flags.eq(row_flags), rows_seen.eq(w.row + 1),
            ]
        with m.If(wv | ~row_open):
            m.d.sync += idle.eq(0)
        with m.Else():
            m.d.sync += idle.eq(saturating_increment(idle, 2 ** p.timer_bits - 1))

        # Events for camera_sync.
        m.d.sync += [
            self.event.frame_start.eq(fs),
            self.event.frame.eq(self.frame),
            self.event.frame_time.eq(self.now),
            self.event.row_start.eq(new_row & ~w.split & synced_now),
            self.event.row.eq(Mux(new_row, w.row, 0)),
            self.event.row_time.eq(self.now),
        ]

        # Counters.
        status = self.status
        with m.If(write_last & (last_flags != 0)):
            m.d.sync += status.bad_rows.eq(status.bad_rows + 1)
        with m.If(drop_row):
            m.d.sync += status.dropped_rows.eq(status.dropped_rows + 1)
        with m.If(close_now):
            m.d.sync += status.reasons.eq(status.reasons | last_flags)
        with m.If(wv & w.glitch):
            m.d.sync += status.glitches.eq(status.glitches + 1)

        # Output: pixels with their row's records.
        beat = data.View(beat_layout, pixels.r_data)
        meta = data.View(meta_layout, starts.r_data)
        tail = data.View(end_layout, ends.r_data)
        o = self.o
        m.d.comb += [
            o.valid.eq(pixels.r_rdy & starts.r_rdy & (~beat.last | ends.r_rdy)),
            o.p.data.eq(beat.data), o.p.first.eq(beat.first), o.p.last.eq(beat.last),
            o.p.camera.eq(self.camera),
            o.p.frame.eq(meta.frame), o.p.row.eq(meta.row), o.p.t_first.eq(meta.t_first),
            o.p.t_last.eq(Mux(beat.last, tail.t_last, 0)),
            o.p.flags.eq(Mux(beat.last, tail.flags, 0)),
            pixels.r_en.eq(o.valid & o.ready),
            starts.r_en.eq(o.valid & o.ready & beat.last),
            ends.r_en.eq(o.valid & o.ready & beat.last),
        ]

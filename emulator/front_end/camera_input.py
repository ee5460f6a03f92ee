"""Cycle-accurate model of :class:`hdl.front_end.camera_input.CameraInput`.

Two halves, as in the hardware:

* :func:`capture_words` replays the PCLK-domain capture on the samples the port saw
  (one per PCLK rising edge, with the edge times) and the AsyncFIFO crossing, and returns
  the system-clock cycle at which each word becomes readable. The crossing is modelled
  from the edge times: a write at PCLK time ``w`` is seen by the first system edge after
  ``w``, passes the second synchronizer stage one clock later and is read in that cycle.
  The write side sees a read through the same two stages in the PCLK domain.
* :class:`CameraInputModel` steps the system-clock assembly one cycle at a time
  (:meth:`~CameraInputModel.offer`, then :meth:`~CameraInputModel.step`), with the output
  buffers modelled by :class:`BufferedFifoModel`.

Cycles are numbered by the value of the system time base ``now`` in that cycle; edge
times are integers (picoseconds in the benches). Models take plain dicts and integers and
never import a simulator.
"""

import bisect
from collections import deque
from dataclasses import dataclass

from hdl.streams import RowFlag

__all__ = ["SystemClock", "BufferedFifoModel", "capture_words", "CameraInputModel"]


@dataclass(frozen=True)
class SystemClock:
    """The system clock's rising edges: the edge that starts cycle ``c`` is at
    ``t0 + c * period``."""
    t0: int
    period: int

    def edge(self, cycle):
        return self.t0 + cycle * self.period

    def first_edge_after(self, time):
        """The cycle whose starting edge is the first one strictly after ``time``."""
        cycle, rem = divmod(time - self.t0, self.period)
        if rem == 0:
            raise ValueError(f"a PCLK edge at {time} coincides with a system clock edge; "
                             "the crossing would be a race (pick edge times that differ)")
        return cycle + 1


class BufferedFifoModel:
    """:class:`amaranth.lib.fifo.SyncFIFOBuffered`: a write is readable two cycles later.

    ``head`` is the readable entry (``None`` when ``r_rdy`` is low); ``level`` counts the
    output register too, as the hardware's ``level`` does.
    """

    def __init__(self, depth):
        self.depth = depth
        self.inner = deque()
        self.head = None

    @property
    def level(self):
        return len(self.inner) + (self.head is not None)

    @property
    def w_rdy(self):
        return len(self.inner) != self.depth - 1

    def step(self, write=None, read=False):
        """Advance one clock: ``write`` an entry (or ``None``); ``read`` pops the head."""
        if write is not None and not self.w_rdy:
            raise AssertionError("model wrote a full FIFO")
        if self.inner and (self.head is None or read):
            self.head = self.inner.popleft()
        elif read:
            self.head = None
        if write is not None:
            self.inner.append(write)


def _saturate(value, top):
    return min(value, top)


def capture_words(params, samples, pclk_times, clock, width):
    """PCLK-domain capture and clock crossing of one camera.

    Parameters
    ----------
    params : hdl.front_end.params.CameraParams
    samples : sequence of (vsync, href, data)
        The port as sampled at each PCLK rising edge, from an edge where the capture's
        registers hold zeros (before the camera became active).
    pclk_times : sequence of int
        Time of each of those edges (same length).
    clock : SystemClock
    width : int
        The ``width`` register.

    Returns
    -------
    list of (cycle, word)
        Each word crossing (fields of ``params.cdc_word_layout()``) with the system cycle
        in which the assembly reads it.
    """
    g = params.glitch_pclks
    row_top = 2 ** params.row_bits - 1
    in_piece = have_slot = lost = False
    length = slot = since = 0
    prev_vsync = prev_href = 0
    written = 0
    read_seen_at = []       # PCLK edge index from which each read is visible to writes
    seen = 0
    last_cycle = None
    out = []
    for s in range(len(samples)):
        x = s + g + 1                      # the PCLK edge that writes this sample's word
        if x >= len(samples):
            break
        vsync, href, value = samples[s]
        vsync_rise = bool(vsync and not prev_vsync)
        run_start = bool(href and (not prev_href or vsync_rise))
        ahead_high = all(samples[j][1] for j in range(s + 1, s + g + 1))
        glitch = run_start and not ahead_high
        start = run_start and not glitch
        cont = in_piece and bool(href) and not vsync_rise
        end = in_piece and (not href or vsync_rise)
        fresh = not have_slot or vsync_rise
        new_slot = fresh or since >= width
        index = 0 if fresh else (_saturate(slot + 1, row_top) if since >= width else slot)
        keep = start or (cont and length < width)
        if keep or end or vsync_rise or glitch:
            while seen < len(read_seen_at) and read_seen_at[seen] <= x - 1:
                seen += 1
            if written - seen < params.cdc_depth:
                word = {"data": value, "pixel": int(keep),
                        "first": int(start), "split": int(start and not new_slot),
                        "row": index, "end": int(end), "short": int(end and length < width),
                        "long": int(end and length > width), "frame_start": int(vsync_rise),
                        "glitch": int(glitch), "lost": int(lost)}
                written += 1
                cycle = clock.first_edge_after(pclk_times[x]) + 1
                if last_cycle is not None:
                    cycle = max(cycle, last_cycle + 1)
                last_cycle = cycle
                out.append((cycle, word))
                # The read updates the consume pointer at the end of the cycle; the PCLK
                # domain sees it two of its edges later.
                p1 = bisect.bisect_right(pclk_times, clock.edge(cycle + 1))
                read_seen_at.append(p1 + 1)
                lost = False
            else:
                lost = True
        since = _saturate(since + 1, params.max_width)
        if start:
            length, slot, have_slot = 1, index, True
            if new_slot:
                since = 1
        elif cont:
            length = _saturate(length + 1, params.max_width + 1)
        elif vsync_rise:
            have_slot = False
        in_piece = start or cont
        prev_vsync, prev_href = vsync, href
    return out


class CameraInputModel:
    """System-clock half of one :class:`~hdl.front_end.camera_input.CameraInput`, cycle by cycle.

    Each cycle call :meth:`offer` (the output beat, or ``None``) and then :meth:`step`
    with the word read this cycle, the time base, the frame number, and whether the
    offered beat was taken. ``event`` and ``status`` mirror the ports (``event`` as
    registered at the end of the last step).
    """

    def __init__(self, params, camera, cfg):
        self.p = params
        self.camera = camera
        self.cfg = cfg
        self.pixels = BufferedFifoModel(params.buffer_depth)
        self.starts = BufferedFifoModel(params.row_queue_depth)
        self.ends = BufferedFifoModel(params.row_queue_depth)
        self.row_open = False
        self.pend = None            # (data, first, t)
        self.cur = None             # (frame, row, t_first)
        self.cur_flags = 0
        self.synced = False
        self.rows_seen = 0
        self.frame_num = 0
        self.idle = 0
        self.event = self._no_event()
        self.status = {"bad_rows": 0, "dropped_rows": 0, "glitches": 0, "reasons": 0}

    @staticmethod
    def _no_event():
        return {"frame_start": 0, "frame": 0, "frame_time": 0, "row_start": 0, "row": 0,
                "row_time": 0}

    def offer(self):
        beat = self.pixels.head
        if beat is None or self.starts.head is None or (beat["last"] and self.ends.head is None):
            return None
        meta, tail = self.starts.head, self.ends.head
        return {"data": beat["data"], "first": beat["first"], "last": beat["last"],
                "camera": self.camera, "frame": meta["frame"], "row": meta["row"],
                "t_first": meta["t_first"],
                "t_last": tail["t_last"] if beat["last"] else 0,
                "flags": tail["flags"] if beat["last"] else 0}

    def step(self, word, now, frame, taken):
        p, cfg = self.p, self.cfg
        count_mask = (1 << p.count_bits) - 1
        wv = word is not None
        w = word or {}
        fs = wv and w["frame_start"]
        early = self.synced and self.rows_seen != 0 and self.rows_seen < cfg["height"]
        synced_now = (not (self.synced and early)) if fs else self.synced
        frame_now = frame if fs else self.frame_num
        new_row = wv and w["pixel"] and w["first"]
        more = wv and w["pixel"] and not w["first"] and self.row_open
        closes = wv and self.row_open and (w["end"] or w["first"] or w["frame_start"])
        timeout = cfg["pclk_timeout"]
        stalled = self.row_open and not wv and timeout != 0 and self.idle >= timeout
        lost_flag = RowFlag.OVERFLOW if wv and w["lost"] else 0
        end_flags = 0
        if wv:
            end_flags = ((RowFlag.SHORT if w["end"] and w["short"] else 0)
                         | (RowFlag.LONG if w["end"] and w["long"] else 0)
                         | (0 if w["end"] else RowFlag.OVERFLOW) | lost_flag)

        pend_first = bool(self.pend and self.pend[1])
        room_row = self.starts.level <= p.row_queue_depth - 2
        ok_more = self.pixels.level <= p.buffer_depth - 3 and (not pend_first or room_row)
        ok_last = self.pixels.level <= p.buffer_depth - 2 and (not pend_first or room_row)

        write = write_last = drop_row = close_now = False
        last_flags = 0
        if more and ok_more:
            write = True
        elif more or closes or stalled:
            close_now = True
            write = write_last = ok_last
            drop_row = not ok_last
            if more:
                last_flags = self.cur_flags | RowFlag.OVERFLOW | lost_flag
            elif closes:
                last_flags = self.cur_flags | end_flags
            else:
                last_flags = self.cur_flags | RowFlag.STALL
        last_flags = int(last_flags)

        beat = meta = tail = None
        if write:
            beat = {"data": self.pend[0], "first": int(pend_first), "last": int(write_last)}
            if pend_first:
                meta = {"frame": self.cur[0], "row": self.cur[1], "t_first": self.cur[2]}
            if write_last:
                tail = {"t_last": self.pend[2], "flags": last_flags}
        row_taken = taken and bool(self.pixels.head["last"])
        self.pixels.step(beat, read=taken)
        self.starts.step(meta, read=row_taken)
        self.ends.step(tail, read=row_taken)

        # Counters (before the row state changes, as in the hardware).
        st = self.status
        if write_last and last_flags:
            st["bad_rows"] = (st["bad_rows"] + 1) & count_mask
        if drop_row:
            st["dropped_rows"] = (st["dropped_rows"] + 1) & count_mask
        if close_now:
            st["reasons"] |= last_flags
        if wv and w["glitch"]:
            st["glitches"] = (st["glitches"] + 1) & count_mask

        self.event = {"frame_start": int(bool(fs)), "frame": frame, "frame_time": now,
                      "row_start": int(bool(new_row and not w["split"] and synced_now)),
                      "row": w["row"] if new_row else 0, "row_time": now}

        if wv or not self.row_open:
            self.idle = 0
        else:
            self.idle = min(self.idle + 1, 2 ** p.timer_bits - 1)
        if fs:
            self.synced, self.frame_num, self.rows_seen = synced_now, frame, 0
        if more and ok_more:
            self.pend = (w["data"], False, now)
            self.cur_flags |= int(lost_flag)
        if close_now:
            self.row_open = False
        if new_row:
            self.row_open = True
            self.pend = (w["data"], True, now)
            self.cur = (frame_now, w["row"], now)
            self.cur_flags = int((0 if synced_now else RowFlag.FRAME)
                                 | (RowFlag.OVERRUN if w["row"] >= cfg["height"] else 0)
                                 | (RowFlag.SPLIT if w["split"] else 0) | lost_flag)
            self.rows_seen = w["row"] + 1

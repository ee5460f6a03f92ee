"""Host side of the pose link: decode the UART packet stream, check it, log it.

:class:`PacketDecoder` turns arbitrary chunks of bytes into records. It looks for the
sync word, checks the length byte and the CRC, and after any failure moves on by one
byte only, so a corrupted, shortened or cut packet costs that packet and never the
intact one behind it. Sequence numbers tell packets lost on the wire (a gap beyond the
``skipped`` count the hardware reports) from records the hardware dropped because the
link was slower than the tracker. Each record's flags say whether the tracker can be
trusted (``status``: tracking, degraded or lost; ``drifted`` since a loss,
:func:`emulator.output.packets.flag_fields`): the decoder reports both per record and
counts them, and the live line says when tracking was lost.

:func:`run_host` reads a serial port (pyserial), prints the live pose and rates, and
writes a CSV log; ``rowtrack host`` is its command line.
"""

import csv
import os
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass

from hdl.output.params import PacketParams

from golden.tracking_status import TrackingStatus

from emulator.output.packets import crc16, decode_payload, flag_fields, pose_to_float

__all__ = ["LinkStats", "PacketDecoder", "RateMeter", "run_host", "PtyLink", "CSV_COLUMNS"]

#: Columns of the CSV log.
CSV_COLUMNS = ("host_time", "seq", "skipped", "lost_before", "t_row", "row", "x_m", "y_m",
               "z_m", "qw", "qx", "qy", "qz", "flags", "status", "drifted")


@dataclass
class LinkStats:
    """What the decoder saw.

    ``packets_ok``: intact packets decoded. ``packets_lost``: packets missing from the
    sequence (damaged, cut or dropped on the wire), from the sequence numbers; packets
    after the last intact one are not known to be missing.
    ``hw_skipped``: records the hardware dropped before sending (the ``skipped``
    fields). ``crc_errors``, ``bad_lengths``: candidate packets rejected. ``discarded``:
    bytes thrown away while resynchronizing. ``seq_errors``: sequence numbers that went
    backwards or repeated (a reset of the hardware, or a false packet).
    ``degraded``, ``lost``, ``drifted``: records with that status (or flag);
    ``losses``: records that were lost after one that was not (or the first).
    """
    packets_ok: int = 0
    packets_lost: int = 0
    hw_skipped: int = 0
    crc_errors: int = 0
    bad_lengths: int = 0
    discarded: int = 0
    seq_errors: int = 0
    degraded: int = 0
    lost: int = 0
    drifted: int = 0
    losses: int = 0


class PacketDecoder:
    """Incremental packet decoder with resynchronization.

    Parameters
    ----------
    params : PacketParams
    """

    def __init__(self, params=PacketParams()):
        if not isinstance(params, PacketParams):
            raise TypeError(f"params must be a PacketParams, not {params!r}")
        self.params = params
        self.stats = LinkStats()
        self._buffer = bytearray()
        self._sync = params.sync.to_bytes(2, "big")
        self._size = params.packet_bytes
        self._last_seq = None
        self._was_lost = False
        self._borrowed = False              # the buffer starts with a decoded packet's byte

    def feed(self, data):
        """Add received bytes; returns the records of the packets they completed.

        Each record is a :func:`emulator.output.packets.decode_payload` dict plus
        ``lost_before``: packets missing from the sequence just before it, ``status``
        (``"tracking"``, ``"degraded"`` or ``"lost"``) and ``drifted`` (bool) from its
        flags.
        """
        self._buffer += data
        out = []
        size = self._size
        while True:
            start = self._buffer.find(self._sync)
            if start < 0:
                # Keep a last byte that may begin a sync word.
                keep = 1 if self._buffer[-1:] == self._sync[:1] else 0
                self._drop(len(self._buffer) - keep)
                return out
            self._drop(start)
            if len(self._buffer) < 3:
                return out
            if self._buffer[2] != self._size - 5:
                self.stats.bad_lengths += 1
                self._drop(1)
                continue
            if len(self._buffer) < size:
                return out
            if crc16(self._buffer[2:size]) != 0:
                self.stats.crc_errors += 1
                self._drop(1)
                continue
            record = decode_payload(self.params, bytes(self._buffer[3:size - 2]))
            # A last byte equal to the first sync byte stays: it may also begin the
            # next packet, if that one lost its first byte (or this one lost its last
            # and borrowed it); either way both packets then decode correctly.
            self._borrowed = self._buffer[size - 1] == self._sync[0]
            del self._buffer[:size - self._borrowed]
            out.append(self._account(record))

    def _drop(self, count):
        if count:
            self.stats.discarded += count - self._borrowed
            self._borrowed = False
            del self._buffer[:count]

    def _account(self, record):
        stats = self.stats
        stats.packets_ok += 1
        stats.hw_skipped += record["skipped"]
        lost = 0
        if self._last_seq is not None:
            gap = (record["seq"] - self._last_seq) % (1 << self.params.seq_bits)
            lost = gap - 1 - record["skipped"]
            if gap == 0 or lost < 0:
                stats.seq_errors += 1
                lost = 0
        stats.packets_lost += lost
        self._last_seq = record["seq"]
        fields = flag_fields(record["flags"])
        status = fields["status"]
        stats.degraded += status == TrackingStatus.DEGRADED
        stats.lost += status == TrackingStatus.LOST
        stats.drifted += fields["drifted"]
        stats.losses += status == TrackingStatus.LOST and not self._was_lost
        self._was_lost = status == TrackingStatus.LOST
        return {**record, "lost_before": lost, "status": status.name.lower(),
                "drifted": fields["drifted"]}


class RateMeter:
    """Events per second over the last ``window`` seconds of a clock."""

    def __init__(self, window=1.0):
        self.window = window
        self._events = deque()

    def add(self, now, count=1):
        self._events.append((now, count))
        while self._events and self._events[0][0] < now - self.window:
            self._events.popleft()

    def rate(self, now):
        while self._events and self._events[0][0] < now - self.window:
            self._events.popleft()
        if not self._events:
            return 0.0
        span = max(now - self._events[0][0], 1e-9)
        return sum(c for _, c in self._events) / max(span, self.window / 10)


def _record_rate(first, last, clk_hz, params):
    """Records per second of hardware time between two records (from ``t_row``)."""
    if first is last:
        return None
    ticks = (last["t_row"] - first["t_row"]) % (1 << params.timestamp_bits)
    records = (last["seq"] - first["seq"]) % (1 << params.seq_bits)
    return records * clk_hz / ticks if ticks else None


def _status_line(record, stats, link_rate, record_rate, params):
    position, quaternion = pose_to_float(params, record)
    pos = " ".join(f"{v:+.4f}" for v in position)
    quat = " ".join(f"{v:+.4f}" for v in quaternion)
    hw = f"{record_rate:,.0f} rec/s" if record_rate else "-"
    status = record["status"].upper() + (", drifted" if record["drifted"] else "")
    return (f"seq {record['seq']:5d} row {record['row']:4d} | {status} | pos [{pos}] m | "
            f"q [{quat}] | link {link_rate:,.0f} pkt/s, hw {hw} | ok {stats.packets_ok} "
            f"lost {stats.packets_lost} crc {stats.crc_errors} skipped {stats.hw_skipped} "
            f"| tracking lost {stats.losses}×")


def run_host(port, *, baud=3_000_000, csv_path=None, count=None, seconds=None,
             clk_hz=100e6, params=PacketParams(), live=True, out=sys.stdout,
             clock=time.monotonic, read_size=4096):
    """Read packets from serial ``port`` until ``count`` packets, ``seconds`` or Ctrl-C.

    Prints a live status line (pose, link and record rates, counts) about five times a
    second when ``live``, logs every record to ``csv_path``, and returns the
    :class:`LinkStats`. ``port`` is a device path or an open pyserial port.
    """
    import serial

    own_port = isinstance(port, str)
    link = serial.Serial(port, baud, timeout=0.05) if own_port else port
    decoder = PacketDecoder(params)
    meter = RateMeter()
    csv_file = open(csv_path, "w", newline="") if csv_path else None
    writer = csv.writer(csv_file) if csv_file else None
    if writer:
        writer.writerow(CSV_COLUMNS)
    start = clock()
    last_print = start
    window = deque(maxlen=64)
    try:
        while (count is None or decoder.stats.packets_ok < count) and \
                (seconds is None or clock() - start < seconds):
            data = link.read(read_size)
            if not data:
                continue
            now = clock()
            for record in decoder.feed(data):
                meter.add(now)
                window.append(record)
                if writer:
                    position, quaternion = pose_to_float(params, record)
                    writer.writerow([f"{now - start:.6f}", record["seq"], record["skipped"],
                                     record["lost_before"], record["t_row"], record["row"],
                                     *(f"{v:.9f}" for v in position),
                                     *(f"{v:.6f}" for v in quaternion), record["flags"],
                                     record["status"], int(record["drifted"])])
            if live and window and now - last_print >= 0.2:
                last_print = now
                rate = _record_rate(window[0], window[-1], clk_hz, params)
                print("\r" + _status_line(window[-1], decoder.stats, meter.rate(now), rate,
                                          params), end="", file=out, flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        if csv_file:
            csv_file.close()
        if own_port:
            link.close()
    if live:
        print(file=out)
    return decoder.stats



class PtyLink:
    """A pseudo-terminal pair standing in for the board's UART: the host tool opens
    :attr:`path`; :meth:`play` writes ``data`` (what the hardware would send, faults
    included) into the other side from a thread.

    Open the port before playing: opening a terminal discards what was written before.
    """

    def __init__(self, data, *, chunk=4096):
        self.data = bytes(data)
        self.chunk = chunk
        self._master, self._slave = os.openpty()
        self.path = os.ttyname(self._slave)
        self._thread = None

    def play(self, before=None):
        """Start writing; ``before()``, if given, runs first in the writer thread."""
        def writer():
            if before is not None:
                before()
            for at in range(0, len(self.data), self.chunk):
                os.write(self._master, self.data[at:at + self.chunk])

        self._thread = threading.Thread(target=writer, daemon=True)
        self._thread.start()

    def close(self):
        if self._thread is not None:
            self._thread.join(timeout=10)
        os.close(self._master)
        os.close(self._slave)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

"""Parameters of the pose output (:mod:`hdl.output.packet`, :mod:`hdl.output.uart`), without
gateware: the packet layout, the pose record as the solver hands it over, the PS FIFO and
counters, and the UART divisor.

No Amaranth at import time: the bit-accurate model (:mod:`emulator.output.packets`) and the host
tool (:mod:`emulator.output.host`) decode packets with the same objects; the layouts are built
when a method is called.
"""

import functools
from dataclasses import dataclass, replace

from golden.checks import check_int
from golden.tracking_status import DRIFTED_BIT, STATUS_BITS, STATUS_SHIFT

from hdl.fixed import SQ, UQ, Overflow, QFormat, Rounding, check_format

__all__ = ["PacketField", "PacketParams", "PoseSource", "PoseOutputParams", "UartParams",
           "CRC16_POLY", "CRC16_INIT", "FRAME_BITS", "FLAG_FIELDS", "FLAGS_DOC"]

#: CRC-16/CCITT-FALSE: polynomial x^16 + x^12 + x^5 + 1, initial value 0xFFFF, no
#: reflection, no final XOR (Python's ``binascii.crc_hqx(data, 0xFFFF)``).
CRC16_POLY = 0x1021
CRC16_INIT = 0xFFFF


#: The fields of a pose record's (and packet's) flags byte, ``(name, lowest bit, bits)``:
#: the solver's :class:`hdl.pose.params.PoseFlag` (0: the row was solved), the tracking
#: status code (:class:`golden.tracking_status.TrackingStatus`: 0 tracking, 1 degraded,
#: 2 lost, 3 reserved and read as lost) and drifted since a loss
#: (:mod:`hdl.pose.status_unit`); bit 7 is reserved (0). Zero means a good pose.
FLAG_FIELDS = (("solver", 0, STATUS_SHIFT), ("status", STATUS_SHIFT, STATUS_BITS),
               ("drifted", DRIFTED_BIT, 1))
#: One line on the flags for the packet table.
FLAGS_DOC = (f"pose flags: bits {STATUS_SHIFT - 1}:0 the solver's PoseFlag (0: solved), "
             f"{STATUS_SHIFT + STATUS_BITS - 1}:{STATUS_SHIFT} tracking status (0 tracking, "
             f"1 degraded, 2 lost), {DRIFTED_BIT} drifted since a loss; 0: a good pose")


def _check_bits(name, value, multiple_of=8, high=64):
    check_int(name, value, multiple_of, high)
    if value % multiple_of:
        raise ValueError(f"{name} must be a multiple of {multiple_of}, not {value}")


@dataclass(frozen=True)
class PacketField:
    """One payload field: ``count`` little-endian integers of ``bits`` bits each."""
    name: str
    bits: int
    signed: bool
    count: int
    doc: str

    @property
    def bytes(self):
        return self.bits // 8 * self.count


@dataclass(frozen=True, kw_only=True)
class PacketParams:
    """The pose packet (no Amaranth here: the emulator and the host tool use it too).

    A packet is ``sync`` (two bytes, high first), ``length`` (one byte: the payload
    bytes), the payload (fields of :meth:`fields`, each little-endian) and the CRC-16 of
    ``length`` and payload (high byte first, so the CRC over everything after the sync
    word, CRC included, is zero).

    Parameters
    ----------
    sync : int
        The 16-bit sync word.
    timestamp_bits, row_bits, seq_bits, skipped_bits, flag_bits : int
        Widths of the row time stamp (system clocks, wraps), row index, packet sequence
        number (wraps), skipped-record count (saturates) and pose flags; multiples of 8.
    position_fmt : QFormat
        Position, metres (a multiple of 8 bits wide, signed).
    quaternion_fmt : QFormat
        Orientation quaternion components (w, x, y, z), signed, a multiple of 8 bits.
    """
    sync: int = 0xA55A
    timestamp_bits: int = 32
    row_bits: int = 16
    seq_bits: int = 16
    skipped_bits: int = 16
    flag_bits: int = 8
    position_fmt: QFormat = SQ(8, 24)
    quaternion_fmt: QFormat = SQ(2, 14)

    def __post_init__(self):
        check_int("sync", self.sync)
        if not 0 <= self.sync <= 0xFFFF or (self.sync >> 8) == (self.sync & 0xFF):
            raise ValueError(f"sync must be a 16-bit word with two different bytes, "
                             f"not {self.sync:#x}")
        for name in ("timestamp_bits", "row_bits", "seq_bits", "skipped_bits", "flag_bits"):
            _check_bits(name, getattr(self, name))
        for name in ("position_fmt", "quaternion_fmt"):
            check_format(name, getattr(self, name), signed=True)
            _check_bits(f"{name} width", getattr(self, name).width, high=32)

    replace = replace

    def fields(self):
        """Payload fields in wire order."""
        return _packet_fields(self)

    @property
    def payload_bytes(self):
        return sum(field.bytes for field in self.fields())

    @property
    def packet_bytes(self):
        """Sync (2) + length (1) + payload + CRC (2)."""
        return 5 + self.payload_bytes

    def record_layout(self):
        """A kept pose as it travels in a packet or sits in the PS FIFO."""
        from amaranth.lib import data
        return data.StructLayout({f.name: self._field_shape(f) for f in self.fields()})

    def _field_shape(self, field):
        from amaranth.hdl import signed, unsigned
        from amaranth.lib import data
        element = signed(field.bits) if field.signed else unsigned(field.bits)
        return element if field.count == 1 else data.ArrayLayout(element, field.count)


@functools.cache
def _packet_fields(params):
    """The payload fields of a :class:`PacketParams` (cached: the host decodes thousands
    of packets a second with them)."""
    return (
        PacketField("seq", params.seq_bits, False, 1,
                    "record number (wraps); consecutive records differ by one"),
        PacketField("skipped", params.skipped_bits, False, 1,
                    "records this sink dropped just before this one (saturates)"),
        PacketField("t_row", params.timestamp_bits, False, 1,
                    "row time stamp, system clocks (wraps)"),
        PacketField("row", params.row_bits, False, 1, "row index within the frame"),
        PacketField("position", params.position_fmt.width, True, 3,
                    f"x, y, z in metres, raw {params.position_fmt}"),
        PacketField("quaternion", params.quaternion_fmt.width, True, 4,
                    f"w, x, y, z, raw {params.quaternion_fmt}"),
        PacketField("flags", params.flag_bits, False, 1, FLAGS_DOC),
    )


@dataclass(frozen=True, kw_only=True)
class PoseSource:
    """The pose record as the tracker hands it over, in its own formats.

    The pose solver emits this record (:func:`hdl.pose.params.solver_source`), so the top
    connects it to :class:`hdl.output.packet.PoseOutput` as it is.
    :class:`~hdl.output.packet.PoseOutput` narrows it into the packet formats: position
    and quaternion rounded half-even and saturated (:func:`hdl.fixed.hdl_resize`), the
    time stamp cut to its low ``timestamp_bits`` (it wraps anyway); row and flags must
    fit; the step is not sent.

    Parameters
    ----------
    position_fmt, quaternion_fmt, step_fmt : QFormat
        Signed formats of the position (metres), the quaternion components and the
        step (metres, radians).
    row_bits, time_bits, flag_bits : int
        Widths of the row index, time stamp and flags.
    """
    position_fmt: QFormat = SQ(8, 24)
    quaternion_fmt: QFormat = SQ(2, 14)
    step_fmt: QFormat = SQ(1, 15)
    row_bits: int = 16
    time_bits: int = 32
    flag_bits: int = 8

    def __post_init__(self):
        for name in ("position_fmt", "quaternion_fmt", "step_fmt"):
            check_format(name, getattr(self, name), signed=True)
        for name in ("row_bits", "time_bits", "flag_bits"):
            _check_bits(name, getattr(self, name), multiple_of=1)

    def layout(self):
        """The pose record, one per image row; the one definition of its fields.

        Fields
        ------
        row : unsigned(row_bits)
        time : unsigned(time_bits)
            Of the row's last measurement.
        flags : unsigned(flag_bits)
            :class:`hdl.pose.params.PoseFlag` (one reason; zero when the row was solved);
            after the status unit (``flag_bits`` 7, :func:`hdl.pose.status_params.status_source`)
            also the tracking status and drifted bits (:data:`FLAG_FIELDS`).
        q : ArrayLayout(quaternion_fmt, 4)
            World-from-body orientation (w, x, y, z) after the row.
        p : ArrayLayout(position_fmt, 3)
            World position of the body (m) after the row.
        step : ArrayLayout(step_fmt, 6)
            The row's step [Tx Ty Tz θx θy θz] (m, rad), zero when flagged.
        """
        from amaranth.lib import data
        return data.StructLayout({
            "row": self.row_bits, "time": self.time_bits, "flags": self.flag_bits,
            "q": data.ArrayLayout(self.quaternion_fmt.shape(), 4),
            "p": data.ArrayLayout(self.position_fmt.shape(), 3),
            "step": data.ArrayLayout(self.step_fmt.shape(), 6),
        })


@dataclass(frozen=True, kw_only=True)
class PoseOutputParams:
    """Parameters of :class:`hdl.output.packet.PoseOutput`.

    Parameters
    ----------
    packet : PacketParams
    source : PoseSource
        Formats of the incoming poses; ``row_bits`` and ``flag_bits`` must fit the
        packet's.
    fifo_depth : int
        Records the PS FIFO holds (a power of two, at least 2).
    count_bits : int
        Width of the event counters (they wrap) and of the rate window.
    decimation_bits : int
        Width of the ``decimation`` register.
    """
    packet: PacketParams = PacketParams()
    source: PoseSource = PoseSource()
    fifo_depth: int = 256
    count_bits: int = 32
    decimation_bits: int = 16

    def __post_init__(self):
        if not isinstance(self.packet, PacketParams):
            raise TypeError(f"packet must be a PacketParams, not {self.packet!r}")
        if not isinstance(self.source, PoseSource):
            raise TypeError(f"source must be a PoseSource, not {self.source!r}")
        for name, packet_name in (("row_bits", "row_bits"), ("flag_bits", "flag_bits")):
            if getattr(self.source, name) > getattr(self.packet, packet_name):
                raise ValueError(f"source.{name} must fit the packet's {packet_name} "
                                 f"({getattr(self.packet, packet_name)}), not "
                                 f"{getattr(self.source, name)}")
        for name, low, high in (("fifo_depth", 2, 1 << 16), ("count_bits", 8, 64),
                                ("decimation_bits", 1, 32)):
            check_int(name, getattr(self, name), low, high)
        if self.fifo_depth & (self.fifo_depth - 1):
            raise ValueError(f"fifo_depth must be a power of two, not {self.fifo_depth}")

    replace = replace

    def config_layout(self):
        """Run-time control: ``uart_enable``, ``fifo_enable`` (a disabled sink takes no
        records and counts none as dropped), ``decimation`` (keep one pose in this many;
        0 and 1 keep every pose), ``rate_window`` (system clocks per pose-rate window;
        0 stops the measurement)."""
        from amaranth.lib import data
        return data.StructLayout({"uart_enable": 1, "fifo_enable": 1,
                                  "decimation": self.decimation_bits,
                                  "rate_window": self.count_bits})

    def status_layout(self):
        """Counters (wrapping): ``poses`` in, ``records`` kept, ``decimated`` away,
        ``uart_dropped`` / ``fifo_dropped`` (a sink was still full), ``packets`` framed;
        ``pose_rate``: poses in the last complete ``rate_window``; ``fifo_level``:
        records ready in the PS FIFO (the head is valid when it is not zero)."""
        from amaranth.lib import data
        c = self.count_bits
        return data.StructLayout({
            "poses": c, "records": c, "decimated": c, "uart_dropped": c,
            "fifo_dropped": c, "packets": c, "pose_rate": c,
            "fifo_level": (self.fifo_depth).bit_length(),
        })


#: Start bit, eight data bits (LSB first), stop bit.
FRAME_BITS = 10


@dataclass(frozen=True, kw_only=True)
class UartParams:
    """Parameters of :class:`hdl.output.uart.UartTx`.

    Parameters
    ----------
    divisor_fmt : QFormat
        Unsigned format of the run-time divisor (system clocks per bit). A divisor
        below 1.0 is taken as 1.0.
    """
    divisor_fmt: QFormat = UQ(16, 4)

    def __post_init__(self):
        check_format("divisor_fmt", self.divisor_fmt, signed=False)
        if self.divisor_fmt.int_bits < 1:
            raise ValueError(f"divisor_fmt must have at least one integer bit, not "
                             f"{self.divisor_fmt}")

    replace = replace

    def divisor_raw(self, clk_hz, baud):
        """The raw divisor register value for ``baud`` at ``clk_hz`` (half-even).

        Raises
        ------
        ValueError
            If ``baud`` is not positive, faster than one bit per clock, or too slow for
            ``divisor_fmt``.
        """
        if not baud > 0 or not clk_hz > 0:
            raise ValueError(f"baud and clk_hz must be positive, not {baud!r} and {clk_hz!r}")
        try:
            raw = int(self.divisor_fmt.quantize(clk_hz / baud, Rounding.HALF_EVEN,
                                                Overflow.ERROR))
        except OverflowError:
            raise ValueError(f"baud must be at least {clk_hz / self.divisor_fmt.max_value:.0f} "
                             f"at {clk_hz:g} Hz with a {self.divisor_fmt} divisor, not {baud}")
        if raw < self.min_divisor_raw:
            raise ValueError(f"baud must be at most one bit per clock ({clk_hz:g}), not {baud}")
        return raw

    @property
    def min_divisor_raw(self):
        """The raw divisor of one clock per bit, the fastest the transmitter goes."""
        return 1 << self.divisor_fmt.frac_bits

"""Bit-accurate model of the pose output: records, packets, CRC-16, UART timing, link budget.

Everything here follows :mod:`hdl.output.packet` and :mod:`hdl.output.uart` from their parameter
objects: the cocotb benches compare the UART line byte for byte with
:func:`encode_packet`, and the host tool decodes with :func:`decode_payload`.

A record is a dict of raw integers: ``seq``, ``skipped``, ``t_row``, ``row``,
``position`` (3), ``quaternion`` (4), ``flags`` (:func:`quantize_pose` gives all but
``seq`` and ``skipped``). A tracker pose, what :func:`narrow_pose` and :func:`keep_poses`
take, is the tracker's pose record: the fields of
:meth:`hdl.output.params.PoseSource.layout` (``row``, ``time``, ``flags``, ``q`` (4),
``p`` (3), ``step`` (6)), as :func:`emulator.pose_solver.pose_solver_model` names them.
"""

import binascii

import numpy as np

from golden.tracking_status import TrackingStatus
from hdl.fixed import Overflow, Rounding, resize
from hdl.output.params import CRC16_INIT, FLAG_FIELDS, PacketParams
from hdl.output.params import FRAME_BITS, UartParams

__all__ = ["crc16", "encode_payload", "encode_packet", "decode_payload", "narrow_pose",
           "keep_poses", "flag_fields",
           "quantize_pose", "pose_to_float", "uart_bit_clocks", "uart_byte_clocks",
           "packets_per_second", "damaged_stream", "format_markdown"]


def crc16(data, crc=CRC16_INIT):
    """CRC-16/CCITT-FALSE of ``data``, continuing from ``crc``.

    Python's ``binascii.crc_hqx`` computes exactly this CRC (polynomial ``CRC16_POLY``,
    MSB first, no reflection or final XOR) in C: the host keeps up with 3 Mbaud, and
    the hardware is checked against an implementation that is not ours. The unit tests
    check it against the bitwise definition from :data:`hdl.output.params.CRC16_POLY`.
    """
    return binascii.crc_hqx(bytes(data), crc)


def _elements(field, value):
    values = [value] if field.count == 1 else list(value)
    if len(values) != field.count:
        raise ValueError(f"{field.name} must have {field.count} elements, not {len(values)}")
    return [int(v) for v in values]


def encode_payload(params, record):
    """The payload bytes of ``record`` (little-endian fields in wire order)."""
    out = bytearray()
    for field in params.fields():
        if field.name not in record:
            raise ValueError(f"record must have a {field.name!r} field")
        lo = -(1 << (field.bits - 1)) if field.signed else 0
        hi = (1 << (field.bits - (1 if field.signed else 0))) - 1
        for value in _elements(field, record[field.name]):
            if not lo <= value <= hi:
                raise ValueError(f"{field.name} value {value} does not fit {field.bits} "
                                 f"{'signed' if field.signed else 'unsigned'} bits")
            out += value.to_bytes(field.bits // 8, "little", signed=field.signed)
    return bytes(out)


def encode_packet(params, record):
    """The bytes the hardware sends for ``record``: sync, length, payload, CRC."""
    body = bytes([params.payload_bytes]) + encode_payload(params, record)
    crc = crc16(body)
    return params.sync.to_bytes(2, "big") + body + crc.to_bytes(2, "big")


def decode_payload(params, payload):
    """A record from its payload bytes (the inverse of :func:`encode_payload`)."""
    if len(payload) != params.payload_bytes:
        raise ValueError(f"payload must be {params.payload_bytes} bytes, not {len(payload)}")
    record, at = {}, 0
    for field in params.fields():
        size = field.bits // 8
        values = [int.from_bytes(payload[at + k * size:at + (k + 1) * size], "little",
                                 signed=field.signed) for k in range(field.count)]
        at += field.bytes
        record[field.name] = values[0] if field.count == 1 else values
    return record


def flag_fields(flags):
    """The fields of a flags byte (:data:`hdl.output.params.FLAG_FIELDS`): ``solver``
    (the PoseFlag bits), ``status`` (a :class:`golden.tracking_status.TrackingStatus`;
    the reserved code reads as LOST, as ``golden.tracking_status.unpack_flags`` reads
    it) and ``drifted`` (bool). Scalar integer arithmetic: the host decodes thousands
    of packets a second."""
    flags = int(flags)
    out = {name: (flags >> low) & ((1 << bits) - 1) for name, low, bits in FLAG_FIELDS}
    out["status"] = TrackingStatus(min(out["status"], TrackingStatus.LOST))
    out["drifted"] = bool(out["drifted"])
    return out


def narrow_pose(params, pose):
    """A tracker pose (``params.source`` formats) in the packet formats, as
    :class:`hdl.output.packet.PoseOutput` narrows it: position and quaternion rounded
    half-even and saturated, the time stamp cut to its low bits."""
    src, packet = params.source, params.packet
    narrowed = {"t_row": int(pose["time"]) & ((1 << packet.timestamp_bits) - 1),
                "row": int(pose["row"]), "flags": int(pose["flags"])}
    for name, value, src_fmt, dst_fmt in (
            ("position", pose["p"], src.position_fmt, packet.position_fmt),
            ("quaternion", pose["q"], src.quaternion_fmt, packet.quaternion_fmt)):
        raw = np.array([int(v) for v in value], dtype=src_fmt.dtype())
        narrowed[name] = [int(v) for v in resize(raw, src_fmt, dst_fmt, Rounding.HALF_EVEN,
                                                 Overflow.SATURATE)]
    return narrowed


def keep_poses(params, poses, decimation, seq=0):
    """The records :class:`hdl.output.packet.PoseOutput` (``params``, a
    :class:`~hdl.output.params.PoseOutputParams`) forms from ``poses``.

    Keeps one pose in ``decimation`` (0 and 1 keep all), starting with the first,
    narrows it into the packet formats and numbers the kept ones from ``seq``
    (wrapping). ``skipped`` is left 0: it depends on the sinks' timing. Returns
    ``(index_of_pose, record)`` pairs.
    """
    period = max(int(decimation), 1)
    mask = (1 << params.packet.seq_bits) - 1
    out = []
    for k, pose in enumerate(poses):
        if k % period == 0:
            out.append((k, {**narrow_pose(params, pose), "seq": (seq + len(out)) & mask,
                            "skipped": 0}))
    return out


def quantize_pose(params, *, t_row, row, position, quaternion, flags=0):
    """A pose from metres and a unit quaternion, rounded half-even and saturated into
    the packet formats (what a tracker in other formats narrows to)."""
    return {
        "t_row": int(t_row) & ((1 << params.timestamp_bits) - 1),
        "row": int(row),
        "position": [int(v) for v in params.position_fmt.quantize(
            position, Rounding.HALF_EVEN, Overflow.SATURATE)],
        "quaternion": [int(v) for v in params.quaternion_fmt.quantize(
            quaternion, Rounding.HALF_EVEN, Overflow.SATURATE)],
        "flags": int(flags),
    }


def pose_to_float(params, record):
    """Position (metres) and quaternion (w, x, y, z) of a record as float arrays."""
    return (params.position_fmt.to_float(np.array(record["position"])),
            params.quaternion_fmt.to_float(np.array(record["quaternion"])))


def _effective_divisor(uart, divisor_raw):
    return max(int(divisor_raw), uart.min_divisor_raw)


def uart_bit_clocks(uart, divisor_raw):
    """Clocks of each of the ten bits of a frame (:class:`hdl.output.uart.UartTx`)."""
    d = _effective_divisor(uart, divisor_raw)
    f = uart.divisor_fmt.frac_bits
    remainder, out = 0, []
    for _ in range(FRAME_BITS):
        total = remainder + d
        out.append(total >> f)
        remainder = total & ((1 << f) - 1)
    return out


def uart_byte_clocks(uart, divisor_raw):
    """Clocks per byte, back to back: ``(10 d) >> f``."""
    return sum(uart_bit_clocks(uart, divisor_raw))


def packets_per_second(params, clk_hz, divisor_raw, uart=UartParams()):
    """Packets per second the UART carries back to back at this divisor."""
    return clk_hz / (params.packet_bytes * uart_byte_clocks(uart, divisor_raw))


def damaged_stream(params, records, rng, *, flip=0.05, drop=0.05, truncate=0.05):
    """The packets of ``records`` as a faulty link delivers them.

    Each packet independently gets, with these probabilities, one to three flipped
    bits, one to three dropped bytes, or is cut short (the rest of it never arrives);
    otherwise it is intact. The last packet is always intact, so that sequence gaps
    account for every damaged one. ``rng`` is a ``numpy.random.Generator``.

    Returns ``(data, intact)``: the bytes and the indices of the intact packets.
    """
    if not 0 <= flip + drop + truncate <= 1:
        raise ValueError(f"flip + drop + truncate must be a probability, not "
                         f"{flip + drop + truncate}")
    out, intact = bytearray(), []
    for k, record in enumerate(records):
        packet = bytearray(encode_packet(params, record))
        fault = rng.random() if k < len(records) - 1 else 1.0
        count = int(rng.integers(1, 4))
        if fault < flip:
            for bit in rng.choice(8 * len(packet), size=count, replace=False):
                packet[bit // 8] ^= 1 << (bit % 8)
        elif fault < flip + drop:
            for at in sorted(rng.choice(len(packet), size=count, replace=False), reverse=True):
                del packet[at]
        elif fault < flip + drop + truncate:
            del packet[int(rng.integers(1, len(packet))):]
        else:
            intact.append(k)
        out += packet
    return bytes(out), intact


def format_markdown(params=PacketParams(), *, clk_hz=100e6, bauds=(115200, 921600, 3000000),
                    pose_rates=(("CVPR 2018 synthetic, 640×480 @ 120 fps", 57.6e3),
                                ("TVCG 2016 real, 670 rows @ 120 fps", 80.4e3),
                                ("CVPR 2018 real, 720 rows @ 120 fps", 86.4e3)),
                    uart=UartParams()):
    """docs/packet_format.md, generated from the same parameters the HDL uses."""
    rows, at = [], 0
    rows.append(f"| 0 | 2 | sync | `{params.sync:#06x}`, high byte first |")
    rows.append(f"| 2 | 1 | length | payload bytes, {params.payload_bytes} |")
    at = 3
    for field in params.fields():
        kind = f"{'s' if field.signed else 'u'}{field.bits}" + (
            f" × {field.count}" if field.count > 1 else "")
        rows.append(f"| {at} | {field.bytes} | {field.name} ({kind}) | {field.doc} |")
        at += field.bytes
    rows.append(f"| {at} | 2 | crc | CRC-16/CCITT-FALSE of bytes 2…{at - 1}, high byte "
                f"first |")
    link = []
    for baud in bauds:
        divisor = uart.divisor_raw(clk_hz, baud)
        rate = packets_per_second(params, clk_hz, divisor, uart)
        needed = " | ".join(f"{int(np.ceil(pose_rate / rate))}" for _, pose_rate in pose_rates)
        link.append(f"| {baud:,} | {divisor / (1 << uart.divisor_fmt.frac_bits):.4f} | "
                    f"{clk_hz / uart_byte_clocks(uart, divisor) * FRAME_BITS:,.0f} | "
                    f"{rate:,.0f} | {needed} |")
    flag_rows = [f"| {low + bits - 1}:{low} | {name} | {meaning} |" if bits > 1 else
                 f"| {low} | {name} | {meaning} |" for (name, low, bits), meaning in zip(
                     FLAG_FIELDS, ("the solver's `PoseFlag`: EMPTY (1), ILL (2), SATURATED "
                                   "(4), OVERRUN (8); 0: the row was solved",
                                   "tracking status: 0 tracking, 1 degraded, 2 lost "
                                   "(3 reserved, read as lost)",
                                   "drifted: a loss happened since the tracker acquired"))]
    low = FLAG_FIELDS[-1][1] + FLAG_FIELDS[-1][2]
    reserved = f"{params.flag_bits - 1}:{low}" if params.flag_bits - 1 > low else f"{low}"
    rate_heads = " | ".join(f"{name}: {rate / 1e3:.1f} kHz" for name, rate in pose_rates)
    return f"""<!-- generated by `rowtrack build --write-docs docs` from hdl/output/packet.py; do not edit -->
# Pose packet format

The fabric sends one packet per kept pose on the UART (8 data bits, no parity, one stop
bit, LSB first) and puts the same record in a FIFO the PS reads through registers
(`pose_out` group of [the register map](register_map.md)).

## Layout ({params.packet_bytes} bytes)

All fields are little-endian two's-complement or unsigned integers except the sync word
and the CRC, which go high byte first; the CRC-16/CCITT-FALSE (polynomial `0x1021`,
initial value `0xFFFF`, no reflection, no final XOR: Python's
`binascii.crc_hqx(data, 0xFFFF)`) covers the length byte and the payload, so the CRC
over bytes 2 to the end of a good packet is zero.

| offset | bytes | field | meaning |
|---|---|---|---|
{chr(10).join(rows)}

Position: raw {params.position_fmt} metres (range ±{2 ** (params.position_fmt.int_bits - 1)} m,
step {params.position_fmt.lsb:.3g} m). Quaternion: raw {params.quaternion_fmt} (step
{params.quaternion_fmt.lsb:.3g}), world-from-body, w first.

## Flags: why a row has no step, and whether the tracker can be trusted

| bits | field | meaning |
|---|---|---|
{chr(10).join(flag_rows)}
| {reserved} | reserved | 0 |

Zero is a good pose. The status (`hdl/pose/status_unit.py`, from the last `window` rows:
update fraction, outlier share of the consistency stage's verdicts, the solver's pivot
check, confident measurements; [docs/pose/tracking_status.md](pose/tracking_status.md))
says whether to trust the pose at all: a *lost* pose is a guess, a *degraded* one
doubtful. *Drifted* stays set after a loss (until `status.clear`): relative tracking
resumed, the absolute pose keeps the error the loss left. The host tool
(`rowtrack host`) reports both per record and counts them. The closed-loop top
(`TopParams.closed_loop`) places the status unit between the tracking loop and the
output; the open-loop top has none and sends 0 in bits 6:4.

## Sequence numbers, skipped records and decimation

The hardware keeps one pose in `decimation` (register; 0 or 1 keep all) and numbers the
kept ones: `seq` grows by one per kept pose whether or not it is sent. Each sink (UART,
PS FIFO) holds one record in flight; a kept record that finds its sink still full is
dropped and counted (`uart_dropped`, `fifo_dropped`), and the next record the sink takes
says how many it dropped in `skipped`. A receiver therefore knows

* `seq − previous seq − 1 − skipped` (modulo 2^{params.seq_bits}) packets lost **on the
  wire** (corrupted, truncated, never arrived), and
* `skipped` records the **hardware** dropped because the link was slower than the
  tracker (decimation itself is visible in the `decimated` counter, not in `seq`).

Nothing is dropped silently: `poses = records + decimated` and
`records = packets + uart_dropped` (UART enabled) hold in the `pose_out.status`
registers.

## Link rate versus pose rate

Packet rate of a back-to-back stream at a {clk_hz / 1e6:g} MHz system clock (the divisor
is `UQ({uart.divisor_fmt.int_bits}, {uart.divisor_fmt.frac_bits})` clocks per bit;
a frame lasts `(10·divisor) >> {uart.divisor_fmt.frac_bits}` clocks), and the smallest
decimation that makes the pose rates of the papers' camera clusters fit:

| baud | divisor (clocks/bit) | actual baud | packets/s | {rate_heads} |
|---|---|---|---|{"---|" * len(pose_rates)}
{chr(10).join(link)}

With a smaller decimation than this the UART sink drops records (counted, and reported
in `skipped`); the PS FIFO still receives every kept record while the PS drains it.
"""

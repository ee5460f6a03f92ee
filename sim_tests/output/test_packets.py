"""The packet format model (emulator/output/packets.py) and its parameters."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from emulator.output import packets
from hdl.fixed import SQ, UQ
from hdl.output.params import (CRC16_INIT, CRC16_POLY, PacketParams, PoseOutputParams,
                               PoseSource)
from hdl.output.params import UartParams

P = PacketParams()
DOCS = Path(__file__).resolve().parents[2] / "docs"


def random_record(rng, params=P):
    """A record with every field random over its full range (extremes included)."""
    record = {}
    for field in params.fields():
        lo = -(1 << (field.bits - 1)) if field.signed else 0
        hi = (1 << (field.bits - (1 if field.signed else 0))) - 1
        values = [int(rng.choice([lo, hi, 0, int(rng.integers(lo, hi, endpoint=True))]))
                  for _ in range(field.count)]
        record[field.name] = values[0] if field.count == 1 else values
    return record


def bitwise_crc16(data, crc=CRC16_INIT):
    """The CRC from its definition: the hardware's polynomial, MSB first."""
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ CRC16_POLY if crc & 0x8000 else crc << 1) & 0xFFFF
    return crc


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=64))
def test_crc16_follows_the_hardware_polynomial(data):
    """The model's CRC (binascii's CRC-16/CCITT-FALSE) is the one the constants that
    build the gateware define."""
    assert packets.crc16(data) == bitwise_crc16(data)


def test_crc16_check_value():
    assert packets.crc16(b"123456789") == 0x29B1     # the catalogued check value


def test_packet_layout_and_round_trip():
    rng = np.random.default_rng(1)
    assert P.payload_bytes == 31 and P.packet_bytes == 36
    for _ in range(200):
        record = random_record(rng)
        packet = packets.encode_packet(P, record)
        assert len(packet) == P.packet_bytes
        assert packet[:2] == b"\xa5\x5a" and packet[2] == P.payload_bytes
        assert packets.crc16(packet[2:]) == 0             # CRC high byte first: residue 0
        assert packets.decode_payload(P, packet[3:-2]) == record


def test_fields_are_little_endian_in_wire_order():
    record = {"seq": 0x0102, "skipped": 0x0304, "t_row": 0x05060708, "row": 0x090A,
              "position": [1, -1, 0x7FFFFFFF], "quaternion": [0x4000, -2, 0, 1], "flags": 0xAB}
    payload = packets.encode_payload(P, record)
    assert payload[:10] == bytes([0x02, 0x01, 0x04, 0x03, 0x08, 0x07, 0x06, 0x05, 0x0A, 0x09])
    assert payload[10:14] == (1).to_bytes(4, "little")
    assert payload[14:18] == b"\xff\xff\xff\xff"
    assert payload[-1] == 0xAB


def test_encode_rejects_bad_records():
    record = random_record(np.random.default_rng(0))
    with pytest.raises(ValueError, match="record must have a 'flags' field"):
        packets.encode_payload(P, {k: v for k, v in record.items() if k != "flags"})
    with pytest.raises(ValueError, match="seq value 65536 does not fit 16 unsigned bits"):
        packets.encode_payload(P, {**record, "seq": 65536})
    with pytest.raises(ValueError, match="position must have 3 elements, not 2"):
        packets.encode_payload(P, {**record, "position": [0, 0]})
    with pytest.raises(ValueError, match="payload must be 31 bytes, not 30"):
        packets.decode_payload(P, bytes(30))


@pytest.mark.parametrize("kwargs, error, message", [
    ({"sync": 0x1FFFF}, ValueError, "sync must be a 16-bit word with two different bytes"),
    ({"sync": 0x5555}, ValueError, "sync must be a 16-bit word with two different bytes"),
    ({"sync": "A55A"}, TypeError, "sync must be an integer"),
    ({"row_bits": 12}, ValueError, "row_bits must be a multiple of 8"),
    ({"seq_bits": 16.0}, TypeError, "seq_bits must be an integer"),
    ({"position_fmt": UQ(8, 24)}, ValueError, "position_fmt must be signed"),
    ({"quaternion_fmt": SQ(2, 13)}, ValueError, "quaternion_fmt width must be a multiple "
                                                "of 8, not 15"),
    ({"quaternion_fmt": 16}, TypeError, "quaternion_fmt must be a QFormat"),
])
def test_packet_params_checks(kwargs, error, message):
    with pytest.raises(error, match=message):
        PacketParams(**kwargs)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"packet": 3}, TypeError, "packet must be a PacketParams"),
    ({"fifo_depth": 100}, ValueError, "fifo_depth must be a power of two, not 100"),
    ({"fifo_depth": 1}, ValueError, "fifo_depth must be an integer between 2 and 65536, not 1"),
    ({"count_bits": "32"}, TypeError, "count_bits must be an integer"),
    ({"source": 1}, TypeError, "source must be a PoseSource"),
    ({"source": PoseSource(row_bits=17)}, ValueError, "source.row_bits must fit the packet's "
                                                     "row_bits \\(16\\), not 17"),
])
def test_pose_output_params_checks(kwargs, error, message):
    with pytest.raises(error, match=message):
        PoseOutputParams(**kwargs)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"step_fmt": 16}, TypeError, "step_fmt must be a QFormat, not 16"),
    ({"step_fmt": UQ(1, 15)}, ValueError, "step_fmt must be signed, not UQ"),
    ({"quaternion_fmt": UQ(2, 14)}, ValueError, "quaternion_fmt must be signed"),
    ({"flag_bits": 0}, ValueError, "flag_bits must be an integer between 1 and 64, not 0"),
])
def test_pose_source_checks(kwargs, error, message):
    with pytest.raises(error, match=message):
        PoseSource(**kwargs)


def test_keep_poses_decimates_and_numbers():
    poses = [{"time": k, "row": k, "p": [0] * 3, "q": [0] * 4, "flags": 0, "step": [0] * 6}
             for k in range(10)]
    kept = packets.keep_poses(PoseOutputParams(), poses, 3, seq=65535)
    assert [k for k, _ in kept] == [0, 3, 6, 9]
    assert [r["seq"] for _, r in kept] == [65535, 0, 1, 2]
    assert [k for k, _ in packets.keep_poses(PoseOutputParams(), poses, 0)] == list(range(10))


def test_narrow_pose_rounds_half_even_and_saturates():
    source = PoseSource(position_fmt=SQ(10, 26), quaternion_fmt=SQ(2, 16), row_bits=10,
                        time_bits=40, flag_bits=4)
    params = PoseOutputParams(source=source)
    pose = {"time": (1 << 35) + 9, "row": 1000, "flags": 5,
            "p": [2, 6, -(1 << 34)],                 # 0.5 and 1.5 LSB of the packet format
            "q": [1 << 16, 10, 6, -(1 << 17)], "step": [1, -1, 0, 0, 0, 0]}
    narrowed = packets.narrow_pose(params, pose)
    assert narrowed["t_row"] == 9 and narrowed["row"] == 1000 and narrowed["flags"] == 5
    assert narrowed["position"] == [0, 2, -(1 << 31)]          # ties to even, saturated
    assert narrowed["quaternion"] == [1 << 14, 2, 2, -(1 << 15)]


def test_quantize_pose_rounds_and_saturates():
    pose = packets.quantize_pose(P, t_row=(1 << 32) + 5, row=3, position=[1.0, -200.0, 2 ** -25],
                                 quaternion=[1.0, 0.5, -2.5, 2 ** -15], flags=2)
    assert pose["t_row"] == 5
    assert pose["position"] == [1 << 24, -(1 << 31), 0]           # half-even, saturated
    assert pose["quaternion"] == [1 << 14, 1 << 13, -(1 << 15), 0]
    position, quaternion = packets.pose_to_float(P, {**pose, "seq": 0, "skipped": 0})
    assert position[0] == 1.0 and quaternion[1] == 0.5


def test_uart_timing_model():
    uart = UartParams()
    divisor = uart.divisor_raw(100e6, 3e6)
    assert divisor == 533                                   # 33.3125 clocks per bit
    bits = packets.uart_bit_clocks(uart, divisor)
    assert len(bits) == 10 and set(bits) == {33, 34} and sum(bits) == (10 * 533) >> 4
    assert packets.uart_bit_clocks(uart, 3) == [1] * 10     # below one clock per bit: 1.0
    rate = packets.packets_per_second(P, 100e6, divisor, uart)
    assert rate == pytest.approx(3e6 / 360, rel=2e-3)


@pytest.mark.parametrize("baud, message", [
    (0, "baud and clk_hz must be positive"),
    (200e6, "baud must be at most one bit per clock"),
    (1000, "baud must be at least 1526"),
])
def test_divisor_errors(baud, message):
    with pytest.raises(ValueError, match=message):
        UartParams().divisor_raw(100e6, baud)


def test_uart_params_checks():
    with pytest.raises(TypeError, match="divisor_fmt must be a QFormat"):
        UartParams(divisor_fmt=20)
    with pytest.raises(ValueError, match="divisor_fmt must be unsigned"):
        UartParams(divisor_fmt=SQ(16, 4))
    with pytest.raises(ValueError, match=r"divisor_fmt must have at least one integer bit, "
                                         r"not UQ\(0, 8\)"):
        UartParams(divisor_fmt=UQ(0, 8))


def test_damaged_stream_marks_intact_packets():
    rng = np.random.default_rng(5)
    records = [{**random_record(rng), "seq": k} for k in range(300)]
    data, intact = packets.damaged_stream(P, records, rng, flip=0.1, drop=0.1, truncate=0.1)
    assert intact[-1] == 299 and 150 < len(intact) < 280
    whole = b"".join(packets.encode_packet(P, records[k]) for k in intact)
    assert len(data) < len(b"".join(packets.encode_packet(P, r) for r in records))
    assert all(packets.encode_packet(P, records[k]) in data for k in intact)
    assert len(whole) == len(intact) * P.packet_bytes
    with pytest.raises(ValueError, match="flip \\+ drop \\+ truncate must be a probability"):
        packets.damaged_stream(P, records, rng, flip=0.6, drop=0.6)


def test_packet_format_doc_is_generated_from_the_parameters():
    from emulator.commands.build import docs_params
    text = packets.format_markdown(P)
    assert f"## Layout ({P.packet_bytes} bytes)" in text
    assert "| 3 | 2 | seq (u16) |" in text and "| 34 | 2 | crc |" in text
    params = docs_params()
    expected = packets.format_markdown(params.pose_output.packet, clk_hz=params.clk_hz,
                                       uart=params.uart)
    assert (DOCS / "packet_format.md").read_text() == expected, \
        "docs/packet_format.md is stale: run `rowtrack build --write-docs docs`"

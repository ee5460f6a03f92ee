"""The host tool: packet decoder with resynchronization, and the whole tool on a
pseudo-terminal pair fed with the bytes the hardware sends, faults injected."""

import csv
import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import serial

from emulator.output import packets
from emulator.cli import main
from emulator.output.host import PacketDecoder, PtyLink, run_host
from hdl.output.params import PacketParams
from sim_tests.output.test_packets import random_record

P = PacketParams()
SEED = int(os.environ.get("SEED", 2024))


def records(count, rng, *, start=0, skipped=None):
    out = []
    for k in range(count):
        record = random_record(rng)
        record["seq"] = (start + k) & 0xFFFF
        record["skipped"] = 0 if skipped is None else skipped[k]
        out.append(record)
    return out


def strip(record):
    """The packet's own fields (without what the decoder derives)."""
    return {k: v for k, v in record.items() if k not in ("lost_before", "status", "drifted")}


def test_decodes_any_chunking():
    rng = np.random.default_rng(SEED)
    recs = records(50, rng)
    data = b"".join(packets.encode_packet(P, r) for r in recs)
    decoder = PacketDecoder(P)
    got, at = [], 0
    while at < len(data):
        step = int(rng.integers(1, 80))
        got += decoder.feed(data[at:at + step])
        at += step
    assert [strip(r) for r in got] == recs
    assert decoder.stats.packets_ok == 50 and decoder.stats.packets_lost == 0
    assert decoder.stats.discarded == decoder.stats.crc_errors == 0


@pytest.mark.parametrize("damage", ["flip", "drop", "truncate", "garbage"])
def test_each_fault_costs_one_packet(damage):
    rng = np.random.default_rng(SEED)
    recs = records(3, rng, start=65534)                  # the sequence wraps too
    good = [packets.encode_packet(P, r) for r in recs]
    bad = bytearray(good[1])
    if damage == "flip":
        bad[20] ^= 0x10
    elif damage == "drop":
        del bad[7]
    elif damage == "truncate":
        del bad[12:]
    else:
        bad = b"\xa5\x5a\x1f" + bytes(rng.integers(0, 256, 60, dtype=np.uint8)) + bad
    decoder = PacketDecoder(P)
    got = decoder.feed(good[0] + bytes(bad) + good[2])
    expected = [recs[0], recs[2]] if damage != "garbage" else recs
    assert [strip(r) for r in got] == expected
    assert decoder.stats.packets_lost == (0 if damage == "garbage" else 1)
    assert got[-1]["lost_before"] == decoder.stats.packets_lost


def test_a_packet_cut_before_its_last_byte_does_not_take_the_next():
    """A packet whose CRC low byte was lost borrows the next sync byte; when that byte
    happens to complete it, both packets still decode (the byte is shared)."""
    rng = np.random.default_rng(SEED)
    for _ in range(2000):
        recs = records(2, rng)
        first = packets.encode_packet(P, recs[0])
        if first[-1] == 0xA5:
            break
    else:
        pytest.fail("no record with a CRC low byte of 0xA5 in 2000 tries")
    decoder = PacketDecoder(P)
    got = decoder.feed(first[:-1] + packets.encode_packet(P, recs[1]))
    assert [strip(r) for r in got] == recs
    decoder = PacketDecoder(P)                           # the next packet lost its first byte
    got = decoder.feed(first + packets.encode_packet(P, recs[1])[1:])
    assert [strip(r) for r in got] == recs


def test_hardware_skips_are_not_wire_losses():
    rng = np.random.default_rng(SEED)
    recs = records(4, rng, skipped=[0, 3, 0, 1])
    recs[1]["seq"], recs[2]["seq"], recs[3]["seq"] = 4, 5, 7
    decoder = PacketDecoder(P)
    decoder.feed(b"".join(packets.encode_packet(P, r) for r in recs))
    assert decoder.stats.hw_skipped == 4 and decoder.stats.packets_lost == 0
    decoder.feed(packets.encode_packet(P, {**recs[0], "seq": 7}))
    assert decoder.stats.seq_errors == 1


def opened_by(pid, path, timeout=30.0):
    """Wait until process ``pid`` has ``path`` open, then a little longer for it to set
    the line up (Linux /proc)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
            if any(os.readlink(f"/proc/{pid}/fd/{fd}") == path for fd in fds):
                time.sleep(0.5)
                return
        except OSError:
            pass
        time.sleep(0.05)
    raise AssertionError(f"process {pid} never opened {path}")


def faulty_stream(count, rng):
    recs = records(count, rng)
    data, intact = packets.damaged_stream(P, recs, rng, flip=0.05, drop=0.05, truncate=0.05)
    assert 0 < len(intact) < count, "the fault injection damaged nothing (or everything)"
    return recs, data, intact


def test_host_on_a_pseudo_terminal_decodes_every_intact_packet(tmp_path):
    rng = np.random.default_rng(SEED)
    recs, data, intact = faulty_stream(400, rng)
    print(f"SEED={SEED}: {len(intact)} intact of {len(recs)}")
    csv_path = tmp_path / "poses.csv"
    with PtyLink(data, chunk=997) as link:
        port = serial.Serial(link.path, 3_000_000, timeout=0.05)
        try:
            link.play()
            stats = run_host(port, csv_path=csv_path, count=len(intact), seconds=30,
                             live=False)
        finally:
            port.close()
    assert stats.packets_ok == len(intact)
    assert stats.packets_lost == len(recs) - len(intact)
    assert stats.seq_errors == 0
    with open(csv_path) as f:
        rows = list(csv.DictReader(f))
    assert [int(row["seq"]) for row in rows] == [recs[k]["seq"] for k in intact]
    first = recs[intact[0]]
    position, quaternion = packets.pose_to_float(P, first)
    assert float(rows[0]["x_m"]) == pytest.approx(position[0], abs=1e-9)
    assert float(rows[0]["qw"]) == pytest.approx(quaternion[0], abs=1e-6)
    assert sum(int(row["lost_before"]) for row in rows) == stats.packets_lost


def test_rowtrack_host_command_on_a_pseudo_terminal():
    """The command line, live output and all, in a separate process."""
    rng = np.random.default_rng(SEED + 1)
    recs, data, intact = faulty_stream(120, rng)
    with PtyLink(data) as link:
        process = subprocess.Popen(
            [sys.executable, "-m", "emulator.cli", "host", "--port", link.path, "--count",
             str(len(intact)), "--seconds", "60", "--json"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        link.play(before=lambda: opened_by(process.pid, link.path))
        out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err
    stats = json.loads(out.strip().splitlines()[-1])
    assert stats["packets_ok"] == len(intact)
    assert stats["packets_lost"] == len(recs) - len(intact)


def test_host_usage_errors(capsys, tmp_path):
    assert main(["host", "--port", "/dev/does-not-exist", "--count", "1"]) == 2
    assert "cannot open --port /dev/does-not-exist" in capsys.readouterr().err
    assert main(["host", "--port", "x", "--baud", "0"]) == 2
    assert "--baud must be positive, not 0" in capsys.readouterr().err
    assert main(["host", "--port", "x", "--count", "-3"]) == 2
    assert "--count must be positive, not -3" in capsys.readouterr().err
    assert main(["host", "--port", "x", "--csv", str(tmp_path / "no" / "f.csv")]) == 2
    assert "--csv: directory" in capsys.readouterr().err

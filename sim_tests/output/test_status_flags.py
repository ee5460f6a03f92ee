"""The tracking-status bits of the pose record's flags byte in the packet path: the
layout (hdl/output/params.py FLAG_FIELDS) against the golden encoding, the decoder's
per-record status and drifted and its counts, the CSV log, the generated packet doc,
and annotated records of the status unit's model through PoseOutput's narrowing."""

import csv
import os

import numpy as np
import serial

from emulator.output import packets
from emulator.output.host import CSV_COLUMNS, PacketDecoder, PtyLink, run_host
from golden.tracking_status import TrackingStatus, pack_flags, unpack_flags
from hdl.output.params import FLAG_FIELDS, PacketParams, PoseOutputParams
from hdl.pose.params import PoseSolverParams
from hdl.pose.status_params import status_source

from sim_tests.output.test_packets import random_record

P = PacketParams()
SEED = int(os.environ.get("SEED", 2024))


def test_flag_fields_match_the_golden_encoding():
    for flags in range(256):
        fields = packets.flag_fields(flags)
        status, drifted = unpack_flags(np.uint8(flags))
        assert fields["status"] == int(status) and fields["drifted"] == bool(drifted)
        assert fields["solver"] == flags & 0xF
    for status in TrackingStatus:
        for drifted in (0, 1):
            flags = int(pack_flags(status, drifted)) | 0b0101
            assert packets.flag_fields(flags) == {"solver": 5, "status": status,
                                                  "drifted": bool(drifted)}
    assert [name for name, _, _ in FLAG_FIELDS] == ["solver", "status", "drifted"]


def _stream(rng, statuses, drifted):
    recs = []
    for k, (status, drift) in enumerate(zip(statuses, drifted)):
        record = random_record(rng)
        record.update(seq=k, skipped=0, flags=int(pack_flags(status, drift)) | (k % 2) * 4)
        recs.append(record)
    return recs


def test_decoder_reports_status_and_drifted_per_record():
    rng = np.random.default_rng(SEED)
    print(f"SEED={SEED}")
    statuses = [0, 0, 1, 2, 2, 1, 0, 2, 0, 3]
    drifted = [0, 0, 0, 1, 1, 1, 1, 1, 1, 1]
    recs = _stream(rng, statuses, drifted)
    decoder = PacketDecoder(P)
    got = decoder.feed(b"".join(packets.encode_packet(P, r) for r in recs))
    names = ["tracking", "tracking", "degraded", "lost", "lost", "degraded", "tracking",
             "lost", "tracking", "lost"]
    assert [r["status"] for r in got] == names
    assert [r["drifted"] for r in got] == [bool(d) for d in drifted]
    stats = decoder.stats
    assert (stats.degraded, stats.lost, stats.drifted, stats.losses) == (2, 4, 7, 3)


def test_csv_log_has_status_and_drifted(tmp_path):
    rng = np.random.default_rng(SEED + 3)
    recs = _stream(rng, [0, 1, 2, 0], [0, 0, 1, 1])
    data = b"".join(packets.encode_packet(P, r) for r in recs)
    csv_path = tmp_path / "poses.csv"
    with PtyLink(data) as link:
        port = serial.Serial(link.path, 3_000_000, timeout=0.05)
        try:
            link.play()
            stats = run_host(port, csv_path=csv_path, count=len(recs), seconds=30,
                             live=False)
        finally:
            port.close()
    with open(csv_path) as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert [r["status"] for r in rows] == ["tracking", "degraded", "lost", "tracking"]
    assert [r["drifted"] for r in rows] == ["0", "0", "1", "1"]
    assert stats.losses == 1 and stats.lost == 1


def test_annotated_records_pass_the_output_unchanged():
    """The status unit's records (7 flag bits) fit the packet; PoseOutput copies the
    flags as they are (narrow_pose is its model)."""
    source = status_source(PoseSolverParams())
    params = PoseOutputParams(source=source)
    pose = {"time": 5, "row": 3, "flags": 0b1100010, "p": [0] * 3, "q": [0] * 4,
            "step": [0] * 6}
    narrowed = packets.narrow_pose(params, pose)
    assert narrowed["flags"] == 0b1100010
    fields = packets.flag_fields(narrowed["flags"])
    assert fields == {"solver": 2, "status": TrackingStatus.LOST, "drifted": True}


def test_generated_doc_lists_the_flag_bits():
    text = packets.format_markdown(P)
    assert "| 5:4 | status | tracking status: 0 tracking, 1 degraded, 2 lost" in text
    assert "| 6 | drifted |" in text and "| 7 | reserved | 0 |" in text

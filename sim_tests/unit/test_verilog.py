"""hdl.verilog.write_verilog keeps an unchanged file untouched (so simulators skip the
rebuild) and rewrites a changed one."""

import os

from hdl.fixed import SQ
from hdl.mac import MacParams, MultiplyAccumulate
from hdl.verilog import write_verilog


def test_unchanged_design_keeps_its_time_stamp_and_a_changed_one_is_rewritten(tmp_path):
    path = write_verilog(MultiplyAccumulate(MacParams()), "mac", tmp_path)
    os.utime(path, (1_000_000, 1_000_000))
    assert write_verilog(MultiplyAccumulate(MacParams()), "mac", tmp_path) == path
    assert path.stat().st_mtime == 1_000_000
    before = path.read_text()
    write_verilog(MultiplyAccumulate(MacParams(a_fmt=SQ(3, 16))), "mac", tmp_path)
    assert path.stat().st_mtime != 1_000_000
    assert path.read_text() != before

"""hdl.verilog: the same Verilog in every process, and write_verilog keeps an unchanged
file untouched (so simulators skip the rebuild) and rewrites a changed one."""

import os
import subprocess
import sys

import pytest

from hdl.front_end.params import CameraParams
from hdl.front_end.camera_sync import CameraFrontEnd
from hdl.fixed import SQ
from hdl.pose.mac import MultiplyAccumulate
from hdl.pose.mac_params import MacParams
from hdl.verilog import to_verilog, write_verilog


def test_unchanged_design_keeps_its_time_stamp_and_a_changed_one_is_rewritten(tmp_path):
    path = write_verilog(MultiplyAccumulate(MacParams()), "mac", tmp_path)
    os.utime(path, (1_000_000, 1_000_000))
    assert write_verilog(MultiplyAccumulate(MacParams()), "mac", tmp_path) == path
    assert path.stat().st_mtime == 1_000_000
    before = path.read_text()
    write_verilog(MultiplyAccumulate(MacParams(a_fmt=SQ(3, 16))), "mac", tmp_path)
    assert path.stat().st_mtime != 1_000_000
    assert path.read_text() != before


#: A process that writes the Verilog of a front end of four cameras (five clock domains
#: that the design uses without defining) and prints it.
_FRONT_END_VERILOG = """
from hdl.front_end.camera_input import CameraParams
from hdl.front_end.camera_sync import CameraFrontEnd
from hdl.verilog import to_verilog
params = CameraParams(n_cameras=4, max_width=16, max_height=4, buffer_depth=16)
print(to_verilog(CameraFrontEnd(params), "front"))
"""


def test_verilog_is_the_same_whatever_the_hash_seed():
    """Amaranth creates undefined clock domains in set order; to_verilog must not
    depend on it (otherwise every process rebuilds the simulator's model)."""
    texts = []
    for seed in ("1", "2", "3"):
        env = {**os.environ, "PYTHONHASHSEED": seed}
        done = subprocess.run([sys.executable, "-c", _FRONT_END_VERILOG], env=env,
                              capture_output=True, text=True, check=True)
        texts.append(done.stdout)
    assert "input pclk3_clk" in texts[0] and "input clk" in texts[0]
    assert texts[0] == texts[1] == texts[2]


def test_a_clock_domain_missing_from_clock_domains_is_named():
    params = CameraParams(n_cameras=2, max_width=16, max_height=4, buffer_depth=16)
    front = CameraFrontEnd(params)
    front.clock_domains = ("sync", "pclk0")
    with pytest.raises(ValueError, match="uses the clock domain 'pclk1', which its "
                                         "clock_domains"):
        to_verilog(front, "front")


def test_a_cached_design_is_not_elaborated_again(tmp_path, monkeypatch):
    import hdl.verilog
    path = write_verilog(MultiplyAccumulate(MacParams()), "mac", tmp_path,
                         cache_key=repr(MacParams()))
    text = path.read_text()

    def fail(*_):
        raise AssertionError("elaborated although the key is unchanged")
    monkeypatch.setattr(hdl.verilog, "to_verilog", fail)
    assert write_verilog(MultiplyAccumulate(MacParams()), "mac", tmp_path,
                         cache_key=repr(MacParams())).read_text() == text
    other = MacParams(a_fmt=SQ(3, 16))
    with pytest.raises(AssertionError, match="elaborated"):
        write_verilog(MultiplyAccumulate(other), "mac", tmp_path, cache_key=repr(other))
    monkeypatch.undo()
    assert write_verilog(MultiplyAccumulate(other), "mac", tmp_path,
                         cache_key=repr(other)).read_text() != text

"""The ``rowtrack`` command line and the harness's configuration errors."""

import json
import subprocess
import sys
import types

import pytest

from emulator.cli import main
from hdl.pose.mac import MultiplyAccumulate
from emulator.hdl_sim import runner as cocotb_runner


def rowtrack(*args):
    return subprocess.run([sys.executable, "-m", "emulator.cli", *args],
                          capture_output=True, text=True)


def test_version_and_help():
    version = rowtrack("--version")
    assert version.returncode == 0 and version.stdout.startswith("rowtrack ")
    help_text = rowtrack("--help")
    assert help_text.returncode == 0
    for command in ("run", "verilog", "bench"):
        assert command in help_text.stdout


def test_verilog_writes_block_and_sidecar(tmp_path):
    assert main(["verilog", "mac", "-o", str(tmp_path)]) == 0
    assert "module mac(" in (tmp_path / "mac.v").read_text()
    sidecar = json.loads((tmp_path / "mac.json").read_text())
    assert sidecar["latency"] == MultiplyAccumulate.latency
    assert {p["name"] for p in sidecar["ports"]} >= {"i__valid", "i__payload", "o__ready"}


def test_unknown_names_fail_cleanly():
    result = rowtrack("verilog", "nosuchblock")
    assert result.returncode == 2
    assert "unknown block 'nosuchblock'" in result.stderr and "Traceback" not in result.stderr
    result = rowtrack("bench", "--only", "nosuchbench")
    assert result.returncode == 2 and "unknown benchmark 'nosuchbench'" in result.stderr


def test_bench_reports_measured_latency():
    result = rowtrack("bench", "--only", "fixed", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert figures["fixed.mac.latency_clocks"] == MultiplyAccumulate.latency
    assert figures["fixed.mac.pairs_per_clock"] == 1.0
    assert figures["fixed.mac.dsp48"] >= 1


def test_unknown_simulator_is_a_clear_error(monkeypatch):
    monkeypatch.setenv("SIM", "modelsim")
    with pytest.raises(ValueError, match="SIM must be one of verilator, icarus, not 'modelsim'"):
        cocotb_runner.simulator_from_env()


def test_missing_simulator_tool_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(cocotb_runner.shutil, "which", lambda tool: None)
    with pytest.raises(cocotb_runner.SimulatorSetupError, match="needs 'iverilog' on PATH"):
        cocotb_runner.run_cocotb(object(), name="mac", sim="icarus",
                                 test_module="sim_tests.pose.mac.mac_bench")


def test_bench_keys_are_prefixed_except_declared_extras(monkeypatch):
    from emulator import bench
    fake = types.ModuleType("fake_bench")
    fake.EXTRA_PREFIXES = ("host",)
    fake.measure = lambda: {"lut": 5, "host.packets_ok": 7}
    fake.report = lambda figures: "\n".join(f"{k}={v}" for k, v in sorted(figures.items()))
    monkeypatch.setitem(sys.modules, "fake_bench", fake)
    monkeypatch.setitem(bench.BENCHES, "top", "fake_bench")
    figures = bench.measure("top")
    assert figures == {"top.lut": 5, "host.packets_ok": 7}
    assert "host.packets_ok=7" in bench.report("top", figures) and "lut=5" in bench.report("top", figures)


def test_bench_json_keeps_standard_output_for_the_figures(monkeypatch, capfd):
    """What a benchmark's simulators and compilers print (at the file-descriptor level,
    as a child process would) goes to standard error; standard output is the JSON."""
    import json
    import os
    from emulator import bench
    from emulator.cli import main

    def measure():
        print("build chatter")
        os.write(1, b"make: Entering directory\n")
        return {"lut": 5}
    fake = types.ModuleType("fake_bench")
    fake.measure = measure
    monkeypatch.setitem(sys.modules, "fake_bench", fake)
    monkeypatch.setitem(bench.BENCHES, "fixed", "fake_bench")
    assert main(["bench", "--only", "fixed", "--json"]) == 0
    out, err = capfd.readouterr()
    assert json.loads(out) == {"fixed.lut": 5}
    assert "build chatter" in err and "make: Entering directory" in err


def test_bench_jobs_reach_the_benchmarks_that_take_them(monkeypatch, capfd):
    """``--jobs N`` goes to a benchmark whose ``measure`` takes ``jobs`` (hw_tracking's
    independent runs); the others run as before; fewer than one is a usage error."""
    from emulator import bench
    seen = []
    parallel, serial = types.ModuleType("parallel_bench"), types.ModuleType("serial_bench")
    parallel.measure = lambda jobs=1: seen.append(jobs) or {"runs": jobs}
    serial.measure = lambda: {"lut": 5}
    for name, module in (("fixed", parallel), ("dt", serial)):
        monkeypatch.setitem(sys.modules, module.__name__, module)
        monkeypatch.setitem(bench.BENCHES, name, module.__name__)
    assert main(["bench", "--only", "fixed", "--only", "dt", "--jobs", "3", "--json"]) == 0
    assert json.loads(capfd.readouterr().out) == {"fixed.runs": 3, "dt.lut": 5}
    assert seen == [3]
    assert main(["bench", "--only", "fixed", "--jobs", "0"]) == 2
    assert "--jobs must be at least 1, not 0" in capfd.readouterr().err and seen == [3]


def test_hw_tracking_runs_are_keyed_by_rig_motion_and_gain_law(monkeypatch):
    """hw_tracking's ``measure`` keys each (rig, motion, gain law) run's figures the same
    way whichever way the runs are spread (``jobs``); ``jobs`` < 1 is refused."""
    from emulator.benches import hw_tracking
    monkeypatch.setattr(hw_tracking, "_measure_run",
                        lambda rig, motion, gain, progress=False: {"gain": gain})
    figures = hw_tracking.measure(rigs=("r",), motions=("paper",))
    assert figures == {f"r.paper.{prefix}gain": gain
                       for gain, prefix in hw_tracking.GAINS.items()}
    with pytest.raises(ValueError, match="jobs must be at least 1, not 0"):
        hw_tracking.measure(rigs=("r",), motions=("paper",), jobs=0)


def test_run_rejects_bad_input_in_a_real_process(tmp_path):
    """``rowtrack run`` as a process: exit 2, one message, no traceback, nothing built
    (sim_tests/top/test_run.py checks every message in-process)."""
    result = rowtrack("run", "--dataset", str(tmp_path / "none.npz"), "--out",
                      str(tmp_path / "report"))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "does not exist" in result.stderr and not (tmp_path / "report").exists()
    assert "e2e" in rowtrack("bench", "--list").stdout.split()

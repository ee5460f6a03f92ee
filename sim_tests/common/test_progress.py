"""emulator.progress.timed_phase: a bar estimated from the last run (or a given
fallback), the phase's time written back only when it succeeds."""

import json
import re

import pytest

from emulator.progress import timed_phase


def test_times_are_recorded_and_estimate_the_next_run(tmp_path, capsys):
    record = tmp_path / "build" / "phases.json"
    with timed_phase("Verilog", "elaborate", record, enabled=True):
        pass
    assert "Verilog (no estimate yet)" in capsys.readouterr().err
    seconds = json.loads(record.read_text())["elaborate"]
    assert 0 <= seconds < 5
    with timed_phase("Verilog", "elaborate", record, enabled=True, fallback=99.0):
        pass
    err = capsys.readouterr().err
    assert re.search(r"Verilog: 00:00 elapsed, (about 00:00 left|longer than estimated)", err)
    assert "01:3" not in err            # the recorded time wins over the fallback


def test_a_fallback_estimates_the_first_run(tmp_path, capsys):
    with timed_phase("simulation", "simulate", tmp_path / "phases.json", fallback=99.0):
        pass
    assert re.search(r"simulation: 00:00 elapsed, about 01:3\d left", capsys.readouterr().err)


def test_a_failed_phase_is_not_recorded(tmp_path):
    record = tmp_path / "phases.json"
    with pytest.raises(RuntimeError):
        with timed_phase("build", "build", record, enabled=False):
            raise RuntimeError("no compiler")
    assert not record.exists()

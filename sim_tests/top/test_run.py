"""``rowtrack run`` (emulator/commands/run.py, emulator/report.py) on a tiny
configuration: stereo20 cut to its 32 middle rows, three frames of the papers' motion.

The run judges the hardware path's closed loop against truth and golden (b)
(emulator/e2e.py ``check_closed_loop``); on this cut it misses the 1.5 × golden (b)
target on some axes (docs/e2e.md), so the tiny run fails with those lines and no other.
A deliberately broken forecast (a motion format too coarse, through the job's
``forecast_changes``) fails the bound against the true motion too. The end-to-end test
runs the job with the co-simulation of the closed-loop HDL top; the report tests use a
run without it plus a :class:`emulator.cosim_loop.LoopCosimResult` built here (its
failure cases too). The open-loop slice's choice of rows (``emulator.cosim``, the
open-loop top's co-simulation) is checked on the same run. Every bad-input message is checked before any long work starts. SEED replays a
run.
"""

import dataclasses
import json
import os
import re

import numpy as np
import pytest

from emulator.cli import build_parser, main
from emulator.commands import run as run_command
from emulator.e2e import GOLDEN_B_RATIO, SHARE_OF_MOTION
from emulator.report import cosim_failures, metrics, write_report
from golden.pose_lsq import UNKNOWNS

SEED = int(os.environ.get("SEED", "1"))
TINY = ["--rows", "32", "--frames", "3", "--seed", str(SEED), "--no-progress"]
PLOTS = ("trajectory.png", "steps.png", "step_errors.png", "golden_trajectory.png",
         "confidence.png")
REQUIRED = ("e2e.hdl_mismatches", "e2e.pose_rate_hz", "e2e.pose_capacity_hz",
            "e2e.latency_us",
            "e2e.emulator_rows_per_s", "e2e.hdl_cycles_per_s", "e2e.golden.rms_t_cm.x",
            "e2e.golden.rms_r_deg.z", "e2e.solved_fraction", "e2e.loop_delay_rows",
            "e2e.loop_delay_clocks", "e2e.motion_gain", "e2e.emulator_pose_vs_truth.rms.Tx",
            *(f"e2e.{key}.{name}" for key in (
                "emulator_vs_truth.rms", "emulator_steps_vs_truth.rms",
                "golden_b_vs_truth.rms", "true_motion.rms", "ratio_to_golden_b",
                "share_of_motion", "emulator_vs_float.rms")
              for name in UNKNOWNS))
#: The failure lines of the hardware path's accuracy bounds (emulator/e2e.py).
ACCURACY_LINE = re.compile(r"hardware path (Tx|Ty|Tz|θx|θy|θz): per-row Y RMS \S+ (m|rad) "
                           r"against truth is (\S+) (×|of)")


def _job(*extra):
    return run_command.check_inputs(build_parser().parse_args(["run", *TINY, *extra]))


@pytest.fixture(scope="module")
def outcome():
    print(f"SEED={SEED}")
    return run_command.run_job(_job("--cosim-rows", "0"), progress=False)


SLICE = {"rows": 4, "cameras": 2, "frames": 2, "segments": 4, "dataset_cameras": (0, 1),
         "first_row": 14}


def _with_cosim(outcome, **changes):
    """The run as if it had co-simulated a 2-camera, 2-frame, 4-row slice."""
    job = dataclasses.replace(outcome.job, cosim=SLICE)
    cosim = _cosim_result(outcome, **changes)
    walls = {**outcome.walls, **{f"cosim_{k}": v for k, v in cosim.timings.items()}}
    return dataclasses.replace(outcome, job=job, cosim=cosim, walls=walls)


def _cosim_result(outcome, **changes):
    """A co-simulation result shaped as emulator.cosim_loop makes it: the emulator's first
    records as both sides, with figures of the right kind."""
    from emulator.cosim_loop import LoopCosimResult
    records = {k: np.asarray(v)[:8] for k, v in outcome.emulated.records.items()}
    forecasts = {"row": np.arange(8), "centre": np.zeros((8, 2), dtype=int),
                 "source_row": np.zeros((8, 2), dtype=int)}
    track = {"row": np.arange(8), "y": np.zeros((8, 6), dtype=int)}
    none = np.zeros(0)
    fields = dict(records=records, expected=records, solver=records, solver_expected=records,
                  forecasts=forecasts, forecasts_expected=forecasts, forecasts_ahead=2,
                  track=track, track_expected=track, mismatches=0, solver_mismatches=0,
                  forecast_mismatches=0, track_mismatches=0,
                  first_mismatch=None, solved=3, frames=2, row_sets=8, rows_match=True,
                  slots=np.arange(8), latency_clocks=300, record_latency_clocks=none,
                  forecast_after_record_clocks=none, forecast_lead_clocks=none,
                  clocks_per_row_set=800.0, row_period_clocks=1700.0,
                  engine_stall_clocks=0, status={}, clocks=40_000, wall_s=2.0,
                  timings={"elaborate": 1.0, "build": 2.0, "simulate": 3.0}, clk_hz=100e6,
                  uart_packets_match=True)
    return LoopCosimResult(**{**fields, **changes})


def _accuracy_failures(failures):
    """``{(axis, "golden (b)" or "motion"): measured}`` of the hardware path's accuracy
    failure lines."""
    out = {}
    for line in failures:
        found = ACCURACY_LINE.match(line)
        if found:
            axis, _, value, kind = found.groups()
            out[(axis, "golden (b)" if kind == "×" else "motion")] = float(value)
    return out


def test_the_tiny_run_is_judged_against_truth_and_golden_b(outcome):
    """One failure line per axis and bound the hardware path misses, none for those it
    meets; the solver itself agrees with float64 on its own measurements."""
    m = metrics(outcome)
    for name in UNKNOWNS:
        print(f"{name}: ÷ golden (b) {m[f'ratio_to_golden_b.{name}']:.2f}, ÷ motion "
              f"{m[f'share_of_motion.{name}']:.3f}")
    print("\n".join(outcome.failures))
    missed = {(name, "golden (b)") for name in UNKNOWNS
              if m[f"ratio_to_golden_b.{name}"] > GOLDEN_B_RATIO}
    missed |= {(name, "motion") for name in UNKNOWNS
               if m[f"share_of_motion.{name}"] > SHARE_OF_MOTION}
    found = _accuracy_failures(outcome.failures)
    assert set(found) == missed
    assert len(outcome.failures) == len(found)          # nothing else failed
    for (name, kind), value in found.items():
        key = "ratio_to_golden_b" if kind == "golden (b)" else "share_of_motion"
        assert value == pytest.approx(m[f"{key}.{name}"], rel=1e-2)
    assert m["emulator_vs_truth.rows"] == m["golden_b_vs_truth.rows"] == 2 * 32
    assert m["solved_fraction"] >= 0.95
    assert m["loop_delay_rows"] == 1
    assert m["emulator_rows_per_s"] > 0
    assert m["golden.rms_t_cm.x"] < 1          # the golden tracker does track
    for name in UNKNOWNS:                      # the loop tracks: within 0.2 × the motion
        assert m[f"share_of_motion.{name}"] <= SHARE_OF_MOTION, name


@pytest.fixture(scope="module")
def broken():
    """The same tiny run with a forecast whose level holds 7 fraction bits (1/128 m or
    rad): the filter cannot follow the motion."""
    from hdl.fixed import SQ
    job = dataclasses.replace(_job("--cosim-rows", "0"),
                              forecast_changes={"motion_fmt": SQ(1, 7)})
    return run_command.run_job(job, progress=False)


def test_a_broken_forecast_fails_the_run_per_axis(broken, tmp_path, monkeypatch, capsys):
    """Bounds against the true motion, not only against golden (b): the broken forecast's
    level misses them on several axes (measured Ty 1.0, θx 0.67, Tz 0.32, θz 0.25 of the
    motion at seed 1), each a line with the axis, the measured share and the bound; the
    command exits 1 and the report says FAILED."""
    found = _accuracy_failures(broken.failures)
    print("\n".join(broken.failures))
    motion = {axis for axis, kind in found if kind == "motion"}
    assert len(motion) >= 2
    for axis in motion:
        assert found[(axis, "motion")] > SHARE_OF_MOTION
        assert any(line.startswith(f"hardware path {axis}: ") and
                   line.endswith(f"; bound {SHARE_OF_MOTION}") for line in broken.failures)
    monkeypatch.setattr(run_command, "run_job", lambda job, progress: broken)
    assert main(["run", *TINY, "--cosim-rows", "0", "--out", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert f"FAILED: hardware path {sorted(motion)[0]}: per-row Y RMS" in out
    assert "÷ true motion:" in out and "hardware ÷ golden (b):" in out
    text = (tmp_path / "report.md").read_text()
    assert "**FAILED**" in text and "**MISSED**" in text


def test_the_run_passes_when_the_hardware_path_meets_its_bounds(outcome, tmp_path,
                                                                monkeypatch, capsys):
    """Exit 0 and PASSED when nothing fails: the tiny run's own figures with its
    accuracy failures removed stand for a hardware path that meets the bounds (the
    figures are still printed and reported)."""
    passing = dataclasses.replace(outcome, failures=[])
    monkeypatch.setattr(run_command, "run_job", lambda job, progress: passing)
    assert main(["run", *TINY, "--cosim-rows", "0", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "FAILED" not in out and "hardware ÷ golden (b):" in out
    assert "**PASSED**" in (tmp_path / "report.md").read_text()


def test_report_with_a_cosimulation(outcome, tmp_path):
    done = _with_cosim(outcome)
    write_report(done, tmp_path)
    figures = json.loads((tmp_path / "metrics.json").read_text())
    assert set(REQUIRED) <= set(figures)
    assert figures["e2e.hdl_mismatches"] == 0
    assert figures["e2e.pose_capacity_hz"] == pytest.approx(100e6 / 800)
    # delivered: the cameras' row sets, or the capacity when that is lower
    assert figures["e2e.pose_rate_hz"] == pytest.approx(
        min(figures["e2e.row_sets_needed_per_s"], 100e6 / 800))
    assert figures["e2e.latency_us"] == pytest.approx(3.0)
    assert figures["e2e.hdl_cycles_per_s"] == pytest.approx(20_000)
    assert figures["e2e.speed_ratio"] == pytest.approx(
        outcome.emulated.rows_per_s / (8 * 2 / 2.0))
    for plot in PLOTS:
        assert (tmp_path / plot).stat().st_size > 10_000, plot
    text = (tmp_path / "report.md").read_text()
    assert ("**PASSED**" in text) == (not outcome.failures)
    assert "300 clocks = 3.000 µs" in text
    assert "docs/results/figures.json" in text
    assert done.all_failures() == outcome.failures      # the co-simulation adds none


def test_bench_page_from_the_same_figures(outcome):
    """The e2e benchmark's page renders from the run's metrics, with and without HDL."""
    from emulator.benches.e2e import report
    for run, hdl in ((outcome, "No co-simulation figures in this run"),
                     (_with_cosim(outcome), "300 clocks = 3.000 µs")):
        page = report({**metrics(run), "failures": 0})
        assert hdl in page and "hardware ÷ golden (b)" in page


def test_mismatches_and_silence_are_failures(outcome):
    assert cosim_failures(_cosim_result(outcome)) == []
    where = "record 3 (frame 1, row 2): q[1] HDL 5 ≠ emulator 6"
    failures = cosim_failures(_cosim_result(outcome, mismatches=2, first_mismatch=where))
    assert failures == [f"HDL ↔ emulator: 2 mismatching PS FIFO record field(s); first "
                        f"difference: {where}"]
    for field, what in (("solver_mismatches", "solver record"),
                        ("forecast_mismatches", "forecast row"),
                        ("track_mismatches", "motion track row")):
        failures = cosim_failures(_cosim_result(outcome, **{field: 1}, first_mismatch=where))
        assert failures == [f"HDL ↔ emulator: 1 mismatching {what} field(s); first "
                            f"difference: {where}"]
    failures = cosim_failures(_cosim_result(outcome, mismatches=2, solver_mismatches=3,
                                            first_mismatch=where))
    assert failures == [f"HDL ↔ emulator: 2 mismatching PS FIFO record field(s), 3 "
                        f"mismatching solver record field(s); first difference: {where}"]
    empty = {k: v[:0] for k, v in outcome.emulated.records.items()}
    assert cosim_failures(_cosim_result(outcome, records=empty, solved=0)) == [
        "HDL ↔ emulator: the co-simulated slice produced no pose record"]
    assert cosim_failures(_cosim_result(outcome, uart_packets_match=False)) == [
        "HDL ↔ emulator: the UART packets differ from the emulator's"]
    assert cosim_failures(_cosim_result(outcome, rows_match=False)) == [
        "HDL ↔ emulator: the HDL front end's row sets are not the slice's rows"]
    unsolved, = cosim_failures(_cosim_result(outcome, solved=0))
    assert unsolved.startswith("HDL ↔ emulator: no row set of the co-simulated slice was "
                               "solved, so the solver's arithmetic was not compared")


def test_a_failed_comparison_exits_non_zero_and_says_where(outcome, tmp_path, monkeypatch,
                                                           capsys):
    failing = _with_cosim(outcome, mismatches=1,
                          first_mismatch="record 0 (row 0): flags HDL 1 ≠ emulator 0")
    monkeypatch.setattr(run_command, "run_job", lambda job, progress: failing)
    assert main(["run", *TINY, "--cosim-rows", "0", "--out", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert ("FAILED: HDL ↔ emulator: 1 mismatching PS FIFO record field(s); first "
            "difference: record 0 (row 0)") in out
    assert "**FAILED**" in (tmp_path / "report.md").read_text()


def test_end_to_end_with_the_cosimulation(tmp_path):
    """The whole job with its co-simulation of the closed-loop top: a 6-camera (three
    pairs: the smallest stereo20 slice whose rows solve), 2-frame, 4-row slice on Icarus
    (``make run`` uses Verilator), its rows played at stereo20's own row period (the
    tiny cut stretches ``t_r`` 15-fold): bit-exact FIFO records, solver records, forecast
    rows, the motion track's rows and UART packets, one record per row set, solved rows, a latency. The only
    failure lines are the hardware path's accuracy lines (on this cut it misses the
    golden (b) ratio on some axes)."""
    from golden.rig import preset
    job = dataclasses.replace(
        _job("--cosim-rows", "4", "--cosim-cameras", "6", "--sim", "icarus", "--out",
             str(tmp_path)), cosim_row_period_s=preset("stereo20").cameras[0].t_r)
    done = run_command.run_job(job, progress=False)
    failed = done.all_failures()
    print("\n".join(failed))
    assert len(_accuracy_failures(failed)) == len(failed)
    write_report(done, tmp_path)
    figures = json.loads((tmp_path / "metrics.json").read_text())
    assert set(REQUIRED) <= set(figures)
    assert figures["e2e.hdl_mismatches"] == 0 and figures["e2e.uart_packets_match"]
    assert figures["e2e.hdl_records"] == figures["e2e.hdl_expected"] == 2 * 4, \
        "a record per row set of the 2-frame, 4-row slice"
    assert figures["e2e.hdl_forecast_rows"] == 2 * 4
    assert figures["e2e.hdl_track_rows"] == 2 * 4       # the motion track's Y compared
    assert figures["e2e.hdl_track_mismatches"] == 0
    assert figures["e2e.hdl_solved_records"] > 0      # the solver's arithmetic was compared
    assert figures["e2e.cosim.dataset_cameras"] == list(job.cosim["dataset_cameras"])
    for key in ("e2e.pose_rate_hz", "e2e.latency_us", "e2e.emulator_rows_per_s",
                "e2e.hdl_cycles_per_s"):
        assert figures[key] > 0, key
    for plot in PLOTS:
        assert (tmp_path / plot).is_file(), plot


def test_check_closed_loop_can_pass(outcome):
    """The tolerance check gives no line when every bound is met: the tiny run's figures
    with golden (b) as good as the hardware path on every axis (its synchronized cameras
    fit the row aligner); a front end that cannot form the row sets is one line."""
    from emulator.e2e import check_closed_loop
    figures = dict(outcome.comparison)
    for name in UNKNOWNS:
        figures[f"golden_b_vs_truth.rms.{name}"] = figures[f"emulator_vs_truth.rms.{name}"]
        figures[f"ratio_to_golden_b.{name}"] = 1.0
    assert check_closed_loop(figures) == []
    assert figures["front_end.trigger_skew_rows"] == 0
    assert figures["front_end.skew_rows_held"] == 1
    assert figures["front_end.shortfall"] is None
    figures["solved_fraction"] = 0.5
    assert check_closed_loop(figures) == [
        "hardware path: 50.0% of the rows of frames ≥ 1 solved, below 95%"]
    figures.update({"solved_fraction": 1.0, "front_end.shortfall": "skew beyond the buffer"})
    assert check_closed_loop(figures) == [
        "front end: skew beyond the buffer; the hardware path assumes row sets this front "
        "end cannot form"]


def test_a_dataset_runs_the_same_closed_loop(outcome, tmp_path):
    """--dataset (a file another program could have written) goes through the same
    closed loop from the dataset's ground truth: its first two frames give the simulated
    run's levels of frame 1 bit for bit."""
    path = tmp_path / "clip.npz"
    outcome.dataset.save(path)
    job = run_command.check_inputs(build_parser().parse_args(
        ["run", "--dataset", str(path), "--frames", "2", "--cosim-rows", "0",
         "--no-progress"]))
    done = run_command.run_job(job, progress=False)
    frame, _, level = done.hardware.levels()
    assert set(frame) == {1}
    full_frame, _, full_level = outcome.hardware.levels()
    np.testing.assert_array_equal(level, full_level[full_frame == 1])
    assert done.comparison["emulator_vs_truth.rows"] == 32


def test_a_dataset_without_ground_truth_is_refused(outcome, tmp_path, monkeypatch, capsys):
    """The loop starts from the true motion of the first tracked row: a dataset without
    ground-truth poses gets one clear message, before any long work."""
    path = tmp_path / "no_truth.npz"
    cameras = [dataclasses.replace(c, rotation=np.full_like(c.rotation, np.nan),
                                   position=np.full_like(c.position, np.nan))
               for c in outcome.dataset.cameras]
    dataclasses.replace(outcome.dataset, cameras=cameras).save(path)
    monkeypatch.setattr(run_command, "run_job", lambda *a, **k: pytest.fail("work started"))
    assert main(["run", "--dataset", str(path), "--cosim-rows", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rowtrack run: error: --dataset '{path}': the dataset has no "
                          f"ground-truth pose for row 0 of frames 0 and 1")
    assert "Traceback" not in err


def test_a_dataset_run_names_its_file_and_reports_the_slice(outcome, tmp_path):
    """--dataset: the report names the file (it once embedded the whole Dataset's repr,
    120 kB of arrays) and says which cameras and rows the slice played."""
    path = tmp_path / "clip.npz"
    outcome.dataset.save(path)
    job = run_command.check_inputs(build_parser().parse_args(
        ["run", "--dataset", str(path), "--cosim-rows", "0", "--no-progress"]))
    done = _with_cosim(dataclasses.replace(outcome, job=job))
    write_report(done, tmp_path / "report")
    text = (tmp_path / "report" / "report.md").read_text()
    assert f"dataset `{path}`" in text
    assert "Dataset(" not in text and "array(" not in text
    assert len(text) < 20_000
    assert "(dataset cameras 0, 1) × 2 frames × rows 14–17" in text
    assert "1.0 s / 2.0 s / 3.0 s" in text


def _flat(dataset):
    """``dataset`` with every row grey: no confident measurement anywhere."""
    from types import SimpleNamespace
    return SimpleNamespace(rig=dataset.rig, cameras=[
        SimpleNamespace(rows=np.full_like(c.rows, 128), time=c.time) for c in dataset.cameras])


def test_the_slice_plays_the_rows_the_emulator_solves_most(outcome):
    from emulator.cosim import slice_params, solving_window
    from emulator.pipeline import run
    from types import SimpleNamespace
    _, config, chosen = slice_params(outcome.dataset.rig, 6, 4, 12)
    first, solved = solving_window(config, outcome.dataset, chosen, 3, 4)
    records = run(config, SimpleNamespace(cameras=[outcome.dataset.cameras[k]
                                                   for k in chosen]), 3).records
    ok = np.asarray(records["flags"]) == 0
    per_row = np.bincount(np.asarray(records["row"])[ok], minlength=32)
    best = max(per_row[r:r + 4].sum() for r in range(32 - 3))
    assert solved == best > 0
    assert per_row[first:first + 4].sum() == best


def test_no_solving_window_is_one_line(outcome):
    from emulator import cosim
    _, config, chosen = cosim.slice_params(outcome.dataset.rig, 6, 4, 12)
    with pytest.raises(cosim.NoSolvingWindow, match=r"the emulator solves no row set of "
                                                    r"cameras \[.*\] in frames 0–2"):
        cosim.solving_window(config, _flat(outcome.dataset), chosen, 3, 4)



# --- bad input: a clear message, exit 2, before any long work ---------------------------

def _rig_file(tmp_path, cameras, **defaults):
    import yaml
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"name": "bad", "allow_unobservable": True,
                                    "defaults": {"width": 64, "height": 32, **defaults},
                                    "cameras": cameras}))
    return str(path)


def _bad_dataset(tmp_path):
    path = tmp_path / "old.npz"
    np.savez(path, format=np.array("rowtrack-rs-dataset"), version=np.array(99))
    return str(path)


BAD_INPUTS = {
    "missing dataset": (lambda p: ["--dataset", str(p / "none.npz")],
                        "dataset '.*none.npz' does not exist"),
    "dataset version": (lambda p: ["--dataset", _bad_dataset(p)],
                        "has dataset version 99; this reader supports version 1"),
    "impossible timing": (lambda p: ["--rig", _rig_file(p, [{"name": "a"}], fps=120,
                                                        t_e=0.01)],
                          "infeasible timing"),
    "no stereo overlap": (lambda p: ["--rig", _rig_file(
        p, [{"name": "a"}, {"name": "b", "yaw_deg": 90}], width=640)],
        r"cannot run on the hardware pipeline: .*cameras \[0, 1\] have no rectified stereo"),
    "rows too narrow": (lambda p: ["--rig", _rig_file(
        p, [{"name": "a"}, {"name": "b", "position": [0.1, 0.0, 0.0]}])],
                        "cannot run on the hardware pipeline: .*width 64 leaves 0 columns"),
    "preset without pairs": (lambda p: ["--rig", "radial4"], "no rectified stereo partner"),
    "unknown rig": (lambda p: ["--rig", "nine"], "must be one of stereo20"),
    "one frame": (lambda p: ["--frames", "1"], "at least 2 frames"),
    "negative duration": (lambda p: ["--duration", "-1"], "--duration must be a positive"),
    "too few rows": (lambda p: ["--rows", "2"], "--rows must be between 3"),
    "cosim rows": (lambda p: ["--rows", "32", "--cosim-rows", "33"],
                   "--cosim-rows must be between 1 and the 32 rows per frame"),
    "cosim cameras": (lambda p: ["--cosim-cameras", "21"],
                      "--cosim-cameras must be between 1 and the 20 cameras"),
    "cosim odd cameras": (lambda p: ["--cosim-cameras", "3"],
                          "--cosim-cameras 3: cameras must be an even number .*whole stereo "
                          "pairs"),
    "cosim frames": (lambda p: ["--frames", "3", "--cosim-frames", "4"],
                     "--cosim-frames must be between 2 and the 3 frames"),
    "cosim one frame": (lambda p: ["--cosim-frames", "1"],
                        "--cosim-frames must be between 2 and the 4 frames in the run, "
                        "not 1"),
    "cosim rows off the frame": (lambda p: ["--rig", "stereo8", "--cosim-rows", "6"],
                                 "--cosim-rows 6: rows 6: a frame of the cut rig lasts 7.5 "
                                 "of its row periods"),
    "dataset and rig": (lambda p: ["--dataset", "x.npz", "--rig", "stereo20"],
                        "--rig applies to a simulated run, not to --dataset"),
    "out is a file": (lambda p: ["--out", _bad_dataset(p)], "exists and is not a directory"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_reported_before_long_work(case, tmp_path, monkeypatch, capsys):
    arguments, message = BAD_INPUTS[case]
    monkeypatch.setattr(run_command, "run_job", lambda *a, **k: pytest.fail("work started"))
    assert main(["run", *arguments(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rowtrack run: error: ") and "Traceback" not in err
    assert re.search(message, err), err


@pytest.mark.parametrize("arguments", [["--sim", "ghdl"], ["--frames", "-1"],
                                       ["--frames", "3", "--duration", "0.1"],
                                       ["--motion-gain", "matrix"]])
def test_malformed_options_are_argparse_errors(arguments, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", *arguments])
    assert exc.value.code == 2


def test_a_golden_loss_fails_the_run(outcome):
    """The golden tracker's status reaches the run: a lost golden tracker is a failure
    line (so `rowtrack run` exits 1 and the report says FAILED), and metrics.json says
    when."""
    from golden.tracking_status import TrackingStatus
    assert not any("golden tracker" in f for f in outcome.all_failures())
    assert metrics(outcome)["golden.status"] in ("tracking", "degraded")
    assert metrics(outcome)["golden.lost_at_ms"] is None
    status = outcome.golden.status.copy()
    lost_from = np.flatnonzero(outcome.golden.tracked)[10]
    status[lost_from:] = TrackingStatus.LOST
    lost = dataclasses.replace(outcome, golden=dataclasses.replace(outcome.golden,
                                                                   status=status))
    failures = [f for f in lost.all_failures() if f.startswith("golden tracker: tracking lost")]
    assert len(failures) == 1
    m = metrics(lost)
    assert m["golden.status"] == "lost"
    assert m["golden.lost_at_ms"] == pytest.approx(
        1000 * (outcome.golden.times[lost_from] - outcome.golden.times[0]))
    assert "status lost" in lost.summary()


def test_the_benchmark_scores_the_run_s_closed_loop(outcome):
    """``rowtrack bench --only hw_tracking`` runs the same function on a dataset and
    scores the same quantities: its figures equal the run's, golden (b)'s too (its
    ``golden.metrics.evaluate`` figures are the run's Y from golden (b)'s trajectory)."""
    from emulator.benches.hw_tracking import golden_b, hardware_path
    bench = hardware_path(outcome.dataset)
    bench.update(golden_b(outcome.dataset, bench["loop_delay_rows"]))
    m = metrics(outcome)
    assert bench["loop_delay_rows"] == m["loop_delay_rows"]
    assert bench["solved_fraction"] == m["solved_fraction"]
    for k, axis in enumerate("xyz"):
        t, r = UNKNOWNS[k], UNKNOWNS[k + 3]
        assert bench[f"rms_t_cm.{axis}"] == pytest.approx(100 * m[f"emulator_vs_truth.rms.{t}"])
        assert bench[f"rms_r_rad.{axis}"] == pytest.approx(m[f"emulator_vs_truth.rms.{r}"])
        assert bench[f"step_rms_t_cm.{axis}"] == pytest.approx(
            100 * m[f"emulator_steps_vs_truth.rms.{t}"])
        assert bench[f"golden_b_rms_t_cm.{axis}"] == pytest.approx(
            100 * m[f"golden_b_vs_truth.rms.{t}"], rel=1e-6)
        assert bench[f"golden_b_rms_r_rad.{axis}"] == pytest.approx(
            m[f"golden_b_vs_truth.rms.{r}"], rel=1e-6)


def test_the_benchmark_does_not_judge_against_a_golden_b_that_lost_the_motion():
    """A ratio to golden (b) is evidence only where golden (b) has not lost the motion: on
    an axis where its error exceeds the true motion the verdict is "not judged" (the
    board rig's golden (b) with the scalar gain diverges to 135 cm while the hardware
    path's 3.8 cm read as "0.03 × golden (b), met"); elsewhere the ratio decides, also
    where golden (b) is above the 0.2 × motion of "it tracks"."""
    from emulator.benches.hw_tracking import MOTIONS, verdicts
    f = {}
    for motion in MOTIONS:
        key = f"board.{motion}."
        f[key + "solved_fraction"] = 1.0
        for unit in ("t_cm", "r_rad"):
            for a in "xyz":
                f[f"{key}motion_rms_{unit}.{a}"] = 1.0
                # x: the hardware within the ratio; y: not, against a golden (b) at half
                # the motion (above "it tracks", still a reference); z: golden (b) lost
                # the motion
                f[f"{key}rms_{unit}.{a}"] = {"x": 0.1, "y": 0.9, "z": 0.1}[a]
                f[f"{key}golden_b_rms_{unit}.{a}"] = {"x": 0.1, "y": 0.5, "z": 1.01}[a]
    ratio = {target: met for target, _, met in verdicts(f, "board")
             if "golden (b)" in target}
    assert ratio["paper: Tx ≤ 1.5 × golden (b)"] is True
    assert ratio["paper: Ty ≤ 1.5 × golden (b)"] is False
    assert ratio["paper: Tz ≤ 1.5 × golden (b)"] is None
    assert ratio["head: θz ≤ 1.5 × golden (b)"] is None


def test_the_benchmark_judges_head_motion_against_paper_motion_and_each_estimate():
    """Issue 16's "head motion within 1.5 × of the paper-motion figures", per axis and per
    estimate: the motion track's keys (unprefixed), or the filter level's (``level_``)."""
    from emulator.benches.hw_tracking import verdicts
    f = {}
    for motion, track, level in (("paper", 1.0, 1.0), ("head", 1.6, 1.2)):
        key = f"board.{motion}."
        f[key + "solved_fraction"] = 1.0
        for unit in ("t_cm", "r_rad"):
            for a in "xyz":
                f[f"{key}motion_rms_{unit}.{a}"] = 100.0
                f[f"{key}golden_b_rms_{unit}.{a}"] = 1.0
                f[f"{key}rms_{unit}.{a}"] = track
                f[f"{key}level_rms_{unit}.{a}"] = level
    head = {estimate: {target: met for target, _, met in verdicts(f, "board", "", estimate)
                       if "paper motion's" in target}
            for estimate in ("", "level_")}
    assert len(head[""]) == 6
    assert head[""]["head: Tx ≤ 1.5 × the paper motion's"] is False      # 1.6 ×
    assert head["level_"]["head: θz ≤ 1.5 × the paper motion's"] is True  # 1.2 ×


def test_the_lanes_in_the_loop_equal_the_float_matcher_and_can_fail(outcome):
    """Level 2 of the lanes inside the closed loop: on the tiny run within the stated
    tolerances (measured 99.5 % of 2,241 well-textured shifts within 1/16 px, worst
    0.155 px, seed 1); with two cameras' measurements swapped the check fails and says
    where."""
    from emulator.e2e import check_closed_loop, lane_agreement
    m = metrics(outcome)
    print({k: v for k, v in m.items() if k.startswith("lanes.")})
    assert not any(line.startswith("lanes") for line in outcome.failures)
    assert m["lanes.well_textured"] > 1000
    k = outcome.job.config.segments
    temporal = list(outcome.emulated.temporal)
    for start in range(0, len(temporal), outcome.job.config.router.cameras * k):
        temporal[start:start + 2 * k] = temporal[start + k:start + 2 * k] + \
            temporal[start:start + k]
    swapped = dataclasses.replace(outcome.hardware, result=dataclasses.replace(
        outcome.emulated, temporal=temporal))
    figures, where = lane_agreement(swapped, outcome.dataset)
    lines = [line for line in check_closed_loop(
        {**outcome.comparison, **{f"lanes.{key}": v for key, v in figures.items()},
         "lanes.worst_at": "frame {}, row {}, camera {}, segment {}".format(*where)})
        if line.startswith("lanes")]
    print(lines)
    assert lines and all(re.search(r"camera [01], segment", line) for line in lines)


def test_rows_cut_a_rig_with_vertical_blanking():
    """stereo8-board reads out over 80 % of its frame period: the cut keeps the frame
    period, blanking and readout time (it took 1/(fps·rows) per row and was infeasible)."""
    from golden.rig import preset
    rig = preset("stereo8-board")
    cut = run_command._cut_rows(rig, 96)
    for before, after in zip(rig.cameras, cut.cameras):
        assert after.height == 96
        assert after.fps == before.fps and after.t_f == before.t_f
        assert after.t_r * 96 == pytest.approx(before.t_r * before.height, rel=1e-12)


def test_the_information_gain_runs_the_emulator_model_beside_golden_b_with_it():
    """``--motion-gain information --cosim-rows 0``: the hardware path's filter and golden
    (b) both take the information gain, and the report says so."""
    job = _job("--motion-gain", "information", "--cosim-rows", "0")
    informed = run_command.run_job(job, progress=False)
    m = metrics(informed)
    assert m["motion_gain"] == "information"
    assert informed.hardware.forecast.motion_gain == "information"
    assert informed.golden_b.params["motion_gain"] == "information"
    assert "information gain" in informed.summary()
    assert m["solved_fraction"] > 0.9
    print({k: m[f"emulator_vs_truth.rms.{k}"] for k in UNKNOWNS})

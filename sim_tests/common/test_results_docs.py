"""``docs/results/`` comes only from ``rowtrack bench``: every page is exactly what its
benchmark renders from the figures in ``docs/results/figures.json`` (apart from the line
that says when it was measured), so a hand edit of a page, or a figure that changed
without its page, fails here."""

import difflib
import json
import shutil
from pathlib import Path

import pytest

from emulator import bench
from emulator.cli import main

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"


@pytest.mark.parametrize("name", bench.names())
def test_results_page_is_its_rendering_from_the_figures(name):
    figures = json.loads((RESULTS / "figures.json").read_text())
    text = (RESULTS / f"{name}.md").read_text()
    measured = bench.page_measured_line(text)
    assert measured, f"docs/results/{name}.md has no measurement line"
    expected = bench.report(name, figures, measured)
    diff = list(difflib.unified_diff(text.splitlines(), expected.splitlines(), "page",
                                     "rendering", lineterm="", n=0))
    assert not diff, (f"docs/results/{name}.md is not its rendering from figures.json "
                      f"(a hand edit, or figures without their page): rerun `rowtrack "
                      f"bench --only {name} --write-docs docs/results`\n"
                      + "\n".join(diff[:20]))


def test_render_docs_undoes_a_hand_edit_and_keeps_the_measurement_line(tmp_path):
    for name in ("figures.json", "fixed.md"):
        shutil.copy(RESULTS / name, tmp_path / name)
    original = (tmp_path / "fixed.md").read_text()
    (tmp_path / "fixed.md").write_text(original.replace("|", "| edited", 1))
    assert main(["bench", "--only", "fixed", "--render-docs", str(tmp_path)]) == 0
    assert (tmp_path / "fixed.md").read_text() == original


def test_render_docs_needs_a_measured_page(tmp_path, capsys):
    shutil.copy(RESULTS / "figures.json", tmp_path / "figures.json")
    (tmp_path / "fixed.md").write_text("a page without its measurement line\n")
    assert main(["bench", "--only", "fixed", "--render-docs", str(tmp_path)]) == 2
    assert "has no measurement line" in capsys.readouterr().err


def test_write_docs_replaces_all_old_figures_of_a_benchmark(tmp_path, monkeypatch):
    """A figure the benchmark no longer reports does not linger in figures.json; other
    benchmarks' figures stay."""
    (tmp_path / "figures.json").write_text(json.dumps(
        {"fixed.gone": 1, "fixed.kept": 2, "simulator.other": 3}))
    monkeypatch.setattr(bench, "measure", lambda name, jobs=1: {"fixed.kept": 5, "fixed.new": 6})
    monkeypatch.setattr(bench, "report", lambda name, figures, measured=None: "page\n")
    assert main(["bench", "--only", "fixed", "--write-docs", str(tmp_path), "--json"]) == 0
    assert json.loads((tmp_path / "figures.json").read_text()) == {
        "fixed.kept": 5, "fixed.new": 6, "simulator.other": 3}

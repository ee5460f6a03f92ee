"""Dependencies run one way: golden ← hdl ← emulator ← sim_tests.

golden/ (the float reference) imports nothing of ours; hdl/ may import golden/ (the
maths its constants come from); emulator/ may import hdl/ and golden/; nothing in
golden/, hdl/ or emulator/ imports sim_tests/ or names one of its modules for a
simulator to load. The imports are parsed, not executed, and every break is reported
with its file and line.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("golden", "hdl", "emulator", "sim_tests")
#: What each product package must not depend on.
FORBIDDEN = {"golden": {"hdl", "emulator", "sim_tests"},
             "hdl": {"emulator", "sim_tests"},
             "emulator": {"sim_tests"}}


def _imported(tree, package, parts):
    """``(line, top-level package)`` of every import in a module of ``package`` whose
    path below the root is ``parts`` (relative imports resolved against it)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = parts[:len(parts) - node.level]
                yield node.lineno, (base[0] if base else package)
            elif node.module:
                yield node.lineno, node.module.split(".")[0]


def _named_modules(tree):
    """``(line, name)`` of string constants that name a module of one of our packages
    (e.g. a cocotb test module handed to the runner)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            head = node.value.split(".")[0]
            if head in PACKAGES and "." in node.value and " " not in node.value:
                yield node.lineno, head


def breaks(root=ROOT):
    """Every dependency that breaks the rule, as ``"file:line: what"``."""
    found = []
    for package, forbidden in FORBIDDEN.items():
        for path in sorted((root / package).rglob("*.py")):
            tree = ast.parse(path.read_text(), filename=str(path))
            where = path.relative_to(root)
            for line, name in _imported(tree, package, where.with_suffix("").parts):
                if name in forbidden:
                    found.append(f"{where}:{line}: {package}/ imports {name}/")
            for line, name in _named_modules(tree):
                if name in forbidden:
                    found.append(f"{where}:{line}: {package}/ names a module of {name}/")
    return found


def test_dependencies_run_one_way():
    found = breaks()
    assert not found, "dependencies must run golden ← hdl ← emulator ← sim_tests:\n" + \
        "\n".join(found)


@pytest.mark.parametrize("package, text, message", [
    ("golden", "from hdl.checks import check_int\n", "golden/bad.py:1: golden/ imports hdl/"),
    ("hdl", "import numpy\n\nfrom emulator import packets\n",
     "hdl/bad.py:3: hdl/ imports emulator/"),
    ("emulator", "def f():\n    from sim_tests.common import x\n",
     "emulator/bad.py:2: emulator/ imports sim_tests/"),
    ("emulator", "RUN = dict(test_module='sim_tests.top.rowtrack_top.top_bench')\n",
     "emulator/bad.py:1: emulator/ names a module of sim_tests/"),
])
def test_a_break_is_named_with_its_file_and_line(tmp_path, package, text, message):
    for name in FORBIDDEN:
        (tmp_path / name).mkdir()
    (tmp_path / package / "bad.py").write_text(text)
    assert breaks(tmp_path) == [message]


def test_relative_imports_stay_inside_their_package(tmp_path):
    for name in FORBIDDEN:
        (tmp_path / name).mkdir()
    (tmp_path / "emulator" / "sub").mkdir()
    (tmp_path / "emulator" / "sub" / "ok.py").write_text("from ..pipeline import run\n")
    assert breaks(tmp_path) == []


#: Modules of parameters: every ``params.py`` and ``*_params.py`` of hdl/, and the
#: pipeline configuration built from them.
PARAMS_MODULES = sorted(
    ".".join(path.relative_to(ROOT).with_suffix("").parts)
    for path in (ROOT / "hdl").rglob("*.py")
    if path.stem == "params" or path.stem.endswith("_params")) + ["hdl.pipeline_config"]


def test_parameters_load_without_amaranth():
    """Parameters are plain Python (STYLE.md), so the models and the configuration read
    them without the HDL: importing any of them, in a fresh interpreter, loads no
    Amaranth module."""
    import subprocess
    import sys
    assert len(PARAMS_MODULES) >= 8, PARAMS_MODULES
    script = ("import importlib, sys\n"
              f"for name in {PARAMS_MODULES!r}:\n"
              "    importlib.import_module(name)\n"
              "    loaded = sorted(m for m in sys.modules if m.split('.')[0] == 'amaranth')\n"
              "    assert not loaded, f'{name} loads {loaded[:3]}'\n")
    run = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr.strip().splitlines()[-1]

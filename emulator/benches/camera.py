"""Benchmark of the camera front end (issue 6): throughput and latency measured on the
generated Verilog with cocotb + Verilator, resources from synth_xilinx.

The simulation is the ``performance`` test of ``emulator/benches/camera_cocotb.py``: eight
cameras with 640-pixel rows, PCLK as fast as the system clock (each camera at its own
phase), no backpressure, every set checked against the emulator cycle by cycle and
every row against the pixels sent.
"""

import json
import math
import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

from emulator.synth import XC7Z020, synth_report

#: The configuration the issue's figures are for: 8 cameras, 640-pixel rows.
N_CAMERAS = 8
SEED = 6

#: Targets from issue 6.
LATENCY_TARGET = 16
RATE_TARGET = 1.0


def _params():
    from hdl.front_end.params import CameraParams
    return CameraParams(n_cameras=N_CAMERAS, max_width=640, max_height=480)


@contextmanager
def _stdout_to_stderr():
    """Send the simulator's output (printed by child processes to file descriptor 1)
    to stderr, so that ``rowtrack bench --json`` prints nothing but the JSON."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def _simulate(params):
    from hdl.front_end.camera_sync import CameraFrontEnd
    from emulator.hdl_sim.runner import run_cocotb
    with tempfile.TemporaryDirectory() as tmp, _stdout_to_stderr():
        path = Path(tmp) / "figures.json"
        run_cocotb(CameraFrontEnd(params), name="camera_front", tag="perf8", sim="verilator",
                   test_module="emulator.benches.camera_cocotb",
                   testcase=["performance"], seed=SEED,
                   extra_env={"ROWTRACK_FIGURES": str(path)})
        return json.loads(path.read_text())


def measure():
    from hdl.front_end.camera_input import CameraInput
    from hdl.front_end.camera_sync import CameraFrontEnd, CameraSync
    from hdl.front_end.row_aligner import RowAligner
    params = _params()
    sim = _simulate(params)
    one = synth_report(CameraInput(params, camera=0, domain="pclk"), "camera_input")
    sync = synth_report(CameraSync(params), "camera_sync8")
    aligner = synth_report(RowAligner(params), "row_aligner8")
    total = synth_report(CameraFrontEnd(params), "camera_front8")
    n = params.n_cameras
    return {
        "latency_clocks": round(sim["latency_clocks"], 2),
        "px_per_clock": round(sim["px_per_clock"], 4),
        "skew_error_clocks": round(sim["skew_error_clocks"], 2),
        "row_sets_checked": sim["sets"],
        "lut_per_camera": math.ceil(total["lut"] / n),
        "ff_per_camera": math.ceil(total["ff"] / n),
        "bram36_per_camera": total["bram36"] / n,
        "input.lut": one["lut"], "input.ff": one["ff"], "input.bram36": one["bram36"],
        "input.lut_levels": one["lut_levels"],
        "sync.lut": sync["lut"], "sync.ff": sync["ff"], "sync.lut_levels": sync["lut_levels"],
        "aligner.lut": aligner["lut"], "aligner.ff": aligner["ff"],
        "aligner.lut_levels": aligner["lut_levels"],
        "front_end.lut": total["lut"], "front_end.ff": total["ff"],
        "front_end.bram36": total["bram36"], "front_end.lut_levels": total["lut_levels"],
    }


def report(figures):
    f = figures
    n = N_CAMERAS
    glitch = _params().glitch_pclks
    verdict = lambda ok: "met" if ok else "**missed**"
    rows = "\n".join(f"| {key} | {value} |" for key, value in sorted(f.items()))
    return f"""# Camera front end: sync, DVP inputs, row aligner

`hdl/front_end/camera_sync.py` `CameraFrontEnd` with {n} cameras, 640-pixel rows, default
`CameraParams` (8-bit pixels, 1024-pixel buffer and a 4-row queue per camera, 8-entry
clock-crossing FIFOs, glitch filter of {glitch} PCLKs).

**Throughput and latency** come from the `performance` cocotb test on the generated
Verilog (Verilator): every camera runs its PCLK at the system clock frequency, each at
its own phase, and plays two frames of four 640-pixel rows; downstream is always ready.
Every row set is compared with `emulator/front_end/camera_sync.py` cycle by cycle, every row with
the pixels the cameras sent.

* `px_per_clock`: pixels per system clock per camera lane while a row set streams
  (the slowest set; {verdict(f['px_per_clock'] >= RATE_TARGET)} against the target
  of {RATE_TARGET} with {n} cameras).
* `latency_clocks`: system clocks from the PCLK edge that samples a row's last pixel at
  the pins of the latest camera to the clock edge that takes the set's last pixel from
  the aligner, including the {glitch}-PCLK glitch look-ahead, the input register, the
  clock crossing and the output buffer (worst set; {verdict(f['latency_clocks'] <=
  LATENCY_TARGET)} against the target of ≤ {LATENCY_TARGET}).
* `skew_error_clocks`: largest difference between a measured frame or row skew and the
  skew between the cameras' PCLK edges that wrote the events into the crossings.

**Resources** from Yosys `synth_xilinx -family xc7` (xc7z020 capacity:
{XC7Z020['lut']} LUTs, {XC7Z020['ff']} FFs, {XC7Z020['bram36']} BRAM36). `*_per_camera`
divide the whole front end (inputs, sync, aligner) by {n}; `input.*` is one
`CameraInput` alone, `sync.*` and `aligner.*` the {n}-camera `CameraSync` and
`RowAligner` alone. A RAMB18 counts as half a BRAM36. `lut_levels` is the longest
register-to-register path in LUTs (an estimate of timing; no vendor tool runs here).

| figure | value |
|---|---|
{rows}
"""

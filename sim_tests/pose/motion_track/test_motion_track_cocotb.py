"""The motion track's Verilog (hdl/pose/motion_track.py) against its model on Icarus and
Verilator (:mod:`sim_tests.pose.motion_track.motion_track_bench`): the seeded random
segments of :func:`.stimulus.random_segments` (from reset, restarts at run-time
``frame_rows`` 8, 5 and 0, gaps longer than a frame, the format's ends), and on Verilator
also the rows a real closed loop gives its track (stereo20 cut to 32 rows, 3 frames).
SEED replays the segments (printed)."""

import os
import pickle

import pytest

from emulator.hdl_sim.runner import run_cocotb
from hdl.pose.motion_track import MotionTrack

from sim_tests.pose.motion_track.stimulus import (RING, expected, loop_rows,
                                                  random_segments)
from sim_tests.pose.tracking_loop.stimulus import CACHE

SEED = int(os.environ.get("SEED", "31"))
BENCH = "sim_tests.pose.motion_track.motion_track_bench"


def _run(sim, params, depth, segments, tag):
    outputs, counts = expected(params, depth, segments)
    CACHE.mkdir(parents=True, exist_ok=True)
    path = CACHE / f"motion_track_{tag}.pkl"
    with open(path, "wb") as f:
        pickle.dump({"segments": segments, "outputs": outputs, "counts": counts}, f)
    run_cocotb(MotionTrack(params, depth), name="motion_track", sim=sim, tag=tag,
               test_module=BENCH, extra_env={"TRACK_CASE": str(path)})


@pytest.mark.parametrize("sim", ["icarus", "verilator"])
def test_motion_track_random_segments(sim):
    print(f"SEED={SEED}")
    params, segments = random_segments(SEED)
    _run(sim, params, RING, segments, f"random_{SEED}")


def test_motion_track_closed_loop_rows_verilator():
    params, period, initial, rows, _ = loop_rows()
    _run("verilator", params, period, [(period, initial, rows)], "closed_loop")

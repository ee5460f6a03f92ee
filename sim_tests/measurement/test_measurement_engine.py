"""The measurement engine's parameters, its model (emulator/measurement/engine.py) and
the row-set fork (hdl/measurement/row_set_fork.py) in the Amaranth simulator, against the fork model,
with and without random valid gaps and ready backpressure. The whole engine runs in the
cocotb bench (sim_tests/measurement/measurement_engine/).

SEED replays a run (printed).
"""

import os
import random
from dataclasses import replace

import numpy as np
import pytest
from amaranth.sim import Simulator

from emulator.measurement.engine import fork_row_sets, row_set_columns, run_engine
from emulator.measurement.router import route
from hdl.front_end.params import CameraParams
from hdl.measurement.engine import MeasurementEngine, default_engine_params
from hdl.measurement.engine_params import EngineParams
from hdl.pose.params import PoseSolverParams
from hdl.measurement.row_set_fork import RowSetFork
from sim_tests.measurement.measurement_engine.stimulus import (engine_params, make_stimulus,
                                                          simulated_dataset, small_rig)
from emulator.hdl_sim.payload import unpack
from sim_tests.front_end.test_camera_input import rejected_components

SEED = int(os.environ.get("SEED", "5"))
CAMERA = CameraParams(n_cameras=4, max_width=256, max_height=6)
SOLVER = PoseSolverParams(slots=16, rows=6)
PAIRS = ((0, 1), (3, 2))


@pytest.fixture(scope="module")
def params():
    return EngineParams.for_cameras(CAMERA, SOLVER, PAIRS)


# --- parameters ---------------------------------------------------------------------------

def test_lanes_take_the_camera_beat(params):
    assert params.aligned_layout() == CAMERA.aligned_layout()
    for lane in (params.temporal, params.stereo):
        assert (lane.width, lane.height) == (CAMERA.max_width, CAMERA.max_height)
    assert params.temporal.segments == 4 and params.stereo.segments == 1
    assert params.count_bits == CAMERA.count_bits
    assert default_engine_params().pairs == ((0, 1), (2, 3))


def test_for_cameras_rejects_what_cannot_match():
    with pytest.raises(TypeError, match="camera must be a CameraParams, not 4"):
        EngineParams.for_cameras(4, SOLVER, PAIRS)
    with pytest.raises(TypeError, match="solver must be a PoseSolverParams"):
        EngineParams.for_cameras(CAMERA, None, PAIRS)
    with pytest.raises(ValueError, match=r"solver.rows must be camera.max_height \(6\), not 480"):
        EngineParams.for_cameras(CAMERA, PoseSolverParams(slots=16), PAIRS)
    with pytest.raises(ValueError, match=r"camera \(max_width 128, max_height 6\) cannot size "
                                         r"a temporal lane with segments=4 and shifts \[-20, 20\]: width 128"):
        EngineParams.for_cameras(CAMERA.replace(max_width=128), SOLVER, PAIRS)
    with pytest.raises(ValueError, match="segments must be an integer at least 1, not 0"):
        EngineParams.for_cameras(CAMERA, SOLVER, PAIRS, segments=0)
    with pytest.raises(ValueError, match=r"solver.slots must be cameras × segments = 8"):
        EngineParams.for_cameras(CAMERA, SOLVER, PAIRS, segments=2)
    with pytest.raises(ValueError, match=r"cameras \[2, 3\] have none"):
        EngineParams.for_cameras(CAMERA, SOLVER, ((0, 1),))
    with pytest.raises(TypeError, match="pairs must be a sequence of"):
        EngineParams.for_cameras(CAMERA, SOLVER, 3)


def test_engine_params_checks(params):
    with pytest.raises(TypeError, match="router must be a RouterParams, not 1"):
        EngineParams(router=1)
    with pytest.raises(ValueError, match="count_bits must be an integer between 1 and 32"):
        params.replace(count_bits=0)
    narrow = params.router.__class__(
        cameras=4, pairs=PAIRS, temporal=params.temporal, solver=SOLVER,
        stereo=params.stereo.replace(width=300))
    with pytest.raises(ValueError, match=r"router.stereo.width must be router.temporal.width "
                                         r"\(256\), not 300"):
        EngineParams(router=narrow)
    # the stereo lanes match the temporal lanes' bits: one descriptor for both
    router = params.router
    sharper = replace(router, stereo=router.stereo.replace(
        descriptor=router.stereo.descriptor.replace(sigma=1.5)))
    with pytest.raises(ValueError, match=r"router.stereo.descriptor must be "
                                         r"router.temporal.descriptor \(DescriptorParams\("):
        EngineParams(router=sharper)
    finer = replace(router, stereo=router.stereo.replace(coeff_frac_bits=12))
    with pytest.raises(ValueError, match=r"router.stereo.coeff_frac_bits must be "
                                         r"router.temporal.coeff_frac_bits \(16\), not 12"):
        EngineParams(router=finer)
    with rejected_components():
        with pytest.raises(TypeError, match="params must be an EngineParams"):
            MeasurementEngine(params.router)
        with pytest.raises(TypeError, match="params must be an EngineParams"):
            RowSetFork(3)


# --- model --------------------------------------------------------------------------------

def _row(camera, row, width, frame=7):
    return [{"data": (camera * 50 + x) & 0xFF, "first": int(x == 0),
             "last": int(x == width - 1), "camera": camera, "frame": frame, "row": row,
             "t_first": 10 * row, "t_last": 0, "flags": 0} for x in range(width)]


def test_row_set_columns_follow_the_aligner(params):
    columns = row_set_columns(params, {1: _row(1, 3, 3), 2: _row(2, 3, 5)})
    assert len(columns) == 5
    assert [c["lane_valid"] for c in columns] == [0b110] * 3 + [0b100] * 2
    assert all(c["missing"] == 0b1001 for c in columns)
    assert columns[1]["lanes"][1]["data"] == 51 and columns[4]["lanes"][1]["data"] == 0
    assert columns[0]["lanes"][0] == dict.fromkeys(columns[0]["lanes"][0], 0)


def test_fork_model_addresses_lanes_and_counts(params):
    on = {"temporal": [1, 2, 3, 4], "stereo": [5, 6], "enable": 1}
    sets = [{k: _row(k, 0, 4) for k in range(4)},
            {0: _row(0, 1, 4), 2: _row(2, 1, 4), 3: _row(3, 1, 4)},
            {k: _row(k, 2, 4) for k in range(4)}]
    fork = fork_row_sets(params, sets, [on, on, dict(on, enable=0)])
    assert fork.tickets == [{"cameras": 0b1111, "pairs": 0b11, "frame": 7, "row": 0},
                            {"cameras": 0b1101, "pairs": 0b10, "frame": 7, "row": 1}]
    assert fork.status == {"row_sets": 3, "dropped": 1, "stereo_skipped": [1, 0]}
    beats, centres = fork.temporal[3]
    assert len(beats) == 8 and centres == [4] * 8
    beats_a, centres, beats_b = fork.stereo[1]          # pair (3, 2): a is camera 3
    assert [b["camera"] for b in beats_a] == [3] * 8 and centres == [6] * 8
    assert [b["camera"] for b in beats_b] == [2] * 8
    assert len(fork.stereo[0][0]) == 4                  # pair (0, 1) only in set 0


@pytest.fixture(scope="module")
def rig_and_dataset():
    rig = small_rig()
    return rig, simulated_dataset(rig, SEED)


def test_engine_model_routes_complete_sets_as_the_row_router(rig_and_dataset):
    """With every set complete and enabled, following tickets gives what grouping the
    measurements by (frame, row) gives (emulator.measurement.router.route)."""
    rig, dataset = rig_and_dataset
    params = engine_params(rig)
    stim = make_stimulus(params, dataset, np.random.default_rng(SEED), faults=False)
    result = run_engine(params, stim.row_sets, stim.configs)
    flat = [m for lane in result.temporal for m in lane]
    assert result.transfers == route(params.router, sorted(flat, key=_order),
                                     [m for lane in result.stereo for m in lane])
    assert len(result.transfers) == len(stim.row_sets) * params.router.solver.slots
    assert any(t["conf"] for t in result.transfers) and any(t["cue"] for t in result.transfers)
    assert result.status["router"]["misaligned"] == 0


def _order(m):
    return m["frame"] - 65536 * (m["frame"] > 32768), m["row"], m["camera"], m["segment"]


# --- the fork in the Amaranth simulator ---------------------------------------------------

def random_row_sets(params, rng, count):
    """Row sets of 1-5 beat rows, cameras present at random (at least one), and their
    configurations (``enable`` 0 for about one set in five)."""
    sets, configs = [], []
    for n in range(count):
        present = [k for k in range(params.cameras) if rng.random() < 0.75] or \
            [rng.randrange(params.cameras)]
        sets.append({k: _row(k, n % 6, rng.randint(1, 5), frame=n // 6) for k in present})
        configs.append({"temporal": [0] * params.cameras, "stereo": [0] * len(params.pairs),
                        "enable": int(rng.random() > 0.2)})
    return sets, configs


def camera_beats(params, beats):
    """A temporal output's beats as plain camera beats (the model's: without ``paired``
    and, with ``follow``, the forecast's ``centre`` and ``source``)."""
    names = [name for name, _ in params.pixel_layout()]
    return [{name: beat[name] for name in names} for beat in beats]


def stereo_beats(params, temporal, j):
    """The beats of pair ``j``'s cameras A and B that go on to its stereo lane: those
    of the rows the fork marked ``paired`` (each row's flag rides on its beats)."""
    return [camera_beats(params, [b for b in temporal[camera] if b["paired"]])
            for camera in params.pairs[j]]


def simulate_fork(params, sets, configs, rng, busy):
    """Play the row sets into a RowSetFork; returns what every output took, the cycles
    the input took a column, and the final status."""
    dut = RowSetFork(params)
    columns = [(column, cfg["enable"], x == 0) for row_set, cfg in zip(sets, configs)
               for x, column in enumerate(row_set_columns(params, row_set))]
    outputs = {"temporal": [[] for _ in dut.temporal], "tickets": [[]]}
    ports = [("temporal", n, port) for n, port in enumerate(dut.temporal)] + \
        [("tickets", 0, dut.tickets)]
    record = {"taken": []}

    def take_outputs(ctx):
        for name, n, port in ports:
                ctx.set(port.ready, 0)
                valid_unready = ctx.get(port.valid)
                ctx.set(port.ready, 1)
                assert ctx.get(port.valid) == valid_unready, f"{name}[{n}].valid follows ready"
                ready = busy or rng.random() < 0.5
                ctx.set(port.ready, ready)
                if ready and ctx.get(port.valid):
                    layout = port.payload.shape()
                    outputs[name][n].append(unpack(layout, ctx.get(port.payload.as_value())))

    async def bench(ctx):
        offering, i, cycle = False, 0, 0
        while i < len(columns):
            assert cycle < 20 * len(columns), "the fork stopped taking columns"
            offering = offering or busy or rng.random() < 0.7
            column, enable, first = columns[i]
            ctx.set(dut.i.valid, offering)
            ctx.set(dut.i.payload, column)
            # enable counts only with a set's first column
            ctx.set(dut.enable, enable if first else rng.randrange(2))
            take_outputs(ctx)
            taken = offering and ctx.get(dut.i.ready)
            if taken:
                record["taken"].append(cycle)
            await ctx.tick()
            cycle += 1
            if taken:
                i, offering = i + 1, False
        ctx.set(dut.i.valid, 0)
        # the fork's input register drains: every set opened, no column left for an output
        while ctx.get(dut.status.row_sets) < len(sets) or \
                any(ctx.get(port.valid) for _, _, port in ports):
            assert cycle < 20 * len(columns), "the fork stopped handing columns on"
            take_outputs(ctx)
            await ctx.tick()
            cycle += 1
        status = ctx.get(dut.status)
        record["status"] = {"row_sets": int(status.row_sets), "dropped": int(status.dropped),
                            "stereo_skipped": [int(v) for v in status.stereo_skipped]}

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return outputs, record


@pytest.mark.parametrize("busy", [True, False], ids=["full_rate", "gaps_and_backpressure"])
def test_fork_matches_model(params, busy):
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    sets, configs = random_row_sets(params, rng, 60)
    outputs, record = simulate_fork(params, sets, configs, rng, busy)
    model = fork_row_sets(params, sets, configs)
    assert outputs["tickets"][0] == model.tickets
    for k, (beats, _) in enumerate(model.temporal):
        assert camera_beats(params, outputs["temporal"][k]) == beats, f"temporal lane {k}"
    for j, (beats_a, _, beats_b) in enumerate(model.stereo):
        got_a, got_b = stereo_beats(params, outputs["temporal"], j)
        assert got_a == beats_a, f"stereo lane {j}, camera a"
        assert got_b == beats_b, f"stereo lane {j}, camera b"
    assert record["status"] == model.status
    assert model.status["dropped"] > 0 and any(model.status["stereo_skipped"])
    if busy:        # one column per clock when nobody stalls
        assert record["taken"] == list(range(len(record["taken"])))

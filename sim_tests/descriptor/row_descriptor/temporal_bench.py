"""cocotb bench for hdl.row_descriptor.RowDescriptor (temporal lane): every measurement
against emulator.row_descriptor.TemporalLaneModel, and its clock cycle at full rate."""

import copy
import os
import random

import cocotb
import numpy as np

from emulator.row_descriptor import TemporalLaneModel
from golden.dataset import Dataset
from emulator.hdl_sim.cocotb_env import load_params, load_sidecar

from emulator.hdl_sim.row_driving import Lane, make_stimulus


#: One model for all tests of a simulation: reset does not clear the lane's reference
#: store, so each test starts from the store the previous one left.
_MODELS = {}
#: Draws of per-row half-widths tried for one that puts a match on a window's edge.
WIDTH_DRAWS = 50


def dataset_rows(params):
    """Rows of camera 0 of the golden simulator's dataset (path from the runner),
    cropped to the lane's height and width from the middle of the image."""
    rows = Dataset.load(os.environ["ROWTRACK_RD_DATASET"]).cameras[0].rows
    y0, x0 = (rows.shape[1] - params.height) // 2, (rows.shape[2] - params.width) // 2
    return rows[:, y0:y0 + params.height, x0:x0 + params.width]


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"],
                    rows=["textured", "faults", "dataset", "square"])
async def temporal_lane_matches_model(dut, traffic, rows):
    params = load_params()
    busy = traffic == "full_rate"
    rng = random.Random(cocotb.RANDOM_SEED)
    np_rng = np.random.default_rng(cocotb.RANDOM_SEED)
    lane = Lane(dut, params, ["i"], rng, busy=busy)
    dut.half_width.value = params.max_half_width      # the built window (driven: Icarus)
    await lane.start()
    data = dataset_rows(params) if rows == "dataset" else None
    beat_rows, centres = make_stimulus(params, rows, np_rng, data)
    beats = [b for row in beat_rows for b in row]
    per_beat = [c for row, c in zip(beat_rows, centres) for _ in row]
    model = _MODELS.setdefault("lane", TemporalLaneModel(params))
    expected = model.run(beats, per_beat)
    await lane.play_all({"i": beat_rows}, centres)
    sent = lane.sources["i"].sent
    if busy and rows != "faults":      # padding a short row holds the input by design
        cycles = [c for c, _ in sent]
        assert cycles == list(range(cycles[0], cycles[0] + len(cycles))), "input bubbles"
    last_cycles = [c for c, b in sent if b["last"]] if rows != "faults" else None
    await lane.check(expected, load_sidecar()["latency"], busy, last_cycles)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def temporal_lane_half_width_per_row(dut, traffic):
    """A random run-time half-width per row, over the whole port (0, below the minimum
    and above the built maximum included: the built maximum), set with each row's
    first beat like the centre."""
    params = load_params()
    busy = traffic == "full_rate"
    print(f"SEED={cocotb.RANDOM_SEED}")
    rng = random.Random(cocotb.RANDOM_SEED)
    np_rng = np.random.default_rng(cocotb.RANDOM_SEED)
    lane = Lane(dut, params, ["i"], rng, busy=busy)
    await lane.start()
    beat_rows, centres = make_stimulus(params, "textured", np_rng)
    beats = [b for row in beat_rows for b in row]
    per_beat = [c for row, c in zip(beat_rows, centres) for _ in row]
    model = _MODELS.setdefault("lane", TemporalLaneModel(params))
    # Widths are drawn until some window is narrow enough for a match to land on its
    # edge, the case this test exists for (trials on a copy: the model keeps its store).
    for _ in range(WIDTH_DRAWS):
        widths = [int(w) for w in np_rng.integers(0, 1 << params.half_width_fmt.width,
                                                  len(beat_rows))]
        per_beat_w = [w for row, w in zip(beat_rows, widths) for _ in row]
        if any(m["edge_hit"] for m in copy.deepcopy(model).run(beats, per_beat, per_beat_w)):
            break
    else:
        raise AssertionError(f"no edge hit in {WIDTH_DRAWS} draws of half-widths")
    expected = model.run(beats, per_beat, per_beat_w)
    for row, centre, width in zip(beat_rows, centres, widths):
        dut.centre.value, dut.half_width.value = centre, width
        await lane.sources["i"].send(row)
    dut.half_width.value = params.max_half_width
    last_cycles = [c for c, b in lane.sources["i"].sent if b["last"]]
    await lane.check(expected, load_sidecar()["latency"], busy, last_cycles)

"""The whole closed-loop top (issue 16) co-simulated against the emulator's closed loop,
bit for bit (:func:`emulator.cosim_loop.closed_loop_cosim`): stereo8 cut to a few rows,
every camera's rows played on the DVP pins, the loop running from reset, every pose
record read from the PS FIFO (flags with the status bits), every solver record (step and
pose), the motion track's ``Y`` of every row and every forecast row the engine took (each
lane's window centre and source row) compared with :func:`emulator.pipeline.run`'s closed loop.

Both runs take many minutes: ``RUN_SLOW=1`` (8 rows × 2 frames, frame 0 and one tracked
frame, on Icarus: about 12 min on an idle core; 24 rows × 3 frames, two tracked frames, on
Verilator). The default suite's co-simulation of the closed-loop top is the end-to-end
job's smaller slice on Icarus (sim_tests/top/test_run.py: three stereo20 pairs, 4 rows × 2
frames, every record, forecast row and track row compared, solved rows among them); the
judge's helpers below run in the default suite. Seed: ``SEED`` (printed).
"""

import os

import numpy as np
import pytest

from golden.rig import preset
from emulator.cosim_loop import cut_rig

SEED = int(os.environ.get("SEED", "1"))
#: The cameras' row period on the pins: stereo8's own (the cut rig stretches ``t_r`` to
#: keep its frame period; the hardware counts row slots by the row order).
ROW_PERIOD_S = preset("stereo8").cameras[0].t_r


def _dataset(rows, frames, seed=SEED):
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    rig = cut_rig(preset("stereo8"), rows)
    return simulate(rig, default_scene_spec(seed), make_trajectory("paper"),
                    frames / rig.cameras[0].fps, seed=seed)


def test_the_cut_rig_keeps_a_whole_number_of_row_periods_per_frame():
    from hdl.pipeline_config import PipelineConfig
    for rows in (24, 32):
        config = PipelineConfig.for_rig(cut_rig(preset("stereo8"), rows), closed_loop=True,
                                        stereo_segments=4)
        assert config.frame_rows == pytest.approx(rows * 600 / 480, abs=1e-9)
        assert config.top.consistency.frame_rows == int(config.frame_rows)


def test_a_rig_cut_to_a_few_rows_compares_only_rows_its_time_format_holds():
    """stereo20 has no blanking: cut to ``rows`` rows a frame is ``rows`` row periods,
    and a camera compared ``Δ`` rows off would need the factor ``rows / (rows − Δ)``.
    The default ``max_row_offset`` stays 16 where the format holds it and shrinks where
    it does not, instead of refusing the rig."""
    from hdl.measurement.consistency_params import ConsistencyParams
    from hdl.pipeline_config import PipelineConfig
    time_max = ConsistencyParams.__dataclass_fields__["time_fmt"].default.max_value
    for rows, offset in ((480, 16), (32, 16), (8, 5), (4, 2)):
        stage = PipelineConfig.for_rig(cut_rig(preset("stereo20"), rows), closed_loop=True,
                                       stereo_segments=4).top.consistency
        assert stage.frame_rows == rows
        assert stage.max_row_offset == offset, rows
        assert rows / (rows - offset) <= time_max < rows / (rows - offset - 1) \
            or offset == 16


def test_a_run_slice_is_its_middle_rows_restamped_to_the_cut_rigs_row_times():
    """:func:`emulator.cosim_loop.slice_dataset`: whole pairs, the middle rows with their
    pixels and truth, the cut rig's row directions (``cy`` moved with the cut) and row
    times (one row period apart, each frame's first row where it was)."""
    from emulator.cosim import slice_rig
    from emulator.cosim_loop import slice_dataset
    dataset = _dataset(32, 2)
    part, chosen, first = slice_dataset(dataset, 4, 8)
    assert chosen == slice_rig(dataset.rig, 4)[1] and first == 12
    t_r = part.rig.cameras[0].t_r
    assert t_r == pytest.approx(dataset.rig.cameras[0].t_r * 4)
    for k, rec in zip(chosen, part.cameras):
        whole, cam = dataset.cameras[k], part.rig.cameras[chosen.index(k)]
        assert cam.cy == dataset.rig.cameras[k].cy - first and cam.height == 8
        np.testing.assert_array_equal(rec.rows, whole.rows[:, 12:20])
        np.testing.assert_array_equal(rec.position, whole.position[:, 12:20])
        np.testing.assert_allclose(rec.time, whole.time[:, :1] + t_r * np.arange(8))
    with pytest.raises(ValueError, match="rows 6: a frame of the cut rig lasts 7.5 of its "
                                         "row periods"):
        slice_dataset(dataset, 4, 6)
    with pytest.raises(ValueError, match="cameras must be an even number"):
        slice_dataset(dataset, 3, 8)


def test_the_verilog_cache_knows_the_built_in_coefficients():
    """Two slices of stereo20 (other pairs chosen at another cut) build tops of equal
    parameters but other coefficient stores; a Verilog cache keyed by the parameters
    alone once co-simulated one with the other's stores (72 mismatching fields)."""
    from emulator.commands.run import _cut_rows
    from emulator.cosim_loop import _design_key, cut_slice
    from hdl.top import board_config
    configs = [board_config(cut_slice(rig, 6, 4)[0])
               for rig in (preset("stereo20"), _cut_rows(preset("stereo20"), 32))]
    assert repr(configs[0].top) == repr(configs[1].top)
    assert not np.array_equal(configs[0].coef_store, configs[1].coef_store)
    assert _design_key(configs[0]) != _design_key(configs[1])
    assert _design_key(configs[0]) == _design_key(board_config(
        cut_slice(preset("stereo20"), 6, 4)[0]))


def _span(values):
    values = np.asarray(values, dtype=float)
    finite = values[np.isfinite(values)]
    return f"{finite.min():.0f}…{finite.max():.0f}" if len(finite) else "none"


def _check(result, frames, rows):
    print(f"SEED={SEED}: {result.row_sets} row sets; {len(result.records['row'])} FIFO, "
          f"{len(result.solver['row'])} solver records ({result.solved} solved), "
          f"{len(result.forecasts['row'])} forecast rows (+{result.forecasts_ahead} ahead) "
          f"compared: {result.mismatches} FIFO + {result.solver_mismatches} solver + "
          f"{result.forecast_mismatches} forecast + {result.track_mismatches} track "
          f"mismatches ({result.first_mismatch}); "
          f"last pixel → PS FIFO ≤ {result.latency_clocks} clocks, → solver record "
          f"{_span(result.record_latency_clocks)} clocks; record → next forecast "
          f"{_span(result.forecast_after_record_clocks)} clocks (offered before it: "
          f"{int(np.isnan(result.forecast_after_record_clocks).sum())}); forecast lead "
          f"{_span(result.forecast_lead_clocks)} clocks; {result.clocks_per_row_set:.0f} "
          f"clocks per row set, row period {result.row_period_clocks:.0f} clocks; engine "
          f"stalls {result.engine_stall_clocks} clocks; {result.clocks} clocks in "
          f"{result.wall_s:.0f} s; {result.status}")
    assert result.rows_match, "the HDL's row sets are not the dataset's rows"
    assert result.row_sets == frames * rows
    assert len(result.records["row"]) == frames * rows
    assert len(result.solver["row"]) == frames * rows
    assert len(result.forecasts["row"]) == frames * rows
    assert result.mismatches == 0, result.first_mismatch
    assert result.solver_mismatches == 0, result.first_mismatch
    assert result.forecast_mismatches == 0, result.first_mismatch
    assert len(result.track["y"]) == frames * rows
    assert result.track_mismatches == 0, result.first_mismatch
    assert result.status["loop.counters"]["track_overrange"] == 0
    assert result.uart_packets_match
    assert result.solved > 0, "the emulator solved no row: the solver's steps went unchecked"
    assert result.status["loop.counters"]["mismatched"] == 0
    for name, fields in result.status.items():
        if name.startswith("camera.inputs["):
            assert fields["dropped_rows"] == 0 and fields["bad_rows"] == 0, name


def _run_and_check(sim, rows, frames):
    from emulator.cosim_loop import closed_loop_cosim
    result = closed_loop_cosim(_dataset(rows, frames), row_period_s=ROW_PERIOD_S,
                               frames=frames, sim=sim, seed=SEED,
                               build_dir=f"build/cosim_loop_{sim}")
    _check(result, frames, rows)


@pytest.mark.skipif(not os.environ.get("RUN_SLOW"), reason="minutes on Verilator: RUN_SLOW=1")
def test_closed_loop_top_equals_the_emulator_on_verilator():
    _run_and_check("verilator", rows=24, frames=3)


@pytest.mark.skipif(not os.environ.get("RUN_SLOW"),
                    reason="about 12 min on Icarus (the default suite's Icarus slice is "
                           "test_run.py's end-to-end job): RUN_SLOW=1")
def test_closed_loop_top_equals_the_emulator_on_icarus():
    _run_and_check("icarus", rows=8, frames=2)


# --- the judge's helpers ---------------------------------------------------------------

def _forecast_columns(rows, cameras, layout, start=10, gap=3):
    """Forecast transfers as the engine takes them, ``(clock, raw)``: ``rows`` of
    ``(row, centres, sources)`` (``sources``: per camera, its segments' rows), one
    transfer per camera, a clock apart, rows ``gap`` clocks apart."""
    from emulator.hdl_sim.payload import pack
    columns, clock = [], start
    for row, centres, sources in rows:
        for c in range(cameras):
            columns.append((clock, pack(layout, {"camera": c, "centre": centres[c],
                                                 "segment_rows": sources[c], "row": row,
                                                 "last": int(c == cameras - 1)})))
            clock += 1
        clock += gap
    return columns


def _small_engine():
    from hdl.front_end.params import CameraParams
    from hdl.top_params import TopParams
    return TopParams.for_pairs(((0, 1),), camera=CameraParams(max_width=256,
                                                              max_height=8)).engine


def test_forecast_rows_are_grouped_compared_and_timed():
    """The engine's forecast transfers back to rows (signed centres, per camera), their
    first offer (a stall before the row's first transfer) and last transfer clocks; a
    corrupted centre is one mismatch, located."""
    from emulator.cosim import compare_records
    from emulator.cosim_loop import FORECAST_FIELDS, _forecast_rows
    engine = _small_engine()
    layout, k = engine.forecast_layout(), engine.temporal.segments
    rows = [(0, (-3, 5), ([7] * k, [7] * k)), (1, (0, -1), ([1] * k, list(range(k)))),
            (2, (2, 2), ([2] * k, [3] * k))]
    columns = _forecast_columns(rows, 2, layout)
    stalls = [columns[2][0] - 2, columns[2][0] - 1]    # row 1 offered 2 clocks early
    got, offered, taken = _forecast_rows(layout, columns, stalls)
    assert got["row"].tolist() == [0, 1, 2]
    assert got["centre"].tolist() == [[-3, 5], [0, -1], [2, 2]]
    assert got["segment_rows"].tolist() == [list(sources) for _, _, sources in rows]
    assert offered == [10, columns[2][0] - 2, columns[4][0]]
    assert taken == [columns[1][0], columns[3][0], columns[5][0]]
    want = {k: np.array(v) for k, v in got.items()}
    assert compare_records(got, want, fields=FORECAST_FIELDS) == (0, None)
    want["centre"][1, 1] = 1
    mismatches, first = compare_records(got, want, [0, 0, 1], FORECAST_FIELDS)
    assert mismatches == 1
    assert first == "record 1 (frame 0, row 1): centre[1] HDL -1 ≠ emulator 1"
    want = {k: np.array(v) for k, v in got.items()}
    want["segment_rows"][2, 1, k - 1] = 4                  # one segment's row address
    assert compare_records(got, want, [0, 0, 1], FORECAST_FIELDS)[0] == 1


def test_track_rows_are_unpacked_signed_and_compared():
    """The motion track's ``Y`` columns back to (rows, 6) signed raw values, each with the
    row of the solver record it follows (-1 beyond them: an extra HDL row is reported,
    not dropped); a corrupted axis is one mismatch, located."""
    from amaranth.lib import data
    from emulator.cosim import compare_records
    from emulator.cosim_loop import TRACK_FIELDS, _track_arrays
    from emulator.hdl_sim.payload import pack
    forecast = _small_engine_forecast()
    layout = data.ArrayLayout(forecast.motion_fmt.shape(), 6)
    low, high = forecast.motion_fmt.min_raw, forecast.motion_fmt.max_raw
    values = [[low, -1, 0, 1, high, 7], [3, -3, 5, -5, 2 ** 20, -(2 ** 20)]]
    columns = [(10 + k, pack(layout, dict(enumerate(v)))) for k, v in enumerate(values)]
    got = _track_arrays(forecast, columns, np.array([4]))
    assert got["y"].tolist() == values and got["row"].tolist() == [4, -1]
    want = {"row": np.array([4, 5]), "y": np.array(values)}
    assert compare_records(got, want, fields=TRACK_FIELDS) == (0, None)
    want["y"][0, 4] = 0
    assert compare_records(got, want, [1, 1], TRACK_FIELDS) == (
        1, f"record 0 (frame 1, row 4): y[4] HDL {high} ≠ emulator 0")


def _small_engine_forecast():
    from hdl.pipeline_config import PipelineConfig
    return PipelineConfig.for_rig(cut_rig(preset("stereo8"), 24), closed_loop=True,
                                  stereo_segments=4).forecast()


def test_a_row_period_too_short_for_the_pixels_is_refused():
    from emulator.cosim import HBLANK, camera_stimulus
    images = np.zeros((2, 1, 2, 640), dtype=np.uint8)
    hblank = camera_stimulus(images, 100e6, ROW_PERIOD_S)["hblank"]
    assert min(hblank) >= HBLANK and hblank[0] > hblank[1]     # camera 1's PCLK is slower
    with pytest.raises(ValueError, match="row_period_s must leave every camera 16 PCLKs"):
        camera_stimulus(images, 100e6, 640 * 10.4e-9)


def test_record_to_the_forecast_it_enters_within_a_frame_only():
    from emulator.cosim_loop import _forecast_after_record
    records, offers, frames = [100, 200, 300, 400, 500], [50, 130, 190, 310, 450], \
        [0, 0, 0, 0, 1]
    assert _forecast_after_record(records, offers, frames, 0)[0] == 30
    # delay 1: set 0 → set 2's forecast 90 clocks later; set 1 → set 3's 110; set 2 → set
    # 4 is another frame's
    assert _forecast_after_record(records, offers, frames, 1).tolist() == [90, 110]
    assert np.isnan(_forecast_after_record([100, 400, 0], [0, 0, 50], [0, 0, 0], 1)[0])

"""emulator.cosim: the comparison of HDL pose records with the emulator's."""

import numpy as np
import pytest

from emulator.cosim import compare_records


def _records(n, seed=7):
    rng = np.random.default_rng(seed)
    return {"row": np.arange(n) % 4, "t_row": rng.integers(0, 2**32, n),
            "flags": np.zeros(n, dtype=np.int64),
            "quaternion": rng.integers(-2**15, 2**15, (n, 4)),
            "position": rng.integers(-2**31, 2**31, (n, 3))}


def _copy(records):
    return {k: np.array(v) for k, v in records.items()}


def test_identical_records_have_no_mismatch():
    records = _records(6)
    assert compare_records(records, _copy(records)) == (0, None)


def test_corrupted_expectation_is_counted_and_located():
    records = _records(6)
    expected = _copy(records)
    expected["quaternion"][5, 2] += 1
    expected["quaternion"][5, 3] += 1
    expected["flags"][4] = 2
    frames = np.array([0, 0, 0, 0, 1, 1])
    mismatches, first = compare_records(records, expected, frames)
    assert mismatches == 3
    assert first == ("record 4 (frame 1, row 0): flags HDL 0 ≠ emulator 2")


def test_missing_records_count_all_their_fields():
    records = _records(5)
    expected = _records(5, seed=8)
    short = {k: v[:3] for k, v in records.items()}
    full = _copy(records)
    mismatches, first = compare_records(short, full)
    assert mismatches == 2 * (3 + 4 + 3)
    assert first.startswith("record 3 (row 3): only the emulator has it")
    mismatches, first = compare_records(full, {k: v[:4] for k, v in records.items()})
    assert mismatches == 10 and "only the HDL has it" in first
    assert compare_records(records, expected)[0] > 0


def test_a_missing_field_is_an_error():
    records = _records(2)
    del records["position"]
    with pytest.raises(ValueError, match=r"records lacks the fields \['position'\]"):
        compare_records(records, _records(2))


def test_row_sets_are_recovered_from_the_engine_columns():
    """Columns as the aligner streams them (the engine model's own helper) back to the
    row sets, with a camera missing from one set and rows of different lengths."""
    from emulator.cosim import row_sets_from_columns
    from emulator.measurement.engine import row_set_columns
    from hdl.front_end.params import CameraParams
    from hdl.top_params import TopParams
    from emulator.hdl_sim.payload import pack

    params = TopParams.for_pairs(((0, 1),), camera=CameraParams(max_width=256, max_height=8))
    layout = params.camera.aligned_layout()
    zero = {"data": 0, "first": 0, "last": 0, "camera": 0, "frame": 0, "row": 0,
            "t_first": 0, "t_last": 0, "flags": 0}

    def beats(camera, row, n):
        return [{**zero, "data": 7 * x % 256, "first": int(x == 0), "last": int(x == n - 1),
                 "camera": camera, "row": row, "t_first": 100 * row + camera} for x in range(n)]

    sets = [{0: beats(0, 0, 5), 1: beats(1, 0, 5)}, {1: beats(1, 1, 3)},
            {0: beats(0, 2, 4), 1: beats(1, 2, 2)}]
    columns = [(clock, pack(layout, {**column, "lanes": dict(enumerate(column["lanes"]))}))
               for clock, column in enumerate(
                   c for s in sets for c in row_set_columns(params.engine, s))]
    got, spans = row_sets_from_columns(layout, columns)
    assert got == sets
    assert spans == [(0, 4), (5, 7), (8, 11)]

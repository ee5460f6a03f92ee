"""emulator.cosim: the comparison of HDL pose records with the emulator's."""

import numpy as np
import pytest

from emulator.cosim import compare_records


def _records(n, seed=7):
    rng = np.random.default_rng(seed)
    return {"row": np.arange(n) % 4, "time": rng.integers(0, 2**32, n),
            "flags": np.zeros(n, dtype=np.int64), "q": rng.integers(-2**15, 2**15, (n, 4)),
            "p": rng.integers(-2**31, 2**31, (n, 3))}


def _copy(records):
    return {k: np.array(v) for k, v in records.items()}


def test_identical_records_have_no_mismatch():
    records = _records(6)
    assert compare_records(records, _copy(records)) == (0, None)


def test_corrupted_expectation_is_counted_and_located():
    records = _records(6)
    expected = _copy(records)
    expected["q"][5, 2] += 1
    expected["q"][5, 3] += 1
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
    del records["p"]
    with pytest.raises(ValueError, match=r"records lacks the fields \['p'\]"):
        compare_records(records, _records(2))

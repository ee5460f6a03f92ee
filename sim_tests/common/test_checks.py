"""golden.checks: the one parameter check helper and its message style."""

import math

import numpy as np
import pytest

from golden.checks import check_int, check_number


@pytest.mark.parametrize("value, low, high, error, message", [
    (True, None, None, TypeError, "n must be an integer, not True"),
    (2.0, None, None, TypeError, "n must be an integer, not 2.0"),
    (0, 1, None, ValueError, "n must be an integer at least 1, not 0"),
    (9, None, 8, ValueError, "n must be an integer at most 8, not 9"),
    (9, 1, 8, ValueError, "n must be an integer between 1 and 8, not 9"),
])
def test_check_int_names_the_parameter_and_the_bound(value, low, high, error, message):
    with pytest.raises(error, match=f"^{message}$"):
        check_int("n", value, low, high)


def test_check_int_takes_numpy_integers_and_the_bounds_themselves():
    for value in (1, 8, np.int64(5), np.uint8(8)):
        check_int("n", value, 1, 8)


@pytest.mark.parametrize("value, kwargs, error, message", [
    (False, {}, TypeError, "x must be a number, not False"),
    ("1", {}, TypeError, "x must be a number, not '1'"),
    (math.nan, {}, ValueError, "x must be a finite number, not nan"),
    (-math.inf, {"low": 0}, ValueError, "x must be a finite number, not -inf"),
    (0.0, {"low": 0, "low_open": True}, ValueError, "x must be a number greater than 0, not 0.0"),
    (1.0, {"low": 0, "high": 1, "high_open": True}, ValueError,
     "x must be a number at least 0 and less than 1, not 1.0"),
    (1.5, {"low": 0, "high": 1}, ValueError, "x must be a number between 0 and 1, not 1.5"),
])
def test_check_number_names_the_parameter_and_the_bound(value, kwargs, error, message):
    with pytest.raises(error, match=f"^{message}$"):
        check_number("x", value, **kwargs)


def test_an_infinity_passes_only_when_allowed():
    check_number("x", math.inf, 0, low_open=True, finite=False)
    with pytest.raises(ValueError, match="x must be a finite number, not nan"):
        check_number("x", math.nan, finite=False)
    with pytest.raises(ValueError, match="x must be a number greater than 0, not -inf"):
        check_number("x", -math.inf, 0, low_open=True, finite=False)


def test_check_number_takes_the_closed_bounds_and_numpy_floats():
    for value in (0, 1, 0.5, np.float32(0.25)):
        check_number("x", value, 0, 1)

"""Parameter checks shared by every parameter class (plain Python, no Amaranth).

One message style, naming the parameter, what it must be and the bad value, as STYLE.md
asks: ``"width must be an integer at least 8, not 7"``, ``"alpha must be a number
greater than 0 and at most 1, not 0.0"``. ``TypeError`` for the wrong kind of value,
``ValueError`` for a value out of range.
"""

import math
from numbers import Integral, Real

__all__ = ["check_int", "check_number"]


def _bounds(low, high, low_open, high_open):
    if low is not None and high is not None and not (low_open or high_open):
        return f"between {low} and {high}"
    parts = []
    if low is not None:
        parts.append(f"{'greater than' if low_open else 'at least'} {low}")
    if high is not None:
        parts.append(f"{'less than' if high_open else 'at most'} {high}")
    return " and ".join(parts)


def _check_range(name, kind, value, low, high, low_open=False, high_open=False):
    below = low is not None and (value <= low if low_open else value < low)
    above = high is not None and (value >= high if high_open else value > high)
    if below or above:
        raise ValueError(f"{name} must be {kind} {_bounds(low, high, low_open, high_open)}, "
                         f"not {value}")


def check_int(name, value, low=None, high=None):
    """Raise ``TypeError`` unless ``value`` is an integer (Python or NumPy, not a
    ``bool``), and ``ValueError`` unless ``low <= value <= high`` (either bound may be
    ``None``)."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise TypeError(f"{name} must be an integer, not {value!r}")
    _check_range(name, "an integer", value, low, high)


def check_number(name, value, low=None, high=None, *, low_open=False, high_open=False,
                 finite=True):
    """Raise ``TypeError`` unless ``value`` is a real number (not a ``bool``), and
    ``ValueError`` unless it is within the bounds (either may be ``None``;
    ``low_open``/``high_open`` exclude the bound itself) and finite (``finite=False``
    lets an infinity through, never a NaN)."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise TypeError(f"{name} must be a number, not {value!r}")
    if math.isnan(value) or (finite and math.isinf(value)):
        raise ValueError(f"{name} must be a finite number, not {value!r}")
    _check_range(name, "a number", value, low, high, low_open, high_open)

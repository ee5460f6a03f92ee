"""Parameter checks shared by the parameter dataclasses (plain Python, no Amaranth).

Messages name the parameter and the bad value, as STYLE.md asks:
``"width must be an integer at least 8, not 7"``.
"""

__all__ = ["check_int"]


def check_int(name, value, low=None, high=None):
    """Raise ``TypeError`` unless ``value`` is an ``int`` (not a ``bool``), and
    ``ValueError`` unless ``low <= value <= high`` (either bound may be ``None``)."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise TypeError(f"{name} must be an integer, not {value!r}")
    if (low is not None and value < low) or (high is not None and value > high):
        if low is not None and high is not None:
            bound = f"between {low} and {high}"
        elif low is not None:
            bound = f"at least {low}"
        else:
            bound = f"at most {high}"
        raise ValueError(f"{name} must be an integer {bound}, not {value}")

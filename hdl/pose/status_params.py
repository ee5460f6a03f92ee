"""Parameters, registers and integer thresholds of the tracking-status unit
(:class:`hdl.pose.status_unit.StatusUnit`; no Amaranth at import time: the bit-accurate
model :mod:`emulator.pose.tracking_status` and the register map use them too).

The rule is :class:`golden.tracking_status.StatusMonitor` with what the hardware has per
row (``docs/pose/tracking_status.md``): the solver's record flags (solved, ``EMPTY``,
``ILL``, ...), the consistency stage's judged and outlier measurements and the
measurements with a confidence. The golden's fractions become unsigned fixed-point
registers compared against integer window sums by cross-multiplication
(``count · 2**f < fraction · n``), so the comparison is exact for the quantized
fraction and needs no division; the window length is a register too.
"""

from dataclasses import dataclass, replace

from golden.checks import check_int, check_number
from golden.tracking_status import DRIFTED_BIT, STATUS_BITS, STATUS_SHIFT, TrackingStatus

from hdl.fixed import UQ, Overflow, Rounding
from hdl.pose.params import PoseFlag, PoseSolverParams, solver_source

__all__ = ["StatusParams", "FRACTION_FMT", "MEASUREMENTS_FMT", "FRACTIONS", "FLAG_BITS",
           "TRACKER_THRESHOLDS", "ROW_COUNTS", "ROW_INPUTS",
           "status_source", "top_status_params", "TrackingStatus", "STATUS_SHIFT",
           "STATUS_BITS", "DRIFTED_BIT"]

#: Format of the fraction registers: ``[0, 2)`` in steps of 2**-16 (the golden's
#: one-decimal fractions compare exactly for windows up to about 30,000 rows: see
#: docs/pose/tracking_status.md).
FRACTION_FMT = UQ(1, 16)
#: Format of the ``degraded_measurements`` register (confident measurements per
#: stepped row, window mean).
MEASUREMENTS_FMT = UQ(8, 4)
#: The fraction settings, in register order.
FRACTIONS = ("lost_update_fraction", "lost_outlier_fraction", "degraded_update_fraction",
             "degraded_outlier_fraction", "degraded_ill_fraction")
#: The thresholds :meth:`StatusParams.for_tracker` takes from the golden tracker's
#: parameters (``degraded_ill_fraction`` stands for its ``degraded_condition``).
TRACKER_THRESHOLDS = ("lost_update_fraction", "lost_outlier_fraction",
                      "degraded_update_fraction", "degraded_outlier_fraction",
                      "degraded_measurements")
#: The per-row counts (the fields of :meth:`StatusParams.row_layout`), each the sum of
#: one verdict bit per measurement (:mod:`hdl.pose.row_counter`).
ROW_COUNTS = ("judged", "outliers", "confident")
#: A row's inputs to the unit, in the order of the emulator's row tuples: its counts,
#: then whether it was determinable.
ROW_INPUTS = (*ROW_COUNTS, "determinable")
#: Width of the annotated flags: the solver's PoseFlag bits, then the status code and
#: the drifted bit (golden.tracking_status's layout).
FLAG_BITS = DRIFTED_BIT + 1

assert STATUS_SHIFT >= len(PoseFlag), "the status bits must sit above the PoseFlag bits"


@dataclass(frozen=True, kw_only=True)
class StatusParams:
    """Sizes and register reset values of the tracking-status unit.

    Parameters
    ----------
    slots : int
        Most measurements a row can have (the solver's slots): the width of the per-row
        counts.
    max_window : int
        Depth of the history memory (a power of two): the largest ``window``.
    window : int
        Rows in the sliding window (register, 1 … ``max_window``); the golden's
        ``status_window`` frames times the rows per frame (:meth:`for_tracker`).
    lost_update_fraction, lost_outlier_fraction, degraded_update_fraction, degraded_outlier_fraction : float
        The golden's thresholds (registers, ``FRACTION_FMT``, half-even).
    degraded_ill_fraction : float
        Degraded when more than this share of the window's formed rows (not ``EMPTY``)
        were flagged ``ILL`` by the solver's pivot check: the golden's "median condition
        above ``degraded_condition``" is "more than half above it" (register,
        ``FRACTION_FMT``).
    degraded_measurements : float
        Degraded below this many confident measurements per stepped row (window mean;
        register, ``MEASUREMENTS_FMT``, half-even).
    count_bits : int
        Width of the wrapping event counters (losses, rows per status).
    """
    slots: int = 16
    max_window: int = 1024
    window: int = 150
    lost_update_fraction: float = 0.2
    lost_outlier_fraction: float = 0.5
    degraded_update_fraction: float = 0.7
    degraded_outlier_fraction: float = 0.25
    degraded_ill_fraction: float = 0.5
    degraded_measurements: float = 6.0
    count_bits: int = 32

    def __post_init__(self):
        check_int("slots", self.slots, 1, 1 << 12)
        check_int("max_window", self.max_window, 2, 1 << 16)
        if self.max_window & (self.max_window - 1):
            raise ValueError(f"max_window must be a power of two, not {self.max_window}")
        check_int("window", self.window, 1, self.max_window)
        for name in FRACTIONS:
            check_number(name, getattr(self, name), 0, 1)
        check_number("degraded_measurements", self.degraded_measurements, 0,
                     MEASUREMENTS_FMT.max_value)
        check_int("count_bits", self.count_bits, 8, 64)

    replace = replace

    @classmethod
    def for_tracker(cls, tracker, *, slots, frame_rows, **changes):
        """The golden ``tracker`` (:class:`golden.tracker_params.TrackerParams`)
        thresholds for a solver of ``slots`` slots whose frames span ``frame_rows`` row
        periods (blanking included): the window is ``status_window`` frames of rows, as
        the golden tracker sizes its :class:`~golden.tracking_status.StatusMonitor`."""
        check_number("frame_rows", frame_rows, 0, low_open=True)
        window = max(round(tracker.status_window * frame_rows), 1)
        fields = {name: getattr(tracker, name) for name in TRACKER_THRESHOLDS}
        return cls(slots=slots, window=window, **{**fields, **changes})

    # --- widths -------------------------------------------------------------------------

    @property
    def window_bits(self):
        """Width of the ``window`` register and of the row counts (0 … max_window)."""
        return self.max_window.bit_length()

    @property
    def row_count_bits(self):
        """Width of one row's measurement counts (0 … slots)."""
        return self.slots.bit_length()

    @property
    def sum_bits(self):
        """Width of a window sum of measurement counts."""
        return (self.max_window * self.slots).bit_length()

    @property
    def address_bits(self):
        return (self.max_window - 1).bit_length()

    # --- registers ----------------------------------------------------------------------

    def raw_settings(self):
        """The registers' reset values (raw): ``window``, the fractions
        (``FRACTION_FMT``) and ``degraded_measurements`` (``MEASUREMENTS_FMT``)."""
        out = {"window": self.window}
        for name in FRACTIONS:
            out[name] = int(FRACTION_FMT.quantize(getattr(self, name), Rounding.HALF_EVEN,
                                                  Overflow.ERROR))
        out["degraded_measurements"] = int(MEASUREMENTS_FMT.quantize(
            self.degraded_measurements, Rounding.HALF_EVEN, Overflow.ERROR))
        return out

    def settings_layout(self):
        """The run-time settings (register ``status.settings``), raw. A ``window`` of 0
        or above ``max_window`` is taken as 1 or ``max_window`` and flagged
        (``state.window_error``); a change of ``window`` restarts the history."""
        from amaranth.lib import data
        return data.StructLayout({"window": self.window_bits,
                                  **{name: FRACTION_FMT.width for name in FRACTIONS},
                                  "degraded_measurements": MEASUREMENTS_FMT.width})

    def row_layout(self):
        """The per-row side input, one transfer per pose record and in the same order:
        ``judged`` measurements the consistency stage judged (non-zero confidence in),
        ``outliers`` among them beyond the Huber threshold, ``confident`` measurements
        with a non-zero confidence after the judge (the golden's ``used``), and
        ``determinable``: at least ``min_cameras`` of the row's cameras were near enough
        in time to step (the update fraction counts only these rows)."""
        from amaranth.lib import data
        return data.StructLayout({name: self.row_count_bits if name in ROW_COUNTS else 1
                                  for name in ROW_INPUTS})

    def state_layout(self):
        """What the unit shows the PS (register ``status.state``): the latest record's
        ``status`` and ``drifted``, ``lost`` (the latch), ``acquired`` (a row was
        TRACKING since reset or ``clear``: a loss after it marks drift),
        ``window_error``, and wrapping counters: ``losses`` (entries into LOST),
        ``degraded_rows``, ``lost_rows``."""
        from amaranth.lib import data
        c = self.count_bits
        return data.StructLayout({"status": STATUS_BITS, "drifted": 1, "lost": 1,
                                  "acquired": 1, "window_error": 1, "losses": c, "degraded_rows": c,
                                  "lost_rows": c})


def status_source(solver):
    """The pose record after the status unit: :func:`hdl.pose.params.solver_source` of
    ``solver`` with flags widened to :data:`FLAG_BITS` (bits 3:0 the solver's
    ``PoseFlag``, 5:4 the status, 6 drifted). The top's ``pose_output.source`` must be
    this once the unit sits between the solver and the output."""
    if not isinstance(solver, PoseSolverParams):
        raise TypeError(f"solver must be a PoseSolverParams, not {solver!r}")
    return replace(solver_source(solver), flag_bits=FLAG_BITS)


def top_status_params(top):
    """The status unit's parameters for a top (:class:`hdl.top_params.TopParams`): its
    solver's slots and the golden defaults; the window's reset value spans
    ``status_window`` of the cameras' ``max_height`` rows (the blanking is not known
    at build time: the PS sets ``window`` for its cameras' frame period)."""
    from golden.tracker_params import TrackerParams
    return StatusParams.for_tracker(TrackerParams(), slots=top.solver.slots,
                                    frame_rows=top.camera.max_height)

"""Co-simulated slice: the HDL top (cocotb) against the bit-accurate models.

:func:`cosim_slice` builds a :class:`hdl.top.RowtrackTop` for a sub-rig of whole stereo
pairs, plays the dataset's rows on its DVP pins, reads the pose records back from the PS
FIFO registers and the UART line, and compares them with the emulator fed with exactly
the row sets the HDL front end produced (their time stamps are the HDL clock's). The
cocotb side lives in ``sim_tests/cocotb/top/cosim_bench.py``; this module prepares its
input, runs it through :func:`sim_tests.common.cocotb_runner.run_cocotb` and judges the
result with :func:`compare_records`.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["RECORD_FIELDS", "CosimResult", "compare_records"]

#: Pose-record fields compared, element by element (``q`` and ``p`` are arrays).
RECORD_FIELDS = ("row", "time", "flags", "q", "p")


@dataclass(frozen=True)
class CosimResult:
    """What a co-simulated slice produced and how it compares.

    Members
    -------
    records : dict
        The HDL's pose records (raw integer arrays: ``row``, ``time``, ``flags``,
        ``q`` (n, 4), ``p`` (n, 3)).
    expected : dict
        The emulator's records for the same row sets.
    mismatches : int
        Record fields that differ (0: bit-exact; see :func:`compare_records`).
    first_mismatch : str or None
        Where the first difference is.
    clocks : int
        System clocks simulated.
    wall_s : float
        Wall time of the simulation.
    row_sets : int
        Row sets the front end delivered to the measurement engine.
    clocks_per_row_set : float
        Measured engine throughput: clocks between row sets entering the engine while
        it is busy (see ``cosim_bench``).
    latency_clocks : int
        Largest time, over the records, from the last pixel of a row set at the DVP pins
        to its pose record in the PS FIFO, in system clocks.
    clk_hz : float
    uart_packets_match : bool
        The bytes on the UART line decode to exactly the emulator's packets.
    """
    records: dict
    expected: dict
    mismatches: int
    first_mismatch: str | None
    clocks: int
    wall_s: float
    row_sets: int
    clocks_per_row_set: float
    latency_clocks: int
    clk_hz: float
    uart_packets_match: bool

    @property
    def cycles_per_s(self):
        """Simulator speed: system clocks per second of wall time."""
        return self.clocks / self.wall_s


def _record_values(records, k):
    """``(label, value)`` of every compared element of record ``k``."""
    out = []
    for name in RECORD_FIELDS:
        value = np.asarray(records[name])[k]
        if np.ndim(value):
            out += [(f"{name}[{i}]", int(v)) for i, v in enumerate(value)]
        else:
            out.append((name, int(value)))
    return out


def compare_records(records, expected, frames=None):
    """Count the record fields in which the HDL's ``records`` differ from ``expected``.

    Records are compared in order, element by element (``q`` and ``p`` per component);
    a record present on one side only counts all of its elements. ``frames`` (optional,
    one per expected record) names the frame in the message.

    Returns
    -------
    mismatches : int
    first : str or None
        e.g. ``"record 5 (frame 1, row 3): q[2] HDL 12 ≠ emulator 13"``.
    """
    counts = []
    for name, side in (("records", records), ("expected", expected)):
        missing = [f for f in RECORD_FIELDS if f not in side]
        if missing:
            raise ValueError(f"{name} lacks the fields {missing}")
        counts.append(len(np.asarray(side["row"])))
    n_hdl, n_model = counts
    mismatches, first = 0, None
    for k in range(max(n_hdl, n_model)):
        side = expected if k < n_model else records
        where = f"record {k} (" + (f"frame {int(frames[k])}, " if frames is not None
                                   and k < len(frames) else "") + \
            f"row {int(np.asarray(side['row'])[k])})"
        if k >= n_hdl or k >= n_model:
            fields = _record_values(side, k)
            mismatches += len(fields)
            if first is None:
                first = f"{where}: only the {'emulator' if k >= n_hdl else 'HDL'} has it " \
                        f"({n_hdl} HDL records, {n_model} emulator records)"
            continue
        for (label, got), (_, want) in zip(_record_values(records, k),
                                           _record_values(expected, k)):
            if got != want:
                mismatches += 1
                if first is None:
                    first = f"{where}: {label} HDL {got} ≠ emulator {want}"
    return mismatches, first

"""Per-row counts for the tracking-status unit: one verdict per measurement in, one
``row`` transfer per row out (:meth:`hdl.pose.status_params.StatusParams.row_layout`).

The consistency stage judges each measurement of a row and forwards it; tapping its
output with three verdict bits per transfer (the judge's input confidence was non-zero,
the measurement was an outlier, its confidence out is non-zero) and ``last``, this block
sums them per row, so that :class:`hdl.pose.status_unit.StatusUnit` gets the row's
``judged``, ``outliers`` and ``confident`` (and the ``determinable`` bit of its last
verdict) beside the solver's record of that row. The
model is :func:`emulator.pose.tracking_status.count_rows`.
"""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.pose.status_params import ROW_COUNTS as VERDICTS, StatusParams

__all__ = ["RowCounter", "verdict_layout", "default_row_counter"]


def verdict_layout():
    """One measurement's verdict, one bit per row count it adds to: ``judged`` (its
    confidence into the judge was not 0), ``outliers`` (beyond ``kσ``, replaced),
    ``confident`` (its confidence out is not 0); ``last`` (the row's final measurement)
    and, with it, the row's ``determinable``."""
    return data.StructLayout({**{name: 1 for name in VERDICTS}, "last": 1,
                              "determinable": 1})


class RowCounter(wiring.Component):
    """Sums the verdicts of each row.

    Parameters
    ----------
    params : StatusParams
        ``slots``: the most measurements a row has; a count stops there (a row with
        more is flagged OVERRUN by the solver, so it never counts as stepped).

    Members
    -------
    i : In(stream.Signature(verdict_layout()))
        One transfer per measurement.
    o : Out(stream.Signature(params.row_layout()))
        One transfer per row, the clock after its ``last`` verdict.

    Throughput: one verdict per clock; ``o`` not ready while a row's counts wait stalls
    ``i`` at the next row's ``last``. Reset: counts 0.
    """

    def __init__(self, params):
        if not isinstance(params, StatusParams):
            raise TypeError(f"params must be a StatusParams, not {params!r}")
        self.params = params
        super().__init__({"i": In(stream.Signature(verdict_layout())),
                          "o": Out(stream.Signature(params.row_layout()))})

    def elaborate(self, platform):
        p = self.params
        m = Module()
        counts = {name: Signal(p.row_count_bits) for name in VERDICTS}
        free = ~self.o.valid | self.o.ready
        # a row's last verdict waits while the previous row's counts are not taken
        m.d.comb += self.i.ready.eq(~self.i.payload.last | free)
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        with m.If(self.i.valid & self.i.ready):
            sums = {name: Mux(counts[name] == p.slots, p.slots,
                              counts[name] + getattr(self.i.payload, name))
                    for name in VERDICTS}
            with m.If(self.i.payload.last):
                m.d.sync += [self.o.valid.eq(1), *(c.eq(0) for c in counts.values()),
                             *(getattr(self.o.payload, name).eq(sums[name])
                               for name in VERDICTS),
                             self.o.payload.determinable.eq(self.i.payload.determinable)]
            with m.Else():
                m.d.sync += [counts[name].eq(sums[name]) for name in VERDICTS]
        return m


def default_row_counter():
    """The row counter of the default top's status unit: the catalog's build."""
    from hdl.pose.status_params import top_status_params
    from hdl.top_params import TopParams
    return RowCounter(top_status_params(TopParams()))

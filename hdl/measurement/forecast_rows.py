"""Forecast rows for the closed-loop measurement engine: one camera per transfer in, one
whole row out.

The forecast (``hdl/pose/forecast_predictor.py``) sends each camera row as ``cameras``
transfers, camera 0 first, ``last`` on the final one. The engine's row-set fork needs
the whole row at once, with the row set's first column: every temporal lane takes its
centre and source row with its first beat. This block gathers a row into registers and
offers it as one transfer; a row that is not ``cameras`` transfers in camera order with
``last`` on the final one (or names a source row the lanes' ``row_bits`` cannot hold)
is discarded and counted, so a damaged forecast stream costs rows, never the
alignment. Model: :func:`emulator.measurement.engine.forecast_rows`.
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.measurement.engine_params import EngineParams

__all__ = ["ForecastRows"]


class ForecastRows(wiring.Component):
    """Gathers a forecast row.

    Parameters
    ----------
    params : EngineParams
        With ``follow``.

    Members
    -------
    i : In(stream.Signature(params.forecast_layout()))
    o : Out(stream.Signature(params.forecast_row_layout()))
        ``centre[k]``, ``source[k]`` (its segments' rows) of camera ``k``; ``row``: the
        final transfer's.
    malformed : Out(params.count_bits)
        Rows discarded (wrapping).

    Latency: a row is offered the clock after its last transfer. Throughput: one
    transfer per clock while ``o`` is empty; ``i`` waits while a row is offered (one
    row buffer: the engine takes a row per row set, whose columns far outnumber the
    cameras). Reset empties the buffer and clears the counter.
    """

    def __init__(self, params):
        if not isinstance(params, EngineParams):
            raise TypeError(f"params must be an EngineParams, not {params!r}")
        if not params.follow:
            raise ValueError("params.follow must be True for a forecast input")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(params.forecast_layout())),
            "o": Out(stream.Signature(params.forecast_row_layout())),
            "malformed": Out(params.count_bits),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        beat, row = self.i.payload, self.o.payload
        last_camera = p.cameras - 1
        position = Signal(range(p.cameras))
        damaged = Signal()              # an earlier transfer of this row was out of order
        m.d.comb += self.i.ready.eq(~self.o.valid)
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        wrong = (beat.camera != position) | (beat.last != (position == last_camera))
        segments = range(p.temporal.segments)
        if p.router.solver.row_bits > p.temporal.row_bits:
            for n in segments:
                wrong |= beat.segment_rows[n][p.temporal.row_bits:].any()
        with m.If(self.i.valid & self.i.ready):
            for k in range(p.cameras):
                with m.If(position == k):
                    m.d.sync += [row.centre[k].eq(beat.centre),
                                 *[row.source[k][n].eq(beat.segment_rows[n])
                                   for n in segments]]
            with m.If(beat.last):
                m.d.sync += [position.eq(0), damaged.eq(0), row.row.eq(beat.row)]
                with m.If(damaged | wrong):
                    m.d.sync += self.malformed.eq(self.malformed + 1)
                with m.Else():
                    m.d.sync += self.o.valid.eq(1)
            with m.Else():
                m.d.sync += damaged.eq(damaged | wrong)
                with m.If(position != last_camera):
                    m.d.sync += position.eq(position + 1)
        return m

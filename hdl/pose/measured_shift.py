"""The predicted shift of each measurement, for the consistency stage (issue 16): the
forecast's ``a·Ŷ`` of the measurement's slot and row with **its own** depth cue and the
row's forecast ``Ŷ`` (:meth:`emulator.pose.forecast.ForecastModel.predict`'s ``shift``,
as :class:`emulator.pose.tracking_loop.TrackingLoopModel` evaluates it a second time
after the stereo lane), bit for bit.

Why per measurement: the forecast predicted the row's shifts before it was read, with
the previous frame's cues; the row's own cues are known only with its measurements. A
row-wide side input (every slot's prediction, before the row's first measurement) would
need the whole row's cues first, i.e. a row of buffering (80 measurements) in the loop.
Here each measurement gets its prediction as it passes: one term of the design row and
one product ``a_i·Ŷ_i`` per clock (:func:`hdl.pose.forecast_predictor.displacement_terms`,
the forecast's own datapath), reading the solver's store through the second read port of
the forecast's copy (its memories' second port and its own Horner datapath; no third
copy of the store).

One measurement at a time: :attr:`latency` clocks from its transfer to ``o.valid``; the
next is taken the clock after the result has gone, so that ``i.ready`` does not depend on
``o.ready`` (issue 17: the consistency stage's ready reached the measurement router
through this unit, 11 LUT levels in the board top). The consistency stage
after it needs more clocks per measurement than that (its ``latency``, 13 at two bits per
clock), so the unit adds its latency to a row's first measurement only.
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.measurement.consistency import judge_layout
from hdl.pose.coef_term_store import term_read_signature
from hdl.pose.forecast_predictor import TERM_STAGES, displacement_terms, term_tag

__all__ = ["MeasuredShift", "query_layout"]


def query_layout(params, stage):
    """A measurement (the stage's ``judge_layout`` without ``predicted`` and
    ``translation``) with the row's
    forecast ``motion`` ``Ŷ`` (6 × ``motion_fmt``)."""
    fields = dict(judge_layout(stage).members)
    del fields["predicted"], fields["translation"]
    fields["motion"] = data.ArrayLayout(params.motion_fmt.shape(), 6)
    return data.StructLayout(fields)


class MeasuredShift(wiring.Component):
    """Predicted shift of each measurement.

    Parameters
    ----------
    params : ForecastParams
    stage : ConsistencyParams
        The stage fed (its ``predicted_fmt`` is ``params.displacement_fmt``).

    Members
    -------
    i : In(stream.Signature(query_layout(params, stage)))
    o : Out(stream.Signature(judge_layout(stage)))
        The measurement with ``predicted`` and its translation part ``translation``
        (the sum of the first three terms, rounded once; ``displacement_fmt``,
        saturated).
    saturated : Out(1)
        With ``o.valid``: ``predicted`` or ``translation`` was saturated.
    coef : Out(term_read_signature(solver))
        The solver's store (the forecast's copy), data ``solver.coef_latency`` clocks
        after the (slot, row, term).
    """

    def __init__(self, params, stage):
        if stage.predicted_fmt != params.displacement_fmt:
            raise ValueError(f"the stage's predicted_fmt {stage.predicted_fmt} must be the "
                             f"forecast's displacement_fmt {params.displacement_fmt}")
        self.params, self.stage = params, stage
        super().__init__({
            "i": In(stream.Signature(query_layout(params, stage))),
            "o": Out(stream.Signature(judge_layout(stage))),
            "saturated": Out(1),
            "coef": Out(term_read_signature(params.solver)),
        })

    @property
    def latency(self):
        """Clocks from a transfer on ``i`` to ``o.valid``: six terms issued, then the
        store's latency, coef × cue, a, a × Ŷ, sum and the output register."""
        return 6 + self.params.solver.coef_latency + TERM_STAGES - 1

    def elaborate(self, platform):
        p, s = self.params, self.params.solver
        m = Module()
        held = Signal(query_layout(p, self.stage))
        active, issuing, term = Signal(), Signal(), Signal(range(6))
        take = Signal()
        m.d.comb += [self.i.ready.eq(~active & ~self.o.valid),
                     take.eq(self.i.valid & self.i.ready),
                     self.coef.slot.eq(held.slot), self.coef.row.eq(held.row),
                     self.coef.term.eq(term)]
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        with m.If(take):
            m.d.sync += [held.eq(self.i.payload), active.eq(1), issuing.eq(1), term.eq(0)]
        with m.If(issuing):
            m.d.sync += term.eq(term + 1)
            with m.If(term == 5):
                m.d.sync += issuing.eq(0)

        # the coefficients of the term issued at stage 0 arrive at stage ``latency``
        latency = s.coef_latency
        tags = [Signal(term_tag(p), name=f"tag{n}") for n in range(latency + TERM_STAGES)]
        m.d.comb += [tags[0].valid.eq(issuing), tags[0].term.eq(term)]
        m.d.sync += [tags[n + 1].eq(tags[n]) for n in range(len(tags) - 1)]
        stages = tags[latency - 1:]
        cue1, y2 = Signal(s.cue_fmt.shape()), Signal(p.motion_fmt.shape())
        m.d.sync += [cue1.eq(held.cue), y2.eq(held.motion[stages[1].term])]
        value, over = displacement_terms(m, p, s, self.coef.first, self.coef.second, stages,
                                         cue1, y2, "")
        # the translation part: the same rounding of the sum after the third term
        translation, translation_over = Signal.like(value), Signal()
        with m.If(stages[5].valid & (stages[5].term == 2)):
            m.d.sync += [translation.eq(value), translation_over.eq(over)]
        with m.If(stages[5].valid & (stages[5].term == 5)):
            m.d.sync += [self.o.valid.eq(1), self.o.payload.predicted.eq(value),
                         self.o.payload.translation.eq(translation),
                         self.saturated.eq(over | translation_over), active.eq(0),
                         *[getattr(self.o.payload, name).eq(getattr(held, name))
                           for name in self.o.payload.shape().members
                           if name not in ("predicted", "translation")]]
        return m

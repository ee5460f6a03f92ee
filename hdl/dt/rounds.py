"""Several rounds of the domain-transform filter with the golden model's schedule."""

import functools

from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.fifo import SyncFIFOBuffered

from golden.checks import check_int

from hdl.dt.params import GUIDE_BITS, SCHEDULE_FMT, SIGMA_FMT, DtFilterParams, schedule_scales
from hdl.fixed import Overflow, Rounding, hdl_mul, hdl_resize


from hdl.dt.filter import DomainTransformFilter, filter_signature

__all__ = ["DomainTransformRounds"]


class DomainTransformRounds(wiring.Component):
    """``rounds`` RF rounds with the golden schedule, one pixel per clock.

    :func:`golden.dt.recursive_filter` runs ``N`` rounds with ``sigma_H,i = scale_i
    sigma_s`` (:func:`golden.dt.sigma_schedule`). Since a round's weights are
    ``exp(-sqrt(2) / sigma_H,i (1 + sigma_s / sigma_r |dI|))``, round ``i`` is a
    :class:`DomainTransformFilter` whose registers are ``scale_i sigma_s`` and
    ``scale_i sigma_r`` (``scale_i`` in ``SCHEDULE_FMT``, the products rounded half up to
    ``SIGMA_FMT``). The stages are chained value to value; the guide follows each pixel
    through a FIFO deep enough for a stage's pixels in flight, so it meets its pixel at
    the next stage.

    Parameters
    ----------
    params : DtFilterParams
        Every stage's build.
    rounds : int
        Number of rounds, 1 to 8 (1 is one :class:`DomainTransformFilter`).

    Members
    -------
    i, o, sigma_s, sigma_r, clamped
        As :class:`DomainTransformFilter`; ``clamped`` is any stage's flag.

    Latency: :attr:`latency` = ``rounds`` times a stage's, when nothing stalls.
    Throughput: one pixel per clock. Backpressure: as a stage; a full guide FIFO cannot
    happen (its depth exceeds a stage's pixels in flight). The registers must hold while
    any pixel of a frame is inside (each stage latches them at its own first pixel).
    """

    def __init__(self, params=DtFilterParams(), rounds=3):
        if not isinstance(params, DtFilterParams):
            raise TypeError(f"params must be a DtFilterParams, not {params!r}")
        check_int("rounds", rounds, 1, 8)
        self.params, self.rounds = params, rounds
        super().__init__(filter_signature(params))

    @property
    def latency(self):
        return self.rounds * DomainTransformFilter.latency_of(self.params)

    @property
    def fifo_depth(self):
        """Guide FIFO entries between stages: a stage's latency plus its output register."""
        return DomainTransformFilter.latency_of(self.params) + 2

    coefficient_settle_clocks = DomainTransformFilter.coefficient_settle_clocks

    def elaborate(self, platform):
        p = self.params
        m = Module()
        stages = [DomainTransformFilter(p) for _ in range(self.rounds)]
        flags = []
        for n, (stage, scale) in enumerate(zip(stages, schedule_scales(self.rounds))):
            m.submodules[f"round{n}"] = stage
            for port, register in ((stage.sigma_s, self.sigma_s), (stage.sigma_r, self.sigma_r)):
                product, fmt = hdl_mul(register, SIGMA_FMT, scale, SCHEDULE_FMT)
                m.d.comb += port.eq(hdl_resize(product, fmt, SIGMA_FMT, Rounding.HALF_UP,
                                               Overflow.ERROR))
            flags.append(stage.clamped)
        m.d.comb += self.clamped.eq(functools.reduce(lambda a, b: a | b, flags))

        # the first stage takes the input; the guide of every pixel it takes goes on
        fifos = [SyncFIFOBuffered(width=GUIDE_BITS, depth=self.fifo_depth)
                 for _ in range(self.rounds - 1)]
        for n, fifo in enumerate(fifos):
            m.submodules[f"guide{n}"] = fifo
        first = stages[0]
        room = fifos[0].w_rdy if fifos else 1
        m.d.comb += [first.i.p.eq(self.i.p), first.i.valid.eq(self.i.valid & room),
                     self.i.ready.eq(first.i.ready & room)]
        if fifos:
            m.d.comb += [fifos[0].w_data.eq(self.i.p.guide),
                         fifos[0].w_en.eq(self.i.valid & self.i.ready)]
        # stage n takes stage n-1's output with the guide from FIFO n-1 and passes it on
        for n in range(1, self.rounds):
            prev, stage, fifo = stages[n - 1], stages[n], fifos[n - 1]
            room = fifos[n].w_rdy if n < len(fifos) else 1
            ok = fifo.r_rdy & room
            m.d.comb += [stage.i.p.guide.eq(fifo.r_data), stage.i.p.value.eq(prev.o.p.value),
                         stage.i.p.last.eq(prev.o.p.last),
                         stage.i.valid.eq(prev.o.valid & ok),
                         prev.o.ready.eq(stage.i.ready & ok),
                         fifo.r_en.eq(prev.o.valid & stage.i.ready & ok)]
            if n < len(fifos):
                m.d.comb += [fifos[n].w_data.eq(fifo.r_data),
                             fifos[n].w_en.eq(prev.o.valid & stage.i.ready & ok)]
        wiring.connect(m, stages[-1].o, wiring.flipped(self.o))
        return m

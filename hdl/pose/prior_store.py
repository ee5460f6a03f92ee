"""The prior information of the motion filter's information gain (issue 16,
docs/pose/information_gain.md): the gateware of
:class:`emulator.pose.information_gain.PriorInformation`, bit-exact with it
(``sim_tests/pose/test_prior_store_hdl.py``).

A row's 21 normal-matrix entries ``N`` (``UPPER`` order) stream in; out stream
``M = N + Λ'`` for the gain solve's normalizer, where ``Λ'`` is the prior with the row
taken in: ``c·N`` for the first solved row, ``Λ + s·(c·N − Λ)`` after (each product
rounded half-even into ``information_fmt``). ``Λ'`` is written to the other half of a
two-bank store; the row's verdict (``keep``: solved or not) then either makes that bank
the prior or drops it, so a row that did not solve changes nothing. The next row's
entries wait for the verdict.
"""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.fixed import SQ, Overflow, Rounding, hdl_add, hdl_mul, hdl_resize
from hdl.pose.forecast_params import ForecastParams
from hdl.pose.program import UPPER

__all__ = ["PriorStore", "entry_layout", "total_fmt", "default_prior_store"]


def total_fmt(params):
    """``N + Λ``: ``information_fmt`` with one more integer bit (the model's sum)."""
    return SQ(params.information_fmt.int_bits + 1, params.information_fmt.frac_bits)


def entry_layout(fmt):
    """One matrix entry of a row; ``last`` marks the 21st."""
    return data.StructLayout({"value": fmt.shape(), "last": 1})


class PriorStore(wiring.Component):
    """Prior information ``Λ`` (21 entries) and ``M = N + Λ'`` of each row.

    Parameters
    ----------
    params : ForecastParams

    Members
    -------
    i : In(stream.Signature(entry_layout(solver.normal_fmt)))
        A row's normal matrix, 21 entries in ``UPPER`` order, ``last`` on the 21st. A
        row ends at its ``last`` or its 21st entry; if not both, it is malformed: counted
        in ``malformed``, its entries go out as they came (``last`` where it ended), and
        the verdict that follows cannot keep it.
    o : Out(stream.Signature(entry_layout(total_fmt(params))))
        ``M = N + Λ'``, one per entry in, ``last`` on the entry that ended the row.
    keep : In(stream.Signature(1))
        The row's verdict after its solve: 1 keeps ``Λ'`` as the prior. Taken once every
        entry of the row is out; the next row's entries wait for it.
    prior_weight : In(prior_fmt), reset ``params.prior_raw``
        ``c = (1 − α)/α``, run-time.
    smoothing : In(gain_fmt), reset ``params.smoothing_raw``
        ``s``, run-time.
    valid : Out(1)
        A row has been kept (before: the next solved row sets ``Λ = c·N``).
    malformed : Out(16)
        Rows whose ``last`` was not on the 21st entry (wraps).

    Latency: :attr:`latency` clocks from an entry's transfer to its ``M`` on ``o``, one
    entry per clock when ``o`` takes them.
    """

    #: Clocks from an entry in to its M out: the entry and prior read, c·N, its rounding,
    #: s·(c·N − Λ), then Λ' and M.
    latency = 5

    def __init__(self, params):
        if not isinstance(params, ForecastParams):
            raise TypeError(f"params must be a ForecastParams, not {params!r}")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(entry_layout(params.solver.normal_fmt))),
            "o": Out(stream.Signature(entry_layout(total_fmt(params)))),
            "keep": In(stream.Signature(1)),
            "prior_weight": In(params.prior_fmt.shape(), init=params.prior_raw),
            "smoothing": In(params.gain_fmt.shape(), init=params.smoothing_raw),
            "valid": Out(1),
            "malformed": Out(16),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        entries = len(UPPER)
        info, normal = p.information_fmt, p.solver.normal_fmt
        diff_fmt = SQ(info.int_bits + 1, info.frac_bits)

        m.submodules.banks = banks = Memory(shape=info.shape(), depth=2 * entries, init=[])
        read = banks.read_port(domain="comb")
        write = banks.write_port()
        current = Signal()          # the bank that holds Λ
        index = Signal(range(entries))
        closed = Signal()           # a row's last entry was taken, its verdict not yet
        drained = Signal()          # ... and its last M has gone out
        bad_row = Signal()          # the row in flight is malformed

        advance = Signal()
        m.d.comb += advance.eq(~self.o.valid | self.o.ready)
        m.d.comb += self.i.ready.eq(advance & ~closed)
        take = Signal()
        m.d.comb += take.eq(self.i.valid & self.i.ready)
        m.d.comb += read.addr.eq(Mux(current, entries, 0) + index)

        # stage 1: the entry and Λ_k; 2: c·N; 3: c·N rounded; 4: s·(c·N − Λ);
        # out: Λ' written to the other bank, M = N + Λ'. `end` marks the entry that
        # closed the row (its `last`, or the 21st).
        stage = data.StructLayout({"valid": 1, "end": 1, "index": range(entries),
                                   "normal": normal.shape(), "prior": info.shape()})
        s1, s2, s3, s4 = (Signal(stage, name=f"s{k}") for k in range(1, 5))
        ends = Signal()
        m.d.comb += ends.eq(self.i.payload.last | (index == entries - 1))
        weighted, weighted_fmt = hdl_mul(self.prior_weight, p.prior_fmt, s1.normal, normal)
        product = Signal(weighted_fmt.shape())
        rounded, rounded4 = Signal(info.shape()), Signal(info.shape())
        diff = Signal(diff_fmt.shape())
        m.d.comb += diff.eq(rounded - s3.prior)
        moved_value, moved_fmt = hdl_mul(self.smoothing, p.gain_fmt, diff, diff_fmt)
        moved = Signal(moved_fmt.shape())
        with m.If(advance):
            m.d.sync += [s1.valid.eq(take), s1.end.eq(ends), s1.index.eq(index),
                         s1.normal.eq(self.i.payload.value), s1.prior.eq(read.data)]
            m.d.sync += [s2.eq(s1), product.eq(weighted)]
            m.d.sync += [s3.eq(s2), rounded.eq(hdl_resize(product, weighted_fmt, info,
                                                           Rounding.HALF_EVEN, Overflow.ERROR))]
            m.d.sync += [s4.eq(s3), rounded4.eq(rounded), moved.eq(moved_value)]

        step = hdl_resize(moved, moved_fmt, diff_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
        kept, kept_fmt = hdl_add(s4.prior, info, step, diff_fmt)
        updated = Signal(info.shape())
        # a convex combination of Λ and c·N: within information_fmt
        m.d.comb += updated.eq(Mux(self.valid, hdl_resize(kept, kept_fmt, info, Rounding.FLOOR,
                                                          Overflow.ERROR), rounded4))
        m.d.comb += [write.addr.eq(Mux(current, 0, entries) + s4.index),
                     write.data.eq(updated), write.en.eq(advance & s4.valid)]
        total, total_format = hdl_add(s4.normal, normal, updated, info)
        with m.If(advance):
            m.d.sync += [self.o.valid.eq(s4.valid), self.o.payload.last.eq(s4.end),
                         self.o.payload.value.eq(hdl_resize(total, total_format, total_fmt(p),
                                                            Rounding.FLOOR, Overflow.ERROR))]

        # row framing: a row ends with `last` or at the 21st entry; either alone is
        # malformed (counted, never kept)
        with m.If(take):
            m.d.sync += index.eq(Mux(ends, 0, index + 1))
            with m.If(ends):
                well_formed = self.i.payload.last & (index == entries - 1)
                m.d.sync += [closed.eq(1), bad_row.eq(~well_formed)]
                with m.If(~well_formed):
                    m.d.sync += self.malformed.eq(self.malformed + 1)
        with m.If(self.o.valid & self.o.ready & self.o.payload.last):
            m.d.sync += drained.eq(1)

        m.d.comb += self.keep.ready.eq(closed & drained)
        with m.If(self.keep.valid & self.keep.ready):
            m.d.sync += [closed.eq(0), drained.eq(0)]
            with m.If(self.keep.payload & ~bad_row):
                m.d.sync += [current.eq(~current), self.valid.eq(1)]
        return m


def default_prior_store():
    """The prior store of the board rig (``stereo8-board``, its solver's formats) with the
    information gain: the catalog's build, for Verilog and synthesis."""
    from golden.rig import preset
    from hdl.pipeline_config import PipelineConfig
    config = PipelineConfig.for_rig(preset("stereo8-board"))
    return PriorStore(config.forecast(motion_gain="information"))

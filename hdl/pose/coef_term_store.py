"""The forecast's copies of a coefficient store: per clock, only the two coefficients one
design term needs (:func:`hdl.pose.forecast_predictor.displacement_terms`).

The forecast and :class:`hdl.pose.measured_shift.MeasuredShift` form a segment's design
row one term per clock: term ``i`` (0–5) needs coefficient ``i`` (``a_T`` for ``i < 3``,
``a_C`` after) and, for ``i ≥ 3``, the rotation coefficient ``a_R`` of the same axis
(``6 + i mod 3``). A :class:`hdl.pose.coef_store.CoefficientStore` of polynomials
evaluates all nine per clock, one Horner chain each; here the terms of the two needed
coefficients are selected as they leave the memories and only two chains run per read
port, in a format that holds every selected term exactly (the fraction and integer bits
of the widest), so the sum is the same number and its one half-even rounding into the
selected coefficient's format gives the same raw value as the nine-chain store — on a
polynomial store, 2 multipliers per Horner step and port instead of 9.

Same memories, contents, checks and latency (``coef_latency``) as the solver's store; no
run-time write port (the forecast's contents are fixed at build time).
"""

from amaranth.hdl import Array, Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import QFormat, Overflow, Rounding, hdl_resize
from hdl.pose.coef_store import CoefficientStore, checked_contents, delayed_rows, horner

__all__ = ["TermStore", "term_read_signature", "second_index"]


def term_read_signature(params):
    """A read port from the reader's side: ``slot``, camera ``row`` and design ``term``
    (0–5) out, sampled every clock; ``params.coef_latency`` clocks later ``first`` (raw
    coefficient ``term``: ``coef_t_fmt`` for terms 0–2, ``coef_c_fmt`` after) and
    ``second`` (coefficient :func:`second_index`, raw ``coef_r_fmt``) in."""
    width = params.coef_width
    return wiring.Signature({"slot": Out(params.slot_bits), "row": Out(params.row_bits),
                             "term": Out(range(6)), "first": In(signed(width)),
                             "second": In(signed(width))})


def second_index(term):
    """The coefficient given as ``second`` for design term ``term``: ``a_R`` of its axis,
    ``6 + term mod 3`` (used by the terms 3–5 only)."""
    return 6 + term % 3


class TermStore(CoefficientStore):
    """Two coefficients of one design term per read port (no write port).

    Parameters
    ----------
    params : PoseSolverParams
    contents : ndarray (slots, entries_per_slot, 9) of int
        Raw contents: polynomial terms, or every row.
    name : str
        The contents' name in error messages.
    second_read : bool
        Add the read port ``second_port``.

    Members
    -------
    slot, row, term : In
        The segment, camera row and design term (sampled every clock).
    first, second : Out(signed(coef_width))
        Its coefficients (:func:`term_read_signature`), ``params.coef_latency`` clocks
        later.
    second_port : In(term_read_signature(params)), with ``second_read``
    """

    writable = False

    def __init__(self, params, contents, *, name="coefficients", second_read=False):
        self.params = params
        self.contents = checked_contents(params, contents, name)
        self.second_read = second_read
        width = params.coef_width
        wiring.Component.__init__(self, {
            "slot": In(params.slot_bits), "row": In(params.row_bits), "term": In(range(6)),
            "first": Out(signed(width)), "second": Out(signed(width)),
            **({"second_port": In(term_read_signature(params))} if second_read else {}),
        })

    def _ports(self):
        """The read ports' (slot, row, term, first, second)."""
        ports = [(self.slot, self.row, self.term, self.first, self.second)]
        if self.second_read:
            q = self.second_port
            ports.append((q.slot, q.row, q.term, q.first, q.second))
        return ports

    def elaborate(self, platform):
        p = self.params
        m = Module()
        ports = self._ports()
        powers = range(p.coef_terms) if p.coef_terms else (None,)
        # memories[k][t][n]: coefficient k, power t, port n's data
        memories = [[self._memory(m, f"coefficients{k}" + ("" if t is None else f"_{t}"),
                                  signed(p.coef_fmt(k, t).width), k, t) for t in powers]
                    for k in range(9)]
        for n, (_, row, term, first, second) in enumerate(ports):
            suffix = f"_{n}" * n
            term1 = Signal(range(6), name=f"term1{suffix}")     # meets the memories' data
            m.d.sync += term1.eq(term)
            choices = ((first, range(6), term1), (second, range(6, 9), term1 % 3))
            if not p.coef_terms:
                m.d.comb += [out.eq(Array(memories[k][0][n] for k in indices)[index])
                             for out, indices, index in choices]
                continue
            rows = delayed_rows(m, p, row, suffix)
            # the term at the rounding, coef_terms − 1 Horner clocks after the data
            held = term1
            for d in range(p.coef_terms - 1):
                later = Signal(range(6), name=f"term{d + 2}{suffix}")
                m.d.sync += later.eq(held)
                held = later
            for out, indices, index in choices:
                fmts = [_union(p.coef_fmt(k, t) for k in indices) for t in powers]
                terms = []
                for t in powers:
                    chosen = Signal(fmts[t].shape(), name=f"chosen{indices[0]}_{t}{suffix}")
                    m.d.comb += chosen.eq(Array(
                        hdl_resize(memories[k][t][n], p.coef_fmt(k, t), fmts[t],
                                   Rounding.FLOOR, Overflow.ERROR) for k in indices)[index])
                    terms.append(chosen)
                acc, fmt = horner(m, p, terms, fmts, rows, f"{indices[0]}{suffix}")
                groups = sorted({k // 3 for k in indices})
                rounded = [hdl_resize(acc, fmt, p.coef_group_fmts[g], Rounding.HALF_EVEN,
                                      Overflow.SATURATE) for g in groups]
                m.d.sync += out.eq(rounded[0] if len(rounded) == 1 else
                                   Mux(held < 3, rounded[0], rounded[1]))
        return m


def _union(fmts):
    """The signed format that holds every value of ``fmts`` exactly."""
    fmts = list(fmts)
    return QFormat(True, max(f.int_bits for f in fmts), max(f.frac_bits for f in fmts))

"""Cue mapper: the per-stereo-segment cues of one or more stereo pairs → each temporal
segment's cue for each pair's camera A and camera B, bit-exact with
:func:`emulator.measurement.cue_map.pair_cues` pair by pair.

The arithmetic, its formats and why it exists: :mod:`hdl.measurement.cue_map_params`.
The gateware walks ``(1 + B_PASSES)·P·K`` items through a six-stage pipeline, one item
per clock: camera A's K segments of every pair, then each of camera B's passes over
every pair (a pass needs the previous pass's cue of the same pair and segment, so it
waits until that result is written when ``P·K < 6``). One multiplier forms the weight,
one the interpolation step; the constants (segment centres, reciprocals) are small
tables indexed by the item. The pairs share those two multipliers (issue 17: a mapper
per pair took 5 DSP48 each on the board, where the walk of all four pairs still
takes a few dozen clocks of a row period's thousands).
"""

from types import SimpleNamespace

from amaranth.hdl import Array, Const, Module, Mux, Signal, Value
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from golden.checks import check_int
from hdl.fixed import Overflow, Rounding, hdl_add, hdl_mul, hdl_resize
from hdl.measurement.cue_map_params import B_PASSES, WEIGHT_FMT, CueMap

__all__ = ["CueMapper"]

#: Pipeline registers from an item's issue to its written result.
STAGES = 6


def _register(m, stage, **values):
    """One pipeline register: each value (or ``(value, shape)``) into a Signal named
    after it and the stage, loaded every clock; returns them as attributes."""
    out = {}
    for name, value in values.items():
        value, shape = value if isinstance(value, tuple) else (value, None)
        value = Value.cast(value)
        reg = Signal(shape if shape is not None else value.shape(), name=f"{name}{stage}")
        m.d.sync += reg.eq(value)
        out[name] = reg
    return SimpleNamespace(**out)


class CueMapper(wiring.Component):
    """Maps the stereo cues of ``pairs`` pairs to the temporal segments' cues of both
    cameras of each.

    Parameters
    ----------
    cue_map : CueMap
    pairs : int
        Stereo pairs mapped in each walk (P), 1 or more.

    Members
    -------
    start : In(1)
        Pulse: ``cues`` and ``usable`` hold a row's stereo cues and stay unchanged
        until ``busy`` falls. A start while busy begins the walk again (the router
        never gives one).
    cues : In(ArrayLayout(ArrayLayout(cue_fmt, K_s), P))
    usable : In(ArrayLayout(K_s, P))
        Raw cue and usability of each pair's stereo segments.
    busy : Out(1)
        High from the clock after ``start`` for :attr:`latency` − 1 clocks; when it
        falls the outputs hold the row's mapped cues, until the next start.
    cue_a, cue_b : Out(ArrayLayout(ArrayLayout(cue_fmt, K), P))
    usable_a, usable_b : Out(ArrayLayout(K, P))
        Each pair's camera A's and camera B's mapped cue of each temporal segment and
        whether it has one (a cue without ``usable`` is 0; none outside the stereo
        lane's columns, ``CueMap.covered``: camera B's passes move by the held results
        before that test).
    """

    def __init__(self, cue_map, pairs=1):
        if not isinstance(cue_map, CueMap):
            raise TypeError(f"cue_map must be a CueMap, not {cue_map!r}")
        check_int("pairs", pairs, 1)
        self.params, self.pairs = cue_map, pairs
        cue = cue_map.cue_fmt.shape()
        cues_k = data.ArrayLayout(data.ArrayLayout(cue, cue_map.segments), pairs)
        usable_k = data.ArrayLayout(cue_map.segments, pairs)
        super().__init__({
            "start": In(1),
            "cues": In(data.ArrayLayout(data.ArrayLayout(cue, cue_map.stereo_segments),
                                        pairs)),
            "usable": In(data.ArrayLayout(cue_map.stereo_segments, pairs)),
            "busy": Out(1),
            "cue_a": Out(cues_k), "usable_a": Out(usable_k),
            "cue_b": Out(cues_k), "usable_b": Out(usable_k),
        })

    @staticmethod
    def gap_of(cue_map, pairs=1):
        """Idle issue clocks after each pass, so that the next pass reads the result of
        the same pair and segment (``STAGES`` clocks after its issue)."""
        return max(0, STAGES - pairs * cue_map.segments)

    @classmethod
    def latency_of(cls, cue_map, pairs=1):
        """Clocks from ``start`` to the clock ``busy`` has fallen with the results."""
        gap = cls.gap_of(cue_map, pairs)
        return (1 + B_PASSES) * (pairs * cue_map.segments + gap) - gap + STAGES

    @property
    def latency(self):
        """:meth:`latency_of` this mapper's map and pairs."""
        return self.latency_of(self.params, self.pairs)

    def elaborate(self, platform):
        cm = self.params
        k_seg, ks, f = cm.segments, cm.stereo_segments, cm.cue_fmt.frac_bits
        n_pairs = self.pairs
        m = Module()

        # --- issue: pass 0 (camera A) of pair j at steps j·K … j·K + K − 1, pass q at
        # q·(P·K + gap) onwards, pair by pair
        items = n_pairs * k_seg
        period = items + self.gap_of(cm, n_pairs)
        item = Signal(range(period))                # position in the pass
        k0 = Signal(range(k_seg))                   # the item's segment ...
        pair = Signal(range(n_pairs))               # ... and pair
        pass_ = Signal(range(B_PASSES + 2))         # B_PASSES + 1: issue over, draining
        drain = Signal(range(STAGES))
        with m.If(self.start):
            m.d.sync += [self.busy.eq(1), item.eq(0), k0.eq(0), pair.eq(0), pass_.eq(0),
                         drain.eq(0)]
        with m.Elif(self.busy):
            with m.If(pass_ == B_PASSES + 1):
                m.d.sync += drain.eq(drain + 1)
                with m.If(drain == STAGES - 2):
                    m.d.sync += self.busy.eq(0)
            with m.Elif((item == period - 1) | ((pass_ == B_PASSES) & (item == items - 1))):
                m.d.sync += [item.eq(0), k0.eq(0), pair.eq(0), pass_.eq(pass_ + 1)]
            with m.Else():
                m.d.sync += item.eq(item + 1)
                with m.If(k0 == k_seg - 1):
                    m.d.sync += [k0.eq(0), pair.eq(pair + 1)]
                with m.Else():
                    m.d.sync += k0.eq(k0 + 1)
        issue = self.busy & (pass_ <= B_PASSES) & (item < items)
        role_b = pass_ != 0

        # stage 1: the position (twice A's column), camera B's moved by the previous
        # pass's cue (camera A's in pass 1, its own after)
        pos_fmt = cm.position_fmt
        centre = Array(Const(t << f, pos_fmt.shape()) for t in cm.temporal)[k0]
        # each pass's results, before the coverage test: camera B's passes move by them
        held = {role: [[Signal(cm.cue_fmt.shape(), name=f"held_{role}{j}_{k}")
                        for k in range(k_seg)] for j in range(n_pairs)] for role in "ab"}
        held_ok = {role: [Signal(k_seg, name=f"held_ok_{role}{j}") for j in range(n_pairs)]
                   for role in "ab"}
        from_b = pass_ > 1

        def held_of(role):
            return (Array(Array(row) for row in held[role])[pair][k0],
                    Array(held_ok[role])[pair].bit_select(k0, 1))
        (held_a, ok_a), (held_b, ok_b) = held_of("a"), held_of("b")
        moved, moved_ok = Mux(from_b, held_b, held_a), Mux(from_b, ok_b, ok_a)
        tag = {"v": issue, "b": role_b, "k": k0, "pair": pair}
        p1 = _register(m, 1, **tag, ok=~role_b | moved_ok,
                       x=(centre + Mux(role_b, moved << 1, 0), pos_fmt.shape()))
        tag = {"v": p1.v, "b": p1.b, "k": p1.k, "pair": p1.pair, "ok": p1.ok}

        # stage 2: clamp; the interval from the inner centres (the clamp cannot change
        # a comparison with them), beside it rather than after
        s_lo, s_hi = cm.stereo[0] << f, cm.stereo[-1] << f
        inner = [p1.x >= (c << f) for c in cm.stereo[1:-1]]
        tag["inside"] = cm.covered(p1.x)
        p2 = _register(m, 2, **tag,
                       x=(Mux(p1.x < s_lo, s_lo, Mux(p1.x > s_hi, s_hi, p1.x)),
                          pos_fmt.shape()),
                       j=(sum(inner) if inner else 0, range(max(2, ks - 1))))
        tag = {"v": p2.v, "b": p2.b, "k": p2.k, "pair": p2.pair, "ok": p2.ok,
               "inside": p2.inside}

        # stage 3: distance from the interval's left centre; its pair's cues and the
        # reciprocal
        far_j = p2.j + 1 if ks > 1 else p2.j
        stereo_cues = Array(Array(self.cues[j][i] for i in range(ks))
                            for j in range(n_pairs))[p2.pair]
        usable = Array(self.usable[j] for j in range(n_pairs))[p2.pair]
        base = Array(Const(c << f, pos_fmt.shape()) for c in cm.stereo)[p2.j]
        reciprocal = (Array(Const(r, cm.reciprocal_fmt.shape()) for r in cm.reciprocal)[p2.j]
                      if ks > 1 else 0)
        cue = cm.cue_fmt.shape()
        p3 = _register(m, 3, **tag, d=(p2.x - base, cm.distance_fmt.shape()),
                       r=(reciprocal, cm.reciprocal_fmt.shape()),
                       near=(stereo_cues[p2.j], cue), far=(stereo_cues[far_j], cue),
                       un=usable.bit_select(p2.j, 1), uf=usable.bit_select(far_j, 1))
        tag = {"v": p3.v, "b": p3.b, "k": p3.k, "pair": p3.pair, "ok": p3.ok,
               "inside": p3.inside, "near": p3.near, "far": p3.far, "un": p3.un,
               "uf": p3.uf}

        # stage 4: the weight
        exact, fmt = hdl_mul(p3.d, cm.distance_fmt, p3.r, cm.reciprocal_fmt)
        p4 = _register(m, 4, **tag, w=(hdl_resize(exact, fmt, WEIGHT_FMT, Rounding.FLOOR,
                                                   Overflow.ERROR), WEIGHT_FMT.shape()))

        # stage 5: near + w · (far − near), exact
        diff = Signal(cm.difference_fmt.shape())
        m.d.comb += diff.eq(p4.far - p4.near)
        step_v, step_fmt = hdl_mul(p4.w, WEIGHT_FMT, diff, cm.difference_fmt)
        total_v, total_fmt = hdl_add(p4.near, cm.cue_fmt, step_v, step_fmt)
        tag = {name: getattr(p4, name) for name in ("v", "b", "k", "pair", "ok", "inside",
                                                     "near", "far", "un", "uf")}
        p5 = _register(m, 5, **tag, total=(total_v, total_fmt.shape()))

        # stage 6: round, or the one usable cue alone; write the item's result
        rounded = hdl_resize(p5.total, total_fmt, cm.cue_fmt, Rounding.HALF_EVEN,
                             Overflow.ERROR)
        value = Mux(p5.un & p5.uf, rounded, Mux(p5.un, p5.near, p5.far))
        has = p5.ok & (p5.un | p5.uf)
        kept = has & p5.inside
        for j in range(n_pairs):
            for k in range(k_seg):
                for role, cues, usable in ((0, self.cue_a, self.usable_a),
                                           (1, self.cue_b, self.usable_b)):
                    name = "ab"[role]
                    with m.If(p5.v & (p5.b == role) & (p5.pair == j) & (p5.k == k)):
                        m.d.sync += [held[name][j][k].eq(Mux(has, value, 0)),
                                     held_ok[name][j][k].eq(has),
                                     cues[j][k].eq(Mux(kept, value, 0)),
                                     usable[j][k].eq(kept)]
        return m

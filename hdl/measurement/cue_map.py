"""Cue mapper: one stereo pair's per-stereo-segment cues → each temporal segment's cue
for camera A and camera B, bit-exact with :func:`emulator.measurement.cue_map.pair_cues`.

The arithmetic, its formats and why it exists: :mod:`hdl.measurement.cue_map_params`.
The gateware walks ``(1 + B_PASSES)·K`` items through a six-stage pipeline, one item
per clock: camera A's K segments, then each of camera B's passes (whose position needs
the previous pass's cue of the same segment, so a pass waits until that result is
written when K < 6). One multiplier forms the weight, one the interpolation step; the
constants (segment centres, reciprocals) are small tables indexed by the item.
"""

from types import SimpleNamespace

from amaranth.hdl import Array, Const, Module, Mux, Signal, Value
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

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
    """Maps one pair's stereo cues to the temporal segments' cues of both cameras.

    Parameters
    ----------
    cue_map : CueMap

    Members
    -------
    start : In(1)
        Pulse: ``cues`` and ``usable`` hold a row's stereo cues and stay unchanged
        until ``busy`` falls. A start while busy begins the walk again (the router
        never gives one).
    cues : In(ArrayLayout(cue_fmt, K_s))
    usable : In(K_s)
        Raw cue and usability of each stereo segment.
    busy : Out(1)
        High from the clock after ``start`` for :attr:`latency` − 1 clocks; when it
        falls the outputs hold the row's mapped cues, until the next start.
    cue_a, cue_b : Out(ArrayLayout(cue_fmt, K))
    usable_a, usable_b : Out(K)
        Camera A's and camera B's mapped cue of each temporal segment and whether it
        has one (a cue without ``usable`` is 0; none outside the stereo lane's columns,
        ``CueMap.covered``: camera B's passes move by the held results before that
        test).
    """

    def __init__(self, cue_map):
        if not isinstance(cue_map, CueMap):
            raise TypeError(f"cue_map must be a CueMap, not {cue_map!r}")
        self.params = cue_map
        cues_k = data.ArrayLayout(cue_map.cue_fmt.shape(), cue_map.segments)
        super().__init__({
            "start": In(1),
            "cues": In(data.ArrayLayout(cue_map.cue_fmt.shape(), cue_map.stereo_segments)),
            "usable": In(cue_map.stereo_segments),
            "busy": Out(1),
            "cue_a": Out(cues_k), "usable_a": Out(cue_map.segments),
            "cue_b": Out(cues_k), "usable_b": Out(cue_map.segments),
        })

    @staticmethod
    def gap_of(cue_map):
        """Idle issue clocks after each pass, so that the next pass reads the result of
        the same segment (``STAGES`` clocks after its issue)."""
        return max(0, STAGES - cue_map.segments)

    @classmethod
    def latency_of(cls, cue_map):
        """Clocks from ``start`` to the clock ``busy`` has fallen with the results."""
        period = cue_map.segments + cls.gap_of(cue_map)
        return (1 + B_PASSES) * period - cls.gap_of(cue_map) + STAGES

    @property
    def latency(self):
        """:meth:`latency_of` this mapper's map."""
        return self.latency_of(self.params)

    def elaborate(self, platform):
        cm = self.params
        k_seg, ks, f = cm.segments, cm.stereo_segments, cm.cue_fmt.frac_bits
        m = Module()

        # --- issue: pass 0 (camera A) at steps 0 … K−1, pass p at p·(K + gap) + k -------
        period = k_seg + self.gap_of(cm)
        k_bits = max(1, (period - 1).bit_length())
        item = Signal(k_bits)                       # position in the pass (K + gap steps)
        pass_ = Signal(range(B_PASSES + 2))         # B_PASSES + 1: issue over, draining
        drain = Signal(range(STAGES))
        with m.If(self.start):
            m.d.sync += [self.busy.eq(1), item.eq(0), pass_.eq(0), drain.eq(0)]
        with m.Elif(self.busy):
            with m.If(pass_ == B_PASSES + 1):
                m.d.sync += drain.eq(drain + 1)
                with m.If(drain == STAGES - 2):
                    m.d.sync += self.busy.eq(0)
            with m.Elif((item == period - 1)
                        | ((pass_ == B_PASSES) & (item == k_seg - 1))):
                m.d.sync += [item.eq(0), pass_.eq(pass_ + 1)]
            with m.Else():
                m.d.sync += item.eq(item + 1)
        issue = self.busy & (pass_ <= B_PASSES) & (item < k_seg)
        k0 = item[:max(1, (k_seg - 1).bit_length())]
        role_b = pass_ != 0

        # stage 1: the position (twice A's column), camera B's moved by the previous
        # pass's cue (camera A's in pass 1, its own after)
        pos_fmt = cm.position_fmt
        centre = Array(Const(t << f, pos_fmt.shape()) for t in cm.temporal)[k0]
        # each pass's results, before the coverage test: camera B's passes move by them
        held = {role: [Signal(cm.cue_fmt.shape(), name=f"held_{role}{k}")
                       for k in range(k_seg)] for role in "ab"}
        held_ok = {role: Signal(k_seg, name=f"held_ok_{role}") for role in "ab"}
        from_b = pass_ > 1
        moved = Mux(from_b, Array(held["b"])[k0], Array(held["a"])[k0])
        moved_ok = Mux(from_b, held_ok["b"].bit_select(k0, 1),
                       held_ok["a"].bit_select(k0, 1))
        tag = {"v": issue, "b": role_b, "k": k0}
        p1 = _register(m, 1, **tag, ok=~role_b | moved_ok,
                       x=(centre + Mux(role_b, moved << 1, 0), pos_fmt.shape()))
        tag = {"v": p1.v, "b": p1.b, "k": p1.k, "ok": p1.ok}

        # stage 2: clamp; the interval from the inner centres (the clamp cannot change
        # a comparison with them), beside it rather than after
        s_lo, s_hi = cm.stereo[0] << f, cm.stereo[-1] << f
        inner = [p1.x >= (c << f) for c in cm.stereo[1:-1]]
        tag["inside"] = cm.covered(p1.x)
        p2 = _register(m, 2, **tag,
                       x=(Mux(p1.x < s_lo, s_lo, Mux(p1.x > s_hi, s_hi, p1.x)),
                          pos_fmt.shape()),
                       j=(sum(inner) if inner else 0, range(max(2, ks - 1))))
        tag = {"v": p2.v, "b": p2.b, "k": p2.k, "ok": p2.ok, "inside": p2.inside}

        # stage 3: distance from the interval's left centre; its cues and reciprocal
        far_j = p2.j + 1 if ks > 1 else p2.j
        stereo_cues = Array(self.cues[i] for i in range(ks))
        base = Array(Const(c << f, pos_fmt.shape()) for c in cm.stereo)[p2.j]
        reciprocal = (Array(Const(r, cm.reciprocal_fmt.shape()) for r in cm.reciprocal)[p2.j]
                      if ks > 1 else 0)
        cue = cm.cue_fmt.shape()
        p3 = _register(m, 3, **tag, d=(p2.x - base, cm.distance_fmt.shape()),
                       r=(reciprocal, cm.reciprocal_fmt.shape()),
                       near=(stereo_cues[p2.j], cue), far=(stereo_cues[far_j], cue),
                       un=self.usable.bit_select(p2.j, 1),
                       uf=self.usable.bit_select(far_j, 1))
        tag = {"v": p3.v, "b": p3.b, "k": p3.k, "ok": p3.ok, "inside": p3.inside,
               "near": p3.near, "far": p3.far, "un": p3.un, "uf": p3.uf}

        # stage 4: the weight
        exact, fmt = hdl_mul(p3.d, cm.distance_fmt, p3.r, cm.reciprocal_fmt)
        p4 = _register(m, 4, **tag, w=(hdl_resize(exact, fmt, WEIGHT_FMT, Rounding.FLOOR,
                                                   Overflow.ERROR), WEIGHT_FMT.shape()))

        # stage 5: near + w · (far − near), exact
        diff = Signal(cm.difference_fmt.shape())
        m.d.comb += diff.eq(p4.far - p4.near)
        step_v, step_fmt = hdl_mul(p4.w, WEIGHT_FMT, diff, cm.difference_fmt)
        total_v, total_fmt = hdl_add(p4.near, cm.cue_fmt, step_v, step_fmt)
        tag = {name: getattr(p4, name) for name in ("v", "b", "k", "ok", "inside", "near",
                                                     "far", "un", "uf")}
        p5 = _register(m, 5, **tag, total=(total_v, total_fmt.shape()))

        # stage 6: round, or the one usable cue alone; write the item's result
        rounded = hdl_resize(p5.total, total_fmt, cm.cue_fmt, Rounding.HALF_EVEN,
                             Overflow.ERROR)
        value = Mux(p5.un & p5.uf, rounded, Mux(p5.un, p5.near, p5.far))
        has = p5.ok & (p5.un | p5.uf)
        kept = has & p5.inside
        for k in range(k_seg):
            for role, cues, usable in ((0, self.cue_a, self.usable_a),
                                       (1, self.cue_b, self.usable_b)):
                name = "ab"[role]
                with m.If(p5.v & (p5.b == role) & (p5.k == k)):
                    m.d.sync += [held[name][k].eq(Mux(has, value, 0)),
                                 held_ok[name][k].eq(has),
                                 cues[k].eq(Mux(kept, value, 0)), usable[k].eq(kept)]
        return m

"""Cue mapper: one stereo pair's per-stereo-segment cues → each temporal segment's cue
for camera A and camera B, bit-exact with :func:`emulator.measurement.cue_map.pair_cues`.

The arithmetic, its formats and why it exists: :mod:`hdl.measurement.cue_map_params`.
The gateware walks ``(1 + B_PASSES)·K`` items through a five-stage pipeline, one item
per clock: camera A's K segments, then each of camera B's passes (whose position needs
the previous pass's cue of the same segment, so a pass waits until that result is
written when K < 5). One multiplier forms the weight, one the interpolation step; the
constants (segment centres, reciprocals) are small tables indexed by the item.
"""

from amaranth.hdl import Array, Const, Module, Mux, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import Overflow, Rounding, hdl_add, hdl_mul, hdl_resize
from hdl.measurement.cue_map_params import B_PASSES, WEIGHT_FMT, CueMap

__all__ = ["CueMapper"]

#: Pipeline registers from an item's issue to its written result.
STAGES = 5


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
        has one (a cue without ``usable`` is 0).
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
        from_b = pass_ > 1
        moved = Mux(from_b, Array(self.cue_b[k] for k in range(k_seg))[k0],
                    Array(self.cue_a[k] for k in range(k_seg))[k0])
        moved_ok = Mux(from_b, self.usable_b.bit_select(k0, 1),
                       self.usable_a.bit_select(k0, 1))
        v1, b1, k1, ok1 = Signal(), Signal(), Signal.like(k0), Signal()
        x1 = Signal(pos_fmt.shape())
        m.d.sync += [v1.eq(issue), b1.eq(role_b), k1.eq(k0),
                     ok1.eq(~role_b | moved_ok),
                     x1.eq(centre + Mux(role_b, moved << 1, 0))]

        # stage 2: clamp, interval, distance; the interval's cues and reciprocal
        s_lo, s_hi = cm.stereo[0] << f, cm.stereo[-1] << f
        xc = Mux(x1 < s_lo, s_lo, Mux(x1 > s_hi, s_hi, x1))
        j = sum(xc >= (s << f) for s in cm.stereo[1:-1]) if ks > 2 else Const(0, 1)
        far_j = j + 1 if ks > 1 else j
        stereo_cues = Array(self.cues[i] for i in range(ks))
        base = Array(Const(s << f, pos_fmt.shape()) for s in cm.stereo)[j]
        v2, b2, k2, ok2 = Signal(), Signal(), Signal.like(k0), Signal()
        d2 = Signal(cm.distance_fmt.shape())
        r2 = Signal(cm.reciprocal_fmt.shape())
        near2, far2 = Signal(cm.cue_fmt.shape()), Signal(cm.cue_fmt.shape())
        un2, uf2 = Signal(), Signal()
        m.d.sync += [v2.eq(v1), b2.eq(b1), k2.eq(k1), ok2.eq(ok1),
                     d2.eq(xc - base),
                     near2.eq(stereo_cues[j]), far2.eq(stereo_cues[far_j]),
                     un2.eq(self.usable.bit_select(j, 1)),
                     uf2.eq(self.usable.bit_select(far_j, 1))]
        if ks > 1:
            m.d.sync += r2.eq(Array(Const(r, cm.reciprocal_fmt.shape())
                                    for r in cm.reciprocal)[j])

        # stage 3: the weight
        exact, fmt = hdl_mul(d2, cm.distance_fmt, r2, cm.reciprocal_fmt)
        v3, b3, k3, ok3 = Signal(), Signal(), Signal.like(k0), Signal()
        w3 = Signal(WEIGHT_FMT.shape())
        near3, far3 = Signal.like(near2), Signal.like(far2)
        un3, uf3 = Signal(), Signal()
        m.d.sync += [v3.eq(v2), b3.eq(b2), k3.eq(k2), ok3.eq(ok2), near3.eq(near2),
                     far3.eq(far2), un3.eq(un2), uf3.eq(uf2),
                     w3.eq(hdl_resize(exact, fmt, WEIGHT_FMT, Rounding.FLOOR,
                                      Overflow.ERROR))]

        # stage 4: near + w · (far − near), exact
        diff = Signal(cm.difference_fmt.shape())
        m.d.comb += diff.eq(far3 - near3)
        step_v, step_fmt = hdl_mul(w3, WEIGHT_FMT, diff, cm.difference_fmt)
        total_v, total_fmt = hdl_add(near3, cm.cue_fmt, step_v, step_fmt)
        v4, b4, k4, ok4 = Signal(), Signal(), Signal.like(k0), Signal()
        total4 = Signal(total_fmt.shape())
        near4, far4 = Signal.like(near2), Signal.like(far2)
        un4, uf4 = Signal(), Signal()
        m.d.sync += [v4.eq(v3), b4.eq(b3), k4.eq(k3), ok4.eq(ok3), near4.eq(near3),
                     far4.eq(far3), un4.eq(un3), uf4.eq(uf3), total4.eq(total_v)]

        # stage 5: round, or the one usable cue alone; write the item's result
        rounded = hdl_resize(total4, total_fmt, cm.cue_fmt, Rounding.HALF_EVEN,
                             Overflow.ERROR)
        value = Mux(un4 & uf4, rounded, Mux(un4, near4, far4))
        has = ok4 & (un4 | uf4)
        for k in range(k_seg):
            for role, cues, usable in ((0, self.cue_a, self.usable_a),
                                       (1, self.cue_b, self.usable_b)):
                with m.If(v4 & (b4 == role) & (k4 == k)):
                    m.d.sync += [cues[k].eq(Mux(has, value, 0)), usable[k].eq(has)]
        return m

"""Shift matcher: Hamming costs over the shift window, per segment, at line rate.

For every column of the compared range the current bit is compared with the reference
bits at all ``n`` shifts of the window at once (``n`` cost counters), so the costs are
complete when the segment's last column has streamed in. A small engine then scans
the frozen costs ``scan_lanes`` at a time, twice (first minimum, then the second
minimum at distance ≥ 2 and the minimum's neighbours), and divides twice in parallel
(offset peak ratio, parabola vertex) with one-bit-per-clock restoring dividers. A row's K
results leave together, in segment order, once its last segment is done: only then is
the row's bad verdict known (a camera reports reason bits with the last pixel).
"""

from amaranth.hdl import Array, Cat, Const, Elaboratable, Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.fixed import UQ, Overflow, Rounding, hdl_resize
from hdl.descriptor.layouts import meta_layout, pair_layout
from hdl.descriptor.params import RowDescriptorParams
from hdl.slot_register import SlotRegister

__all__ = ["SerialDivider", "ShiftMatcher"]


class SerialDivider(Elaboratable):
    """Restoring divider: ``quotient = min(num // den, 2**quotient_bits − 1)``.

    One quotient bit per clock, most significant first; ``den = 0`` gives all ones. A
    pulse on ``start`` loads ``num``/``den``; ``quotient`` is final ``quotient_bits``
    clocks later (``busy`` low again) and holds until the next ``start``.
    """

    def __init__(self, num_width, den_width, quotient_bits):
        self.quotient_bits = quotient_bits
        self.start = Signal()
        self.num = Signal(num_width)
        self.den = Signal(den_width)
        self.quotient = Signal(quotient_bits)
        self.busy = Signal()

    def elaborate(self, platform):
        m = Module()
        qb = self.quotient_bits
        rem = Signal.like(self.num)
        divisor = Signal(len(self.den) + qb - 1)
        count = Signal(range(qb + 1))
        fits = rem >= divisor
        m.d.comb += self.busy.eq(count != 0)
        with m.If(self.start):
            m.d.sync += [rem.eq(self.num), divisor.eq(self.den << (qb - 1)),
                         self.quotient.eq(0), count.eq(qb)]
        with m.Elif(self.busy):
            m.d.sync += [rem.eq(Mux(fits, rem - divisor, rem)),
                         self.quotient.eq(Cat(fits, self.quotient[:-1])),
                         divisor.eq(divisor >> 1), count.eq(count - 1)]
        return m


def _slot_shape(ports):
    """A port index, one bit at least: with a zero-width index (one port) the Amaranth
    simulator passed the lanes' tests, but the Verilog lost the engine's dividers in
    synthesis and failed the temporal lane's Verilator bench (the construct at fault
    was not isolated)."""
    return range(max(ports, 2))


def _first_min(items):
    """Lowest value and its index among ``(value, index)`` in index order (ties: first)."""
    while len(items) > 1:
        nxt = []
        for t in range(0, len(items) - 1, 2):
            (va, ia), (vb, ib) = items[t], items[t + 1]
            take_b = vb < va
            nxt.append((Mux(take_b, vb, va), Mux(take_b, ib, ia)))
        if len(items) % 2:
            nxt.append(items[-1])
        items = nxt
    return items[0]


class ShiftMatcher(wiring.Component):
    """Per-segment shift, sub-pixel refinement and confidence of a streaming row.

    Input columns carry the current bit and the reference bit of the same column. Two
    delay lines (taps from the row's centre: ``params.delays``) line ``cur[x]`` up with
    ``ref[x − centre − shift_min]``; an ``n``-bit window of later reference bits gives
    every shift of the window. Columns outside ``params.compare_range(centre)`` are not
    counted (they depend on the built window only); the range is cut into K equal segments by a Bresenham stepper (golden's
    ``lo + (hi − lo)·k // K`` bounds exactly). When a segment ends its costs are frozen
    for the engine and the counters restart; if the engine is still busy with the
    previous segment, the input stalls (never when every segment is at least
    ``params.engine_period`` columns long, which the parameters guarantee).

    The row's run-time half-width ``meta.half_width`` (saturated by the framer) limits
    the search to ``[−w, w]`` around the centre: costs outside are read as ``top`` (above
    any cost), so they win neither minimum nor count as neighbours, and a best shift on
    the run-time window's first or last shift is ``edge_hit`` (no sub-pixel), as on the
    built window's. At ``max_half_width`` nothing changes (bit for bit).

    With ``ports`` > 1 one matcher serves that many column streams (cameras) in turn
    (issue 17 item 3): port ``k`` is read in every ``ports``-th clock (a clock with
    nothing offered there is a bubble), and the front's per-row state (delay lines,
    stepper, cost counters) is kept per port in rings that turn with the ports
    (:class:`hdl.slot_register.SlotRegister`), so the adders and comparators are built
    once. The engine is shared: a segment that ends while it works on another port's
    waits in a queue of ``ports − 1`` jobs (costs and facts), so the segments of every
    port that end together stall nothing, and a row's results wait in their port's own
    bank. Each port's measurements are
    those of a matcher of its own, bit for bit, on its own output.

    Parameters
    ----------
    params : RowDescriptorParams
    ports : int
        Column streams served (default 1: one stream, the lane's own matcher).

    Members
    -------
    i : In(stream.Signature(pair_layout(params))), ``.array(ports)`` with ``ports`` > 1
    o : Out(stream.Signature(params.measurement_layout())), ``.array(ports)`` with ``ports`` > 1
        K measurements per row, segment order, Q formats in the layout's docstring; with
        ports, each port's rows on its own output (one row at a time leaves the
        matcher: a port whose output stalls holds the others').

    Latency :attr:`latency` clocks from the row's last column to its segment-0
    measurement, then one measurement per clock, when the engine is free (with ports,
    one engine job and a clock to start it, ``engine_result_step + 1`` clocks, more per
    other port's segment queued ahead of the row's last: at most ``ports − 1``). Throughput
    one column per clock (per port, one per ``ports`` clocks). Backpressure: ``o``
    holds; the engine waits to store its next result while the previous row's
    measurements are leaving, and input stalls behind it. Reset empties the pipeline
    and the engine; the costs restart with each segment.
    """

    def __init__(self, params, ports=1):
        if not isinstance(params, RowDescriptorParams):
            raise TypeError(f"params must be a RowDescriptorParams, not {params!r}")
        if not isinstance(ports, int) or isinstance(ports, bool) or not 1 <= ports <= 16:
            raise ValueError(f"ports must be an integer between 1 and 16, not {ports!r}")
        self.params = params
        self.ports = ports
        column = In(stream.Signature(pair_layout(params)))
        measurements = Out(stream.Signature(params.measurement_layout()))
        super().__init__({
            "i": column if ports == 1 else column.array(ports),
            "o": measurements if ports == 1 else measurements.array(ports),
        })

    @property
    def latency(self):
        """Two front stages, with ports a clock in the job queue, the engine's schedule,
        one clock to start the output sequence and one to register the first
        measurement."""
        return 2 + (self.ports > 1) + self.params.engine_result_step + 2

    @property
    def last_port_latency(self):
        """:attr:`latency` of the last port's row when every port's rows end together
        and columns come every ``ports`` clocks: one engine job per other port's segment
        queued ahead of it, a clock to start each, and a clock per port ahead for its
        column's slot (the engine's cocotb bench checks it)."""
        return self.latency + (self.ports - 1) * (self.params.engine_result_step + 2)

    def elaborate(self, platform):
        m = Module()
        front = self._front(m)
        self._engine(m, front)
        return m

    # --- front: delay lines, segment stepper, cost counters ------------------------------

    def _front(self, m):
        p, ports = self.params, self.ports
        n, k_seg, r, width = p.n_shifts, p.segments, p.radius, p.width
        cost_shape = p.cost_fmt.shape()
        dc_max, dr_max = p.max_delays
        geometry = {"d_cur": max(dc_max, 1).bit_length(),       # at least one bit (Verilog)
                    "d_ref": max(dr_max, 1).bit_length(),
                    "start_pos": range(2 * width), "length": range(width + 1)}

        engine_busy = Signal()
        s2_valid = Signal()
        s2 = Signal(data.StructLayout({
            "cur": 1, "ref": 1, "strong": 1, "in_range": 1, "seg_first": 1, "seg_end": 1,
            "seg": p.segment_bits, "meta": meta_layout(p), "no_reference": 1,
            "slot": _slot_shape(ports)}))
        stall = s2_valid & s2.in_range & s2.seg_end & engine_busy
        advance = ~stall

        # the port served this step (round robin; one slot per step, beat or bubble)
        slot = Signal(_slot_shape(ports), name="slot") if ports > 1 else Const(0)  # one port: none
        inputs = list(self.i) if ports > 1 else [self.i]
        with m.If(advance):
            m.d.sync += [slot.eq(Mux(slot == ports - 1, 0, slot + 1))] if ports > 1 else []
        offered = Array(port.valid for port in inputs)[slot] if ports > 1 else self.i.valid
        payload = Array(i.payload.as_value() for i in inputs)[slot] if ports > 1 else self.i.payload.as_value()

        # skid register: ready is a flip-flop (with ports, and the slot's decode), so a
        # stall does not ripple through the store and the FIR back to the camera input
        # within one clock
        skid_valid = Signal()
        skid = Signal(pair_layout(p))
        item = Signal(pair_layout(p))
        item_valid = skid_valid | offered
        m.d.comb += item.eq(Mux(skid_valid, skid.as_value(), payload))
        m.d.comb += [port.ready.eq(~skid_valid & (slot == k)) for k, port in enumerate(inputs)]
        with m.If(skid_valid & advance):
            m.d.sync += skid_valid.eq(0)
        with m.Elif(~skid_valid & offered & ~advance):
            m.d.sync += [skid_valid.eq(1), skid.eq(payload)]
        accept = item_valid & advance

        def state(shape, name):
            return SlotRegister(m, shape, slots=ports, step=advance, name=name)

        # stage 0: delay lines (bit 0 newest), the row's geometry from its centre (every
        # item carries it)
        cur_line, strong_line = state(dc_max + 1, "cur_line"), state(dc_max + 1, "strong_line")
        ref_line = state(dr_max + 1, "ref_line")
        with m.If(accept):
            m.d.comb += [cur_line.next.eq(Cat(item.cur, cur_line.head[:-1])),
                         strong_line.next.eq(Cat(item.strong, strong_line.head[:-1])),
                         ref_line.next.eq(Cat(item.ref, ref_line.head[:-1]))]
        a = item.meta.centre + p.match.shift_min
        a_top = a + (n - 1)
        d_cur = Mux(a < 0, -a, 0)
        lo = r + Mux(a_top > 0, a_top, 0)
        hi = width - r + Mux(a < 0, a, 0)
        s1_valid = Signal()
        s1 = Signal(data.StructLayout({"item": pair_layout(p), "slot": _slot_shape(ports),
                                       **geometry}))
        with m.If(advance):
            m.d.sync += [s1_valid.eq(item_valid), s1.item.eq(item), s1.slot.eq(slot),
                         s1.d_cur.eq(d_cur), s1.d_ref.eq(Mux(a > 0, a, 0)),
                         s1.start_pos.eq(lo + d_cur + r), s1.length.eq(hi - lo)]

        # stage 1: taps (the lines as stage 0 left them), compared range, segment stepper
        # t(p) = K(p+1) − 1 − len·s(p)
        acc, seg = state(range(width + k_seg), "acc"), state(p.segment_bits, "seg")
        prev_end = state(1, "prev_end")
        in_range = s1.item.pos >= s1.start_pos
        seg_end = acc.head + k_seg >= s1.length
        seg_first = (s1.item.pos == s1.start_pos) | prev_end.head
        with m.If(s1_valid):
            with m.If(s1.item.first):
                m.d.comb += [acc.next.eq(k_seg - 1), seg.next.eq(0), prev_end.next.eq(0)]
            with m.Elif(in_range):
                m.d.comb += [acc.next.eq(Mux(seg_end, acc.head + k_seg - s1.length,
                                             acc.head + k_seg)),
                             seg.next.eq(seg.head + seg_end), prev_end.next.eq(seg_end)]
        with m.If(advance):
            m.d.sync += [
                s2_valid.eq(s1_valid),
                s2.cur.eq(cur_line.tail.bit_select(s1.d_cur, 1)),
                s2.strong.eq(strong_line.tail.bit_select(s1.d_cur, 1)),
                s2.ref.eq(ref_line.tail.bit_select(s1.d_ref, 1)),
                s2.in_range.eq(in_range), s2.seg_first.eq(seg_first),
                s2.seg_end.eq(seg_end), s2.seg.eq(seg.head),
                s2.meta.eq(s1.item.meta), s2.no_reference.eq(s1.item.no_reference),
                s2.slot.eq(s1.slot),
            ]

        # stage 2: reference window, n cost counters, bit-change and strong counters
        window = state(n, "window")
        new_window = Cat(s2.ref, window.head[:n - 1])
        counters = [state(cost_shape, f"cost{k}") for k in range(n)]
        # a counter holds outside the compared range and in a bubble: by adding 0, not
        # by a multiplexer (a ring has no clock enable to hold with)
        counted = s2_valid & s2.in_range
        nxt = [Mux(s2.seg_first & counted, 0, c.head) + ((s2.cur ^ new_window[k]) & counted)
               for k, c in enumerate(counters)]
        min_t = p.match.min_transitions
        trans, prev_cur = state(p.transition_bits, "trans"), state(1, "prev_cur")
        trans_sum = trans.head + (s2.cur ^ prev_cur.head)
        trans_next = Mux(s2.seg_first, 0, Mux(trans_sum > min_t, min_t, trans_sum))
        min_s = p.match.min_strong
        strong = state(p.strong_bits, "strong")
        strong_sum = Mux(s2.seg_first, 0, strong.head) + s2.strong
        strong_next = Mux(strong_sum > min_s, min_s, strong_sum)
        m.d.comb += [c.next.eq(v) for c, v in zip(counters, nxt)]
        with m.If(s2_valid):
            m.d.comb += [window.next.eq(new_window), prev_cur.next.eq(s2.cur)]
            with m.If(s2.in_range):
                m.d.comb += [trans.next.eq(trans_next), strong.next.eq(strong_next)]

        snapshot = advance & s2_valid & s2.in_range & s2.seg_end
        flat = (trans_next < min_t) | (strong_next < min_s)
        return {"busy": engine_busy, "snapshot": snapshot, "costs": nxt,
                "textureless": flat, "s2": s2}

    # --- engine: two scans, two divisions, result bank, output sequence ------------------

    def _job_queue(self, m, front, incoming, step, shadow, snap, first, last):
        """Start the engine on each segment's job (``step`` 1); with ports, up to
        ``ports − 1`` jobs wait in a queue, in order, so the segments of every port that
        end together stall nothing. The front stalls only when the queue is full (with
        one port: while the engine works). With ports every job passes through the
        queue (a clock more), so the frozen costs have one source and need no
        multiplexer: with one, the board's two-port temporal matcher took 2,359 LUT,
        without 1,934 (before the counters' hold was folded into their adders)."""
        queue = [Signal(incoming.shape(), name=f"queued{k}") for k in range(self.ports - 1)]
        queued = [Signal(name=f"queued{k}_valid") for k in range(self.ports - 1)]
        idle = step == 0
        put = front["snapshot"]
        m.d.comb += front["busy"].eq(~idle & Cat(queued).all() if queue else ~idle)

        def start(job):
            m.d.sync += [sh.eq(v) for sh, v in zip(shadow, job.costs)]
            m.d.sync += [snap.eq(job.facts), first.eq(job.first), last.eq(job.last),
                         step.eq(1)]
        if not queue:
            with m.If(put):
                start(incoming)
            return
        take = idle & queued[0]                     # the oldest queued job starts
        with m.If(take):
            start(queue[0])
        # the queue moves up one place when its oldest job starts; a new one goes to
        # the first place then free
        for k, (job, valid) in enumerate(zip(queue, queued)):
            after_job = Mux(take, queue[k + 1].as_value(), job.as_value()) \
                if k + 1 < len(queue) else job.as_value()
            after_valid = Mux(take, queued[k + 1], valid) if k + 1 < len(queue) \
                else valid & ~take
            before_free = 1 if k == 0 else Mux(take, queued[k], queued[k - 1])
            lands = put & ~after_valid & before_free
            m.d.sync += [job.eq(Mux(lands, incoming.as_value(), after_job)),
                         valid.eq(after_valid | lands)]

    def _engine(self, m, front):
        p = self.params
        n, lanes, groups = p.n_shifts, p.scan_lanes, p.scan_groups
        cost_fmt = p.cost_fmt
        cost_shape = cost_fmt.shape()
        top = (1 << cost_fmt.width) - 1
        idx_shape = range(groups * lanes + 1)
        quotient = max(p.ratio_quotient_bits, p.subpixel_quotient_bits)
        load_step = 2 * groups + 5

        # the job: a segment's frozen costs, its facts and the run-time window's first
        # and last cost index (p.window_indices)
        facts_layout = data.StructLayout({
            "textureless": 1, "seg": p.segment_bits,
            "meta": meta_layout(p), "no_reference": 1, "slot": _slot_shape(self.ports)})
        job_layout = data.StructLayout({"costs": data.ArrayLayout(cost_shape, n),
                                        "facts": facts_layout, "first": range(n),
                                        "last": range(n)})
        shadow = [Signal(cost_shape, name=f"frozen{k}") for k in range(n)]
        snap = Signal(facts_layout)
        first, last = Signal(range(n), name="win_first"), Signal(range(n), name="win_last")
        step = Signal(range(p.engine_result_step + 1))
        incoming = Signal(job_layout)
        half_width = Signal(signed(p.half_width_fmt.width + 1))
        s2 = front["s2"]
        below = -p.match.shift_min - half_width
        above = half_width - p.match.shift_min
        m.d.comb += [half_width.eq(s2.meta.half_width),
                     incoming.facts.textureless.eq(front["textureless"]),
                     incoming.facts.seg.eq(s2.seg), incoming.facts.meta.eq(s2.meta),
                     incoming.facts.no_reference.eq(s2.no_reference),
                     incoming.facts.slot.eq(s2.slot),
                     incoming.first.eq(Mux(below > 0, below, 0)),
                     incoming.last.eq(Mux(above < n - 1, above, n - 1))]
        m.d.comb += [incoming.costs[k].eq(v) for k, v in enumerate(front["costs"])]
        self._job_queue(m, front, incoming, step, shadow, snap, first, last)

        def during(first, last):
            return (step >= first) & (step <= last)

        # read: one group of costs per step into the lane registers (an index outside
        # the run-time window, or ≥ n (padding): ``top``, above every cost, since a
        # cost is at most ``max_segment_cost``); steps 1 … G (pass 1) and G + 2 … 2G + 1
        # (pass 2)
        group = Signal(max(groups - 1, 1).bit_length())
        reading = during(1, groups) | during(groups + 2, 2 * groups + 1)
        with m.If(reading):
            m.d.sync += group.eq(Mux(group == groups - 1, 0, group + 1))
        lane_value = [Signal(cost_shape, name=f"lane{k}") for k in range(lanes)]
        lane_index = [Signal(idx_shape, name=f"lane_index{k}") for k in range(lanes)]
        for lane in range(lanes):
            column = [shadow[g * lanes + lane] if g * lanes + lane < n else Const(top)
                      for g in range(groups)]
            index = group * lanes + lane
            inside = (index >= first) & (index <= last)
            m.d.sync += [lane_value[lane].eq(Mux(inside, Array(column)[group], top)),
                         lane_index[lane].eq(index)]

        # pass 1: each group's first minimum (steps 2 … G + 1), folded (3 … G + 2)
        r1_value, r1_index = Signal(cost_shape), Signal(idx_shape)
        c1, i1 = Signal(cost_shape), Signal(idx_shape)
        group_min, group_idx = _first_min(list(zip(lane_value, lane_index)))
        m.d.sync += [r1_value.eq(group_min), r1_index.eq(group_idx)]
        with m.If((step == 3) | (during(4, groups + 2) & (r1_value < c1))):
            m.d.sync += [c1.eq(r1_value), i1.eq(r1_index)]

        # pass 2: mark each lane against the final first minimum (G + 3 … 2G + 2),
        # reduce (G + 4 … 2G + 3), fold (G + 5 … 2G + 4): second minimum, neighbours
        marks = Signal(data.StructLayout({
            "far": data.ArrayLayout(cost_shape, lanes), "below": lanes, "above": lanes,
            "value": data.ArrayLayout(cost_shape, lanes)}))
        for lane, (value, index) in enumerate(zip(lane_value, lane_index)):
            offset = index - i1
            real = (index >= first) & (index <= last)
            m.d.sync += [
                marks.far[lane].eq(Mux(real & ((offset >= 2) | (offset <= -2)), value, top)),
                marks.below[lane].eq(real & (offset == -1)),
                marks.above[lane].eq(real & (offset == 1)),
                marks.value[lane].eq(value),
            ]
        far_min = _first_min([(marks.far[k], Const(0)) for k in range(lanes)])[0]
        r2 = Signal(data.StructLayout({"far": cost_shape, "cm_hit": 1, "cp_hit": 1,
                                       "cm": cost_shape, "cp": cost_shape}))
        m.d.sync += [r2.far.eq(far_min), r2.cm_hit.eq(marks.below.any()),
                     r2.cp_hit.eq(marks.above.any()), r2.cm.eq(0), r2.cp.eq(0)]
        for k in range(lanes):
            with m.If(marks.below[k]):
                m.d.sync += r2.cm.eq(marks.value[k])
            with m.If(marks.above[k]):
                m.d.sync += r2.cp.eq(marks.value[k])
        c2, cm, cp = (Signal(cost_shape, name=nm) for nm in ("c2", "cm", "cp"))
        with m.If(step == groups + 4):
            m.d.sync += [c2.eq(top), cm.eq(0), cp.eq(0)]
        with m.If(during(groups + 5, 2 * groups + 4)):
            with m.If(r2.far < c2):
                m.d.sync += c2.eq(r2.far)
            with m.If(r2.cm_hit):
                m.d.sync += cm.eq(r2.cm)
            with m.If(r2.cp_hit):
                m.d.sync += cp.eq(r2.cp)

        # step 2G + 5: load both dividers; they run for the next Q steps
        edge = (i1 == first) | (i1 == last)
        cf, fs = p.confidence_fmt, p.subpixel_frac_bits
        kappa = p.match.peak_ratio_offset
        offset_width = max(cost_fmt.width, kappa.bit_length()) + 1
        m.submodules.ratio_div = ratio_div = SerialDivider(
            offset_width + cf.frac_bits + 1, offset_width, p.ratio_quotient_bits)
        m.submodules.subpx_div = subpx_div = SerialDivider(
            cost_fmt.width + fs, cost_fmt.width + 2, p.subpixel_quotient_bits)
        load = step == load_step
        diff = Mux(cm >= cp, cm - cp, cp - cm)
        m.d.comb += [
            ratio_div.start.eq(load),
            ratio_div.num.eq((c2 + kappa) << (cf.frac_bits + 1)),
            ratio_div.den.eq(c1 + kappa),
            subpx_div.start.eq(load),
            subpx_div.num.eq(Mux(edge, 0, diff << fs)),
            subpx_div.den.eq(Mux(edge, 1, cm + cp - (c1 << 1))),
        ]

        # step 2G + 6 + Q: round half-up (magnitudes), saturate
        ratio = Signal(cf.shape())
        magnitude = Signal(UQ(1, fs).shape())
        with m.If(step == load_step + quotient + 1):
            m.d.sync += [
                ratio.eq(hdl_resize(ratio_div.quotient, UQ(cf.int_bits, cf.frac_bits + 1),
                                    cf, Rounding.HALF_UP, Overflow.SATURATE)),
                magnitude.eq(hdl_resize(subpx_div.quotient, UQ(1, fs + 1), UQ(1, fs),
                                        Rounding.HALF_UP, Overflow.SATURATE)),
            ]

        # step 2G + 7 + Q: cap, sign, flags; store in the bank
        capped = Mux(ratio > p.cap_raw(), p.cap_raw(), ratio)
        result_layout = data.StructLayout({
            "shift": p.shift_fmt.shape(), "subpixel": p.subpixel_fmt.shape(),
            "confidence": cf.shape(), "textureless": 1, "edge_hit": 1})
        # a row's results wait for its last segment, each port's in its own bank
        bank = Array(Array(Signal(result_layout, name=f"result{s}_{k}")
                           for k in range(p.segments)) for s in range(self.ports))
        seq_busy = Signal()
        seq_idx = Signal(p.segment_bits)
        seq_row = Signal(data.StructLayout({"meta": meta_layout(p), "no_reference": 1,
                                            "slot": _slot_shape(self.ports)}))
        result_step = step == p.engine_result_step
        with m.If((step != 0) & ~result_step):
            m.d.sync += step.eq(step + 1)
        with m.If(result_step & ~seq_busy):
            entry = bank[snap.slot][snap.seg]
            m.d.sync += [
                entry.shift.eq(snap.meta.centre + p.match.shift_min + i1),
                entry.subpixel.eq(Mux(edge, 0, Mux(cm < cp, -magnitude, magnitude))),
                entry.confidence.eq(Mux((c1 + kappa == 0) & (c2 + kappa == 0), 0, capped)),
                entry.textureless.eq(snap.textureless),
                entry.edge_hit.eq(edge), step.eq(0),
            ]
            with m.If(snap.seg == p.segments - 1):
                m.d.sync += [seq_busy.eq(1), seq_idx.eq(0), seq_row.meta.eq(snap.meta),
                             seq_row.no_reference.eq(snap.no_reference),
                             seq_row.slot.eq(snap.slot)]

        # output sequence: the row's K results with its final verdict, on its port's
        # output (one register for all ports)
        if self.ports == 1:
            out, out_valid, taken = self.o.payload, self.o.valid, self.o.ready
        else:
            out, out_valid = Signal(p.measurement_layout()), Signal()
            out_port = Signal(_slot_shape(self.ports))
            taken = Array(port.ready for port in self.o)[out_port]
            for k, port in enumerate(self.o):
                m.d.comb += [port.payload.eq(out), port.valid.eq(out_valid & (out_port == k))]
            with m.If(seq_busy & (~out_valid | taken)):
                m.d.sync += out_port.eq(seq_row.slot)
        with m.If(~out_valid | taken):
            m.d.sync += out_valid.eq(seq_busy)
            with m.If(seq_busy):
                entry = bank[seq_row.slot][seq_idx]
                meta = seq_row.meta
                zero = entry.textureless | meta.bad | seq_row.no_reference
                m.d.sync += [
                    out.camera.eq(meta.camera), out.frame.eq(meta.frame),
                    out.row.eq(meta.row), out.t_first.eq(meta.t_first),
                    out.segment.eq(seq_idx), out.shift.eq(entry.shift),
                    out.subpixel.eq(entry.subpixel),
                    out.confidence.eq(Mux(zero, 0, entry.confidence)),
                    out.textureless.eq(entry.textureless), out.edge_hit.eq(entry.edge_hit),
                    out.bad.eq(meta.bad), out.no_reference.eq(seq_row.no_reference),
                    seq_idx.eq(seq_idx + 1),
                ]
                with m.If(seq_idx == p.segments - 1):
                    m.d.sync += seq_busy.eq(0)

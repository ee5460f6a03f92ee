"""Measurement router: the row-descriptor lanes' measurements → the pose solver's stream.

The gateware twin of :mod:`emulator.measurement.router` (its docstring lists every
decision; :func:`emulator.measurement.router.route_tickets` is the model this block is
checked against, transfer by transfer). Inside:

* one small FIFO per lane; each measurement is narrowed on the way in (temporal:
  ``shift + subpixel`` half-even/saturated into the solver's ``shift_fmt``, confidence
  into ``conf_fmt``; stereo: the disparity into ``cue_fmt`` and whether it gives a depth),
  so the FIFOs hold only what the router reads;
* a ticket FIFO: the measurement engine announces each row set (which temporal and
  stereo lanes receive it, its frame and row) before or while its pixels enter the lanes;
* per stereo lane a resynchronizer that takes the ticket's K_s measurements into cue
  registers, dropping older rows and giving up at a newer one (the stereo join can lose
  a row);
* with ``cue_fallback``, a store of each pair's last usable cue per (row, stereo
  segment) (:class:`amaranth.lib.memory.Memory`, ``height`` words of ``pairs × K_s``
  cues and valid bits): read when a ticket is fetched, merged into the cue registers
  (a failed segment takes the stored cue) and written back when the ticket is resolved;
  cleared by a sweep of ``height`` clocks after reset, during which no ticket is fetched;
* one cue mapper for all pairs (:class:`hdl.measurement.cue_map.CueMapper`), started
  once the cue registers are final: each temporal segment's cue for camera A and for
  camera B of every pair, interpolated at the segment's centre column (the pairs take
  turns at its two multipliers);
* an emitter that walks the marked cameras in order, K measurements each, one transfer
  per clock into an output register.

Formats: ``docs/measurement/measurement_router.md``.
"""

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFO
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl.fixed import Overflow, Rounding, hdl_add, hdl_resize
from hdl.measurement.cue_map import CueMapper
from hdl.measurement.router_params import RouterParams
from hdl.pose.params import PoseSolverParams
from hdl.pose_solver import measurement_layout
from hdl.descriptor.params import STEREO_640X480, TEMPORAL_640X480

__all__ = ["MeasurementRouter", "RouterParams", "ticket_layout", "router_status_layout",
           "default_router"]

#: Rows of measurements each lane FIFO holds: one being routed, one arriving.
FIFO_ROWS = 2
#: Tickets the engine may send ahead of the row being routed.
TICKET_DEPTH = 4
#: Width of the wrapping status counters.
COUNTER_BITS = 16


def ticket_layout(params):
    """One row set handed to the lanes: bit k of ``cameras`` iff temporal lane k receives
    it, bit j of ``pairs`` iff stereo lane j does; ``frame`` and ``row`` as the lanes
    report them."""
    return data.StructLayout({"cameras": params.cameras, "pairs": len(params.pairs),
                              "frame": params.temporal.frame_bits,
                              "row": params.temporal.row_bits})


def router_status_layout(params):
    """Wrapping 16-bit counters: ``rows`` (row sets routed, i.e. tickets with a camera),
    ``empty`` (routed rows none of whose transfers carries weight), ``misaligned``
    (measurements whose frame/row differ from their ticket: temporal ones sent with zero
    confidence, older stereo ones dropped), ``stereo_missing`` (marked stereo lanes that
    had no measurement of their ticket's row)."""
    return data.StructLayout({name: COUNTER_BITS for name in
                              ("rows", "empty", "misaligned", "stereo_missing")})


def _temporal_entry(params):
    s = params.solver
    return data.StructLayout({
        "frame": params.temporal.frame_bits, "row": params.temporal.row_bits,
        "t_first": min(params.temporal.timestamp_bits, s.time_bits),
        "shift": s.shift_fmt.shape(), "conf": s.conf_fmt.shape(), "edge_hit": 1})


def _stereo_entry(params):
    return data.StructLayout({
        "frame": params.stereo.frame_bits, "row": params.stereo.row_bits,
        "cue": params.solver.cue_fmt.shape(), "usable": 1})


def _exact_shift(m, lane):
    """``shift + subpixel`` of a lane measurement, exact: ``(value, format)``."""
    return hdl_add(m.shift, lane.shift_fmt, m.subpixel, lane.subpixel_fmt)


def _gives_depth(params, m, exact):
    """A stereo measurement ``m`` gives a depth (``RouterParams.stereo_window``): peak
    ratio at its bound, no window edge, integer disparity in the accepted range, refined
    disparity positive (``emulator.measurement.router.usable_cues``)."""
    least, low, high = params.depth_limits()
    return ((m.confidence >= least) & ~m.edge_hit & (m.shift >= low) & (m.shift <= high)
            & (exact > 0))


def _order(params, entry, ticket):
    """(same, older) of a buffered measurement against the ticket, frames modulo
    ``2**frame_bits`` as in :func:`emulator.measurement.router.stream_order`."""
    bits = params.temporal.frame_bits
    gap = (entry.frame - ticket.frame)[:bits]
    # gap == 0 is the same test, but as a subtraction it put the difference's full
    # carry in front of the zero test (issue 17: 12 LUT levels to the empty counter);
    # an equality is a flat XOR tree.
    same_frame = entry.frame[:bits] == ticket.frame[:bits]
    same = same_frame & (entry.row == ticket.row)
    older = gap[-1] | (same_frame & (entry.row < ticket.row))
    return same, older


def _or_tree(values):
    """Bitwise OR of equally wide values as a balanced tree."""
    if len(values) == 1:
        return values[0]
    half = len(values) // 2
    return _or_tree(values[:half]) | _or_tree(values[half:])


def _lowest(bits):
    """``(any, index)`` of the lowest set bit of a list of 1-bit values, as a balanced
    tree (log depth)."""
    if len(bits) == 1:
        return bits[0], Const(0, 1)
    half = len(bits) // 2
    any_lo, index_lo = _lowest(bits[:half])
    any_hi, index_hi = _lowest(bits[half:])
    return any_lo | any_hi, Mux(any_lo, index_lo, index_hi + half)


def _isolate_lowest(mask):
    """The lowest set bit of ``mask`` alone (``mask & −mask``)."""
    return (mask & -mask)[:len(mask)]


def _clear_lowest(mask):
    """``mask`` without its lowest set bit (``mask & (mask − 1)``)."""
    return (mask & (mask - 1))[:len(mask)]


class MeasurementRouter(wiring.Component):
    """Routes each ticket's lane measurements to the pose solver, bit-exact with
    :func:`emulator.measurement.router.route_tickets`.

    Parameters
    ----------
    params : RouterParams

    Members
    -------
    temporal : In(stream.Signature(params.temporal.measurement_layout())).array(cameras)
        Each camera's temporal-lane measurements (K per row, segment order).
    stereo : In(stream.Signature(params.stereo.measurement_layout())).array(len(pairs))
        Each stereo pair's measurements (K_s per row).
    tickets : In(stream.Signature(ticket_layout(params)))
        One per row set, in the order the row sets enter the lanes.
    o : Out(stream.Signature(hdl.pose_solver.measurement_layout(params.solver)))
        ``slot, row, time, shift (shift_fmt), cue (cue_fmt), conf (conf_fmt), last``; a
        ticket with cameras gives K transfers per marked camera in slot order, ``last`` on
        the final one; a ticket without cameras gives none.
    status : Out(router_status_layout(params))

    Latency :attr:`latency` clocks from a ticket's transfer to its first ``o.valid``
    when its measurements are already buffered, at least one stereo lane is marked and
    ``o`` is ready (K_s clocks less with no stereo lane marked). Throughput: one
    transfer per clock within a row; a waiting row's first transfer comes ``latency −
    1`` clocks after the previous row's last (``latency − 2`` idle clocks).
    Backpressure: ``o`` holds its transfer; full lane FIFOs (``FIFO_ROWS`` rows) lower
    the lanes' ``ready``. ``status`` counts an event two clocks after it. Reset
    empties the FIFOs and clears the counters; with ``cue_fallback`` it also empties
    the cue store, a sweep of ``height`` clocks before the first ticket is fetched.
    """

    def __init__(self, params):
        if not isinstance(params, RouterParams):
            raise TypeError(f"params must be a RouterParams, not {params!r}")
        self.params = params
        super().__init__({
            "temporal": In(stream.Signature(params.temporal.measurement_layout()))
            .array(params.cameras),
            "stereo": In(stream.Signature(params.stereo.measurement_layout()))
            .array(len(params.pairs)),
            "tickets": In(stream.Signature(ticket_layout(params))),
            "o": Out(stream.Signature(measurement_layout(params.solver))),
            "status": Out(router_status_layout(params)),
        })

    @property
    def latency(self):
        """Ticket FIFO, fetch, K_s resynchronizer clocks and their check, the cue
        mapper's start and walk over the pairs
        (:attr:`hdl.measurement.cue_map.CueMapper.latency`), output register."""
        p = self.params
        return 5 + p.stereo.segments + CueMapper.latency_of(p.cue_map, len(p.pairs))

    def elaborate(self, platform):
        p = self.params
        m = Module()
        ticket = Signal(ticket_layout(p))
        ticket_fifo = m.submodules.ticket_fifo = SyncFIFO(
            width=ticket_layout(p).size, depth=TICKET_DEPTH)
        m.d.comb += [ticket_fifo.w_data.eq(self.tickets.payload),
                     ticket_fifo.w_en.eq(self.tickets.valid),
                     self.tickets.ready.eq(ticket_fifo.w_rdy)]
        fetch = Signal()            # the ticket FIFO's head becomes the current ticket
        resolving = Signal()
        mapping = Signal()          # the cue mapper runs on the resolved cues
        emitting = Signal()
        clearing = Signal(init=p.cue_fallback)      # the cue store's sweep after reset
        m.d.comb += [fetch.eq(~resolving & ~mapping & ~emitting & ~clearing
                              & ticket_fifo.r_rdy),
                     ticket_fifo.r_en.eq(fetch)]
        incoming = data.View(ticket_layout(p), ticket_fifo.r_data)
        with m.If(fetch):
            m.d.sync += [ticket.eq(incoming), resolving.eq(1)]

        pairs = self._stereo(m, ticket, incoming, fetch, resolving)
        if p.cue_fallback:
            self._fallback(m, ticket, incoming, fetch, resolving & pairs["done"], pairs,
                           clearing)
        heads = self._temporal_fifos(m)

        resolved = resolving & pairs["done"]
        mapped = self._map(m, pairs, ticket, resolved, mapping)
        with m.If(resolved):
            m.d.sync += [resolving.eq(0), mapping.eq(ticket.cameras.any())]
        with m.If(mapped["done"]):
            m.d.sync += [mapping.eq(0), emitting.eq(1)]
        counts = self._emit(m, ticket, heads, mapped, emitting, start=mapped["done"])
        # counter increments registered first: the adders stay off the emit path
        steps = {
            "rows": counts["row"], "empty": counts["empty"],
            "misaligned": sum(pairs["dropped"], counts["misaligned"]),
            "stereo_missing": sum(pairs["missing"]),
        }
        for name, value in steps.items():
            step = Signal(range(len(p.pairs) + 2), name=f"{name}_step")
            counter = getattr(self.status, name)
            m.d.sync += [step.eq(value), counter.eq(counter + step)]
        return m

    # --- stereo lanes: FIFO, resynchronizer, cue registers -------------------------------

    def _stereo(self, m, ticket, incoming, fetch, resolving):
        """Per stereo lane: cue and usable registers of the current ticket's K_s
        segments, ``done`` once all marked lanes are resolved, per-clock ``dropped``
        and ``missing`` pulses."""
        p = self.params
        ks = p.stereo.segments
        layout = _stereo_entry(p)
        cues, usable, dones, dropped, missing = [], [], [], [], []
        for j, port in enumerate(self.stereo):
            fifo = m.submodules[f"stereo_fifo{j}"] = SyncFIFO(
                width=layout.size, depth=FIFO_ROWS * ks)
            exact, fmt = _exact_shift(port.payload, p.stereo)
            entry = Signal(layout, name=f"stereo_in{j}")
            m.d.comb += [
                entry.frame.eq(port.payload.frame), entry.row.eq(port.payload.row),
                entry.cue.eq(hdl_resize(exact, fmt, p.solver.cue_fmt,
                                        Rounding.HALF_EVEN, Overflow.SATURATE)),
                entry.usable.eq(_gives_depth(p, port.payload, exact)),
                fifo.w_data.eq(entry), fifo.w_en.eq(port.valid), port.ready.eq(fifo.w_rdy),
            ]
            head = data.View(layout, fifo.r_data)
            same, older = _order(p, head, ticket)
            cue = [Signal(p.solver.cue_fmt.shape(), name=f"cue{j}_{s}") for s in range(ks)]
            use = [Signal(name=f"usable{j}_{s}") for s in range(ks)]
            done = Signal(name=f"done{j}")
            taken = Signal(range(ks), name=f"taken{j}")
            look = resolving & ~done & fifo.r_rdy
            m.d.comb += fifo.r_en.eq(look & (same | older))
            with m.If(fetch):
                m.d.sync += [done.eq(~incoming.pairs[j]), taken.eq(0)]
                m.d.sync += [u.eq(0) for u in use]
            with m.Elif(look & same):
                for s in range(ks):
                    with m.If(taken == s):
                        m.d.sync += [cue[s].eq(head.cue), use[s].eq(head.usable)]
                m.d.sync += taken.eq(taken + 1)
                with m.If(taken == ks - 1):
                    m.d.sync += done.eq(1)
            with m.Elif(look & ~older):
                m.d.sync += done.eq(1)
            cues.append(cue)
            usable.append(use)
            dones.append(done)
            dropped.append(look & older)
            missing.append(look & ~same & ~older)
        all_done = Signal()
        m.d.comb += all_done.eq(Cat(*dones).all())
        return {"cue": cues, "usable": usable, "done": all_done, "dropped": dropped,
                "missing": missing}

    def _fallback(self, m, ticket, incoming, fetch, resolved, pairs, clearing):
        """The cue store: read at ``fetch`` (the incoming ticket's row), merged into the
        cue registers and written back on ``resolved``: a segment without a usable cue
        takes the stored one of its row (``emulator.measurement.router.route_tickets``).
        Rows ``≥ height`` neither read nor write."""
        p = self.params
        height, ks = p.temporal.height, p.stereo.segments
        entry = data.StructLayout({"cue": p.solver.cue_fmt.shape(), "valid": 1})
        words = data.ArrayLayout(entry, len(p.pairs) * ks)
        store = m.submodules.cue_store = Memory(shape=words, depth=height, init=[])
        read = store.read_port()
        write = store.write_port()
        m.d.comb += [read.addr.eq(incoming.row), read.en.eq(fetch)]
        in_range = Signal()
        with m.If(fetch):
            m.d.sync += in_range.eq(incoming.row < height)
        merged = Signal(words)
        for j in range(len(p.pairs)):
            for s in range(ks):
                stored, out = read.data[j * ks + s], merged[j * ks + s]
                live = pairs["usable"][j][s]
                m.d.comb += [out.valid.eq(live | (stored.valid & in_range)),
                             out.cue.eq(Mux(live, pairs["cue"][j][s], stored.cue))]
                with m.If(resolved):
                    m.d.sync += [pairs["cue"][j][s].eq(out.cue),
                                 pairs["usable"][j][s].eq(out.valid)]
        sweep = Signal(range(height))
        with m.If(clearing):
            m.d.comb += [write.addr.eq(sweep), write.en.eq(1), write.data.eq(0)]
            m.d.sync += sweep.eq(sweep + 1)
            with m.If(sweep == height - 1):
                m.d.sync += clearing.eq(0)
        with m.Else():
            m.d.comb += [write.addr.eq(ticket.row), write.data.eq(merged),
                         write.en.eq(resolved & in_range)]

    # --- cue mapper ----------------------------------------------------------------------

    def _map(self, m, pairs, ticket, resolved, mapping):
        """The cue mapper of all pairs, started the clock after ``resolved`` of a ticket
        with cameras (the cue registers then hold the fallback's merge). Returns each
        camera's ``cue`` and ``usable`` (K each, its role's outputs) and ``done``: the
        clock the mapper's results are final."""
        p = self.params
        start = Signal()
        m.d.sync += start.eq(resolved & ticket.cameras.any())
        mapper = m.submodules.cue_map = CueMapper(p.cue_map, len(p.pairs))
        m.d.comb += mapper.start.eq(start)
        cue, usable = {}, {}
        for j, (a, b) in enumerate(p.pairs):
            m.d.comb += mapper.usable[j].eq(Cat(pairs["usable"][j]))
            m.d.comb += [mapper.cues[j][s].eq(pairs["cue"][j][s])
                         for s in range(p.stereo.segments)]
            cue[a], usable[a] = mapper.cue_a[j], mapper.usable_a[j]
            cue[b], usable[b] = mapper.cue_b[j], mapper.usable_b[j]
        return {"cue": [cue[c] for c in range(p.cameras)],
                "usable": [usable[c] for c in range(p.cameras)],
                "done": mapping & ~start & ~mapper.busy}

    # --- temporal lanes: FIFOs ----------------------------------------------------------

    def _temporal_fifos(self, m):
        """Per camera a FIFO of narrowed measurements; returns their read ports."""
        p = self.params
        layout = _temporal_entry(p)
        fifos = []
        for c, port in enumerate(self.temporal):
            fifo = m.submodules[f"temporal_fifo{c}"] = SyncFIFO(
                width=layout.size, depth=FIFO_ROWS * p.temporal.segments)
            exact, fmt = _exact_shift(port.payload, p.temporal)
            entry = Signal(layout, name=f"temporal_in{c}")
            m.d.comb += [
                entry.frame.eq(port.payload.frame), entry.row.eq(port.payload.row),
                entry.t_first.eq(port.payload.t_first),
                entry.shift.eq(hdl_resize(exact, fmt, p.solver.shift_fmt,
                                          Rounding.HALF_EVEN, Overflow.SATURATE)),
                entry.conf.eq(hdl_resize(port.payload.confidence, p.temporal.confidence_fmt,
                                         p.solver.conf_fmt, Rounding.HALF_EVEN,
                                         Overflow.SATURATE)),
                entry.edge_hit.eq(port.payload.edge_hit),
                fifo.w_data.eq(entry), fifo.w_en.eq(port.valid), port.ready.eq(fifo.w_rdy),
            ]
            fifos.append(fifo)
        return fifos

    # --- emitter ------------------------------------------------------------------------

    def _emit(self, m, ticket, fifos, mapped, emitting, *, start):
        """Walk the marked cameras, K transfers each, into the output register, with
        the mapper's cues (``mapped``); returns this clock's ``row``, ``empty`` and
        ``misaligned`` counter increments."""
        p = self.params
        k_seg = p.temporal.segments
        layout = _temporal_entry(p)
        camera = Signal(range(p.cameras))
        selected = Signal(p.cameras)        # one-hot ``camera``
        pending = Signal(p.cameras)         # marked cameras after the current one
        segment = Signal(range(k_seg))
        opening = Signal()                  # the row's first transfer is next
        time = Signal(p.solver.time_bits)
        weighted = Signal()                 # a transfer of this row carried weight
        _, first = _lowest(list(ticket.cameras))
        _, following = _lowest(list(pending))
        with m.If(start):
            m.d.sync += [camera.eq(first), selected.eq(_isolate_lowest(ticket.cameras)),
                         pending.eq(_clear_lowest(ticket.cameras)),
                         segment.eq(0), opening.eq(1), weighted.eq(0)]

        head = data.View(layout, Array(f.r_data for f in fifos)[camera])
        ready = Cat(f.r_rdy for f in fifos)
        advance = ~self.o.valid | self.o.ready
        fire = emitting & (selected & ready).any() & advance
        for c, fifo in enumerate(fifos):           # one-hot: no multiplexer on this path
            m.d.comb += fifo.r_en.eq(emitting & advance & selected[c] & fifo.r_rdy)

        # the mapped cue of (camera, segment); 0 where it has none
        cue_of = Array(Array(mapped["cue"][c][k] for k in range(k_seg))
                       for c in range(p.cameras))[camera][segment]
        # every camera's head is judged beside the others and the one-hot ``selected``
        # picks a verdict: the same-row test and the weight no longer wait for the camera
        # multiplexer (issue 17: 14 LUT levels to ``weighted`` in the board top)
        usable_c = [mapped["usable"][c].bit_select(segment, 1) for c in range(p.cameras)]
        same_c, weight_c = [], []
        for c, fifo in enumerate(fifos):
            entry = data.View(layout, fifo.r_data)
            same_one, _ = _order(p, entry, ticket)
            same_c.append(selected[c] & same_one)
            weight_c.append(Mux(selected[c] & same_one & ~entry.edge_hit & usable_c[c],
                                entry.conf, 0))
        same = Cat(same_c).any()
        weight = Signal.like(head.conf)
        m.d.comb += weight.eq(_or_tree(weight_c))
        closing = (segment == k_seg - 1) & ~pending.any()
        row_time = Mux(opening, head.t_first, time)

        out = self.o.payload
        with m.If(advance):
            m.d.sync += self.o.valid.eq(fire)
        with m.If(fire):
            m.d.sync += [
                out.slot.eq(camera * k_seg + segment), out.row.eq(ticket.row),
                out.time.eq(row_time), out.shift.eq(head.shift),
                out.cue.eq(cue_of), out.conf.eq(weight),
                out.last.eq(closing),
                time.eq(row_time), opening.eq(0),
                segment.eq(Mux(segment == k_seg - 1, 0, segment + 1)),
            ]
            with m.If(segment == k_seg - 1):
                m.d.sync += [camera.eq(following), selected.eq(_isolate_lowest(pending)),
                             pending.eq(_clear_lowest(pending))]
            with m.If(closing):
                m.d.sync += emitting.eq(0)
        # ``weighted`` follows the registered weights, a clock behind: the row's empty
        # verdict is taken the clock after its closing transfer (no new transfer can
        # come before: ``emitting`` is off), the weight test off the emitter's path
        fired_open, closed = Signal(), Signal()
        m.d.sync += [fired_open.eq(fire & ~closing), closed.eq(fire & closing)]
        with m.If(fired_open):
            m.d.sync += weighted.eq(weighted | (out.conf != 0))
        row_done = fire & closing
        return {"row": row_done, "empty": closed & ~weighted & (out.conf == 0),
                "misaligned": fire & ~same}


def default_router():
    """Two cameras as one stereo pair, 640×480, the lanes' default parameters (K = 4
    temporal segments, one stereo segment): the catalog's build."""
    params = RouterParams(cameras=2, pairs=((0, 1),), temporal=TEMPORAL_640X480,
                          stereo=STEREO_640X480, solver=PoseSolverParams(slots=8))
    return MeasurementRouter(params)

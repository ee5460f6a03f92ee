"""Fan-out of the aligned row sets to the row-descriptor lanes, with one ticket per set.

The row aligner (:mod:`hdl.front_end.row_aligner`) delivers row ``y`` of every camera as one
stream, a column per transfer (:func:`hdl.streams.aligned_row_layout`). The lanes of the
measurement engine each take one camera's beats: the temporal lane of camera ``k``, and
the ``a`` or ``b`` input of the stereo lane of the pair camera ``k`` belongs to. The
router (:mod:`hdl.measurement.router`) needs to know which lanes got which row: one
*ticket* per row set, marking the temporal lanes and the stereo lanes that received it.
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.measurement.engine_params import EngineParams, fork_status_layout
from hdl.measurement.router import ticket_layout

__all__ = ["RowSetFork"]


class RowSetFork(wiring.Component):
    """Eager fork of row sets into per-lane camera beat streams.

    Each column of a row set goes to every output it is addressed to, exactly once: to
    ``temporal[k]`` when lane ``k`` carries a beat, to ``stereo_a[j]`` / ``stereo_b[j]``
    when pair ``j`` = (A, B) is complete in the set (both cameras in it) and its camera
    carries a beat, and, with the set's first column, to ``tickets``. An output that
    takes the column early is marked *taken* and waits; the column is consumed when
    every addressed output has taken it. When ``enable`` (sampled with the set's first
    column) is 0 the set is consumed and counted as dropped, and no output sees it.

    Parameters
    ----------
    params : EngineParams

    Members
    -------
    i : In(stream.Signature(params.aligned_layout()))
        Row sets from the row aligner. The first column after a set's end opens the
        next set; a set ends with the column on which every lane still in it carries
        ``last``.
    enable : In(1)
    temporal : Out(stream.Signature(params.pixel_layout())).array(cameras)
    stereo_a, stereo_b : Out(stream.Signature(params.pixel_layout())).array(pairs)
        Camera beats, unchanged (``hdl.streams.camera_pixel_layout``).
    tickets : Out(stream.Signature(ticket_layout(params.router)))
        ``cameras``: the temporal lanes that get the set; ``pairs``: the stereo lanes;
        ``frame``, ``row``: the set's row key.
    status : Out(fork_status_layout(params))
        Wrapping counters of row sets received, dropped, and skipped per stereo pair.

    Latency 0 (outputs are combinational from ``i``; ``valid`` never depends on the
    same port's ``ready``). Throughput one column per clock when no addressed output
    stalls. Backpressure: ``i.ready`` waits for the slowest addressed output. Reset:
    the next column opens a set.
    """

    latency = 0

    def __init__(self, params):
        if not isinstance(params, EngineParams):
            raise TypeError(f"params must be an EngineParams, not {params!r}")
        self.params = params
        beat = stream.Signature(params.pixel_layout())
        n_pairs = len(params.pairs)
        super().__init__({
            "i": In(stream.Signature(params.aligned_layout())),
            "enable": In(1),
            "temporal": Out(beat).array(params.cameras),
            "stereo_a": Out(beat).array(n_pairs),
            "stereo_b": Out(beat).array(n_pairs),
            "tickets": Out(stream.Signature(ticket_layout(params.router))),
            "status": Out(fork_status_layout(params)),
        })

    def _outputs(self):
        """Every output port with the camera whose beats it carries (None: tickets) and
        the stereo pair it serves (None: a temporal lane or the tickets)."""
        pairs = self.params.pairs
        return ([(port, k, None) for k, port in enumerate(self.temporal)] +
                [(port, a, j) for j, (port, (a, _)) in enumerate(zip(self.stereo_a, pairs))] +
                [(port, b, j) for j, (port, (_, b)) in enumerate(zip(self.stereo_b, pairs))] +
                [(self.tickets, None, None)])

    def elaborate(self, platform):
        p = self.params
        m = Module()
        col = self.i.payload
        live = col.lane_valid
        lasts = Cat(lane.last for lane in col.lanes)

        in_set = Signal()                       # the next column continues a set
        set_enable = Signal()
        set_pairs = Signal(len(p.pairs))
        opens = ~in_set
        enabled = Mux(opens, self.enable, set_enable)
        complete = Cat(live[a] & live[b] for a, b in p.pairs)
        pairs = Mux(opens, complete, set_pairs)

        taken, done = [], []
        for port, camera, pair in self._outputs():
            if camera is None:
                want = enabled & opens
            elif pair is None:
                want = enabled & live[camera]
            else:
                want = enabled & live[camera] & pairs[pair]
            flag = Signal(name=f"taken{len(taken)}")
            m.d.comb += port.valid.eq(self.i.valid & want & ~flag)
            taken.append(flag)
            done.append(~want | flag | port.ready)
        m.d.comb += self.i.ready.eq(Cat(done).all())
        transfer = self.i.valid & self.i.ready

        for port, camera, _ in self._outputs():
            if camera is not None:
                m.d.comb += port.payload.eq(col.lanes[camera])
        frame, row = col.lanes[p.cameras - 1].frame, col.lanes[p.cameras - 1].row
        for k in reversed(range(p.cameras - 1)):        # the key of the lowest live lane
            frame = Mux(live[k], col.lanes[k].frame, frame)
            row = Mux(live[k], col.lanes[k].row, row)
        m.d.comb += [self.tickets.payload.cameras.eq(live),
                     self.tickets.payload.pairs.eq(complete),
                     self.tickets.payload.frame.eq(frame),
                     self.tickets.payload.row.eq(row)]

        with m.If(transfer):
            m.d.sync += [flag.eq(0) for flag in taken]
            m.d.sync += in_set.eq((live & ~lasts).any())
            with m.If(opens):
                m.d.sync += [set_enable.eq(self.enable), set_pairs.eq(complete)]
        with m.Else():
            for (port, _, _), flag in zip(self._outputs(), taken):
                with m.If(port.valid & port.ready):
                    m.d.sync += flag.eq(1)

        status = self.status
        with m.If(transfer & opens):
            m.d.sync += status.row_sets.eq(status.row_sets + 1)
            with m.If(~self.enable):
                m.d.sync += status.dropped.eq(status.dropped + 1)
            with m.Else():
                for j in range(len(p.pairs)):
                    with m.If(~complete[j]):
                        m.d.sync += status.stereo_skipped[j].eq(status.stereo_skipped[j] + 1)
        return m

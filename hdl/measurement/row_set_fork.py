"""Fan-out of the aligned row sets to the row-descriptor lanes, with one ticket per set.

The row aligner (:mod:`hdl.front_end.row_aligner`) delivers row ``y`` of every camera as one
stream, a column per transfer (:func:`hdl.streams.aligned_row_layout`). The temporal
lane of camera ``k`` takes camera ``k``'s beats; the stereo lane of its pair takes the
descriptor bits of those rows from the pair's two temporal lanes, so each beat also
says whether its row goes on to the stereo lane (``paired``: both cameras of the pair
are in the set). The router (:mod:`hdl.measurement.router`) needs to know which lanes
got which row: one *ticket* per row set, marking the temporal lanes and the stereo
lanes that received it.

In the closed loop (``EngineParams.follow``) the fork also joins each row set with its
forecast row (:class:`hdl.measurement.forecast_rows.ForecastRows`): the temporal lanes'
beats carry the row's centre and source row (``hdl.streams.followed_pixel_layout``),
and a set opens only when a forecast row is there. Both streams follow the camera rows
in order, so the join compares the keys: the forecast row's ``row`` with the set's. On
a mismatch, with ``H`` = the lanes' ``height`` and ``gap = (forecast row − set row) mod
H``: a forecast ahead (``0 < 2·gap < H``: the set's own forecast was lost) drops the
set (counted ``unforecast``) and keeps the forecast for a later set; a forecast behind
(any other gap, or a forecast row ``≥ H``: it was for a set that never came) is
discarded (counted ``forecast_skipped``) and the set waits for the next. A set whose
row is ``≥ H`` has no forecast and is dropped (``unforecast``). A set with ``enable``
0 is dropped as in the open loop without taking a forecast row. So a lost, extra or
mislabelled forecast row costs at most the sets up to the next matching key, counted,
and never lets a set run with another row's forecast under a wrong key.

The fork's ``ready`` is the AND of every lane's, and its outputs' ``valid`` follow the
join, so its logic must start from flip-flops to stay within the LUT-level target
(issue 17): a :class:`hdl.register_slice.RegisterSlice` takes each column with its set's
key (the lowest live lane's ``frame`` and ``row``, a priority multiplexer over the
lanes), ``enable`` and whether the row can have a forecast, and the join's ahead/behind
verdict on a key mismatch is registered (the set waits one clock more on a lost or extra
forecast row; a matching key costs no clock).
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.measurement.engine_params import EngineParams, fork_status_layout
from hdl.measurement.router import ticket_layout
from hdl.register_slice import RegisterSlice

__all__ = ["RowSetFork"]


class RowSetFork(wiring.Component):
    """Eager fork of row sets into per-camera beat streams.

    Each column of a row set goes to every output it is addressed to, exactly once: to
    ``temporal[k]`` when lane ``k`` carries a beat (``paired`` when camera ``k``'s pair
    is complete in the set: both cameras in it) and, with the set's first column, to
    ``tickets``. An output that
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
    forecast : In(stream.Signature(params.forecast_row_layout())), with ``follow`` only
        Forecast rows, one taken per row set handed on (see the module docstring).
    temporal : Out(stream.Signature(params.temporal.input_layout(follow, True))).array(cameras)
        Camera beats (``hdl.streams.camera_pixel_layout``) and ``paired``; with
        ``follow`` also the forecast row's ``centre[k]`` and ``source[k]`` (valid with
        the set's first column, which the lanes sample).
    tickets : Out(stream.Signature(ticket_layout(params.router)))
        ``cameras``: the temporal lanes that get the set; ``pairs``: the stereo lanes;
        ``frame``, ``row``: the set's row key.
    status : Out(fork_status_layout(params))
        Wrapping counters of row sets received, dropped, and skipped per stereo pair
        (with ``follow`` also ``forecast_skipped`` and ``unforecast``).

    Latency :attr:`latency` clock (the input register; ``valid`` never depends on the
    same port's ``ready``). Throughput one column per clock when no addressed output
    stalls. Backpressure: ``i.ready`` is registered and falls the clock after the
    slowest addressed output stalled. Reset: the next column opens a set.
    """

    latency = RegisterSlice.latency

    def __init__(self, params):
        if not isinstance(params, EngineParams):
            raise TypeError(f"params must be an EngineParams, not {params!r}")
        self.params = params
        follow = {"forecast": In(stream.Signature(params.forecast_row_layout()))} \
            if params.follow else {}
        super().__init__({
            "i": In(stream.Signature(params.aligned_layout())),
            "enable": In(1),
            **follow,
            "temporal": Out(stream.Signature(
                params.temporal.input_layout(params.follow, paired=True))).array(params.cameras),
            "tickets": Out(stream.Signature(ticket_layout(params.router))),
            "status": Out(fork_status_layout(params)),
        })

    def _staged_layout(self):
        """A column in the input register, with what the fork reads of it first: its
        set's key, ``enable``, the pairs with both cameras in it, and (``follow``)
        whether the row can have a forecast."""
        p = self.params
        pixel = self.i.payload.lanes[0]
        joinable = {"joinable": 1} if p.follow else {}
        return data.StructLayout({"column": p.aligned_layout(), "enable": 1,
                                  "frame": len(pixel.frame), "row": len(pixel.row),
                                  "complete": len(p.pairs), **joinable})

    def _outputs(self):
        """Every output port with the camera whose beats it carries (None: tickets)."""
        return [*enumerate(self.temporal), (None, self.tickets)]

    def elaborate(self, platform):
        p = self.params
        m = Module()
        m.submodules.slice = staged = RegisterSlice(self._staged_layout())
        arriving = self.i.payload
        frame, row = arriving.lanes[p.cameras - 1].frame, arriving.lanes[p.cameras - 1].row
        for k in reversed(range(p.cameras - 1)):        # the key of the lowest live lane
            frame = Mux(arriving.lane_valid[k], arriving.lanes[k].frame, frame)
            row = Mux(arriving.lane_valid[k], arriving.lanes[k].row, row)
        m.d.comb += [staged.i.valid.eq(self.i.valid), self.i.ready.eq(staged.i.ready),
                     staged.i.payload.column.eq(arriving), staged.i.payload.enable.eq(self.enable),
                     staged.i.payload.frame.eq(frame), staged.i.payload.row.eq(row),
                     staged.i.payload.complete.eq(
                         Cat(arriving.lane_valid[a] & arriving.lane_valid[b]
                             for a, b in p.pairs))]
        if p.follow:
            m.d.comb += staged.i.payload.joinable.eq(row < p.temporal.height)

        head = staged.o
        col = head.payload.column
        live = col.lane_valid
        lasts = Cat(lane.last for lane in col.lanes)
        in_set = Signal()                       # the next column continues a set
        set_enable = Signal()
        set_pairs = Signal(len(p.pairs))
        opens = ~in_set
        enable = head.payload.enable
        join = self._join(m, head, opens) if p.follow else {"accept": enable, "wait": 0}
        enabled = Mux(opens, join["accept"], set_enable)
        complete = head.payload.complete
        pairs = Mux(opens, complete, set_pairs)

        # An output wants the column when the set is enabled and it is addressed; the AND
        # of every output's ``done`` is taken over the addressed ones alone, from
        # registers, and ``enabled`` (the join's verdict) joins it last
        taken, done = [], []
        for camera, port in self._outputs():
            addressed = opens if camera is None else live[camera]
            flag = Signal(name=f"taken{len(taken)}")
            m.d.comb += port.valid.eq(head.valid & enabled & addressed & ~flag)
            taken.append(flag)
            done.append(~addressed | flag | port.ready)
        all_done = Signal()
        m.d.comb += [all_done.eq(Cat(done).all()),
                     head.ready.eq((~enabled | all_done) & ~(opens & join["wait"]))]
        transfer = head.valid & head.ready

        pair_index = {camera: j for j, pair in enumerate(p.pairs) for camera in pair}
        for camera, port in enumerate(self.temporal):
            m.d.comb += [port.payload[name].eq(col.lanes[camera][name])
                         for name, _ in p.pixel_layout()]
            m.d.comb += port.payload.paired.eq(pairs[pair_index[camera]])
            if p.follow:
                forecast = self.forecast.payload
                m.d.comb += [port.payload.centre.eq(forecast.centre[camera]),
                             port.payload.source.eq(forecast.source[camera])]
        if p.follow:
            # the forecast row is taken with the set's first column
            with m.If(transfer & opens & join["accept"]):
                m.d.comb += self.forecast.ready.eq(1)
        m.d.comb += [self.tickets.payload.cameras.eq(live),
                     self.tickets.payload.pairs.eq(complete),
                     self.tickets.payload.frame.eq(head.payload.frame),
                     self.tickets.payload.row.eq(head.payload.row)]

        with m.If(transfer):
            m.d.sync += [flag.eq(0) for flag in taken]
            m.d.sync += in_set.eq((live & ~lasts).any())
            with m.If(opens):
                m.d.sync += [set_enable.eq(join["accept"]), set_pairs.eq(complete)]
        with m.Else():
            for (_, port), flag in zip(self._outputs(), taken):
                with m.If(port.valid & port.ready):
                    m.d.sync += flag.eq(1)

        status = self.status
        with m.If(transfer & opens):
            m.d.sync += status.row_sets.eq(status.row_sets + 1)
            with m.If(~enable):
                m.d.sync += status.dropped.eq(status.dropped + 1)
            with m.Elif(join["accept"]):
                for j in range(len(p.pairs)):
                    with m.If(~complete[j]):
                        m.d.sync += status.stereo_skipped[j].eq(status.stereo_skipped[j] + 1)
            if p.follow:
                with m.Else():
                    m.d.sync += status.unforecast.eq(status.unforecast + 1)
        if p.follow:
            with m.If(join["skip"]):
                m.d.sync += status.forecast_skipped.eq(status.forecast_skipped + 1)
        return m

    def _join(self, m, head, opens):
        """The key comparison of an opening set (at ``head``) with the forecast row
        waiting (module docstring): ``accept`` the set with it, ``wait`` (the set is held
        this clock), and ``skip`` (the forecast row is discarded this clock). On a
        mismatch the set first waits a clock for the registered ``ahead`` verdict."""
        p = self.params
        height = p.temporal.height
        forecast = self.forecast
        key, row = forecast.payload.row, head.payload.row
        diff = Signal(range(-(1 << len(key)), 1 << len(key)))
        m.d.comb += diff.eq(key - row)
        gap = Mux(diff < 0, diff + height, diff)
        ahead = Signal()                # the verdict on the keys of the clock before
        settled = Signal()              # a mismatch has waited a clock: ``ahead`` is its
        m.d.sync += ahead.eq((key < height) & (gap != 0) & (2 * gap < height))
        match = forecast.valid & (key == row)
        asks = head.payload.enable & head.payload.joinable   # needs a forecast
        mismatch = head.valid & opens & asks & forecast.valid & ~match
        # neither stream moves while a mismatch waits, so the keys stay the same
        m.d.sync += settled.eq(mismatch & ~settled)
        skip = Signal()
        m.d.comb += skip.eq(mismatch & settled & ~ahead)
        with m.If(skip):
            m.d.comb += forecast.ready.eq(1)
        return {"accept": asks & match,
                "wait": asks & ~match & ~(forecast.valid & settled & ahead), "skip": skip}

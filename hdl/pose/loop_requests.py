"""The forecast's requests in the closed loop (issue 16): one per row slot, in order, each
with the depth cue every segment had in the same camera row of the previous frame
(:class:`emulator.pose.tracking_loop.TrackingLoopModel`'s ``request`` and cue store, bit
for bit).

**Row slots.** The model counts row periods from the dataset's time stamps,
``round((t − t0)/t_r)``. In gateware they come from the row stream's order: camera rows
``0 … height − 1`` frame after frame, and a frame period of ``frame_rows`` row periods
(a register, blanking included), so row ``r`` of frame ``f`` is slot
``f · frame_rows + r`` (modulo ``2**slot_bits``). That assumes what the datasets and the
sensors give: every frame reads all its rows in order, one per row period, and the frame
period is a whole number of row periods (stereo20: 480 rows, no blanking; the cut rigs of
the tests: ``t_r = 1/(120·height)``). A frame period that is not a whole number of rows
would need a fractional slot accumulator; a dropped frame would need the frame count from
the camera input.

**Cue store.** ``height`` words of ``slots`` cues (lib.memory, one write enable per
slot): every measurement with a non-zero cue writes its slot of its row as it enters the
loop (the consistency stage passes cues on unchanged, so this is the model's write from
the judged transfers). A request reads its row's word when it is prepared, right after
the previous request was taken. The word is final then if ``height ≥ loop_delay_rows +
2`` (checked): the previous request needed the records up to ``loop_delay_rows + 1``
slots before it, which include the same row of the previous frame, whose measurements
have all written by the time its record is out.

**Restart.** A ``restart`` strobe is held until the next request would be row 0 (a frame
boundary of the requests), and takes effect there once the forecast is ``drained`` (every
row forecast has its record, so no context, measurement or forecast row of the old run
is left in the loop or the engine): the requests go on with row 0 of slot 0, and
``restarting`` restarts the forecast's filter in the same clock. Until then row 0 is not
offered. The cue store is kept: it holds the previous frame's cues, all written (the
model's :meth:`~emulator.pose.tracking_loop.TrackingLoopModel.restart`).
"""

from amaranth.hdl import Module, Mux, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.checks import check_int
from hdl.pose.forecast import request_layout
from hdl.pose.forecast_filter import DEFAULT_SLOT_BITS
from hdl.pose.forecast_params import ForecastParams

__all__ = ["RequestGenerator"]


class RequestGenerator(wiring.Component):
    """Requests for the forecast, and the cue store.

    Parameters
    ----------
    params : ForecastParams
    slot_bits : int
        The forecast's row slot width.

    Members
    -------
    o : Out(stream.Signature(request_layout(params, slot_bits)))
        Row 0 of slot 0 first after reset or a restart (``valid`` drops, without a
        transfer, while a pending restart holds row 0 back).
    write_en : In(1); write_slot, write_row, write_cue : In
        A measurement's cue for the store (``write_en`` only for a non-zero cue).
    frame_rows : In(unsigned(slot_bits)), reset ``frame_rows``
        Row periods per frame period, at least ``height``; change it with ``restart``.
    restart : In(1)
        Strobe: restart at the next frame boundary (see the module docstring).
    drained : In(1)
        The forecast has no request in progress and every request's record.
    restarting : Out(1)
        The restart takes effect in this clock (the forecast's ``restart``).
    restart_pending : Out(1)
        A ``restart`` was strobed and has not taken effect: set the clock after the
        strobe, clear the clock after ``restarting``.

    After reset the store is cleared first, one word per clock (``height`` clocks);
    requests wait for it (block RAM contents survive a reset).
    """

    def __init__(self, params, frame_rows, *, slot_bits=DEFAULT_SLOT_BITS):
        if not isinstance(params, ForecastParams):
            raise TypeError(f"params must be a ForecastParams, not {params!r}")
        if params.height < params.loop_delay_rows + 2:
            raise ValueError(f"height {params.height} must be at least loop_delay_rows + 2 "
                             f"= {params.loop_delay_rows + 2} (the cue store is read one "
                             f"request ahead)")
        check_int("frame_rows", frame_rows, params.height, 2 ** slot_bits - 1)
        self.params, self.slot_bits = params, slot_bits
        s = params.solver
        super().__init__({
            "o": Out(stream.Signature(request_layout(params, slot_bits))),
            "write_en": In(1), "write_slot": In(s.slot_bits), "write_row": In(s.row_bits),
            "write_cue": In(s.cue_fmt.shape()),
            "frame_rows": In(unsigned(slot_bits), init=frame_rows),
            "restart": In(1), "drained": In(1), "restarting": Out(1),
            "restart_pending": Out(1),
        })

    def elaborate(self, platform):
        p, s = self.params, self.params.solver
        m = Module()
        m.submodules.cues = store = Memory(
            shape=data.ArrayLayout(s.cue_fmt.shape(), s.slots), depth=p.height, init=[])
        read, write = store.read_port(), store.write_port(granularity=1)
        clearing, clear_addr = Signal(init=1), Signal(range(p.height))
        with m.If(clearing):
            m.d.comb += [write.addr.eq(clear_addr), write.en.eq((1 << s.slots) - 1)]
            m.d.sync += clear_addr.eq(clear_addr + 1)
            with m.If(clear_addr == p.height - 1):
                m.d.sync += [clearing.eq(0), clear_addr.eq(0)]
        with m.Else():
            m.d.comb += [write.addr.eq(self.write_row),
                         write.en.eq(Mux(self.write_en, 1 << self.write_slot, 0)),
                         *[write.data[k].eq(self.write_cue) for k in range(s.slots)]]

        row, slot = Signal(range(p.height)), Signal(self.slot_bits)
        offered = Signal()               # the request of ``row`` is read
        pending, hold = self.restart_pending, Signal()
        fetch = Signal()                 # read the row's cues in this clock
        m.d.comb += [fetch.eq(~clearing & ~offered),
                     read.addr.eq(row), read.en.eq(fetch),
                     hold.eq(pending & (row == 0)),
                     self.restarting.eq(hold & self.drained),
                     self.o.valid.eq(offered & ~hold),
                     self.o.payload.row.eq(row), self.o.payload.slot.eq(slot),
                     self.o.payload.cue.eq(read.data)]
        with m.If(fetch):
            m.d.sync += offered.eq(1)
        with m.If(self.o.valid & self.o.ready):
            last = row == p.height - 1
            m.d.sync += [offered.eq(0), row.eq(Mux(last, 0, row + 1)),
                         slot.eq(slot + Mux(last, self.frame_rows - (p.height - 1), 1))]
        with m.If(self.restarting):
            m.d.sync += [slot.eq(0), pending.eq(0)]
        with m.If(self.restart):
            m.d.sync += pending.eq(1)
        return m

"""Gathers row y from every enabled camera and hands the set downstream in lock step.

The cameras of the cluster share their row timing, so row ``y`` of every camera arrives
at about the same time, give or take the skew. :class:`RowAligner` waits at each row
for the enabled cameras (with a time-out for a missing one), then streams the set one
column per transfer, lane ``k`` carrying camera ``k``.

Rows are identified by their key ``(frame, row)``, compared modulo the key width (the
frame number wraps). A row older than the set being sent (or the last one sent), or with an
index past the frame height, cannot join any set: it is discarded and counted as stale,
at once, so a camera that has fallen out of step never backs up. A camera missing from
a set for want of a row (rather than because it is ahead) is marked *absent* and not
waited for until it shows a usable row again, so a lost camera costs one time-out, not
one per row. At each new frame every enabled camera is waited for again.
"""

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.front_end.params import CameraParams
from hdl.front_end.camera_input import saturating_increment, wire

__all__ = ["RowAligner"]


def _older(a, b, bits):
    """``a`` comes before ``b`` modulo ``2**bits`` (their difference is negative)."""
    return (a - b)[bits - 1]


def _lowest(mask, keys):
    """The key of the lowest set bit of ``mask`` (``keys[0]`` if none is set)."""
    result = keys[-1]
    for k in reversed(range(len(keys) - 1)):
        result = Mux(mask[k], keys[k], result)
    return result


class RowAligner(wiring.Component):
    """Aligns rows of ``n_cameras`` pixel streams into row sets.

    Parameters
    ----------
    params : CameraParams

    Members
    -------
    i : In(stream.Signature(params.pixel_layout())).array(n_cameras)
        One camera's rows per lane (from :class:`~hdl.front_end.camera_input.CameraInput`).
    o : Out(stream.Signature(params.aligned_layout()))
        Row sets, one column per transfer (:func:`hdl.streams.aligned_row_layout`).
    cfg : In(params.align_config_layout())
        ``enable``: cameras taking part (a disabled camera's rows are discarded);
        ``timeout``: system clocks to wait at a row for the cameras that have not shown
        it yet.
    height : In(unsigned(row_bits))
        Rows per frame; rows at or past it are stale.
    status : Out(params.align_status_layout())
        Per camera: sets it was missing from, rows discarded as stale (both wrap).

    Latency: :attr:`latency` clocks while a set streams (the data path is
    combinational); a set starts two clocks after its last camera's first pixel is
    offered (its decisions read the row comparisons a clock late, from flip-flops).
    Throughput: one column per clock. Backpressure: ``o.ready`` low holds every lane.
    Reset: waits for a new set.
    """

    latency = 0

    def __init__(self, params=CameraParams()):
        if not isinstance(params, CameraParams):
            raise TypeError(f"params must be a CameraParams, not {params!r}")
        self.params = params
        super().__init__({
            "i": In(stream.Signature(params.pixel_layout())).array(params.n_cameras),
            "o": Out(stream.Signature(params.aligned_layout())),
            "cfg": In(params.align_config_layout()),
            "height": In(params.row_bits),
            "status": Out(params.align_status_layout()),
        })

    def elaborate(self, platform):
        p = self.params
        n = p.n_cameras
        key_bits = p.frame_bits + p.row_bits
        m = Module()

        streaming = Signal()
        target_valid = Signal()
        target = Signal(key_bits)
        # The floor: the target of the last commit (the set streaming now, or the last
        # set sent or given up). A register rather than Mux(streaming, target, last key)
        # keeps a multiplexer off the stale test (issue 17, LUT levels).
        floor_valid = Signal()
        floor_key = Signal(key_bits)
        timer = Signal(p.timer_bits)
        active = Signal(n)
        done = Signal(n)
        missing = Signal(n)
        absent = Signal(n)

        enable = self.cfg.enable
        keys = [Cat(lane.p.row, lane.p.frame) for lane in self.i]
        head = wire(m, Cat(lane.valid & enable[k] for k, lane in enumerate(self.i)), "head")
        first = Cat(lane.p.first for lane in self.i)
        # While a set streams, its own key is the floor: a camera showing it now has
        # missed the set.
        in_frame = Cat(lane.p.row < self.height for lane in self.i)
        stale = wire(m, Cat(head[k] & first[k] & (
            ~in_frame[k] | (floor_valid & ~_older(floor_key, keys[k], key_bits)))
            for k in range(n)), "stale")
        usable = wire(m, head & first & ~stale, "usable")
        # ``same`` counts only while waiting, when the target is newer than the floor:
        # a row showing the target is then never stale for its key, so the floor test
        # (a subtraction) need not sit in front of the equality.
        same = wire(m, Cat(head[k] & first[k] & in_frame[k] & target_valid &
                           (keys[k] == target) for k in range(n)), "same")
        older = wire(m, Cat(usable[k] & target_valid & _older(keys[k], target, key_bits)
                            for k in range(n)), "older")
        newer = wire(m, Cat(usable[k] & target_valid & _older(target, keys[k], key_bits)
                            for k in range(n)), "newer")
        # Every decision reads the verdicts of the clock before (issue 17, LUT levels: the
        # floor and key comparisons end at flip-flops). A usable row is popped only as
        # part of a set, and no set's row is usable (the floor is its key), so a verdict
        # still holds a clock later unless the target or the floor moved; ``fresh`` is low
        # for the clock after either moves. A row older than the target still wins over a
        # commit: the commit reads the same clock's verdicts.
        shown = Signal(n)
        # Per camera: its row starts a frame other than the floor's.
        new_frame = Signal(n)
        seen = Signal(n)
        ahead = Signal(n)
        behind = Signal(n)
        fresh = Signal()
        m.d.sync += [
            shown.eq(usable), seen.eq(same), ahead.eq(newer), behind.eq(older), fresh.eq(1),
            new_frame.eq(Cat(~floor_valid | (key[p.row_bits:] != floor_key[p.row_bits:])
                             for key in keys)),
        ]
        awaited = enable & ~absent & ~seen & ~ahead
        live = wire(m, active & ~done, "live")
        # Rows that cannot join a set: stale rows, stray pixels, disabled cameras.
        discard = wire(m, Cat(lane.valid & (~enable[k] | (~(streaming & live[k]) &
                                                          (~lane.p.first | stale[k])))
                              for k, lane in enumerate(self.i)), "discard")

        all_live_valid = Const(1)
        for k, lane in enumerate(self.i):
            all_live_valid &= ~live[k] | lane.valid
        o = self.o
        m.d.comb += [
            o.valid.eq(streaming & all_live_valid),
            o.p.lane_valid.eq(live),
            o.p.missing.eq(missing),
        ]
        transfer = wire(m, o.valid & o.ready, "transfer")
        for k, lane in enumerate(self.i):
            m.d.comb += [
                o.p.lanes[k].eq(Mux(live[k], lane.p.as_value(), 0)),
                lane.ready.eq((transfer & live[k]) | discard[k]),
            ]

        status = self.status
        for k, lane in enumerate(self.i):
            with m.If(discard[k] & stale[k]):
                m.d.sync += status.stale_count[k].eq(status.stale_count[k] + 1)

        with m.If(streaming):
            finished = Cat(live[k] & self.i[k].p.last for k in range(n))
            with m.If(transfer):
                m.d.sync += done.eq(done | finished)
                with m.If((live & ~finished) == 0):
                    m.d.sync += [streaming.eq(0), target_valid.eq(0)]
        with m.Elif(~target_valid):
            with m.If(fresh & shown.any()):
                m.d.sync += [target_valid.eq(1), target.eq(_lowest(shown, keys)),
                             timer.eq(0), fresh.eq(0)]
                # The trigger brings every camera back in step at each frame.
                with m.If(_lowest(shown, new_frame)):
                    m.d.sync += absent.eq(0)
        with m.Elif(fresh & behind.any()):
            m.d.sync += [target.eq(_lowest(behind, keys)), fresh.eq(0)]
        with m.Else():
            m.d.sync += timer.eq(saturating_increment(timer, 2 ** p.timer_bits - 1))
            with m.If(fresh & ((awaited == 0) | (timer >= self.cfg.timeout))):
                m.d.sync += [
                    active.eq(seen), done.eq(0), missing.eq(enable & ~seen),
                    absent.eq(enable & ~seen & ~ahead),
                    streaming.eq(seen.any()), floor_valid.eq(1), floor_key.eq(target),
                    fresh.eq(0),
                ]
                with m.If(seen == 0):
                    m.d.sync += target_valid.eq(0)
                for k in range(n):
                    with m.If(enable[k] & ~seen[k]):
                        m.d.sync += status.missing_count[k].eq(status.missing_count[k] + 1)
        return m

"""Master/slave camera sync: trigger the cluster, watch its syncs, measure skew.

The thesis' hardware sketch has the FPGA trigger the master camera, the rolling-shutter
cameras run as master and slaves, and every row go to the FPGA as soon as it is read.
:class:`CameraSync` is the FPGA side of that arrangement:

* a trigger generator (frame period, trigger pulse and exposure strobe in system clocks)
  with one delayed copy per camera for sensors that take a frame-sync input (FSIN),
* the system time base (``now``) and frame number every camera input stamps with,
* per camera, the skew of each frame start and each row start against the master's
  (paired by frame number and by row index), a desync flag when a skew exceeds the
  threshold (counted once per frame, re-armed at the master's next frame start), and
  a lost flag when a camera has sent nothing for a programmable time.

:class:`CameraFrontEnd` wires one :class:`~hdl.front_end.camera_input.CameraInput` per camera,
the sync block and the :class:`~hdl.front_end.row_aligner.RowAligner` into the front end.
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hdl.front_end.camera_input import CameraInput, saturating_increment, wire
from hdl.front_end.params import CameraParams
from hdl.fixed import Overflow, Rounding, SQ, hdl_resize
from hdl.front_end.row_aligner import RowAligner
from hdl.logic import same
from hdl.streams import dvp_signature

__all__ = ["CameraSync", "CameraFrontEnd", "sync_config_layout", "sync_status_layout",
           "front_config_layout", "front_status_layout"]


def sync_config_layout(params):
    """Registers of :class:`CameraSync`, all in system clocks.

    ``trigger_enable``; ``period`` (frame period); ``pulse`` (width of the trigger and
    FSIN pulses); ``exposure`` (length of the exposure strobe); ``delay[k]`` (camera
    ``k``'s FSIN delay after the trigger; keep ``delay + pulse <= period``);
    ``skew_threshold`` (largest tolerated ``|skew|``); ``lost_timeout`` (a camera silent
    for longer is lost; 0 disables; make it longer than the gap between frames).
    """
    p = params
    return data.StructLayout({
        "trigger_enable": 1, "period": p.timer_bits, "pulse": p.timer_bits,
        "exposure": p.timer_bits, "delay": data.ArrayLayout(p.timer_bits, p.n_cameras),
        "skew_threshold": p.skew_bits - 1, "lost_timeout": p.timer_bits,
    })


def sync_status_layout(params):
    """Per-camera sync status: flags, wrapping counters, the latest skews."""
    p = params
    n = p.n_cameras
    skew = SQ(p.skew_bits, 0).shape()
    return data.StructLayout({
        "desync": n, "lost": n,
        "desync_count": data.ArrayLayout(p.count_bits, n),
        "lost_count": data.ArrayLayout(p.count_bits, n),
        "frame_skew": data.ArrayLayout(skew, n),
        "row_skew": data.ArrayLayout(skew, n),
    })


def front_config_layout(params):
    """All run-time registers of :class:`CameraFrontEnd`."""
    return data.StructLayout({"input": params.input_config_layout(),
                              "sync": sync_config_layout(params),
                              "align": params.align_config_layout()})


def front_status_layout(params):
    """All status of :class:`CameraFrontEnd`: time base, frame number and counters."""
    return data.StructLayout({
        "now": params.timestamp_bits, "frame": params.frame_bits,
        "sync": sync_status_layout(params), "align": params.align_status_layout(),
        "inputs": data.ArrayLayout(params.input_status_layout(), params.n_cameras),
    })


class CameraSync(wiring.Component):
    """Trigger generator, time base and skew monitor of the camera cluster.

    Parameters
    ----------
    params : CameraParams

    Members
    -------
    cfg : In(sync_config_layout(params))
    events : In(params.event_layout()).array(n_cameras)
        Each camera input's frame and row syncs.
    now : Out(unsigned(timestamp_bits))
        Cycle counter (0 in the first cycle after reset, wraps).
    frame : Out(unsigned(frame_bits))
        Number of the latest trigger (the first is frame 0; all ones before it).
    trigger, expose : Out(1)
        Master trigger pulse and exposure strobe, both starting at the frame start.
    fsin : Out(n_cameras)
        Per-camera trigger pulses, each ``delay[k]`` clocks after the trigger.
    skew : Out(params.skew_layout()).array(n_cameras)
        Skew measurements against the master, as strobes (the master's stay zero).
    status : Out(sync_status_layout(params))

    Latency: the events are registered on entry; a skew is measured in the second cycle
    after the later of the two events arrives, and the flags and counters follow it by
    one more clock (a lost camera is flagged one clock after its timeout, counted from
    the registered events). The trigger outputs are
    registered: they rise one clock after the period counter wraps.
    """

    def __init__(self, params=CameraParams()):
        if not isinstance(params, CameraParams):
            raise TypeError(f"params must be a CameraParams, not {params!r}")
        self.params = params
        super().__init__({
            "cfg": In(sync_config_layout(params)),
            "events": In(params.event_layout()).array(params.n_cameras),
            "now": Out(params.timestamp_bits),
            "frame": Out(params.frame_bits, init=2 ** params.frame_bits - 1),
            "trigger": Out(1), "expose": Out(1), "fsin": Out(params.n_cameras),
            "skew": Out(params.skew_layout()).array(params.n_cameras),
            "status": Out(sync_status_layout(params)),
        })

    def elaborate(self, platform):
        m = Module()
        self._trigger(m)
        self._monitor(m)
        return m

    def _trigger(self, m):
        p, cfg = self.params, self.cfg
        phase = Signal(p.timer_bits)
        on = cfg.trigger_enable
        m.d.sync += self.now.eq(self.now + 1)
        with m.If(on):
            m.d.sync += phase.eq(Mux(phase + 1 >= cfg.period, 0, phase + 1))
            with m.If(phase == 0):
                m.d.sync += self.frame.eq(self.frame + 1)
        with m.Else():
            m.d.sync += phase.eq(0)
        m.d.sync += [
            self.trigger.eq(on & (phase < cfg.pulse)),
            self.expose.eq(on & (phase < cfg.exposure)),
            self.fsin.eq(Cat(on & (phase >= delay) & (phase - delay < cfg.pulse)
                             for delay in cfg.delay)),
        ]

    def _skew(self, later, earlier):
        """Saturated ``later - earlier`` of two wrapping time stamps."""
        p = self.params
        diff = (later - earlier)[:p.timestamp_bits]
        return hdl_resize(diff, SQ(p.timestamp_bits, 0), SQ(p.skew_bits, 0),
                          Rounding.FLOOR, Overflow.SATURATE)

    def _monitor(self, m):
        p = self.params
        # The events are registered on entry: the camera inputs' decode stays out of the
        # pairing's compare chains (issue 17: ≤ 8 LUT levels through the front end).
        events = []
        for k, ev in enumerate(self.events):
            held = Signal(p.event_layout(), name=f"event{k}")
            m.d.sync += held.eq(ev)
            events.append(held)
        master = events[p.master]
        m_frame = Signal(p.frame_bits)
        m_frame_t = Signal(p.timestamp_bits)
        m_row = Signal(p.row_bits)
        m_row_t = Signal(p.timestamp_bits)
        # The master's latest syncs, including this cycle's.
        mf_t = wire(m, Mux(master.frame_start, master.frame_time, m_frame_t), "mf_t")
        mr_t = wire(m, Mux(master.row_start, master.row_time, m_row_t), "mr_t")
        with m.If(master.frame_start):
            m.d.sync += [m_frame.eq(master.frame), m_frame_t.eq(master.frame_time)]
        with m.If(master.row_start):
            m.d.sync += [m_row.eq(master.row), m_row_t.eq(master.row_time)]

        for k, ev in enumerate(events):
            self._lost(m, k, ev)
            if k != p.master:
                self._pair(m, k, ev, master, (m_frame, mf_t), (m_row, mr_t))

    def _lost(self, m, k, ev):
        p, cfg, status = self.params, self.cfg, self.status
        idle = Signal(p.timer_bits, name=f"idle{k}")
        lost_now = wire(m, (cfg.lost_timeout != 0) & (idle >= cfg.lost_timeout), f"lost_now{k}")
        with m.If(ev.frame_start | ev.row_start):
            m.d.sync += idle.eq(0)
        with m.Else():
            m.d.sync += idle.eq(saturating_increment(idle, 2 ** p.timer_bits - 1))
        m.d.sync += status.lost[k].eq(lost_now)
        with m.If(lost_now & ~status.lost[k]):
            m.d.sync += status.lost_count[k].eq(status.lost_count[k] + 1)

    def _pair(self, m, k, ev, master, frame_of_master, row_of_master):
        """Pair camera ``k``'s syncs with the master's; the master's event of a cycle is
        taken before the camera's. ``frame_of_master`` and ``row_of_master``: the master's
        held frame (row) number and the time of its latest, this cycle's included.

        A camera event matches the master's latest (this cycle's event if any, else the
        held one) when no master event of this cycle was matched by camera ``k``'s pending
        one; both cases are compared beside each other and the master's event picks one,
        so the compares do not follow each other (issue 17, LUT levels)."""
        p, cfg, status = self.params, self.cfg, self.status
        m_frame, mf_t = frame_of_master
        m_row, mr_t = row_of_master
        fm_pend = Signal(name=f"fm_pend{k}")    # master frame start awaits camera k
        fc_pend = Signal(name=f"fc_pend{k}")    # camera k frame start awaits master
        fc_frame = Signal(p.frame_bits, name=f"fc_frame{k}")
        fc_t = Signal(p.timestamp_bits, name=f"fc_t{k}")
        rm_pend = Signal(name=f"rm_pend{k}")
        rc_pend = Signal(name=f"rc_pend{k}")
        rc_row = Signal(p.row_bits, name=f"rc_row{k}")
        rc_t = Signal(p.timestamp_bits, name=f"rc_t{k}")

        # Frame starts, matched by frame number.
        f_hit_m = wire(m, master.frame_start & fc_pend & same(fc_frame, master.frame),
                       f"f_hit_m{k}")
        fm_pend1 = wire(m, Mux(master.frame_start, ~f_hit_m, fm_pend), f"fm_pend1_{k}")
        fc_pend1 = fc_pend & ~f_hit_m
        f_hit_c = wire(m, ev.frame_start & Mux(master.frame_start,
                                               ~f_hit_m & same(master.frame, ev.frame),
                                               fm_pend & same(m_frame, ev.frame)),
                       f"f_hit_c{k}")
        frame_hit = f_hit_m | f_hit_c
        # Both candidate skews are computed and the hit picks one: the match compare then
        # runs beside the subtraction instead of in front of it (issue 17, LUT levels).
        frame_skew = wire(m, Mux(f_hit_m, self._skew(fc_t, master.frame_time),
                                 self._skew(ev.frame_time, mf_t)), f"frame_skew{k}")
        m.d.sync += [fm_pend.eq(fm_pend1 & ~f_hit_c), fc_pend.eq(fc_pend1)]
        with m.If(ev.frame_start & ~f_hit_c):
            m.d.sync += [fc_pend.eq(1), fc_frame.eq(ev.frame), fc_t.eq(ev.frame_time)]

        # Row starts, matched by row index; a frame start on either side forgets rows.
        frame_edge = master.frame_start | ev.frame_start
        rc_pend0 = wire(m, rc_pend & ~frame_edge, f"rc_pend0_{k}")
        r_hit_m = wire(m, master.row_start & rc_pend0 & same(rc_row, master.row), f"r_hit_m{k}")
        rm_pend1 = wire(m, Mux(master.row_start, ~r_hit_m, rm_pend & ~master.frame_start),
                        f"rm_pend1_{k}")
        rc_pend1 = rc_pend0 & ~r_hit_m
        r_hit_c = wire(m, ev.row_start & Mux(master.row_start,
                                             ~r_hit_m & same(master.row, ev.row),
                                             rm_pend & ~master.frame_start & same(m_row, ev.row)),
                       f"r_hit_c{k}")
        row_hit = r_hit_m | r_hit_c
        row_skew = wire(m, Mux(r_hit_m, self._skew(rc_t, master.row_time),
                               self._skew(ev.row_time, mr_t)), f"row_skew{k}")
        m.d.sync += [rm_pend.eq(rm_pend1 & ~r_hit_c), rc_pend.eq(rc_pend1)]
        with m.If(ev.row_start & ~r_hit_c):
            m.d.sync += [rc_pend.eq(1), rc_row.eq(ev.row), rc_t.eq(ev.row_time)]

        out = self.skew[k]
        m.d.sync += [
            out.frame_valid.eq(frame_hit), out.frame_skew.eq(frame_skew),
            out.row_valid.eq(row_hit),
            out.row.eq(Mux(r_hit_m, master.row, Mux(r_hit_c, ev.row, 0))),
            out.row_skew.eq(row_skew),
        ]
        with m.If(frame_hit):
            m.d.sync += status.frame_skew[k].eq(frame_skew)
        with m.If(row_hit):
            m.d.sync += status.row_skew[k].eq(row_skew)

        # Desync: any skew beyond the threshold, counted once per master frame.
        def beyond(valid, skew):
            magnitude = Mux(skew < 0, -skew, skew).as_unsigned()[:p.skew_bits]
            return valid & (magnitude > cfg.skew_threshold)
        flag = wire(m, beyond(out.frame_valid, out.frame_skew) |
                    beyond(out.row_valid, out.row_skew), f"desync_flag{k}")
        rearm = Signal(name=f"rearm{k}")
        m.d.sync += rearm.eq(master.frame_start)
        armed = wire(m, status.desync[k] & ~rearm, f"armed{k}")
        m.d.sync += status.desync[k].eq(armed | flag)
        with m.If(flag & ~armed):
            m.d.sync += status.desync_count[k].eq(status.desync_count[k] + 1)


class CameraFrontEnd(wiring.Component):
    """The camera front end: sync, one input per camera, and the row aligner.

    Parameters
    ----------
    params : CameraParams
    domains : sequence of str, optional
        Each camera's pixel clock domain (default ``pclk0``, ``pclk1``, ...).

    Members
    -------
    dvp : In(dvp_signature(pixel_bits)).array(n_cameras)
        Camera ``k``'s port, in ``domains[k]``.
    cfg : In(front_config_layout(params))
    o : Out(stream.Signature(params.aligned_layout()))
        Row sets (:class:`~hdl.front_end.row_aligner.RowAligner`).
    trigger, expose, fsin, skew
        As :class:`CameraSync`.
    status : Out(front_status_layout(params))

    Latency: :attr:`latency` system clocks from the cycle a row's closing word is read
    from its clock crossing to the last pixel of the set on ``o`` (when nothing stalls
    and the set is already streaming); add the crossing (two or three system clocks
    after the PCLK edge that writes the word) and the capture
    (``glitch_pclks + 2`` PCLKs from the pins).
    """

    latency = CameraInput.latency + RowAligner.latency

    def __init__(self, params=CameraParams(), *, domains=None):
        if not isinstance(params, CameraParams):
            raise TypeError(f"params must be a CameraParams, not {params!r}")
        if domains is None:
            domains = tuple(f"pclk{k}" for k in range(params.n_cameras))
        domains = tuple(domains)
        if len(domains) != params.n_cameras:
            raise ValueError(f"domains must name one clock domain per camera "
                             f"({params.n_cameras}), not {len(domains)}")
        if len(set(domains)) != len(domains):
            raise ValueError(f"domains must be distinct, not {domains!r}")
        self.params = params
        self.domains = domains
        #: The clock domains it uses without defining them, in port order
        #: (:func:`hdl.verilog.to_verilog`).
        self.clock_domains = ("sync", *domains)
        super().__init__({
            "dvp": In(dvp_signature(params.pixel_bits)).array(params.n_cameras),
            "cfg": In(front_config_layout(params)),
            "o": Out(stream.Signature(params.aligned_layout())),
            "trigger": Out(1), "expose": Out(1), "fsin": Out(params.n_cameras),
            "skew": Out(params.skew_layout()).array(params.n_cameras),
            "status": Out(front_status_layout(params)),
        })

    def elaborate(self, platform):
        p = self.params
        m = Module()
        m.submodules.sync = sync = CameraSync(p)
        m.submodules.aligner = aligner = RowAligner(p)
        m.d.comb += [
            sync.cfg.eq(self.cfg.sync), aligner.cfg.eq(self.cfg.align),
            aligner.height.eq(self.cfg.input.height),
            self.trigger.eq(sync.trigger), self.expose.eq(sync.expose),
            self.fsin.eq(sync.fsin),
            self.status.now.eq(sync.now), self.status.frame.eq(sync.frame),
            self.status.sync.eq(sync.status), self.status.align.eq(aligner.status),
        ]
        for k, domain in enumerate(self.domains):
            cam = CameraInput(p, camera=k, domain=domain)
            m.submodules[f"input{k}"] = cam
            wiring.connect(m, wiring.flipped(self.dvp[k]), cam.dvp)
            wiring.connect(m, cam.o, aligner.i[k])
            m.d.comb += [
                cam.now.eq(sync.now), cam.frame.eq(sync.frame), cam.cfg.eq(self.cfg.input),
                sync.events[k].eq(cam.event), self.skew[k].eq(sync.skew[k]),
                self.status.inputs[k].eq(cam.status),
            ]
        wiring.connect(m, aligner.o, wiring.flipped(self.o))
        return m

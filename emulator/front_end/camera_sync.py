"""Cycle-accurate models of :class:`hdl.front_end.camera_sync.CameraSync` and of the whole
:class:`hdl.front_end.camera_sync.CameraFrontEnd`.

:class:`FrontEndModel` composes the per-camera capture and crossing
(:func:`emulator.front_end.camera_input.capture_words`), the assembly
(:class:`~emulator.front_end.camera_input.CameraInputModel`), the aligner
(:class:`~emulator.front_end.row_aligner.RowAlignerModel`) and :class:`CameraSyncModel`, and
predicts every row set, skew measurement and counter, cycle by cycle, from what the
cameras put on their pins and the downstream ``ready`` of each cycle.
"""

from hdl.fixed import Overflow, Rounding, SQ, resize

from emulator.front_end.camera_input import CameraInputModel, capture_words
from emulator.front_end.row_aligner import RowAlignerModel

__all__ = ["CameraSyncModel", "FrontEndModel", "skew_of"]


def skew_of(params, later, earlier):
    """Saturated ``later - earlier`` of two wrapping time stamps, as the hardware does."""
    bits = params.timestamp_bits
    diff = (later - earlier) & ((1 << bits) - 1)
    diff = diff - (1 << bits) if diff >> (bits - 1) else diff
    return int(resize(diff, SQ(bits, 0), SQ(params.skew_bits, 0),
                      Rounding.FLOOR, Overflow.SATURATE))


class _Pairing:
    """Camera k's pending frame and row syncs against the master's."""

    def __init__(self):
        self.fm_pend = self.fc_pend = self.rm_pend = self.rc_pend = False
        self.fc_frame = self.fc_t = self.rc_row = self.rc_t = 0


class CameraSyncModel:
    """:class:`~hdl.front_end.camera_sync.CameraSync`, cycle by cycle.

    The attributes ``now``, ``frame``, ``trigger``, ``expose``, ``fsin``, ``skew`` and
    ``status`` hold the registered outputs of the current cycle; :meth:`step` takes the
    cycle's events (one dict per camera) and advances to the next cycle.
    """

    def __init__(self, params, cfg):
        self.p = params
        self.cfg = cfg
        n = params.n_cameras
        self.now = 0
        self.frame = 2 ** params.frame_bits - 1
        self.phase = 0
        self.trigger = self.expose = 0
        self.fsin = 0
        self.m_frame = self.m_frame_t = self.m_row = self.m_row_t = 0
        self.pairs = [_Pairing() for _ in range(n)]
        self.idle = [0] * n
        self.rearm = False
        self.skew = [self._no_skew() for _ in range(n)]
        #: The events registered on entry (none after reset).
        self.held = [{name: 0 for name, _ in params.event_layout()} for _ in range(n)]
        self.status = {"desync": [False] * n, "lost": [False] * n,
                       "desync_count": [0] * n, "lost_count": [0] * n,
                       "frame_skew": [0] * n, "row_skew": [0] * n}

    @staticmethod
    def _no_skew():
        return {"frame_valid": 0, "frame_skew": 0, "row_valid": 0, "row": 0, "row_skew": 0}

    def step(self, events):
        """Advance one cycle with this cycle's ``events``; the monitor sees the previous
        cycle's (the gateware registers them on entry)."""
        events, self.held = self.held, [dict(ev) for ev in events]
        p, cfg, st = self.p, self.cfg, self.status
        n = p.n_cameras
        count_mask = (1 << p.count_bits) - 1
        timer_top = 2 ** p.timer_bits - 1

        # Trigger generator (registered outputs from this cycle's phase).
        on = cfg["trigger_enable"]
        phase = self.phase
        trigger = int(bool(on) and phase < cfg["pulse"])
        expose = int(bool(on) and phase < cfg["exposure"])
        fsin = sum(1 << k for k, d in enumerate(cfg["delay"])
                   if on and phase >= d and phase - d < cfg["pulse"])
        frame = self.frame
        if on:
            if phase == 0:
                frame = (frame + 1) & ((1 << p.frame_bits) - 1)
            nxt = (phase + 1) & timer_top
            self.phase = 0 if phase + 1 >= cfg["period"] else nxt
        else:
            self.phase = 0

        # Desync flags and counters follow last cycle's measurements.
        rearm = self.rearm
        new_desync = list(st["desync"])
        for k in range(n):
            if k == p.master:
                continue
            s = self.skew[k]
            flag = ((s["frame_valid"] and abs(s["frame_skew"]) > cfg["skew_threshold"])
                    or (s["row_valid"] and abs(s["row_skew"]) > cfg["skew_threshold"]))
            armed = st["desync"][k] and not rearm
            new_desync[k] = bool(armed or flag)
            if flag and not armed:
                st["desync_count"][k] = (st["desync_count"][k] + 1) & count_mask
        st["desync"] = new_desync

        # Lost cameras.
        timeout = cfg["lost_timeout"]
        for k, ev in enumerate(events):
            lost_now = timeout != 0 and self.idle[k] >= timeout
            if lost_now and not st["lost"][k]:
                st["lost_count"][k] = (st["lost_count"][k] + 1) & count_mask
            st["lost"][k] = lost_now
            self.idle[k] = 0 if ev["frame_start"] or ev["row_start"] else min(
                self.idle[k] + 1, timer_top)

        # Pairing against the master.
        master = events[p.master]
        mf = master["frame"] if master["frame_start"] else self.m_frame
        mf_t = master["frame_time"] if master["frame_start"] else self.m_frame_t
        mr = master["row"] if master["row_start"] else self.m_row
        mr_t = master["row_time"] if master["row_start"] else self.m_row_t
        skews = [self._no_skew() for _ in range(n)]
        for k, ev in enumerate(events):
            if k != p.master:
                skews[k] = self._pair(self.pairs[k], ev, master, mf, mf_t, mr, mr_t)
                if skews[k]["frame_valid"]:
                    st["frame_skew"][k] = skews[k]["frame_skew"]
                if skews[k]["row_valid"]:
                    st["row_skew"][k] = skews[k]["row_skew"]
        if master["frame_start"]:
            self.m_frame, self.m_frame_t = master["frame"], master["frame_time"]
        if master["row_start"]:
            self.m_row, self.m_row_t = master["row"], master["row_time"]

        self.skew = skews
        self.rearm = bool(master["frame_start"])
        self.now = (self.now + 1) & ((1 << p.timestamp_bits) - 1)
        self.frame = frame
        self.trigger, self.expose, self.fsin = trigger, expose, fsin

    def _pair(self, s, ev, master, mf, mf_t, mr, mr_t):
        p = self.p
        # Frame starts.
        f_hit_m = bool(master["frame_start"] and s.fc_pend and s.fc_frame == master["frame"])
        fm_pend1 = (not f_hit_m) if master["frame_start"] else s.fm_pend
        fc_pend1 = s.fc_pend and not f_hit_m
        f_hit_c = bool(ev["frame_start"] and fm_pend1 and mf == ev["frame"])
        frame_skew = (skew_of(p, s.fc_t, master["frame_time"]) if f_hit_m
                      else skew_of(p, ev["frame_time"], mf_t))
        s.fm_pend = fm_pend1 and not f_hit_c
        s.fc_pend = fc_pend1
        if ev["frame_start"] and not f_hit_c:
            s.fc_pend, s.fc_frame, s.fc_t = True, ev["frame"], ev["frame_time"]
        # Row starts.
        frame_edge = master["frame_start"] or ev["frame_start"]
        rc_pend0 = s.rc_pend and not frame_edge
        r_hit_m = bool(master["row_start"] and rc_pend0 and s.rc_row == master["row"])
        rm_pend1 = (not r_hit_m) if master["row_start"] else (
            s.rm_pend and not master["frame_start"])
        rc_pend1 = rc_pend0 and not r_hit_m
        r_hit_c = bool(ev["row_start"] and rm_pend1 and mr == ev["row"])
        row_skew = (skew_of(p, s.rc_t, master["row_time"]) if r_hit_m
                    else skew_of(p, ev["row_time"], mr_t))
        row = master["row"] if r_hit_m else (ev["row"] if r_hit_c else 0)
        s.rm_pend = rm_pend1 and not r_hit_c
        s.rc_pend = rc_pend1
        if ev["row_start"] and not r_hit_c:
            s.rc_pend, s.rc_row, s.rc_t = True, ev["row"], ev["row_time"]
        return {"frame_valid": int(f_hit_m or f_hit_c), "frame_skew": frame_skew,
                "row_valid": int(r_hit_m or r_hit_c), "row": row, "row_skew": row_skew}


class FrontEndModel:
    """The camera front end, cycle by cycle.

    Parameters
    ----------
    params : hdl.front_end.params.CameraParams
    cfg : dict
        The run-time registers, shaped like ``front_config_layout(params)`` (arrays as
        lists or index-keyed dicts).
    cameras : sequence of (samples, pclk_times)
        What each camera's port saw at each of its PCLK rising edges (see
        :func:`~emulator.front_end.camera_input.capture_words`).
    clock : emulator.front_end.camera_input.SystemClock
    ready : callable
        ``ready(cycle)``: the downstream ``o.ready`` in that cycle.
    """

    def __init__(self, params, cfg, cameras, clock, ready):
        self.p = params
        self.ready = ready
        icfg, scfg, acfg = cfg["input"], _listify(cfg["sync"]), cfg["align"]
        self.words = []
        for samples, times in cameras:
            self.words.append(dict(capture_words(params, samples, times, clock,
                                                 icfg["width"])))
        self.inputs = [CameraInputModel(params, k, icfg) for k in range(params.n_cameras)]
        self.aligner = RowAlignerModel(params, acfg, icfg["height"])
        self.sync = CameraSyncModel(params, scfg)
        self.cycle = 0
        #: (cycle, set) of every transfer on ``o``.
        self.transfers = []
        #: (cycle, camera, measurement) of every skew strobe.
        self.skews = []

    def run(self, cycles):
        """Advance ``cycles`` cycles."""
        for _ in range(cycles):
            self._step()

    def _step(self):
        c = self.cycle
        now, frame = self.sync.now, self.sync.frame
        for k, s in enumerate(self.sync.skew):
            if s["frame_valid"] or s["row_valid"]:
                self.skews.append((c, k, dict(s)))
        offers = [inp.offer() for inp in self.inputs]
        ready = bool(self.ready(c))
        out, taken = self.aligner.cycle(offers, ready)
        if out is not None and ready:
            self.transfers.append((c, out))
        events = [dict(inp.event) for inp in self.inputs]
        for k, inp in enumerate(self.inputs):
            inp.step(self.words[k].get(c), now, frame, taken[k])
        self.sync.step(events)
        self.cycle += 1

    def status(self):
        """The ``status`` port, shaped like ``front_status_layout(params)``."""
        sync = self.sync.status
        return {
            "now": self.sync.now, "frame": self.sync.frame,
            "sync": {"desync": _mask(sync["desync"]), "lost": _mask(sync["lost"]),
                     **{key: _indexed(sync[key]) for key in
                        ("desync_count", "lost_count", "frame_skew", "row_skew")}},
            "align": {key: _indexed(v) for key, v in self.aligner.status.items()},
            "inputs": {k: dict(inp.status) for k, inp in enumerate(self.inputs)},
        }


def _listify(cfg):
    out = dict(cfg)
    delay = out["delay"]
    out["delay"] = [delay[k] for k in range(len(delay))]
    return out


def _indexed(values):
    return {k: v for k, v in enumerate(values)}


def _mask(bits):
    return sum(1 << k for k, bit in enumerate(bits) if bit)

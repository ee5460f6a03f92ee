"""The camera front end on the cocotb bench: cameras, downstream, model and truth.

:class:`FrontEndRun` drives :class:`hdl.front_end.camera_sync.CameraFrontEnd`'s generated
Verilog: one :class:`~emulator.hdl_sim.dvp.DvpPlayer` per camera with its own PCLK
(period, phase, jitter), triggered by the block's own FSIN outputs, plays image rows;
the downstream ``ready`` follows a seeded per-cycle pattern; every transfer on ``o``
and every skew strobe is recorded with its system cycle. Afterwards
:meth:`FrontEndRun.check_model` replays the recorded pins through
:class:`emulator.front_end.camera_sync.FrontEndModel` and demands the same transfers, strobes and
counters, cycle for cycle, and the ``truth`` helpers compare against what the cameras
actually sent.
"""

from dataclasses import dataclass, field

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge
from cocotb.utils import get_sim_time

from emulator.front_end.camera_input import SystemClock
from emulator.front_end.camera_sync import FrontEndModel
from hdl.front_end.camera_sync import front_config_layout, front_status_layout
from emulator.hdl_sim.clocking import CLOCK_PERIOD_NS, reset, start_clock
from emulator.hdl_sim.dvp import DvpPlayer, DvpTiming, drive_cocotb
from emulator.hdl_sim.payload import pack, unpack

__all__ = ["SYS_PS", "Scenario", "FrontEndRun", "row_runs", "write_time", "dataset_images"]

SYS_PS = CLOCK_PERIOD_NS * 1000


@dataclass
class Scenario:
    """One bench run. Times in system clocks unless named ``_ps``.

    ``periods_ps``/``phases_ps``: each camera's PCLK; ``delays``: FSIN delays;
    ``ready``: probability of ``o.ready`` per cycle; ``stall``: ``(first, count)``
    cycles with ``o.ready`` low; ``faults``: camera -> tuple of Fault.
    """
    n_frames: int
    timing: DvpTiming
    periods_ps: tuple
    phases_ps: tuple
    delays: tuple
    period: int
    jitter_ps: int = 0
    ready: float = 1.0
    stall: tuple = None
    faults: dict = field(default_factory=dict)
    skew_threshold: int = 12
    align_timeout: int = 40
    pclk_timeout: int = 60
    lost_timeout: int = 0
    images: object = None

    def config(self, params):
        n = params.n_cameras
        return {
            "input": {"width": self.timing.width, "height": self.timing.height,
                      "pclk_timeout": self.pclk_timeout},
            "sync": {"trigger_enable": 1, "period": self.period, "pulse": 4, "exposure": 20,
                     "delay": {k: self.delays[k] for k in range(n)},
                     "skew_threshold": self.skew_threshold,
                     "lost_timeout": self.lost_timeout},
            "align": {"enable": (1 << n) - 1, "timeout": self.align_timeout},
        }


def dataset_images(path, n_cameras, width, height, n_frames):
    """``(n_cameras, n_frames, height, width)`` rows of a golden simulator dataset."""
    from golden.dataset import Dataset
    cams = Dataset.load(path).cameras
    if len(cams) < n_cameras:
        raise ValueError(f"the dataset has {len(cams)} cameras, the bench needs {n_cameras}")
    return np.stack([rec.rows[:n_frames, :height, :width] for rec in cams[:n_cameras]])


class FrontEndRun:
    def __init__(self, dut, params, scenario, rng):
        self.dut = dut
        self.p = params
        self.sc = scenario
        self.rng = rng
        n = params.n_cameras
        t = scenario.timing
        self.images = (scenario.images if scenario.images is not None else
                       np.array([[rng.randrange(1 << params.pixel_bits) for _ in range(t.width)]
                                 for _ in range(n * scenario.n_frames * t.height)])
                       .reshape(n, scenario.n_frames, t.height, t.width))
        self.cfg = scenario.config(params)
        self.pixel_layout = params.aligned_layout()
        self.skew_layout = params.skew_layout()
        self.players = [DvpPlayer(frames=self.images[k], timing=t,
                                  period_ps=scenario.periods_ps[k],
                                  phase_ps=scenario.phases_ps[k],
                                  jitter_ps=scenario.jitter_ps, rng=rng,
                                  faults=tuple(scenario.faults.get(k, ())))
                        for k in range(n)]
        self.cycles = self._ready_pattern()
        self.transfers = []
        self.skews = []
        self.cycle = 1
        self.t0 = None

    def _ready_pattern(self):
        sc = self.sc
        length = sc.n_frames * sc.period * 2 + 20000
        pattern = [self.rng.random() < sc.ready for _ in range(length)]
        pattern[:2] = [True, True]
        if sc.stall:
            first, count = sc.stall
            pattern[first:first + count] = [False] * count
        return pattern

    def ready(self, cycle):
        return self.cycles[cycle] if cycle < len(self.cycles) else True

    async def run(self, extra_cycles=400):
        """Reset, play every frame, and keep going until all rows have drained."""
        dut, p = self.dut, self.p
        clock = start_clock(dut)
        for k in range(p.n_cameras):
            getattr(dut, f"pclk{k}_rst").value = 1
        dut.cfg.value = pack(front_config_layout(p), self.cfg)
        dut.o__ready.value = 1
        for k, player in enumerate(self.players):
            cocotb.start_soon(drive_cocotb(dut, f"dvp__{k}", f"pclk{k}_clk", player,
                                           trigger=self._fsin(k)))
        await reset(dut)
        for k in range(p.n_cameras):
            getattr(dut, f"pclk{k}_rst").value = 0
        cocotb.start_soon(self._monitor())
        await ClockCycles(dut.clk, self.sc.n_frames * self.sc.period)
        while any(pl.busy for pl in self.players):
            await ClockCycles(dut.clk, 50)
        await ClockCycles(dut.clk, extra_cycles)
        await ReadOnly()
        self.end_cycle = self.cycle
        self.status = unpack(front_status_layout(p), dut.status.value)
        return clock

    def _fsin(self, k):
        fsin = self.dut.fsin
        return lambda: int(fsin.value) >> k & 1

    async def _monitor(self):
        dut = self.dut
        skew_ports = [getattr(dut, f"skew__{k}") for k in range(self.p.n_cameras)]
        valid_bits = sum(1 << f.offset for name, f in self.skew_layout
                         if name in ("frame_valid", "row_valid"))
        while True:
            await RisingEdge(dut.clk)
            self.cycle += 1
            c = self.cycle
            if self.t0 is None:
                self.t0 = int(get_sim_time("ps")) - c * SYS_PS
            ready = self.ready(c)
            dut.o__ready.value = int(ready)
            await ReadOnly()
            if c == 2:
                now = unpack(front_status_layout(self.p), dut.status.value)["now"]
                assert now == c, f"cycle numbering is off: now={now} in bench cycle {c}"
            if ready and int(dut.o__valid.value):
                self.transfers.append((c, unpack(self.pixel_layout, dut.o__payload.value)))
            for k, port in enumerate(skew_ports):
                value = int(port.value)
                if value & valid_bits:
                    self.skews.append((c, k, unpack(self.skew_layout, value)))

    # --- checks ------------------------------------------------------------------------

    def model(self):
        model = FrontEndModel(self.p, self.cfg,
                              [(pl.samples, pl.times) for pl in self.players],
                              SystemClock(self.t0, SYS_PS), self.ready)
        model.run(self.end_cycle)
        return model

    def check_model(self):
        """The emulator predicts every transfer, skew strobe and counter exactly."""
        model = self.model()
        assert len(self.transfers) == len(model.transfers), (
            f"{len(self.transfers)} transfers on o, the model predicts {len(model.transfers)}")
        for got, exp in zip(self.transfers, model.transfers):
            assert got == exp, f"o differs from the model: got {got}, expected {exp}"
        for got, exp in zip(self.skews, model.skews):
            assert got == exp, f"skew strobe differs from the model: got {got}, expected {exp}"
        assert len(self.skews) == len(model.skews), (
            f"{len(self.skews)} skew strobes, the model predicts {len(model.skews)}")
        assert self.status == model.status(), "status differs from the model"
        return model

    def sets(self):
        """Row sets sent on ``o``: dicts with frame, row, lanes {k: row record}, missing,
        the cycle of the last transfer."""
        sets, current = [], None
        for cycle, out in self.transfers:
            live = [k for k in out["lanes"] if out["lane_valid"] >> k & 1]
            if current is None:
                head = out["lanes"][live[0]]
                current = {"frame": head["frame"], "row": head["row"], "missing": out["missing"],
                           "lanes": {k: {"pixels": [], "first_cycle": cycle} for k in live},
                           "open": set(live)}
            for k in live:
                beat = out["lanes"][k]
                lane = current["lanes"][k]
                lane["pixels"].append(beat["data"])
                if beat["last"]:
                    lane.update(flags=beat["flags"], t_first=beat["t_first"],
                                t_last=beat["t_last"], frame=beat["frame"], row=beat["row"],
                                last_cycle=cycle)
                    current["open"].discard(k)
            if not current["open"]:
                current["last_cycle"] = cycle
                sets.append(current)
                current = None
        return sets


def row_runs(player, glitch_pclks):
    """HREF runs each frame put on the pins: per played frame, a list of
    ``(first_sample, last_sample)`` (runs of at most ``glitch_pclks`` are left out)."""
    href = [s[1] for s in player.samples]
    starts = list(player.frame_starts) + [len(href)]
    frames = []
    for a, b in zip(starts, starts[1:]):
        runs, x = [], a
        while x < b:
            if href[x] and (x == 0 or not href[x - 1]):
                y = x
                while y + 1 < len(href) and href[y + 1]:
                    y += 1
                if y - x + 1 > glitch_pclks:
                    runs.append((x, y))
                x = y + 1
            else:
                x += 1
        frames.append(runs)
    return frames


def write_time(player, sample, glitch_pclks):
    """Time of the PCLK edge that writes the word of ``sample`` into the crossing."""
    return player.times[sample + glitch_pclks + 1]


# --- checks of a run against what the cameras sent ---------------------------------

def all_rows(run):
    """(camera, frame, row) of every row the cameras were asked to send."""
    return {(k, f, y) for k in range(run.p.n_cameras) for f in range(run.sc.n_frames)
            for y in range(run.sc.timing.height)}


def check_rows(run, sets, expected_good):
    """Good rows carry their pixels bit-exact; flagged rows carry a prefix of theirs;
    every row in ``expected_good`` arrives good, in a set with its own frame and row."""
    good = set()
    for s in sets:
        for k, lane in s["lanes"].items():
            assert (lane["frame"], lane["row"]) == (s["frame"], s["row"])
            frame, row = lane["frame"], lane["row"]
            if frame >= run.sc.n_frames or row >= run.sc.timing.height:
                continue
            truth = [int(v) for v in run.images[k, frame, row]]
            if lane["flags"] == 0:
                assert lane["pixels"] == truth, f"camera {k} frame {frame} row {row} differs"
                good.add((k, frame, row))
            else:
                assert lane["pixels"] == truth[:len(lane["pixels"])], (
                    f"flagged row camera {k} frame {frame} row {row} is not a prefix")
    missing = expected_good - good
    assert not missing, f"good rows that did not arrive: {sorted(missing)[:10]}"
    return good


#: Clocks by which two row starts must be apart for their order as the camera sync sees
#: it to be certain (each crosses into the system clock one to two clocks after its
#: PCLK edge).
ORDER_MARGIN = 2


def pairable_rows(pk, pm, run_k, run_m, offset, height):
    """Camera ``k``'s rows of one frame that the sync must pair with the master's and
    those it may pair. It pairs row y when neither camera has started row y + 1 before
    the other's row y (``hdl.front_end.camera_sync``: the latest unpaired row start of each side is
    kept), so a skew of about a row period or more leaves a row unpaired; starts within
    ``ORDER_MARGIN`` clocks of each other may go either way."""
    def start(player, runs, y):
        return player.times[runs[y][0] + offset] / SYS_PS if y < height else float("inf")
    certain, possible = set(), set()
    for y in range(height):
        margin = min(start(pm, run_m, y + 1) - start(pk, run_k, y),
                     start(pk, run_k, y + 1) - start(pm, run_m, y))
        if margin > ORDER_MARGIN:
            certain.add(y)
        if margin > -ORDER_MARGIN:
            possible.add(y)
    return certain, possible


def check_skews(run, frames, tolerance=1):
    """Measured skews equal the skews between the PCLK edges that wrote the events into
    the crossings, within ``tolerance`` clocks, for every frame and for the rows the sync
    pairs (:func:`pairable_rows`). Returns the largest error against those edges and
    against the edges that sampled the events at the pins (the two differ by
    ``glitch_pclks + 1`` times the difference of the cameras' PCLK periods)."""
    g = run.p.glitch_pclks
    master = run.p.master
    height = run.sc.timing.height
    runs = [row_runs(pl, g) for pl in run.players]
    worst = {"write": 0.0, "pin": 0.0}
    for k in range(run.p.n_cameras):
        if k == master:
            continue
        pk, pm = run.players[k], run.players[master]
        measured_f = [s["frame_skew"] for c, cam, s in run.skews if cam == k and s["frame_valid"]]
        assert len(measured_f) == len(frames)
        measured_r = {}             # frame index -> {row: skew}; a new frame when rows restart
        f, last = 0, -1
        for c, cam, s in run.skews:
            if cam == k and s["row_valid"]:
                f, last = (f + 1, s["row"]) if s["row"] <= last else (f, s["row"])
                measured_r.setdefault(f, {})[s["row"]] = s["row_skew"]
        for i, f in enumerate(frames):
            certain, possible = pairable_rows(pk, pm, runs[k][f], runs[master][f], g + 1,
                                              height)
            rows = set(measured_r.get(i, {}))
            assert certain <= rows <= possible, (
                f"camera {k} frame {f}: rows paired {sorted(rows)}, must be "
                f"{sorted(certain)}, may be {sorted(possible)}")
        for edge, offset in (("write", g + 1), ("pin", 0)):
            for i, f in enumerate(frames):
                pairs = [(measured_f[i], pk.times[pk.frame_starts[f] + offset]
                          - pm.times[pm.frame_starts[f] + offset])]
                pairs += [(skew, pk.times[runs[k][f][y][0] + offset]
                           - pm.times[runs[master][f][y][0] + offset])
                          for y, skew in sorted(measured_r.get(i, {}).items())]
                errors = [abs(m - t / SYS_PS) for m, t in pairs]
                worst[edge] = max([worst[edge]] + errors)
    assert worst["write"] <= tolerance, (
        f"skew measured {worst['write']:.2f} clocks away from the injected skew")
    return worst


def check_timestamps(run, sets):
    """Each time stamp is the system cycle in which its word was read from the crossing:
    one to two clocks after the PCLK edge that wrote it."""
    g = run.p.glitch_pclks
    runs = [row_runs(pl, g) for pl in run.players]
    for s in sets:
        for k, lane in s["lanes"].items():
            if lane["flags"]:
                continue
            first, last = runs[k][lane["frame"]][lane["row"]]
            for stamp, sample in ((lane["t_first"], first), (lane["t_last"], last)):
                d = run.t0 + stamp * SYS_PS - write_time(run.players[k], sample, g)
                assert SYS_PS < d < 2 * SYS_PS, (
                    f"camera {k} frame {lane['frame']} row {lane['row']}: time stamp "
                    f"{stamp} is {d / SYS_PS:.2f} clocks after its pixel was written")


def latencies(run, sets):
    """Per set, clocks from the latest camera's last pixel at its input register (the
    PCLK edge that samples it) to the edge that takes the set's last pixel from ``o``."""
    g = run.p.glitch_pclks
    runs = [row_runs(pl, g) for pl in run.players]
    out = []
    for s in sets:
        pin = max(run.players[k].times[runs[k][lane["frame"]][lane["row"]][1]]
                  for k, lane in s["lanes"].items())
        out.append((run.t0 + (s["last_cycle"] + 1) * SYS_PS - pin) / SYS_PS)
    return out

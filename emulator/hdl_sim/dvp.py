"""A DVP camera for benches: plays image rows on VSYNC/HREF/data with its own PCLK.

The camera waits for its trigger (FSIN), then plays one frame of a
``(n_frames, height, width)`` array (one camera's slice of ``Dataset.rows``), row by
row as a rolling-shutter sensor reads it out: a VSYNC pulse, vertical blanking, then
each row on HREF with horizontal blanking between rows. Faults can be injected at chosen
rows (:class:`Fault`).

:class:`DvpPlayer` holds the schedule and the clock; the thin drivers
(:func:`drive_cocotb`, :func:`drive_amaranth`) only move pins. Every PCLK rising edge is
recorded (``samples``, ``times`` in picoseconds) so the emulator can replay exactly what
the port saw. Edge times are kept odd (in picoseconds) so that they never coincide with
a system clock edge of an even period and phase: the crossing is then never a race.
"""

from dataclasses import dataclass, field

__all__ = ["DvpTiming", "Fault", "FAULT_KINDS", "frame_waveform", "DvpPlayer",
           "drive_cocotb", "drive_amaranth"]

#: Faults a camera can inject; see :class:`Fault`.
FAULT_KINDS = ("short", "long", "glitch", "dropout", "no_vsync", "extra_vsync", "stall",
               "stop")


@dataclass(frozen=True, kw_only=True)
class DvpTiming:
    """Frame timing of a camera, in PCLKs.

    ``start``: from the trigger to VSYNC; ``vsync``: VSYNC pulse; ``vblank``: from VSYNC
    low to the first row; ``hblank``: HREF low between rows, plus a random
    ``0..hblank_jitter`` extra per row (row-time jitter).
    """
    width: int
    height: int
    start: int = 3
    vsync: int = 3
    vblank: int = 6
    hblank: int = 6
    hblank_jitter: int = 0

    @property
    def frame_pclks(self):
        """Longest frame from its trigger, in PCLKs."""
        return (self.start + self.vsync + self.vblank
                + self.height * (self.width + self.hblank + self.hblank_jitter))


@dataclass(frozen=True)
class Fault:
    """A fault injected by one camera at frame ``frame``, row ``row``.

    ``short``/``long``: the row has ``arg`` pixels fewer/more. ``glitch``: an HREF pulse
    of ``arg`` PCLKs in the blanking after the row. ``dropout``: HREF low for
    ``arg`` PCLKs from the middle of the row. ``no_vsync``: the frame's VSYNC is not
    sent. ``extra_vsync``: a VSYNC pulse just before the row. ``stall``: PCLK stops for
    ``arg`` picoseconds in the middle of the row. ``stop``: the camera sends nothing
    from this frame on.
    """
    kind: str
    frame: int
    row: int = 0
    arg: int = 0

    def __post_init__(self):
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"kind must be one of {', '.join(FAULT_KINDS)}, not {self.kind!r}")


def frame_waveform(image, timing, faults, rng):
    """One frame as a list of PCLK samples ``(vsync, href, data, pause_ps)``.

    ``image`` is ``(height, width)``; ``faults`` are this frame's; ``rng`` a seeded
    ``random.Random`` (jitter, extra pixels). ``pause_ps`` stops PCLK before the sample.
    """
    by_row = {}
    for f in faults:
        by_row.setdefault((f.kind, f.row), f)
    out = []

    def idle(count):
        out.extend([(0, 0, 0, 0)] * count)

    def pixels(values):
        out.extend((0, 1, int(v), 0) for v in values)

    if ("no_vsync", 0) in by_row:
        idle(timing.vsync)
    else:
        out.extend([(1, 0, 0, 0)] * timing.vsync)
    idle(timing.vblank)
    for y in range(timing.height):
        if ("extra_vsync", y) in by_row:
            out.extend([(1, 0, 0, 0)] * timing.vsync)
            idle(1)
        row = [int(v) for v in image[y]]
        width = len(row)
        half = width // 2
        if ("short", y) in by_row:
            row = row[:width - by_row["short", y].arg]
        if ("long", y) in by_row:
            row = row + [rng.randrange(256) for _ in range(by_row["long", y].arg)]
        row_start = len(out)
        if ("dropout", y) in by_row:
            gap = by_row["dropout", y].arg
            pixels(row[:half])
            out.extend((0, 0, v, 0) for v in row[half:half + gap])
            pixels(row[half + gap:])
        else:
            pixels(row)
        if ("stall", y) in by_row:
            index = min(row_start + half, len(out) - 1)
            vs, href, value, _ = out[index]
            out[index] = (vs, href, value, by_row["stall", y].arg)
        blank = timing.hblank + (rng.randint(0, timing.hblank_jitter)
                                 if timing.hblank_jitter else 0)
        if ("glitch", y) in by_row:
            pulse = by_row["glitch", y].arg
            idle(1)
            out.extend((0, 1, rng.randrange(256), 0) for _ in range(pulse))
            blank -= 1 + pulse
        idle(max(blank, 1))
    return out


@dataclass
class DvpPlayer:
    """One camera: its PCLK, its trigger handling and its frame schedule.

    Parameters
    ----------
    frames : array (n_frames, height, width)
        Rows to play (uint8 or wider raw pixels).
    timing : DvpTiming
    period_ps : int
        Nominal PCLK period (a multiple of 4 keeps edges odd).
    phase_ps : int
        First rising edge (odd).
    jitter_ps : int
        Each period varies by a random even amount in ``[-jitter_ps, jitter_ps]``.
    faults : sequence of Fault
    rng : random.Random
    free_run : int or None
        If set, frames start every ``free_run`` PCLKs without a trigger.
    """
    frames: object
    timing: DvpTiming
    period_ps: int
    phase_ps: int
    rng: object
    jitter_ps: int = 0
    faults: tuple = ()
    free_run: int = None
    samples: list = field(default_factory=list)
    times: list = field(default_factory=list)
    #: PCLK edge index of each played frame's first sample.
    frame_starts: list = field(default_factory=list)

    def __post_init__(self):
        if self.period_ps % 4 or self.phase_ps % 2 == 0 or self.jitter_ps % 2:
            raise ValueError("period_ps must be a multiple of 4, phase_ps odd and "
                             "jitter_ps even, so that PCLK edges stay at odd picoseconds")
        self._queue = []
        self._countdown = None
        self._next_frame = 0
        self._prev_trigger = 0
        self._pin = (0, 0, 0)
        self._since_start = 0
        if any(f.kind == "stall" and f.arg % 2 for f in self.faults):
            raise ValueError("a stall must last an even number of picoseconds")
        stop = [f.frame for f in self.faults if f.kind == "stop"]
        self._stop_frame = min(stop) if stop else len(self.frames)

    def rising(self, time_ps, trigger):
        """A PCLK rising edge at ``time_ps``; ``trigger`` is the camera's FSIN level."""
        self.samples.append(self._pin)
        self.times.append(time_ps)
        self._since_start += 1
        start = (trigger and not self._prev_trigger) if self.free_run is None else (
            self._since_start >= self.free_run)
        self._prev_trigger = trigger
        if start and self._countdown is None and self._next_frame < self._stop_frame:
            self._countdown = self.timing.start
            self._since_start = 0

    def falling(self):
        """Falling edge: returns the pins to drive and the picoseconds to the next rise
        after this falling edge."""
        if not self._queue and self._countdown is not None:
            if self._countdown == 0:
                i = self._next_frame
                faults = [f for f in self.faults if f.frame == i]
                self._queue = frame_waveform(self.frames[i], self.timing, faults, self.rng)
                self._queue.reverse()
                self.frame_starts.append(len(self.samples))
                self._next_frame += 1
                self._countdown = None
            else:
                self._countdown -= 1
        vsync, href, value, pause = self._queue.pop() if self._queue else (0, 0, 0, 0)
        self._pin = (vsync, href, value)
        jitter = 2 * self.rng.randint(-self.jitter_ps // 2, self.jitter_ps // 2) \
            if self.jitter_ps else 0
        return self._pin, self.period_ps // 2 + jitter + pause

    @property
    def half_ps(self):
        return self.period_ps // 2

    @property
    def busy(self):
        """Still playing (or about to play) a frame."""
        return bool(self._queue) or self._countdown is not None


async def drive_cocotb(dut, prefix, clock_name, player, trigger=None):
    """Drive ``<clock_name>`` and the ``<prefix>__vsync/href/data`` pins of a cocotb
    ``dut`` from ``player`` forever. ``trigger()`` returns the FSIN level."""
    from cocotb.triggers import Timer
    from cocotb.utils import get_sim_time
    clk = getattr(dut, clock_name)
    vsync = getattr(dut, f"{prefix}__vsync")
    href = getattr(dut, f"{prefix}__href")
    pins = getattr(dut, f"{prefix}__data")
    clk.value = 0
    vsync.value = href.value = pins.value = 0
    await Timer(player.phase_ps, unit="ps")
    while True:
        clk.value = 1
        player.rising(int(get_sim_time("ps")), bool(trigger()) if trigger else False)
        await Timer(player.half_ps, unit="ps")
        clk.value = 0
        (v, h, d), wait = player.falling()
        vsync.value, href.value, pins.value = v, h, d
        await Timer(wait, unit="ps")


async def drive_amaranth(ctx, clk, port, player, until_ps, trigger=None):
    """The same, in the Amaranth simulator: drive clock signal ``clk`` and the ``port``
    (vsync, href, data members) until ``until_ps``."""
    time = 0
    ctx.set(clk, 0)
    await ctx.delay(player.phase_ps * 1e-12)
    time += player.phase_ps
    while time < until_ps:
        ctx.set(clk, 1)
        player.rising(time, bool(ctx.get(trigger)) if trigger is not None else False)
        await ctx.delay(player.half_ps * 1e-12)
        ctx.set(clk, 0)
        (v, h, d), wait = player.falling()
        ctx.set(port.vsync, v)
        ctx.set(port.href, h)
        ctx.set(port.data, d)
        await ctx.delay(wait * 1e-12)
        time += player.half_ps + wait

"""Cycle-accurate model of :class:`hdl.front_end.row_aligner.RowAligner`."""

__all__ = ["RowAlignerModel"]


def _older(a, b, bits):
    """``a`` comes before ``b`` modulo ``2**bits``."""
    return (a - b) & (1 << (bits - 1)) != 0


class RowAlignerModel:
    """Each cycle, :meth:`cycle` takes the beat each lane offers (a pixel dict or
    ``None``) and the downstream ``ready``, and returns the set offered downstream this
    cycle (or ``None``; it is transferred if ``ready``) and which lanes were popped.
    ``status`` mirrors the counters."""

    def __init__(self, params, cfg, height):
        self.p = params
        self.cfg = cfg
        self.height = height
        self.key_bits = params.frame_bits + params.row_bits
        n = params.n_cameras
        self.streaming = self.target_valid = self.last_valid = False
        self.target = self.last_key = self.timer = 0
        self.active = [False] * n
        self.done = [False] * n
        self.missing = [False] * n
        self.absent = [False] * n
        # Last clock's usable/same/newer/older verdicts, and whether the target and the
        # floor have kept still since: every decision reads these, as the hardware does.
        self.shown = [False] * n
        self.seen = [False] * n
        self.ahead = [False] * n
        self.behind = [False] * n
        self.fresh = False
        self.status = {"missing_count": [0] * n, "stale_count": [0] * n}
        self.zero = {name: 0 for name, _ in params.pixel_layout()}

    def _key(self, beat):
        return (beat["frame"] << self.p.row_bits) | beat["row"]

    def cycle(self, offers, ready):
        p, n, bits = self.p, self.p.n_cameras, self.key_bits
        enable = [bool(self.cfg["enable"] >> k & 1) for k in range(n)]
        count_mask = (1 << p.count_bits) - 1
        head = [offers[k] is not None and enable[k] for k in range(n)]
        first = [offers[k] is not None and bool(offers[k]["first"]) for k in range(n)]
        keys = [self._key(b) if b is not None else 0 for b in offers]
        floor_valid = self.streaming or self.last_valid
        floor_key = self.target if self.streaming else self.last_key
        stale = [head[k] and first[k] and (
            offers[k]["row"] >= self.height
            or (floor_valid and not _older(floor_key, keys[k], bits)))
            for k in range(n)]
        usable = [head[k] and first[k] and not stale[k] for k in range(n)]
        tv = self.target_valid
        same = [usable[k] and tv and keys[k] == self.target for k in range(n)]
        older = [usable[k] and tv and _older(keys[k], self.target, bits) for k in range(n)]
        newer = [usable[k] and tv and _older(self.target, keys[k], bits) for k in range(n)]
        shown, seen, ahead, behind = self.shown, self.seen, self.ahead, self.behind
        fresh = self.fresh
        self.shown, self.seen, self.ahead, self.behind = usable, same, newer, older
        self.fresh = True
        awaited = [enable[k] and not self.absent[k] and not seen[k] and not ahead[k]
                   for k in range(n)]
        live = [self.active[k] and not self.done[k] for k in range(n)]
        discard = [offers[k] is not None and (not enable[k] or (
            not (self.streaming and live[k]) and (not first[k] or stale[k])))
            for k in range(n)]
        valid = self.streaming and all(offers[k] is not None for k in range(n) if live[k])
        out = None
        if valid:
            out = {"lanes": {k: offers[k] if live[k] else self.zero for k in range(n)},
                   "lane_valid": _mask(live), "missing": _mask(self.missing)}
        transfer = valid and ready
        taken = [(transfer and live[k]) or discard[k] for k in range(n)]

        st = self.status
        for k in range(n):
            if discard[k] and stale[k]:
                st["stale_count"][k] = (st["stale_count"][k] + 1) & count_mask

        if self.streaming:
            if transfer:
                finished = [live[k] and bool(offers[k]["last"]) for k in range(n)]
                self.done = [self.done[k] or finished[k] for k in range(n)]
                if not any(live[k] and not finished[k] for k in range(n)):
                    self._close_set()
        elif not self.target_valid:
            if fresh and any(shown):
                self.target_valid = True
                self.target = keys[shown.index(True)]
                self.timer = 0
                self.fresh = False
                row_bits = p.row_bits
                if not self.last_valid or self.target >> row_bits != self.last_key >> row_bits:
                    self.absent = [False] * n
        elif fresh and any(behind):
            self.target = keys[behind.index(True)]
            self.fresh = False
        else:
            start = fresh and (not any(awaited) or self.timer >= self.cfg["timeout"])
            self.timer = min(self.timer + 1, 2 ** p.timer_bits - 1)
            if start:
                self.active = list(seen)
                self.done = [False] * n
                self.missing = [enable[k] and not seen[k] for k in range(n)]
                self.absent = [enable[k] and not seen[k] and not ahead[k] for k in range(n)]
                self.streaming = any(seen)
                self.fresh = False
                if not any(seen):
                    self._close_set()
                for k in range(n):
                    if self.missing[k]:
                        st["missing_count"][k] = (st["missing_count"][k] + 1) & count_mask
        return out, taken

    def _close_set(self):
        self.streaming = False
        self.target_valid = False
        self.last_valid = True
        self.last_key = self.target


def _mask(bits):
    return sum(1 << k for k, bit in enumerate(bits) if bit)


"""Bit-accurate model of the measurement router: row-descriptor lanes → pose solver.

The row-descriptor lanes (:mod:`emulator.row_descriptor`) give, per row, K segment
measurements of every camera's temporal lane (current row against the same row of the
previous frame) and of every stereo pair's lane (camera A's row against camera B's).
The pose solver (:mod:`emulator.pose_solver`) takes one transfer per equation:
``slot, row, time, shift, cue, conf, last`` (``hdl/pose/accumulator.py``). This module
is the glue, integers only, every narrowing through :func:`hdl.fixed.resize`.

Decisions (each one is a choice the HDL router must copy):

* **Slot.** ``camera · K + segment``: camera-major, as :func:`golden.pose_lsq.rig_slots`
  orders the coefficient store (``rig.row_points`` must equal the lanes' K).
* **Shift.** ``shift + subpixel`` (exact sum of the lane's ``SQ(s, 0)`` and
  ``SQ(1, f)``), rounded half-even and saturated into the solver's ``shift_fmt``. Same
  sign: the lane's ``cur[x] ≈ ref[x − d]`` is the image displacement from the reference
  row to the current one, which is the solver's shift.
* **Cue.** The disparity of the camera's stereo pair in the same (frame, row): the
  stereo lane's ``shift + subpixel``, half-even, saturated into ``cue_fmt``, one per
  stereo segment, mapped to each temporal segment by :mod:`emulator.measurement.cue_map`
  (interpolated at the segment's centre column as camera A sees it: camera B's centre
  moved right by camera A's cue there; with K_s = 1 one disparity serves the whole
  row). The coefficient table is built with ``cue_scale = 1/(f·b)``. With a
  ``fallback`` (the closed loop's store of each pair's last usable cue per row and
  stereo segment, i.e. the previous frame's), a stereo segment whose match fails takes
  the stored cue of the same row instead (issue 16 item 4), before the map. Every
  camera must belong to exactly one pair: the depth-map cue of the radial rigs is not
  modelled.
* **Confidence.** The temporal lane's peak ratio, half-even and saturated into
  ``conf_fmt``. It is set to zero (the measurement adds nothing to the normal
  equations) when the temporal segment hit the shift-window edge (its shift is a
  bound, not a measurement), when the pair has no stereo measurement of this row and
  segment, or when that stereo measurement gives no depth: its peak ratio below
  ``stereo_window.min_ratio`` (or 0: textureless), its integer disparity outside
  ``stereo_window.accepted`` (the window's guard bands and edges: the surface may lie
  beyond the depth range, issue 18), or its disparity ≤ 0 (no finite depth). The lanes
  already give zero confidence to textureless, bad and reference-less segments.
* **Rows.** Every temporal measurement of a row is sent, zero-weight ones included,
  in slot order, ``last`` on the final one: the stream stays one transfer per
  (camera, segment) and never exceeds ``slots`` (no OVERRUN). A row none of whose
  measurements carries weight reaches the solver as an EMPTY row: it gets a flagged
  record with no step. Cameras without this row contribute no transfers; a row no
  camera delivered produces nothing.
* **Time.** ``t_first`` of the lowest-numbered camera present, masked to the solver's
  ``time_bits``.

The hardware does not group measurements by (frame, row): it follows **tickets**, one
per row set the measurement engine hands to the lanes (:func:`route_tickets` models it,
decision by decision):

* **Temporal lanes** emit exactly K measurements, in segment order, for every row they
  receive (bad rows included), so the router takes exactly K from each lane the ticket
  marks; their slot is ``camera · K + position``. One whose (frame, row) is not the
  ticket's is counted ``misaligned`` and gets zero confidence; its row label is the
  ticket's.
* **Stereo lanes** may lose a row (``hdl.descriptor.framer.StereoJoin`` drops a row whose
  partner never came), so a marked stereo lane is resynchronized measurement by
  measurement: an older (frame, row) than the ticket's (frames compared modulo
  ``2**frame_bits``, as the join does) is dropped and counted ``misaligned``; the
  ticket's own are taken (K_s of them); a newer one ends the search, is left for its
  own ticket, and the row counts as ``stereo_missing`` (its cameras get zero
  confidence).
* **Cue fallback** (``RouterParams.cue_fallback``): a store of each pair's last usable
  cue per (row, stereo segment), as :func:`emulator.pipeline.run`'s ``cue_fallback``:
  each ticket's row reads it (:func:`route_row`'s ``fallback``) and then writes its own
  usable cues into it, whether the pair was marked or not. Rows ``≥ height`` (a
  camera's bad row number) neither read nor write it. It starts empty (the gateware
  clears it after reset).
"""

import numpy as np

from hdl.fixed import Overflow, Rounding, add, resize
from hdl.measurement.router_params import RouterParams

from emulator.measurement.cue_map import pair_cues
from emulator.pose_solver import PoseRows

__all__ = ["RouterParams", "measured_shifts", "usable_cues", "route_row", "route", "route_tickets",
           "stream_order", "pose_rows"]


def _field(records, name):
    return np.array([m[name] for m in records], dtype=np.int64)


def _exact_shifts(records, lane):
    """``shift + subpixel`` of lane measurements, exact: ``(raw array, format)``."""
    return add(_field(records, "shift"), lane.shift_fmt,
               _field(records, "subpixel"), lane.subpixel_fmt)


def measured_shifts(records, lane, dst):
    """``shift + subpixel`` of measurements of a lane with parameters ``lane``, rounded
    half-even and saturated into ``dst`` (raw int array)."""
    return resize(*_exact_shifts(records, lane), dst, Rounding.HALF_EVEN, Overflow.SATURATE)


def usable_cues(params, stereo):
    """``{(camera A, segment): raw cue}`` of the stereo measurements that give a depth."""
    if not stereo:
        return {}
    exact, _ = _exact_shifts(stereo, params.stereo)
    cue = measured_shifts(stereo, params.stereo, params.solver.cue_fmt)
    least, low, high = params.depth_limits()
    return {(m["camera"], m["segment"]): int(c) for m, c, e in zip(stereo, cue, exact)
            if m["confidence"] >= least and not m["edge_hit"] and low <= m["shift"] <= high
            and e > 0}


def route_row(params, temporal, stereo, fallback=None):
    """Solver transfers of one row: ``temporal`` and ``stereo`` are the lanes'
    measurement dicts of that (frame, row), any order; ``fallback`` optionally maps
    ``(camera A, stereo segment)`` to the raw cue used where the stereo lane gave none
    usable. Returns dicts in stream order."""
    d, s = params.temporal, params.solver
    ordered = sorted(temporal, key=lambda m: (m["camera"], m["segment"]))
    if not ordered:
        return []
    cues = {**(fallback or {}), **usable_cues(params, stereo)}
    time = ordered[0]["t_first"] & ((1 << s.time_bits) - 1)
    shift = measured_shifts(ordered, d, s.shift_fmt)
    conf = resize(_field(ordered, "confidence"), d.confidence_fmt, s.conf_fmt,
                  Rounding.HALF_EVEN, Overflow.SATURATE)
    mapped = {}
    for a, b in params.pairs:
        mapped[a], mapped[b] = pair_cues(params.cue_map, [
            cues.get((a, j)) for j in range(params.stereo.segments)])
    out = []
    for m, shift_raw, conf_raw in zip(ordered, shift, conf):
        cue = mapped[m["camera"]][m["segment"]]
        usable = cue is not None and not m["edge_hit"]
        out.append({"slot": m["camera"] * d.segments + m["segment"], "row": m["row"],
                    "time": time, "shift": int(shift_raw), "cue": cue or 0,
                    "conf": int(conf_raw) if usable else 0, "last": 0})
    out[-1]["last"] = 1
    return out


def _by_row(records):
    """Group measurement dicts by (frame, row), keeping first-arrival order."""
    groups = {}
    for m in records:
        groups.setdefault((m["frame"], m["row"]), []).append(m)
    return groups


def route(params, temporal, stereo):
    """Solver transfers of whole measurement streams (all temporal lanes' records and
    all stereo lanes' records), row by row in the order rows first arrive."""
    pairs = _by_row(stereo)
    return [t for key, group in _by_row(temporal).items()
            for t in route_row(params, group, pairs.get(key, []))]


def stream_order(params, m, ticket):
    """−1, 0 or 1: measurement ``m`` is of an older row than ``ticket``, of its row, or
    of a newer one (frames modulo ``2**frame_bits``, then row index)."""
    bits = params.temporal.frame_bits
    gap = (m["frame"] - ticket["frame"]) % (1 << bits)
    if gap == 0:
        return (m["row"] > ticket["row"]) - (m["row"] < ticket["row"])
    return -1 if gap >> (bits - 1) else 1


def _marked(mask, count):
    return [n for n in range(count) if mask >> n & 1]


def _take(queue, ticket, count):
    """Pop ``count`` measurements of a lane queue; raise if the lane has fewer."""
    if len(queue) < count:
        raise ValueError(f"ticket {ticket!r}: a marked lane has fewer than {count} "
                         f"measurements left")
    return [queue.pop(0) for _ in range(count)]


def _ticket_stereo(params, ticket, queues, status):
    """The marked stereo lanes' measurements of the ticket's row (resynchronized)."""
    found = []
    for j in _marked(ticket["pairs"], len(params.pairs)):
        queue, taken = queues[j], 0
        while taken < params.stereo.segments:
            if not queue:
                raise ValueError(f"ticket {ticket!r}: stereo lane {j} ran out of "
                                 f"measurements")
            order = stream_order(params, queue[0], ticket)
            if order > 0:
                status["stereo_missing"] += 1
                break
            m = queue.pop(0)
            if order < 0:
                status["misaligned"] += 1
                continue
            found.append({**m, "camera": params.pairs[j][0], "segment": taken})
            taken += 1
    return found


def _ticket_temporal(params, ticket, queues, status):
    """K measurements of every marked temporal lane, labelled with the lane and
    position; misaligned ones with zero confidence and the ticket's row."""
    out = []
    for camera in _marked(ticket["cameras"], params.cameras):
        for k, m in enumerate(_take(queues[camera], ticket, params.temporal.segments)):
            aligned = stream_order(params, m, ticket) == 0
            status["misaligned"] += not aligned
            out.append({**m, "camera": camera, "segment": k, "row": ticket["row"],
                        "confidence": m["confidence"] if aligned else 0})
    return out


def route_tickets(params, tickets, temporal, stereo):
    """What the hardware router emits for a ticket stream.

    Parameters
    ----------
    params : RouterParams
    tickets : list of dict
        ``cameras`` and ``pairs`` bit masks, ``frame``, ``row`` (the ticket layout).
    temporal, stereo : list of list of dict
        Each temporal lane's and each stereo lane's measurements in stream order.

    Returns
    -------
    transfers : list of dict
        The solver stream (:func:`route_row` of each ticket's measurements).
    status : dict
        ``rows``, ``empty``, ``misaligned``, ``stereo_missing`` (unwrapped counts).

    Raises
    ------
    ValueError
        If a ticket needs measurements a lane does not have (the hardware would wait).
    """
    temporal = [list(q) for q in temporal]
    stereo = [list(q) for q in stereo]
    status = dict.fromkeys(("rows", "empty", "misaligned", "stereo_missing"), 0)
    transfers, store = [], {}
    for ticket in tickets:
        pair_meas = _ticket_stereo(params, ticket, stereo, status)
        row = ticket["row"]
        stored = params.cue_fallback and row < params.temporal.height
        out = route_row(params, _ticket_temporal(params, ticket, temporal, status),
                        pair_meas, store.get(row) if stored else None)
        if stored:
            store[row] = {**store.get(row, {}), **usable_cues(params, pair_meas)}
        if out:
            status["rows"] += 1
            status["empty"] += not any(t["conf"] for t in out)
        transfers += out
    return transfers, status


def pose_rows(params, transfers):
    """The transfers as :class:`emulator.pose_solver.PoseRows` (one row per ``last``),
    for :func:`emulator.pose_solver.pose_solver_model`."""
    rows, current = [], []
    for t in transfers:
        current.append(t)
        if t["last"]:
            rows.append(current)
            current = []
    if current:
        raise ValueError("transfers must end with a last transfer")
    width = params.solver.slots
    fields = {name: np.zeros((len(rows), width), dtype=np.int64)
              for name in ("slot", "shift", "cue", "conf")}
    present = np.zeros((len(rows), width), dtype=bool)
    for r, row in enumerate(rows):
        for k, t in enumerate(row):
            for name in fields:
                fields[name][r, k] = t[name]
            present[r, k] = True
    return PoseRows(**fields, present=present,
                    row=np.array([row[0]["row"] for row in rows], dtype=np.int64),
                    time=np.array([row[0]["time"] for row in rows], dtype=np.int64))

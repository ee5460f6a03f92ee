"""Stimulus for the measurement router: tickets and per-lane measurement streams.

Two sources, both checked against :func:`emulator.measurement.router.route_tickets`:

* :func:`synthetic` builds streams from a seeded RNG: raw fields over their whole
  formats (shift and sub-pixel extremes, negative disparities, zero confidences, edge
  hits), tickets with missing cameras and pairs, misaligned temporal rows, stale
  stereo rows and stereo rows the join lost;
* :func:`lane_streams` runs real simulated rows through the emulator's lane models
  (:mod:`emulator.pipeline`, e.g. on a small cut of the stereo20 rig) and splits the
  measurements per lane, one ticket per row set, some row sets missing a camera.
"""

import dataclasses

from emulator.measurement.router import route_tickets
from golden.descriptor import STEREO_MATCH
from hdl.fixed import SQ, UQ
from hdl.measurement.router_params import RouterParams, StereoWindow
from hdl.pose.params import PoseSolverParams
from hdl.descriptor.params import RowDescriptorParams

__all__ = ["NARROW", "GUARDED", "measurement", "synthetic", "lane_streams", "expected",
           "FIELDS"]

#: Router for the synthetic streams: four cameras, K = 4, K_s = 2, a 3-bit frame
#: counter (wraps within a run), solver formats narrower than the lanes' (SQ(7, 0) +
#: SQ(1, 6) shift, SQ(8, 0) + SQ(1, 6) disparity, UQ(2, 6) confidence) so shift, cue
#: and confidence are rounded and shift and cue saturate.
NARROW = RouterParams(
    cameras=4, pairs=((1, 0), (2, 3)),
    temporal=RowDescriptorParams(width=320, height=8, frame_bits=3),
    stereo=RowDescriptorParams(width=320, height=8, frame_bits=3,
                               match=dataclasses.replace(STEREO_MATCH, segments=2)),
    solver=PoseSolverParams(slots=16, rows=8, shift_fmt=SQ(4, 3), cue_fmt=UQ(5, 4),
                            conf_fmt=UQ(1, 4), time_bits=24))

#: :data:`NARROW` with a stereo window that rejects more than its edges (issue 18):
#: disparities 12 … 68 of [10, 70] give a depth, peak ratios from 1.2.
GUARDED = dataclasses.replace(NARROW, stereo_window=StereoWindow(guard=2, min_ratio=1.2))

#: The lane measurement layout's fields (``hdl.streams.row_measurement_layout``).
FIELDS = ("camera", "frame", "row", "t_first", "segment", "shift", "subpixel",
          "confidence", "textureless", "edge_hit", "bad", "no_reference")


def measurement(camera, segment, frame, row, *, t_first=0, shift=0, subpixel=0,
                confidence=0, edge_hit=0):
    """A lane measurement dict with every field of the stream layout."""
    return {"camera": camera, "frame": frame, "row": row, "t_first": t_first,
            "segment": segment, "shift": shift, "subpixel": subpixel,
            "confidence": confidence, "textureless": 0, "edge_hit": edge_hit, "bad": 0,
            "no_reference": 0}


def _raw(rng, fmt):
    """A raw value of ``fmt``: its extremes, zero, or uniform over its range."""
    pick = rng.random()
    if pick < 0.1:
        return fmt.min_raw
    if pick < 0.2:
        return fmt.max_raw
    if pick < 0.25:
        return 0
    return int(rng.integers(fmt.min_raw, fmt.max_raw + 1))


def _shift(rng, lane, window=None):
    """(shift, subpixel): mostly random raw values, sometimes a sum of exactly zero or
    of the smallest negative step (the disparity rule's boundary), and with a stereo
    ``window`` sometimes an integer disparity on either side of its accepted range's
    ends."""
    pick = rng.random()
    if pick < 0.1:
        return 0, 0
    if pick < 0.2:
        return -1, lane.subpixel_fmt.max_raw
    if window is not None and pick < 0.4:
        low, high = window.accepted
        return int(rng.choice([low - 1, low, high, high + 1])), _raw(rng, lane.subpixel_fmt)
    return _raw(rng, lane.shift_fmt), _raw(rng, lane.subpixel_fmt)


def _confidence(rng, lane, window=None):
    """A raw confidence: 0, random, and with a stereo ``window`` sometimes just below or
    at its least accepted one."""
    pick = rng.random()
    if pick < 0.15:
        return 0
    if window is not None and pick < 0.35:
        least = window.min_confidence_raw(lane.confidence_fmt)
        return int(rng.choice([max(least - 1, 0), least]))
    return _raw(rng, lane.confidence_fmt)


def _row_of(lane, rng, camera, frame, row, segments, window=None):
    """``segments`` random measurements of one row of one lane (shared metadata); a
    stereo lane's with its ``window``'s boundaries."""
    t_first = int(rng.integers(0, 1 << lane.timestamp_bits))
    out = []
    for k in range(segments):
        shift, subpixel = _shift(rng, lane, window)
        out.append(measurement(
            camera, k, frame, row, t_first=t_first, shift=shift, subpixel=subpixel,
            confidence=_confidence(rng, lane, window), edge_hit=int(rng.random() < 0.1)))
    return out


def _step(params, frame, row, back=1):
    """(frame, row) ``back`` row sets earlier (frames modulo ``2**frame_bits``)."""
    index = frame * params.temporal.height + row - back
    frame, row = divmod(index, params.temporal.height)
    return frame % (1 << params.temporal.frame_bits), row


def synthetic(params, rng, tickets):
    """``tickets`` random row sets: ``(tickets, temporal streams, stereo streams)``.

    Frames start near the top of ``frame_bits`` so they wrap. The last ticket is full
    and clean, so a stereo row lost earlier is always followed by a newer one.
    """
    t_lane, s_lane = params.temporal, params.stereo
    temporal = [[] for _ in range(params.cameras)]
    stereo = [[] for _ in params.pairs]
    out = []
    frame, row = (1 << t_lane.frame_bits) - 1, t_lane.height - 3
    everyone = (1 << params.cameras) - 1
    for n in range(tickets):
        clean = n == tickets - 1
        cameras = everyone if clean or rng.random() < 0.7 else \
            int(rng.integers(0, everyone + 1))
        pairs = sum(1 << j for j, (a, b) in enumerate(params.pairs)
                    if cameras >> a & 1 and cameras >> b & 1)
        out.append({"cameras": cameras, "pairs": pairs, "frame": frame, "row": row})
        for c in range(params.cameras):
            if cameras >> c & 1:
                at = (frame, row) if clean or rng.random() > 0.05 else \
                    _step(params, frame, row, int(rng.choice([-9, -1, 1, 9])))
                temporal[c] += _row_of(t_lane, rng, c, *at, t_lane.segments)
        for j, (a, _) in enumerate(params.pairs):
            if not clean and rng.random() < 0.1:               # a stale row in the lane
                back = int(rng.integers(1, 2 * t_lane.height))
                stereo[j] += _row_of(s_lane, rng, a, *_step(params, frame, row, back),
                                     s_lane.segments, params.stereo_window)
            if pairs >> j & 1 and (clean or rng.random() > 0.1):   # else: join lost it
                stereo[j] += _row_of(s_lane, rng, a, frame, row, s_lane.segments,
                                     params.stereo_window)
        frame, row = _step(params, frame, row, -1)
    return out, temporal, stereo


def lane_streams(config, dataset, frames, pairs, rng, drop=0.1):
    """Real lane measurements (:func:`emulator.pipeline.run`) of the cameras of the
    first ``pairs`` stereo pairs, renumbered ``0 …``, as per-lane streams and one
    ticket per row set; with probability ``drop`` a row set loses a random camera
    (its temporal row and its pair's stereo row are not delivered).

    Returns ``(router params, tickets, temporal streams, stereo streams)``.
    """
    from emulator.pipeline import run
    full = config.router
    kept = full.pairs[:pairs]
    cameras = [c for pair in kept for c in pair]
    number = {c: n for n, c in enumerate(cameras)}
    params = dataclasses.replace(
        full, cameras=len(cameras), pairs=tuple((number[a], number[b]) for a, b in kept),
        solver=dataclasses.replace(full.solver, slots=len(cameras) * full.temporal.segments))
    result = run(config, dataset, frames=frames)
    keys = list(dict.fromkeys((m["frame"], m["row"]) for m in result.temporal))
    tickets, lost = [], set()
    for frame, row in keys:
        mask = (1 << params.cameras) - 1
        if rng.random() < drop:
            gone = int(rng.integers(params.cameras))
            mask &= ~(1 << gone)
            lost.add((frame, row, gone))
        pair_mask = sum(1 << j for j, (a, b) in enumerate(params.pairs)
                        if mask >> a & 1 and mask >> b & 1)
        tickets.append({"cameras": mask, "pairs": pair_mask, "frame": frame, "row": row})

    def stream(records, camera):
        return [{**{k: m[k] for k in FIELDS}, "camera": number[camera]} for m in records
                if m["camera"] == camera and (m["frame"], m["row"], number[camera]) not in lost]

    temporal = [stream(result.temporal, c) for c in cameras]
    stereo = []
    for j, (a, b) in enumerate(kept):
        gone = {(f, r) for f, r, n in lost if n in (number[a], number[b])}
        stereo.append([m for m in stream(result.stereo, a) if (m["frame"], m["row"]) not in gone])
    return params, tickets, temporal, stereo


def expected(params, tickets, temporal, stereo):
    """The model's transfers (solver layout field dicts) and status counters, wrapped
    to the hardware's 16 bits."""
    transfers, status = route_tickets(params, tickets, temporal, stereo)
    fields = ("slot", "row", "time", "shift", "cue", "conf", "last")
    return ([{k: int(t[k]) for k in fields} for t in transfers],
            {k: v & 0xFFFF for k, v in status.items()})

"""The golden per-row 6-DoF tracker (float64): rows in, one pose per row slot out.

Per slot (one row period, :mod:`golden.tracker_slots`) every camera's current row is
matched against a reference row (:mod:`golden.reference_rows`) in ``segments`` segments
with the row descriptor and Hamming matcher of :mod:`golden.descriptor`; each segment
gives one linear equation in the rig's motion (:mod:`golden.tracker_geometry`,
:mod:`golden.pose_lsq`), with depth from :mod:`golden.depth` or
:mod:`golden.depth_maps`.

What is estimated. The unknown of a slot at time t is ``Y = [T θ]``, the rig's motion
over one frame period, from the estimated pose at ``t − 1/fps`` (the same row slot of
the previous frame) to the pose at ``t``. Every reference is built from the previous
frame with the estimated poses of its rows, so a measurement constrains exactly this
motion: errors chain from frame to frame, not from row to row. The equations are
linearised about the forecast ``Ŷ`` of a Holt–Winters filter on Y
(:mod:`golden.temporal_filter`): ``s − g(Ŷ) = A δ``, with ``g`` the exact predicted shift
of each segment (full projection with the lens) and ``A`` the segment-averaged design
rows, which depend only on calibration, pixel position and depth (the hardware's
precomputed coefficients).

Per-measurement confidence is the matcher's peak ratio times the Huber consistency
weight of its innovation against the channel's robust scale (capped: a persistent bias
stays an outlier), times a weight for its sensitivity to depth error; an outlier is
replaced by the forecast, and a camera group (stereo pair) that persistently disagrees
with the others is dropped (:mod:`golden.tracker_robust`). A segment whose reference is
flat (a blank frame) gives no measurement. A slot steps if a measurement has confidence ≥ ``min_confidence``,
``min_cameras`` cameras contribute and the weighted system is well conditioned
(``max_condition``). A step moves the motion filter towards ``Ŷ + δ`` and the slot's
pose — carried on from the previous slot at the current rate — towards the pose the
measurement gives, both with gains weighted by how much the slot's system tells
(:func:`golden.temporal_filter.information_gain`). A slot beyond ``max_condition`` steps
in the directions it determines (``boundary="partial"``, the frame boundary's few cameras).

Never a silent failure: every slot gets a status (:mod:`golden.tracking_status`:
tracking, degraded, lost) from the recent update fraction, the share of outlier
innovations, the condition and the confident measurements. On a loss the tracker carries
on at the last motion measured while tracking and re-acquires with a widened window and
reweighted solves about each slot's own solution (:mod:`golden.tracker_solve`); poses
after a loss are flagged drifted. See ``docs/tracker.md``.
"""

from dataclasses import asdict
from types import SimpleNamespace

import numpy as np

from .descriptor import describe, match, segment_bounds, strength, textureless
from .depth import StereoDepth, stereo_pairs
from .pose_lsq import body_step
from .reference_rows import HomographyReference, PreviousFrameReference, Reference
from .temporal_filter import DelayedForecast, HoltWinters, information_gain
from .tracker_geometry import DesignTable, reference_pixels, segment_means
from .tracker_motion import PoseTrack, compose, ground_truth_track
from .tracker_params import (BOUNDARIES, DEPTHS, MOTION_GAINS, REFERENCES, SOLVERS,
                             TrackerParams, TrackResult)
from .tracker_slots import RowSlots
from .tracker_solve import SlotSolver
from .tracking_status import StatusMonitor, TrackingStatus

__all__ = ["REFERENCES", "DEPTHS", "SOLVERS", "MOTION_GAINS", "BOUNDARIES", "TrackerParams",
           "TrackResult", "Tracker", "track"]

#: Gauss–Newton iterations and finite-difference probe (m or rad) of the nonlinear
#: refinement.
REFINE_ITERATIONS = 4
REFINE_PROBE = 1e-6

#: Columns beyond the descriptor kernel on each side of a segment's predicted reference
#: columns that must hold scene content (the parabola's neighbours); reference pixels
#: further out only raise the costs of far shifts.
REFERENCE_MARGIN = 2


def _row_means(values):
    """Mean of each row's finite values (0 for a row without any)."""
    finite = np.isfinite(values)
    count = finite.sum(axis=-1)
    return np.where(finite, values, 0.0).sum(axis=-1) / np.maximum(count, 1)


class Tracker:
    """Runs the golden tracker over a dataset (see the module docstring).

    Parameters
    ----------
    dataset : golden.dataset.Dataset
    params : TrackerParams
    """

    def __init__(self, dataset, params):
        self.rig, self.recordings = dataset.rig, dataset.cameras
        self.params = params
        self.slots = RowSlots(dataset)
        self.desc, self.matcher = params.descriptor, params.matcher
        self.track = PoseTrack(len(self.slots))
        self._cache = {}
        self.columns = np.arange(0, self.rig.cameras[0].width, params.geometry_stride)
        self.design_tables = [DesignTable(cam, self.columns) for cam in self.rig.cameras]
        self._init_from_ground_truth(dataset)
        self.depth, self.depth_source = self._depth_source(dataset)
        if params.reference == "homography":
            self.reference = HomographyReference(self.rig, self.recordings, self.track,
                                                 self.desc, params.reselect_angle)
        else:
            self.reference = PreviousFrameReference(self.rig, self.recordings, self.track,
                                                    self.frame_bits)
        self.solver = SlotSolver(self.rig, params, self.depth_source == "oracle")
        window = round(params.status_window * self.slots.period / self.slots.t_r)
        self.status = StatusMonitor(max(window, 1), params)
        self.recovering = self.drifted = self.reacquired = False
        self.good_motion = self.motion.level.copy()

    # --- set-up ----------------------------------------------------------------------

    def _init_from_ground_truth(self, dataset):
        """Poses of the initialisation slots from the ground truth (the papers' known
        first frame), and the motion filter started from the motion they show."""
        gt = ground_truth_track(dataset)
        slots = self.slots
        first = slots.first_tracked
        init = np.flatnonzero(slots.occupied[:first])
        rotations, positions = gt.at(slots.times[init])
        for s, rotation, position in zip(init, rotations, positions):
            self.track.append(slots.times[s], rotation, position)
        span = slots.times[init[-1]] - slots.times[init[0]]
        motion = body_step(rotations[0], positions[0], rotations[-1], positions[-1])
        motion *= slots.period / span
        self.motion = HoltWinters(motion, alpha=self.params.alpha, beta=self.params.beta)
        self.forecasts = DelayedForecast(self.motion, self.params.loop_delay_rows)
        self.track.set_extrapolation(motion / slots.period)

    def _depth_source(self, dataset):
        kind = self.params.depth
        if kind == "auto":
            kind = "stereo" if stereo_pairs(self.rig) else "overlap"
        if kind == "stereo":
            return StereoDepth(self.rig, self.desc, blocks=self.params.disparity_blocks), kind
        if kind == "oracle":
            from .depth_maps import OracleDepth
            return OracleDepth(dataset), kind
        from .depth_maps import OverlapDepth
        return OverlapDepth(self.rig, self.recordings, self.track, self.predict), kind

    def predict(self, times):
        """Rig poses (R, p) the tracker predicts for rows at ``times``: the estimate one
        frame earlier composed with the motion forecast."""
        return compose(*self.track.at(times - self.slots.period), self.motion.forecast())

    def _cached(self, kind, n, frame, compute):
        """Per-frame values of camera ``n``, kept for this frame and the previous one."""
        key = (kind, n, frame)
        if key not in self._cache:
            for old in [k for k in self._cache if k[:2] == (kind, n) and k[2] < frame - 1]:
                del self._cache[old]
            self._cache[key] = compute()
        return self._cache[key]

    def frame_bits(self, n, frame):
        """Descriptor bits (H, W) of frame ``frame`` of camera ``n``."""
        return self._cached("bits", n, frame,
                            lambda: describe(self.recordings[n].rows[frame], self.desc))

    def frame_strong(self, n, frame):
        """Strong columns (H, W) of frame ``frame`` of camera ``n`` (the matcher's test
        for flat, noise-only segments)."""
        return self._cached("strong", n, frame,
                            lambda: strength(self.recordings[n].rows[frame], self.desc))

    def _inverse_depth(self, n, frame, rows):
        """1/Z (B, W) of camera n's rows (NaN: unknown)."""
        if not isinstance(self.depth, StereoDepth):
            return self.depth.inverse_depth(n, frame, rows)
        if not self.depth.has_depth(n):
            return np.full((len(rows), self.rig.cameras[n].width), np.nan)
        pair = self.depth.pair_of[n]
        left, right, _ = self.depth.pairs[pair]
        # a whole frame at once: the same values per row, far fewer matcher calls
        maps = self._cached("depth", pair, frame, lambda: self.depth.inverse_depth(
            pair, self.frame_bits(left, frame), self.frame_bits(right, frame),
            self.frame_strong(left, frame) if self.params.strong_test else None))
        return maps[0 if n == left else 1][rows]

    # --- measurements of a block -----------------------------------------------------

    def _reference(self, n, frame, rows, rotations, positions, inverse_depth):
        """The reference rows of a block, where the current pixels' points sit in them
        (x, (B, C)) and each row's window centre."""
        cam = self.rig.cameras[n]
        rays, depth = cam.rays[rows][:, self.columns], inverse_depth[:, self.columns]
        if isinstance(self.reference, HomographyReference):
            ref = self.reference.rows(n, frame, rows, rotations, positions, self.columns,
                                      inverse_depth if self.params.parallax else None)
        else:
            ref = self.reference.rows(n, frame, rows)
        x, y = reference_pixels(cam, rays, depth, rotations, positions, ref.view_rotation,
                                ref.source_centre)
        if isinstance(self.reference, HomographyReference) or not self.params.follow_rows:
            return ref, x, self._centres(x)
        if self.params.follow_segments:
            # the centre and the rows' addresses come from one prediction, as in hardware
            centres = self._centres(x)
            ref = self._segment_rows(n, frame, rows, y - rows[:, None], centres)
        else:
            offset = _row_means(y - rows[:, None])
            source = np.clip(rows + np.rint(offset).astype(int), 0, cam.height - 1)
            ref = self.reference.rows(n, frame, source)
        x, _ = reference_pixels(cam, rays, depth, rotations, positions, ref.view_rotation,
                                ref.source_centre)
        return ref, x, (centres if self.params.follow_segments else self._centres(x))

    def _centres(self, x):
        """Window centre of each row (B,): the mean predicted shift, rounded, within a
        quarter of the row."""
        limit = self.rig.cameras[0].width // 4
        return np.clip(np.rint(_row_means(self.columns - x)), -limit, limit).astype(int)

    def _segment_rows(self, n, frame, rows, displacement, centres):
        """A reference row per current row put together from K stored rows (``follow_
        segments``): segment k's row is the current row plus the mean of ``displacement``
        (B, C) over its columns, and reference column j comes from the row of the segment
        that current column ``j + centre`` belongs to (each segment's window, at its
        centre shift, reads its own row); the view rotation and source centre are per
        current pixel, from its own segment's row."""
        cam, stride = self.rig.cameras[n], self.params.geometry_stride
        matcher = self.params.recovery_matcher if self.recovering else self.matcher
        bounds = np.array([segment_bounds(cam.width, self.desc, matcher, int(c))
                           for c in centres])                             # (B, K, 2)
        offsets, _ = segment_means(displacement, np.isfinite(displacement),
                                   -(-bounds[..., 0] // stride), -(-bounds[..., 1] // stride))
        offsets = np.where(np.isfinite(offsets), offsets, _row_means(displacement)[:, None])
        source = np.clip(rows[:, None] + np.rint(offsets).astype(int), 0, cam.height - 1)
        parts = [self.reference.rows(n, frame, source[:, k]) for k in range(source.shape[1])]

        def segment_of(columns):            # (B, L): the segment of current columns
            columns = np.broadcast_to(columns, (len(rows), np.shape(columns)[-1]))
            return (columns[:, None, :] >= bounds[:, 1:, 0, None]).sum(axis=1)

        by_column = segment_of(np.arange(cam.width) + centres[:, None])
        by_pixel = segment_of(self.columns)
        pick = np.arange(len(rows))[:, None]
        bits = np.stack([part.bits for part in parts])[by_column, pick, np.arange(cam.width)]
        rotation = np.stack([part.view_rotation for part in parts])[by_pixel, pick]
        centre = np.stack([part.source_centre[:, 0] for part in parts])[by_pixel, pick]
        return Reference(bits=bits, valid=np.ones(bits.shape, dtype=bool),
                         view_rotation=rotation, source_centre=centre)

    def _entry(self, n, frame, rows, slot_ids, forecasts):
        """Predict, build the reference and prepare one camera's rows of a block."""
        cam, rec = self.rig.cameras[n], self.recordings[n]
        times = rec.time[frame, rows]
        prev_rot, prev_pos = self.track.at(times - self.slots.period)
        rotations, positions = compose(prev_rot, prev_pos, forecasts)
        full_depth = self._inverse_depth(n, frame, rows)
        inverse_depth = full_depth[:, self.columns]
        ref, vx, centres = self._reference(n, frame, rows, rotations, positions, full_depth)
        predicted = self.columns - vx
        strong = self.frame_strong(n, frame)[rows] if self.params.strong_test else None
        return SimpleNamespace(camera=n, frame=frame, rows=rows, slots=slot_ids,
                               inverse_depth=inverse_depth, ref=ref, predicted=predicted,
                               centres=centres, bits=self.frame_bits(n, frame)[rows],
                               strong=strong)

    def _measure(self, entries):
        """Match the block's rows (grouped by window centre across cameras) and form each
        entry's segment equations (arrays (B, K, ...))."""
        p, width = self.params, self.rig.cameras[0].width
        matcher = p.recovery_matcher if self.recovering else self.matcher
        centres = np.concatenate([e.centres for e in entries])
        owner = np.concatenate([np.full(len(e.rows), j) for j, e in enumerate(entries)])
        local = np.concatenate([np.arange(len(e.rows)) for e in entries])
        cur = np.concatenate([e.bits for e in entries])
        strong = np.concatenate([e.strong for e in entries]) if self.params.strong_test \
            else None
        ref = np.concatenate([e.ref.bits for e in entries])
        for e in entries:
            b = len(e.rows)
            e.shift, e.peak_ratio = np.full((b, p.segments), np.nan), np.zeros((b, p.segments))
            e.lo, e.hi = np.zeros((b, p.segments), int), np.zeros((b, p.segments), int)
        for centre in np.unique(centres):
            sel = np.flatnonzero(centres == centre)
            result = match(cur[sel], ref[sel], self.desc, matcher, centre=int(centre),
                           cur_strong=None if strong is None else strong[sel])
            bounds = np.array(segment_bounds(width, self.desc, matcher, int(centre)))
            # a flat reference (a blank or lost frame) matches anything: no measurement
            flat_ref = textureless(np.roll(ref[sel], int(centre), axis=1), self.desc, matcher,
                                   int(centre))
            good = ~result.textureless & ~result.edge_hit & ~flat_ref
            for j in np.unique(owner[sel]):
                mine = owner[sel] == j
                e, rows = entries[j], local[sel][mine]
                e.shift[rows] = np.where(good[mine], result.shift[mine], np.nan)
                e.peak_ratio[rows] = np.where(good[mine], result.peak_ratio[mine], 0.0)
                e.lo[rows], e.hi[rows] = bounds[:, 0], bounds[:, 1]
        for e in entries:
            self._equations(e)

    def _equations(self, e):
        """Segment-averaged design rows and predicted shifts of an entry; segments with too
        little depth or an unusable reference get no measurement."""
        p, cam = self.params, self.rig.cameras[e.camera]
        usable = np.isfinite(e.inverse_depth) & np.isfinite(e.predicted)
        table = self.design_tables[e.camera]
        design = table.rows(e.rows, e.inverse_depth)
        stride = p.geometry_stride
        lo, hi = -(-e.lo // stride), -(-e.hi // stride)     # strided columns in [lo, hi)
        e.design, share = segment_means(design, usable, lo, hi)
        unit = table.rows(e.rows, np.ones_like(e.inverse_depth))[..., :3]
        e.unit_translation, _ = segment_means(unit, usable, lo, hi)   # d shift / d(1/Z)
        e.expected, _ = segment_means(e.predicted, usable, lo, hi)
        margin = self.desc.radius + REFERENCE_MARGIN
        invalid = np.cumsum(np.concatenate([np.zeros((len(e.rows), 1)), ~e.ref.valid],
                                           axis=1), axis=1)
        offset = e.centres[:, None]
        first = np.clip(e.lo - offset - margin, 0, cam.width)
        last = np.clip(e.hi - offset + margin, 0, cam.width)
        clean = (np.take_along_axis(invalid, last, 1) == np.take_along_axis(invalid, first, 1))
        ok = clean & (share >= p.min_depth_fraction)
        e.usable = ok                   # could measure, matched or not
        e.shift = np.where(ok, e.shift, np.nan)
        e.peak_ratio = np.where(ok, e.peak_ratio, 0.0)
        columns = self.columns
        e.masks = usable[:, None, :] & (columns >= e.lo[..., None]) & (columns < e.hi[..., None])

    # --- the slot loop ---------------------------------------------------------------

    def run(self, progress=False):
        slots, p = self.slots, self.params
        n_cams = len(self.rig.cameras)
        size = len(slots)
        out = {
            "updated": np.zeros(size, dtype=bool), "condition": np.full(size, np.nan),
            "equations": np.zeros(size, dtype=int),
            "camera_confidence": np.full((size, n_cams), np.nan),
            "motion": np.full((size, 6), np.nan), "forecast": np.full((size, 6), np.nan),
            "measured": np.full((size, 6), np.nan), "linear_step": np.full((size, 6), np.nan),
            "refined_step": np.full((size, 6), np.nan),
            "status": np.zeros(size, dtype=np.uint8), "drifted": np.zeros(size, dtype=bool),
            "judged": np.zeros(size, dtype=int), "outliers": np.zeros(size, dtype=int),
            "dropped_group": np.full(size, -1), "partial": np.zeros(size, dtype=bool),
            "determinable": np.zeros(size, dtype=bool)}
        starts = range(slots.first_tracked, size, p.block_rows)
        if progress:
            from tqdm import tqdm
            starts = tqdm(starts, unit="block", desc=f"track {self.rig.name}")
        for first in starts:
            self._run_block(first, min(first + p.block_rows, size), out)
        occupied = np.flatnonzero(slots.occupied)
        n = self.track.count
        return TrackResult(
            times=self.track.times[:n].copy(), rotations=self.track.rotations[:n].copy(),
            positions=self.track.positions[:n].copy(),
            tracked=occupied >= slots.first_tracked,
            **{key: value[occupied] for key, value in out.items()},
            period=slots.period,
            params={**asdict(p), "depth_source": self.depth_source})

    def _run_block(self, first, stop, out):
        slots, k = self.slots, self.params.segments
        occupied = np.flatnonzero(slots.occupied[first:stop]) + first
        # one Holt–Winters step per occupied slot (a blanking interval is not extrapolated);
        # a slot within the loop delay of the block's start gets an older forecast
        block_forecasts = {s: self.forecasts.forecast(s, k + 1, latest=first - 1)
                           for k, s in enumerate(occupied)}
        entries = []
        for n in range(len(self.rig.cameras)):
            frames, rows, slot_ids = slots.members(n, first, stop)
            for frame in np.unique(frames[frames >= 1]):
                part = frames == frame
                forecasts = np.array([block_forecasts[s] for s in slot_ids[part]])
                entries.append(self._entry(n, int(frame), rows[part], slot_ids[part],
                                           forecasts))
        if entries:
            self._measure(entries)
        table = SimpleNamespace(
            slot=np.concatenate([np.repeat(e.slots, k) for e in entries] or [[]]).astype(int),
            camera=np.concatenate([np.full(e.shift.size, e.camera) for e in entries] or [[]]
                                  ).astype(int),
            channel=np.concatenate([np.tile(e.camera * k + np.arange(k), len(e.rows))
                                    for e in entries] or [[]]).astype(int),
            design=np.concatenate([e.design.reshape(-1, 6) for e in entries] or [np.zeros((0, 6))]),
            innovation=np.concatenate([(e.shift - e.expected).ravel() for e in entries] or [[]]),
            ratio=np.concatenate([e.peak_ratio.ravel() for e in entries] or [[]]),
            unit=np.concatenate([e.unit_translation.reshape(-1, 3) for e in entries]
                                or [np.zeros((0, 3))]),
            usable=np.concatenate([e.usable.ravel() for e in entries] or [[]]).astype(bool),
            source=[(e, i) for e in entries for i in range(len(e.rows))])
        self.solver.set_geometry(table.design)
        order = np.argsort(table.slot, kind="stable")
        bounds = np.searchsorted(table.slot[order], np.append(occupied, stop))
        previous = self.track.at(slots.times[occupied] - slots.period)
        for j, s in enumerate(occupied):
            mine = order[bounds[j]:bounds[j + 1]]
            self._step(s, block_forecasts[s], table, mine, (previous[0][j], previous[1][j]),
                       out)

    def _step(self, s, linearised_at, table, mine, previous, out):
        """Robust weighted solve of slot ``s`` from the block's measurements ``mine``
        (:class:`golden.tracker_solve.SlotSolver`), the slot's status, then the motion
        filter and the pose."""
        p = self.params
        forecast = self.forecasts.forecast(s)       # what the loop knows when s starts
        design = table.design[mine]
        solved = self.solver.solve(
            table.innovation[mine] - design @ (forecast - linearised_at), design,
            table.ratio[mine], table.camera[mine], table.channel[mine], table.unit[mine],
            forecast[:3], self.recovering, table.usable[mine])
        if solved.step is not None and not solved.partial and p.solver == "nonlinear":
            parts = [table.source[m // p.segments] for m in mine[::p.segments]]
            out["linear_step"][s] = solved.step
            solved.step = self._refine(parts, forecast, solved.step, solved.confidence,
                                       solved.outlier)
            out["refined_step"][s] = solved.step
        step, normal, typical = solved.step, solved.normal, self.solver.typical
        status = self.status.update(step is not None, solved.judged, solved.outliers,
                                    solved.condition, solved.used, solved.determinable)
        gain = None
        if step is not None and p.motion_gain == "information" and typical is not None:
            gain = information_gain(normal, typical, p.alpha)
        current = self.motion.forecast()            # the filter's own state is up to date
        measured = None if step is None else forecast + step
        if status == TrackingStatus.LOST and not self.recovering:
            # lost: carry on at the last motion measured while tracking (the poses of the
            # frames to come keep their rows consistent) and re-acquire with a widened
            # search, the filter's recent values and trend forgotten
            self.recovering = self.drifted = True
            self.reacquired = False
            measured, level = None, self.forecasts.reset(s, self.good_motion)
        elif self.recovering and measured is not None and not self.reacquired:
            level = self.forecasts.reset(s, measured)          # the first motion found
            self.reacquired = True
        else:
            level = self.forecasts.update(s, measured, gain)
        if self.recovering and status != TrackingStatus.LOST:
            self.recovering = False
        if status == TrackingStatus.TRACKING:
            self.good_motion = level
        # the pose carried on from the latest one at the current rate (Y is the motion
        # over the last frame, i.e. the rate half a frame ago: the trend brings it up to
        # date) ...
        last = self.track.count - 1
        dt = self.slots.times[s] - self.track.times[last]
        half_frame = 0.5 * self.slots.period / self.slots.t_r
        rate = (current + half_frame * self.motion.trend) / self.slots.period
        rotation, position = compose(self.track.rotations[last], self.track.positions[last],
                                     rate * dt)
        if measured is not None:  # ... pulled towards the measured one, weighted by information
            target = compose(*previous, measured)
            pull = p.pose_alpha * np.eye(6) if typical is None else \
                information_gain(normal, typical, p.pose_alpha)
            rotation, position = compose(rotation, position,
                                         pull @ body_step(rotation, position, *target))
        self.track.append(self.slots.times[s], rotation, position)
        self.track.set_extrapolation(level / self.slots.period)
        out["updated"][s], out["condition"][s] = measured is not None, solved.condition
        out["equations"][s], out["motion"][s] = solved.used, level
        out["forecast"][s] = forecast
        out["status"][s], out["drifted"][s] = status, self.drifted
        out["judged"][s], out["outliers"][s] = solved.judged, solved.outliers
        out["partial"][s], out["dropped_group"][s] = solved.partial, solved.dropped
        out["determinable"][s] = solved.determinable
        out["camera_confidence"][s] = solved.camera_confidence
        if measured is not None:
            out["measured"][s] = measured

    def _exact_shifts(self, parts, motions):
        """Segment shifts (M, equations) predicted by the full projection model for one-
        frame motions ``motions`` (M, 6): the nonlinear counterpart of the design rows."""
        shifts = []
        for e, i in parts:
            cam = self.rig.cameras[e.camera]
            time = self.recordings[e.camera].time[e.frame, e.rows[i]] - self.slots.period
            rotation, position = compose(*self.track.at(time), motions)
            rays = np.broadcast_to(cam.rays[e.rows[i]][self.columns],
                                   (len(motions), len(self.columns), 3))
            view = e.ref.view_rotation[i]
            view = view[None] if view.ndim == 3 else view       # per pixel: over motions
            vx, _ = reference_pixels(cam, rays, e.inverse_depth[i], rotation, position,
                                     view, e.ref.source_centre[i])
            masks = e.masks[i]
            shifts.append(np.where(masks, self.columns - vx[:, None, :], 0.0).sum(axis=-1)
                          / np.maximum(masks.sum(axis=-1), 1))
        return np.concatenate(shifts, axis=-1)

    def _refine(self, parts, forecast, step, confidence, outlier):
        """Weighted nonlinear least squares on the exact model (Gauss–Newton with a
        finite-difference Jacobian) from the linear step; outliers keep standing for the
        forecast as in the linear solve."""
        measured = np.concatenate([e.shift[i] for e, i in parts])
        measured = np.where(outlier, self._exact_shifts(parts, forecast[None])[0], measured)
        use = confidence > 0
        weight = confidence[use]
        probe = np.vstack([np.zeros(6), REFINE_PROBE * np.eye(6)])
        for _ in range(REFINE_ITERATIONS):
            predicted = self._exact_shifts(parts, forecast + step + probe)[:, use]
            jacobian = ((predicted[1:] - predicted[0]) / REFINE_PROBE).T
            residual = measured[use] - predicted[0]
            weighted = jacobian * weight[:, None]
            change = np.linalg.solve(weighted.T @ jacobian, weighted.T @ residual)
            step = step + change
            if np.abs(change).max() < 1e-9:
                break
        return step


def track(dataset, params=None, *, progress=False):
    """Run the golden tracker on ``dataset``; returns a :class:`TrackResult`."""
    return Tracker(dataset, params or TrackerParams()).run(progress)

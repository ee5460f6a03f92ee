"""Per-camera depth for rigs without stereo pairs (CVPR 2018 §3.3), and the oracle.

:class:`OverlapDepth` keeps one inverse-depth map per camera, bootstrapped by a plane
sweep against the cameras that overlap it and carried from frame to frame (the papers'
depth source for the radial rigs; see its docstring for what is and is not the paper).

:class:`OracleDepth` is the simulator's true depth (ray cast into the dataset's scene at
the true row poses). It exists for ablations only — it tells how much of the tracker's
error comes from depth — and every result made with it is labelled ``oracle``.
"""

import cv2
import numpy as np

from .descriptor import cost_peaks
from .scene import scene_from_config
from .tracker_geometry import camera_poses, project, rotate

__all__ = ["OracleDepth", "scene_depth", "overlap_neighbours", "OverlapDepth"]


def scene_depth(spec, origins, directions):
    """Ray parameter of the first surface hit in the scene ``spec`` (room + boxes).

    ``origins`` (..., 3) and ``directions`` (..., 3) in world metres; with directions
    whose camera z component is 1 the result is the camera depth Z.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / directions
        lo, hi = (spec.room_lo - origins) * inverse, (spec.room_hi - origins) * inverse
        hit = np.min(np.where(directions > 0, hi, lo), axis=-1)          # leave the room
        for box in spec.boxes:
            a = (np.array(box.lo) - origins) * inverse
            b = (np.array(box.hi) - origins) * inverse
            near = np.max(np.fmin(a, b), axis=-1)
            far = np.min(np.fmax(a, b), axis=-1)
            enters = (near <= far) & (near > 0) & (near < hit)
            hit = np.where(enters, near, hit)
    return hit


class OracleDepth:
    """True inverse depth of camera rows, from the dataset's scene and ground truth.

    Parameters
    ----------
    dataset : golden.dataset.Dataset
    """

    def __init__(self, dataset):
        self.spec = scene_from_config(dataset.info["scene"], "dataset scene")
        self.rig, self.recordings = dataset.rig, dataset.cameras

    def inverse_depth(self, n, frame, rows):
        """1/Z (B, W) of rows ``rows`` of frame ``frame`` of camera ``n`` at their true
        poses."""
        cam, rec = self.rig.cameras[n], self.recordings[n]
        rotation, centre = camera_poses(cam, rec.rotation[frame, rows], rec.position[frame, rows])
        return 1.0 / scene_depth(self.spec, centre[:, None, :], rotate(rotation, cam.rays[rows]))


def _rolling_terms(rotations, centres, start, points):
    """Camera coordinates ``L0`` and their change per row ``L1`` (..., W, 3) of world
    vectors (..., W, 3) relative to the pose of row ``start`` (...) of a rolling-shutter
    frame (poses ``rotations``, ``centres`` per row; pass a zero centre slope for
    directions by giving ``centres=None``)."""
    to_cam = np.swapaxes(rotations[start], -1, -2)
    slope_to_cam = np.swapaxes(np.gradient(rotations, axis=0)[start], -1, -2)
    if centres is None:
        return rotate(to_cam, points), rotate(slope_to_cam, points)
    relative = points - centres[start][..., None, :]
    shift = (to_cam @ np.gradient(centres, axis=0)[start][..., None])[..., None, :, 0]
    return rotate(to_cam, relative), rotate(slope_to_cam, relative) - shift


def _solve_rows(camera, base, change, start):
    """Pixel positions (x, y) and depths of points with camera coordinates
    ``base + (y − start) change`` seen in row y (two fixed-point iterations: within a
    frame the pose is linear in the row to well below a pixel); NaN where not seen."""
    first = start[..., None].astype(float)
    row = np.broadcast_to(first, base.shape[:-1])
    for _ in range(2):
        local = base + (row - first)[..., None] * change
        x, y = project(camera, local)
        row = np.clip(np.nan_to_num(y, nan=-1.0), 0, camera.height - 1)
    inside = (x >= 0) & (x <= camera.width - 1) & (y >= 0) & (y <= camera.height - 1)
    return np.where(inside, x, np.nan), np.where(inside, y, np.nan), local[..., 2]


def overlap_neighbours(rig, depth=2.0, minimum=0.15, count=2):
    """For each camera, the (up to ``count``) other cameras that see the largest share
    (at least ``minimum``) of its image, and the mask (H, W) of its pixels that one of
    them sees, for points ``depth`` metres away."""
    neighbours, reach = [], []
    for cam in rig.cameras:
        points = (depth * cam.rays) @ cam.R.T + cam.c              # rig frame
        seen_by = []
        for m, other in enumerate(rig.cameras):
            if other is not cam:
                x, y = project(other, (points - other.c) @ other.R)
                seen = (x >= 0) & (x <= other.width - 1) & (y >= 0) & (y <= other.height - 1)
                seen_by.append((seen.mean(), m, seen))
        seen_by.sort(key=lambda item: -item[0])
        chosen = [(m, seen) for share, m, seen in seen_by[:count] if share >= minimum]
        neighbours.append([m for m, _ in chosen])
        reach.append(np.any([seen for _, seen in chosen], axis=0) if chosen
                     else np.zeros(points.shape[:2], dtype=bool))
    return neighbours, reach


class OverlapDepth:
    """Per-camera inverse-depth maps bootstrapped from overlapping cameras and carried from
    frame to frame (CVPR 2018 §3.3).

    * Bootstrap (first frame, poses given): a plane sweep over ``candidates`` inverse
      depths against the overlapping neighbours' same frame (rolling-shutter aware:
      every row at its own pose); cost = mean absolute difference over a
      ``patch``×``patch`` window, averaged over the neighbours that see the pixel;
      winner-take-all, parabola refinement, and a ratio test (second-best cost at least
      ``min_ratio`` × the best, two candidates away) against ambiguous matches.
    * Each new frame: the previous frame's map is first completed where it has holes that
      a neighbour can see and that the last sweep did not already give up on, by the same
      sweep on those tiles (the previous frame's images at the estimated poses); then it
      is carried into the new frame: every pixel's point is projected with the predicted
      row poses and splatted with a z-buffer (nearest point wins), and one-pixel cracks
      are closed from their neighbours. Regions that appear in the new frame thus get
      their depth one frame later; pixels no neighbour sees never get one.

    Parameters
    ----------
    rig : golden.rig.Rig
    recordings : list of golden.dataset.CameraRecording
    track : golden.tracker_motion.PoseTrack
        Poses of past rows (estimated, or given for the first frame).
    predict : callable
        ``predict(times)`` -> rig rotations and positions the tracker predicts for rows
        not estimated yet (the map of a new frame is carried to these poses, so that it
        is consistent with the poses the measurements are linearised about).
    near, far : float
        Depth range of the sweep (m).
    candidates : int
        Inverse depths tried, evenly spaced in 1/Z.
    patch : int
        Side of the matching window (pixels).
    min_ratio : float
        Second-best to best cost ratio below which a pixel stays unknown.
    tile : int
        Side of the tiles in which holes are swept.
    """

    def __init__(self, rig, recordings, track, predict, *, near=0.4, far=10.0,
                 candidates=48, patch=7, min_ratio=1.05, tile=64):
        self.rig, self.recordings, self.track, self.predict = rig, recordings, track, predict
        self.neighbours, self.reach = overlap_neighbours(rig)
        self.candidates = np.linspace(1.0 / far, 1.0 / near, candidates)
        self.patch, self.min_ratio, self.tile = patch, min_ratio, tile
        self._maps = {}
        self.swept_pixels = 0

    def inverse_depth(self, n, frame, rows):
        """1/Z (B, W) of rows ``rows`` of frame ``frame`` of camera ``n`` (NaN: unknown)."""
        state = self._maps.get(n)
        if state is None or state["frame"] != frame:
            state = self._carry(n, frame)
            self._maps[n] = state
        return state["map"][rows]

    def _poses(self, n, frame, predicted=False):
        cam, times = self.rig.cameras[n], self.recordings[n].time[frame]
        return camera_poses(cam, *(self.predict(times) if predicted else self.track.at(times)))

    def _carry(self, n, frame):
        """The map of frame ``frame`` from the previous frame's map, completed first."""
        cam = self.rig.cameras[n]
        state = self._maps.get(n)
        if state is not None and state["frame"] == frame - 1:
            previous, given_up = state["map"].copy(), state["given_up"]
            todo = np.isnan(previous) & self.reach[n] & ~given_up
        else:
            previous = np.full((cam.height, cam.width), np.nan)
            todo = self.reach[n].copy()
        given_up = np.zeros_like(todo)
        t = self.tile
        for y0 in range(0, cam.height, t):
            for x0 in range(0, cam.width, t):
                part = todo[y0:y0 + t, x0:x0 + t]
                if part.sum() >= t:               # skip tiles with a few stray holes
                    region = (y0, min(y0 + t, cam.height), x0, min(x0 + t, cam.width))
                    value = self.sweep(n, frame - 1, region)
                    fill = part & np.isnan(previous[y0:y0 + t, x0:x0 + t])
                    previous[y0:y0 + t, x0:x0 + t][fill] = value[fill]
                    given_up[y0:y0 + t, x0:x0 + t] = fill & np.isnan(value)
        return {"frame": frame, "map": self.propagate(n, frame - 1, previous, frame),
                "given_up": given_up}

    def sweep(self, n, frame, region):
        """Inverse depth of the pixels ``region = (y0, y1, x0, x1)`` of frame ``frame`` of
        camera ``n`` from its neighbours' same frame (NaN: unknown)."""
        cam = self.rig.cameras[n]
        r = self.patch // 2
        inner = region
        y0, y1 = max(region[0] - r, 0), min(region[1] + r, cam.height)
        x0, x1 = max(region[2] - r, 0), min(region[3] + r, cam.width)
        self.swept_pixels += (inner[1] - inner[0]) * (inner[3] - inner[2])
        rotation, centre = self._poses(n, frame)
        own = self.recordings[n].rows[frame, y0:y1, x0:x1].astype(np.float32)
        rows = np.arange(y0, y1)
        directions = rotate(rotation[rows], cam.rays[y0:y1, x0:x1])
        origins = centre[rows][:, None, :]
        total = np.zeros((len(self.candidates),) + own.shape, np.float32)
        weight = np.zeros_like(total)
        for m in self.neighbours[n]:
            other = self.rig.cameras[m]
            image = self.recordings[m].rows[frame].astype(np.float32)
            m_rotation, m_centre = self._poses(m, frame)
            # a candidate's point is origin + direction / w: its terms are linear in 1/w
            from_origin = _rolling_terms(m_rotation, m_centre, rows,
                                         np.broadcast_to(origins, directions.shape))
            along = _rolling_terms(m_rotation, None, rows, directions)
            for d, w in enumerate(self.candidates):
                x, y, _ = _solve_rows(other, from_origin[0] + along[0] / w,
                                      from_origin[1] + along[1] / w, rows)
                seen = np.isfinite(x)
                sample = cv2.remap(image, np.nan_to_num(x, nan=-1).astype(np.float32),
                                   np.nan_to_num(y, nan=-1).astype(np.float32),
                                   cv2.INTER_LINEAR)
                diff = np.where(seen, np.abs(sample - own), 0).astype(np.float32)
                total[d] += cv2.boxFilter(diff, -1, (self.patch, self.patch), normalize=False)
                weight[d] += cv2.boxFilter(seen.astype(np.float32), -1,
                                           (self.patch, self.patch), normalize=False)
        enough = weight >= self.patch * self.patch / 2
        cost = np.moveaxis(np.where(enough, total / np.maximum(weight, 1), np.inf), 0, -1)
        best, c0, c2, cm, cp, edge = cost_peaks(cost)
        with np.errstate(divide="ignore", invalid="ignore"):
            denom = cm - 2 * c0 + cp
            delta = np.where(~edge & (denom > 0), (cm - cp) / (2 * denom), 0.0)
        step = self.candidates[1] - self.candidates[0]
        value = self.candidates[best] + np.clip(delta, -0.5, 0.5) * step
        good = np.isfinite(cm + c0 + cp) & ~edge & (c2 >= self.min_ratio * c0)
        out = np.where(good, value, np.nan)
        return out[inner[0] - y0:inner[1] - y0, inner[2] - x0:inner[3] - x0]

    def propagate(self, n, frame, inverse_depth, target):
        """Carry a map of frame ``frame`` (at the track's poses) into frame ``target`` (at
        the predicted poses): z-buffer splat, then one-pixel cracks closed."""
        cam = self.rig.cameras[n]
        rotation, centre = self._poses(n, frame)
        ys, xs = np.nonzero(np.isfinite(inverse_depth))
        w = inverse_depth[ys, xs]
        points = centre[ys] + rotate(rotation[ys], cam.rays[ys, xs][:, None, :])[:, 0] / w[:, None]
        t_rotation, t_centre = self._poses(n, target, predicted=True)
        terms = _rolling_terms(t_rotation, t_centre, ys, points[:, None])
        x, y, z = (v[:, 0] for v in _solve_rows(cam, *terms, ys))
        seen = np.isfinite(x) & (z > 0)
        out = np.zeros((cam.height, cam.width))
        np.maximum.at(out, (np.rint(y[seen]).astype(int), np.rint(x[seen]).astype(int)),
                      1.0 / z[seen])
        known = (out > 0).astype(np.float32)
        neighbours = cv2.boxFilter(known, -1, (3, 3), normalize=False) - known
        nearest = cv2.dilate(out.astype(np.float32), np.ones((3, 3), np.uint8))
        out = np.where((out == 0) & (neighbours >= 3), nearest, out)
        return np.where(out > 0, out, np.nan)

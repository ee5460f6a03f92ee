"""Reference rows that a current row is matched against.

(a) :class:`HomographyReference` — the papers' rotation compensation (TVCG 2016 §3.4,
CVPR 2018 §3.2.2). The previous frame's rows, each at its own estimated rotation
``R_q``, are warped by the rotation-only homography (undistort, rotate, distort) into a
global-shutter frame ``F_GS`` at a reference rotation ``R_ref``; ``F_GS`` is rebuilt
when a new previous frame is needed or when the rotation since ``R_ref`` exceeds the
re-selection angle (≈0.06 rad). A current row is then read out of ``F_GS`` along the
directions it has at its *predicted* rotation, so that rotation — the dominant image
motion, horizontal and vertical — is compensated and the matcher sees mainly the
translation's shift. (The papers compare with ``F_GS`` at ``R_ref`` directly; reading
at the predicted rotation also removes the vertical displacement a rotation since
``R_ref`` would cause, which decorrelates the row's content.)

(b) :class:`PreviousFrameReference` — the hardware-friendly variant: the previous
frame's stored descriptor row, no image warping. The matcher's window is centred on
the shift predicted from the current motion estimate. The tracker picks which stored row
to read (the same row index, or the row the content is predicted to come from).

Both return a :class:`Reference`: descriptor bits, which reference pixels are usable,
and the pose the reference pixels were seen with (``R_view``, per-pixel source centres)
for :func:`golden.tracker_geometry.reference_pixels`.
"""

from typing import NamedTuple

import cv2
import numpy as np

from .descriptor import describe
from .rotations import rotation_angle
from .tracker_geometry import camera_poses, project, rotate

__all__ = ["Reference", "HomographyReference", "PreviousFrameReference", "fill_row_gaps"]

#: Fixed-point iterations that find, for a pixel of F_GS, the previous-frame row it is
#: read from (each row has its own rotation).
SOURCE_ROW_ITERATIONS = 3

#: Iterations that find the previous-frame row (hence camera centre) a parallax-
#: compensated reference pixel is read from: the centre moves ~0.02 mm per row, so the
#: second pass is already exact to far below a hundredth of a pixel.
PARALLAX_ITERATIONS = 2

#: Largest spacing (pixels) of the grid on which F_GS's source map is solved.
GRID_STEP = 4


class Reference(NamedTuple):
    bits: np.ndarray            # (B, W) descriptor bits
    valid: np.ndarray           # (B, W) reference pixel holds scene content
    view_rotation: np.ndarray   # (B, 3, 3) rig rotation the row is seen with
    source_centre: np.ndarray   # (B, C, 3) or (B, 1, 3) camera centre (world) per pixel


def fill_row_gaps(values):
    """``values`` (B, W) with each NaN replaced by the nearest finite value of its row
    (the left one on a tie); rows without any finite value stay NaN."""
    values = np.asarray(values, dtype=float)
    columns = np.arange(values.shape[-1])
    finite = np.isfinite(values)
    left = np.maximum.accumulate(np.where(finite, columns, -1), axis=-1)
    right = np.minimum.accumulate(np.where(finite, columns, values.shape[-1])[..., ::-1],
                                  axis=-1)[..., ::-1]
    use_right = (left < 0) | ((right < values.shape[-1]) & (right - columns < columns - left))
    source = np.where(use_right, right, left)
    picked = np.take_along_axis(values, np.clip(source, 0, values.shape[-1] - 1), axis=-1)
    return np.where(finite.any(axis=-1, keepdims=True), picked, np.nan)


def _interpolate_columns(values, grid, width):
    """Rows of values (B, len(grid)) at columns ``grid`` (increasing, 0 and width − 1
    included), linearly interpolated to all ``width`` columns."""
    full = np.arange(width)
    k = np.clip(np.searchsorted(grid, full, side="right") - 1, 0, len(grid) - 2)
    frac = (full - grid[k]) / (grid[k + 1] - grid[k])
    return values[:, k] * (1 - frac) + values[:, k + 1] * frac


def _sample(image, x, y):
    """Bilinear samples of a float32 image at positions (B, W); 0 outside."""
    return cv2.remap(image, x.astype(np.float32), y.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


class HomographyReference:
    """Reference (a): rows read from a rotation-compensated copy of the previous frame.

    Parameters
    ----------
    rig : golden.rig.Rig
    recordings : list of golden.dataset.CameraRecording
        Rows (read) and row times of every camera.
    track : golden.tracker_motion.PoseTrack
        The tracker's estimate (the previous frame's row rotations and centres).
    desc : golden.descriptor.DescriptorParams
    reselect_angle : float
        Rotation (rad) since ``R_ref`` beyond which ``F_GS`` is rebuilt.
    """

    def __init__(self, rig, recordings, track, desc, reselect_angle):
        self.rig, self.recordings, self.track, self.desc = rig, recordings, track, desc
        self.reselect_angle = reselect_angle
        self._frames = {}
        self.rebuilds = 0

    def _build(self, n, frame, reference_rotation):
        """F_GS of camera n from its frame ``frame`` at rig rotation ``reference_rotation``.

        The source position of every F_GS pixel is solved on a grid of at most
        :data:`GRID_STEP` pixels and interpolated bilinearly (the map is smooth: below
        0.01 px from the exact one for the papers' lenses).
        """
        cam, rec = self.rig.cameras[n], self.recordings[n]
        rot_q, pos_q = self.track.at(rec.time[frame])                   # (H, 3, 3)
        warp = np.einsum("ji,hkj,kl,lm->him", cam.R, rot_q, reference_rotation, cam.R)
        slope = np.gradient(warp, axis=0)                               # per source row
        grid_x = np.linspace(0, cam.width - 1, (cam.width - 2) // GRID_STEP + 2)
        grid_y = np.linspace(0, cam.height - 1, (cam.height - 2) // GRID_STEP + 2)
        xu, yu = cam.pixel_to_normalized(*np.meshgrid(grid_x, grid_y))
        rays = np.stack([xu, yu, np.ones_like(xu)], axis=-1)
        rows = np.arange(cam.height)
        at_rows = [np.stack([np.interp(grid_y, rows, m[:, i, j]) for i in range(3)
                             for j in range(3)], -1).reshape(-1, 3, 3) for m in (warp, slope)]
        base, change = rotate(at_rows[0], rays), rotate(at_rows[1], rays)
        own_row = grid_y[:, None]
        source_row = np.broadcast_to(own_row, rays.shape[:2])
        for _ in range(SOURCE_ROW_ITERATIONS):
            x, source_row = project(cam, base + (source_row - own_row)[..., None] * change)
        full_x, full_y = np.meshgrid(np.arange(cam.width, dtype=float),
                                     np.arange(cam.height, dtype=float))
        to_grid_x = full_x * ((len(grid_x) - 1) / (cam.width - 1))
        to_grid_y = full_y * ((len(grid_y) - 1) / (cam.height - 1))
        x = _sample(np.nan_to_num(x, nan=-1e4).astype(np.float32), to_grid_x, to_grid_y)
        y = _sample(np.nan_to_num(source_row, nan=-1e4).astype(np.float32), to_grid_x,
                    to_grid_y)
        inside = (x >= 0) & (x <= cam.width - 1) & (y >= 0) & (y <= cam.height - 1)
        x, y = np.where(inside, x, -1.0), np.where(inside, y, -1.0)
        self._frames[n] = {
            "frame": frame, "rotation": reference_rotation,
            "image": _sample(rec.rows[frame].astype(np.float32), x, y),
            "valid": inside.astype(np.float32), "source_row": y.astype(np.float32),
            "centres": camera_poses(cam, rot_q, pos_q)[1]}
        self.rebuilds += 1

    def rows(self, n, frame, rows, rotations, positions, columns, inverse_depth=None):
        """The reference for rows ``rows`` (B,) of frame ``frame`` of camera ``n`` at the
        predicted rig poses ``rotations`` (B, 3, 3), ``positions`` (B, 3).

        Without ``inverse_depth`` the row is read along its pixels' directions at the
        predicted rotation (rotation-only compensation; source centres at ``columns``).
        With ``inverse_depth`` (B, W) the parallax is compensated too: each pixel is read
        along the direction from its source row's camera centre to the point it sees at
        the predicted pose, so the reference shows the current row as predicted. A pixel
        without depth takes the depth of the nearest pixel of its row that has one
        (:func:`fill_row_gaps`), never "infinitely far" (which would show it shifted by
        the whole frame's parallax); a row without any depth is read along its
        directions and marked not valid.
        """
        state = self._frames.get(n)
        if state is None or state["frame"] != frame - 1 or np.any(
                rotation_angle(state["rotation"].T @ rotations) > self.reselect_angle):
            self._build(n, frame - 1, rotations[0])
            state = self._frames[n]
        cam = self.rig.cameras[n]
        to_canvas = cam.R.T @ state["rotation"].T
        grid = np.unique(np.append(columns[::2], cam.width - 1))   # smooth map: solve on a
        rays = cam.rays[rows][:, grid]                             # grid, linear in between
        if inverse_depth is None:
            directions, centres = rotate(rotations, rays @ cam.R.T), None
        else:
            filled = fill_row_gaps(inverse_depth[:, grid])
            depthless = np.isnan(filled[:, 0])
            w = np.nan_to_num(filled)[..., None]
            point = rotate(rotations, rays @ cam.R.T + w * cam.c) + w * positions[:, None, :]
            centres = self._centres(state, np.broadcast_to(rows[:, None], w.shape[:2]))
            for _ in range(PARALLAX_ITERATIONS):
                directions = point - w * centres
                x, y = project(cam, directions @ to_canvas.T)
                centres = self._centres(state, _sample(state["source_row"], *(
                    np.nan_to_num(v, nan=-1e4) for v in (x, y))))
        x, y = project(cam, directions @ to_canvas.T)
        x, y = (_interpolate_columns(np.nan_to_num(v, nan=-1e4), grid, cam.width)
                for v in (x, y))
        bits = describe(_sample(state["image"], x, y), self.desc)
        valid = _sample(state["valid"], x, y) > 0.999
        if inverse_depth is not None:     # the reference now shows the predicted row
            valid &= ~depthless[:, None]
            return Reference(bits=bits, valid=valid, view_rotation=rotations,
                             source_centre=camera_poses(cam, rotations, positions)[1][:, None])
        source_row = _sample(state["source_row"], x[:, columns], y[:, columns])
        return Reference(bits=bits, valid=valid, view_rotation=rotations,
                         source_centre=self._centres(state, source_row))

    @staticmethod
    def _centres(state, source_row):
        """Camera centres (..., 3) of (fractional) previous-frame rows (linear between
        rows, clamped to the frame)."""
        table = state["centres"]
        row = np.clip(source_row, 0, len(table) - 1)
        k = np.minimum(row.astype(int), len(table) - 2)
        frac = (row - k)[..., None]
        return table[k] * (1 - frac) + table[k + 1] * frac


class PreviousFrameReference:
    """Reference (b): the previous frame's stored descriptor rows, as read.

    Parameters
    ----------
    rig : golden.rig.Rig
    recordings : list of golden.dataset.CameraRecording
    track : golden.tracker_motion.PoseTrack
    frame_bits : callable
        ``frame_bits(n, frame)`` -> (H, W) descriptor bits of a whole frame.
    """

    def __init__(self, rig, recordings, track, frame_bits):
        self.rig, self.recordings, self.track = rig, recordings, track
        self.frame_bits = frame_bits

    def rows(self, n, frame, source_rows):
        """The stored rows ``source_rows`` (B,) of frame ``frame − 1`` of camera ``n``."""
        cam, rec = self.rig.cameras[n], self.recordings[n]
        rotation, position = self.track.at(rec.time[frame - 1, source_rows])
        bits = self.frame_bits(n, frame - 1)[source_rows]
        return Reference(bits=bits, valid=np.ones(bits.shape, dtype=bool),
                         view_rotation=rotation,
                         source_centre=camera_poses(cam, rotation, position)[1][:, None, :])

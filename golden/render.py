"""Ray casting of image rows, each row at its own pose.

For every pixel the camera-frame ray (lens undistortion included, precomputed once per
camera) is turned into the world by that row's rotation and cast from that row's camera
centre: the room is left through the nearest of three slab planes, boxes are entered by
the slab test. The hit point's face and position give atlas coordinates; the pixel's
footprint on the surface picks the mip levels; ``cv2.remap`` does the bilinear lookups.
Rows are processed in chunks (cache-sized float32 arrays), and boxes that cannot appear
in a chunk (a cone test on the chunk's rays and pose spread) are skipped.

Nothing here depends on how rows are grouped: a row rendered alone, inside a rolling-
shutter frame or inside a global-shutter frame at the same pose gives the same values.
"""

import math

import cv2
import numpy as np

from .rotations import rotation_angle

__all__ = ["Renderer"]

#: Rows per chunk: float32 temporaries of 64×640 stay in the L2 cache.
CHUNK_ROWS = 64

#: OpenCV's remap takes maps of at most 32766 columns.
_REMAP_COLS = 4096


def _remap(image, x, y):
    """Bilinear samples of ``image`` at float32 positions ``x``, ``y`` (1-D)."""
    n = x.size
    cols = min(n, _REMAP_COLS)
    rows = -(-n // cols)
    if rows * cols != n:
        x = np.concatenate([x, np.zeros(rows * cols - n, np.float32)])
        y = np.concatenate([y, np.zeros(rows * cols - n, np.float32)])
    out = cv2.remap(image, x.reshape(rows, cols), y.reshape(rows, cols), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    return out.ravel()[:n]


def sample_trilinear(pyramid, x, y, level):
    """Texture values at level-0 atlas positions ``x``, ``y`` blended between the mip
    levels around ``level`` (all float32, 1-D).

    Pixels are bucketed by ``ceil(level)`` (one radix sort), so each bucket is one pair
    of remaps: bucket 0 reads level 0 only, bucket l blends levels l−1 and l.
    """
    top = len(pyramid) - 1
    level = np.clip(level, 0, top)
    bucket = np.ceil(level).astype(np.int8)
    order = np.argsort(bucket, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(np.bincount(bucket, minlength=top + 1))])
    xs, ys, ls = x[order], y[order], level[order]
    values = np.empty_like(xs)
    for l in range(top + 1):
        part = slice(bounds[l], bounds[l + 1])
        if part.start == part.stop:
            continue
        scale = np.float32(0.5**l)
        coarse = _remap(pyramid[l], xs[part] * scale, ys[part] * scale)
        if l == 0:
            values[part] = coarse
            continue
        fine = _remap(pyramid[l - 1], xs[part] * (2 * scale), ys[part] * (2 * scale))
        values[part] = fine + (ls[part] - np.float32(l - 1)) * (coarse - fine)
    out = np.empty_like(values)
    out[order] = values
    return out


class Renderer:
    """Renders rows of one camera in one scene.

    Parameters
    ----------
    scene : golden.scene.Scene
    camera : golden.camera.Camera
    """

    def __init__(self, scene, camera):
        self.scene, self.camera = scene, camera
        rays = camera.rays
        self._ray = [np.ascontiguousarray(rays[..., k], dtype=np.float32) for k in range(3)]
        self._pitch = (camera.pixel_pitch * scene.scale).astype(np.float32)
        unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        axis = unit.mean(axis=1)
        self._row_axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        self._row_spread = np.arccos(np.clip(
            np.einsum("hwk,hk->hw", unit, self._row_axis), -1, 1)).max(axis=1)

    def render(self, rotations, origins, rows=None):
        """Radiance (gray levels, float32) of ``rows`` seen from per-row poses.

        Parameters
        ----------
        rotations : (n, 3, 3)
            Camera-to-world rotation for each rendered row.
        origins : (n, 3)
            Camera centre in the world for each rendered row.
        rows : int array (n,), optional
            Image rows to render (default: all rows, n = height).

        Returns
        -------
        float32 (n, width)
        """
        rotations = np.asarray(rotations, dtype=float)
        origins = np.asarray(origins, dtype=float)
        rows = np.arange(self.camera.height) if rows is None else np.asarray(rows)
        if rotations.shape != (len(rows), 3, 3) or origins.shape != (len(rows), 3):
            raise ValueError(f"rotations and origins must have shapes ({len(rows)}, 3, 3) and "
                             f"({len(rows)}, 3), not {rotations.shape} and {origins.shape}")
        out = np.empty((len(rows), self.camera.width), np.float32)
        for start in range(0, len(rows), CHUNK_ROWS):
            part = slice(start, start + CHUNK_ROWS)
            out[part] = self._render_chunk(rotations[part], origins[part], rows[part])
        return out

    def _visible_boxes(self, rotations, origins, rows):
        """Indices of boxes that a ray of these rows could hit.

        Conservative cone test: the cone holds every ray of the rows at the middle pose,
        widened by the rows' rotation spread; the boxes' bounding spheres are widened by
        the spread of the camera centres.
        """
        scene = self.scene
        if not len(scene.box_lo):
            return np.array([], dtype=int)
        mid = len(rotations) // 2
        centre = origins.mean(axis=0)
        reach = np.linalg.norm(origins - centre, axis=1).max()
        turn = rotation_angle(rotations[mid].T @ rotations).max()
        row_axes = self._row_axis[rows]
        cam_axis = row_axes.sum(axis=0)
        cam_axis /= np.linalg.norm(cam_axis)
        spread = (np.arccos(np.clip(row_axes @ cam_axis, -1, 1))
                  + self._row_spread[rows]).max() + turn
        to_box = scene.box_centre - centre
        dist = np.linalg.norm(to_box, axis=1)
        radius = scene.box_radius + reach
        cos_angle = np.clip(to_box @ (rotations[mid] @ cam_axis) / np.maximum(dist, 1e-12), -1, 1)
        margin = np.arcsin(np.clip(radius / np.maximum(dist, 1e-12), 0, 1))
        visible = (dist <= radius) | (np.arccos(cos_angle) - margin <= spread)
        return np.flatnonzero(visible)

    def _render_chunk(self, rotations, origins, rows):
        scene = self.scene
        if len(rows) and rows[-1] - rows[0] == len(rows) - 1 and np.all(np.diff(rows) == 1):
            rows = slice(int(rows[0]), int(rows[-1]) + 1)  # views instead of copies
        ray = [r[rows] for r in self._ray]
        # World directions: d_k = Σ_j R[k, j] ray_j, one rotation per row.
        d = [sum(rotations[:, k, j, None].astype(np.float32) * ray[j] for j in range(3))
             for k in range(3)]
        positive = [dk > 0 for dk in d]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = [np.float32(1) / dk for dk in d]
            t, face = None, None
            for a in range(3):  # leave the room through the nearest wall
                lo = (scene.room_lo[a] - origins[:, a, None]).astype(np.float32)
                hi = (scene.room_hi[a] - origins[:, a, None]).astype(np.float32)
                t_a = np.where(positive[a], hi, lo) * inv[a]
                face_a = np.where(positive[a], np.int16(3 + a), np.int16(a))
                if t is None:
                    t, face = t_a, face_a
                else:
                    closer = t_a < t
                    np.copyto(t, t_a, where=closer)
                    np.copyto(face, face_a, where=closer)
            for b in self._visible_boxes(rotations, origins, rows):
                self._enter_box(b, origins, positive, inv, t, face)
        axis = face % 3
        on_x, on_z = axis == 0, axis == 2
        point = [origins[:, k, None].astype(np.float32) + t * d[k] for k in range(3)]
        u = np.where(on_x, point[1], point[0])
        v = np.where(on_z, point[1], point[2])
        scale = np.float32(scene.scale)
        x = u * scale + scene.face_x[face]
        y = scene.face_y[face] - v * scale
        normal = np.abs(np.where(on_x, d[0], np.where(on_z, d[2], d[1])))
        level = np.log2(t * self._pitch[rows] / normal)
        shape = x.shape
        return sample_trilinear(scene.atlas.pyramid, x.ravel(), y.ravel(),
                                level.ravel()).reshape(shape)

    def _enter_box(self, b, origins, positive, inv, t, face):
        """Where rays enter box ``b`` before ``t``, update ``t`` and ``face`` in place."""
        scene = self.scene
        near, t_near, t_far = [], None, None
        for a in range(3):
            lo = (scene.box_lo[b, a] - origins[:, a, None]).astype(np.float32) * inv[a]
            hi = (scene.box_hi[b, a] - origins[:, a, None]).astype(np.float32) * inv[a]
            near.append(np.fmin(lo, hi))
            far = np.fmax(lo, hi)
            t_near = near[a] if t_near is None else np.fmax(t_near, near[a])
            t_far = far if t_far is None else np.fmin(t_far, far)
        hit = np.flatnonzero((t_near <= t_far) & (t_near > 0) & (t_near < t))
        if not hit.size:
            return
        entry_axis = np.argmax(np.stack([n.ravel()[hit] for n in near]), axis=0)
        # Entering along +axis crosses the low side (surface 2 + 2b), else the high side.
        entering_low = np.choose(entry_axis, [p.ravel()[hit] for p in positive])
        surface = 2 + 2 * b + (~entering_low).astype(np.int16)
        t.ravel()[hit] = t_near.ravel()[hit]
        face.ravel()[hit] = 3 * surface + entry_axis

"""Ray casting of image rows, each row at its own pose.

For every pixel the camera-frame ray (lens undistortion included, precomputed once per
camera) is turned into the world by that row's rotation and cast from that row's camera
centre: the room is left through the nearest of three slab planes, boxes are entered by
the slab test. The hit point's face and position give atlas coordinates; the pixel's
footprint on the surface picks the mip levels; ``cv2.remap`` does the bilinear lookups.
Rows are processed in chunks (cache-sized float32 arrays), and boxes that cannot appear
in a chunk (cone and elevation tests on the chunk's rays and pose spread) are skipped.

Nothing here depends on how rows are grouped: a row rendered alone, inside a rolling-
shutter frame or inside a global-shutter frame at the same pose gives the same values.
"""

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

    Pixels are bucketed by ``ceil(level)``: bucket 0 reads level 0 only, bucket l blends
    levels l−1 and l, one pair of remaps per bucket.
    """
    top = len(pyramid) - 1
    level = np.clip(level, 0, top)
    bucket = np.ceil(level).astype(np.int8)
    counts = np.bincount(bucket, minlength=top + 1)
    out = np.empty_like(x)
    for l in np.flatnonzero(counts):
        idx = np.flatnonzero(bucket == l) if counts[l] < len(x) else slice(None)
        scale = np.float32(0.5**l)
        xs, ys = x[idx], y[idx]
        coarse = _remap(pyramid[l], xs * scale, ys * scale)
        if l == 0:
            out[idx] = coarse
            continue
        fine = _remap(pyramid[l - 1], xs * (2 * scale), ys * (2 * scale))
        out[idx] = fine + (level[idx] - np.float32(l - 1)) * (coarse - fine)
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
        self._bounds = [b.astype(np.float32) for b in (scene.room_lo, scene.room_hi,
                                                       scene.box_lo, scene.box_hi)]
        unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        axis = unit.mean(axis=1)
        self._row_axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        self._row_spread = np.arccos(np.clip(
            np.einsum("hwk,hk->hw", unit, self._row_axis), -1, 1)).max(axis=1)
        elevation = np.arcsin(unit[..., 1])  # angle above/below the camera's x–z plane
        self._row_elevation = np.stack([elevation.min(axis=1), elevation.max(axis=1)], axis=1)

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
        count = self.camera.height if rows is None else len(rows)
        if rotations.shape != (count, 3, 3) or origins.shape != (count, 3):
            raise ValueError(f"rotations and origins must have shapes ({count}, 3, 3) and "
                             f"({count}, 3), not {rotations.shape} and {origins.shape}")
        out = np.empty((count, self.camera.width), np.float32)
        for start in range(0, count, CHUNK_ROWS):
            part = slice(start, min(start + CHUNK_ROWS, count))
            # Whole-image chunks index the camera tables with slices (views, not copies).
            chunk_rows = part if rows is None else np.asarray(rows)[part]
            out[part] = self._render_chunk(rotations[part], origins[part], chunk_rows)
        return out

    def _visible_boxes(self, rotations, origins, rows):
        """Indices of boxes that a ray of these rows could hit.

        Conservative tests at the middle pose, widened by the rows' rotation spread, on
        the boxes' bounding spheres widened by the spread of the camera centres: the
        sphere must meet the cone that holds the rows' rays, and its elevation range (in
        the camera frame) must meet the rows' — a chunk of rows is a thin horizontal band,
        which the cone alone would not see.
        """
        scene = self.scene
        if not len(scene.box_lo):
            return ()
        mid = len(rotations) // 2
        centre = origins.mean(axis=0)
        reach = np.sqrt(np.max(np.sum(np.square(origins - centre), axis=1)))
        turn = np.max(rotation_angle(rotations[mid].T @ rotations))
        row_axes = self._row_axis[rows]
        cam_axis = row_axes.sum(axis=0)
        cam_axis /= np.sqrt(cam_axis @ cam_axis)
        spread = np.max(np.arccos(np.clip(row_axes @ cam_axis, -1, 1))
                        + self._row_spread[rows]) + turn
        to_box = scene.box_centre - centre
        dist = np.maximum(np.sqrt(np.sum(np.square(to_box), axis=1)), 1e-12)
        radius = scene.box_radius + reach
        angle = np.arccos(np.clip(to_box @ (rotations[mid] @ cam_axis) / dist, -1, 1))
        margin = np.arcsin(np.clip(radius / dist, 0, 1))
        elevation = np.arcsin(np.clip(to_box @ rotations[mid][:, 1] / dist, -1, 1))
        band = self._row_elevation[rows]
        in_band = ((elevation + margin + turn >= band[:, 0].min())
                   & (elevation - margin - turn <= band[:, 1].max()))
        return np.flatnonzero((dist <= radius) | ((angle - margin <= spread) & in_band))

    def _render_chunk(self, rotations, origins, rows):
        scene = self.scene
        room_lo, room_hi, _, _ = self._bounds
        ray = [r[rows] for r in self._ray]
        rot = rotations.astype(np.float32)
        # World directions: d_k = Σ_j R[k, j] ray_j, one rotation per row.
        d = []
        for k in range(3):
            dk = rot[:, k, 0, None] * ray[0]
            dk += rot[:, k, 1, None] * ray[1]
            dk += rot[:, k, 2, None] * ray[2]
            d.append(dk)
        o = origins.astype(np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = [np.float32(1) / dk for dk in d]
            # Leave the room: per axis the exit is the positive one of the two slab
            # distances (the centre is inside); the nearest axis wins.
            t_axis = [np.fmax((room_lo[a] - o[:, a, None]) * inv[a],
                              (room_hi[a] - o[:, a, None]) * inv[a]) for a in range(3)]
            to_y = t_axis[1] < t_axis[0]
            t = np.minimum(t_axis[0], t_axis[1])
            to_z = t_axis[2] < t
            np.minimum(t, t_axis[2], out=t)
            axis = (to_y & ~to_z).view(np.int8) + 2 * to_z.view(np.int8)
            positive = [dk > 0 for dk in d]
            high = (positive[0] & (axis == 0)) | (positive[1] & to_y & ~to_z) | (positive[2] & to_z)
            face = (axis + 3 * high.view(np.int8)).astype(np.int16)  # surface 1: high side
            for b in self._visible_boxes(rotations, origins, rows):
                self._enter_box(b, o, positive, inv, t, face, axis)
        on_x, on_z = axis == 0, axis == 2
        point = [o[:, k, None] + t * d[k] for k in range(3)]
        u = point[0] + on_x * (point[1] - point[0])
        v = point[2] + on_z * (point[1] - point[2])
        face = face.astype(np.intp)
        scale = np.float32(scene.scale)
        x = u * scale + scene.face_x[face]
        y = scene.face_y[face] - v * scale
        normal = np.abs(d[1] + on_x * (d[0] - d[1]) + on_z * (d[2] - d[1]))
        level = np.log2(t * self._pitch[rows] / normal)
        return sample_trilinear(scene.atlas.pyramid, x.ravel(), y.ravel(),
                                level.ravel()).reshape(x.shape)

    def _enter_box(self, b, o, positive, inv, t, face, axis):
        """Where rays enter box ``b`` before ``t``, update ``t``, ``face`` and ``axis``."""
        _, _, box_lo, box_hi = self._bounds
        near, t_near, t_far = [], None, None
        for a in range(3):
            lo = (box_lo[b, a] - o[:, a, None]) * inv[a]
            hi = (box_hi[b, a] - o[:, a, None]) * inv[a]
            near.append(np.fmin(lo, hi))
            far = np.fmax(lo, hi)
            t_near = near[a] if t_near is None else np.fmax(t_near, near[a])
            t_far = far if t_far is None else np.fmin(t_far, far)
        hit = np.flatnonzero((t_near <= t_far) & (t_near > 0) & (t_near < t))
        if not hit.size:
            return
        entry_axis = np.argmax(np.stack([n.ravel()[hit] for n in near]), axis=0).astype(np.int8)
        # Entering along +axis crosses the low side (surface 2 + 2b), else the high side.
        entering_low = np.stack([p.ravel()[hit] for p in positive])[entry_axis, np.arange(hit.size)]
        surface = 2 + 2 * b + (~entering_low).view(np.int8)
        t.ravel()[hit] = t_near.ravel()[hit]
        axis.ravel()[hit] = entry_axis
        face.ravel()[hit] = 3 * surface + entry_axis

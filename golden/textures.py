"""Surface textures: procedural generation, user images, and a mip-mapped atlas.

All faces share one texel size, so a face maps to the atlas by an offset only. Each face
is a tile padded on every side with a continuation of its texture and sized to a
multiple of 2^levels, and each tile gets its own Gaussian pyramid (``cv2.pyrDown``), so
no level ever blends two faces. Level l of the atlas is sampled at ``x_0 / 2^l``
(pyrDown keeps the even samples). The renderer blends the two levels around each
pixel's footprint (trilinear mip-mapping): surfaces from 0.5 m to 10 m stay free of
aliasing, which a row matcher would otherwise see as spurious shifts.
"""

import cv2
import numpy as np

__all__ = ["procedural_texture", "image_texture", "TextureAtlas"]

#: Widest atlas row in texels (OpenCV's remap needs both sides < 32767).
ATLAS_WIDTH = 8192


def procedural_texture(rng, shape, texel):
    """A gray texture with detail at every scale from 0.8 m down to 2 texels.

    Band-limited value noise in octaves (amplitude growing with scale) under randomly
    placed rectangles and ellipses (2–40 cm) with sharp, slightly softened edges, so rows
    have both fine texture and strong edges at any distance. float32 in [8, 247].
    """
    h, w = shape
    noise = np.zeros(shape, np.float32)
    cell = 0.8 / texel
    while cell >= 2.0:
        grid = rng.standard_normal((int(h / cell) + 3, int(w / cell) + 3)).astype(np.float32)
        size = (int(grid.shape[1] * cell), int(grid.shape[0] * cell))
        up = cv2.resize(grid, size, interpolation=cv2.INTER_CUBIC)
        oy, ox = rng.integers(0, int(cell) + 1, 2)
        noise += float(cell) ** 0.35 * up[oy:oy + h, ox:ox + w]
        cell /= 2
    noise *= 28.0 / max(float(noise.std()), 1e-6)
    paint = np.zeros(shape, np.float32)
    alpha = np.zeros(shape, np.float32)
    area = h * w * texel * texel
    for _ in range(int(rng.poisson(14 * area)) + 2):
        size = np.exp(rng.uniform(np.log(0.02), np.log(0.4), 2)) / texel
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        value = float(rng.uniform(-90, 90))
        if rng.random() < 0.5:
            p0 = (int(cx - size[0] / 2), int(cy - size[1] / 2))
            p1 = (int(cx + size[0] / 2), int(cy + size[1] / 2))
            cv2.rectangle(paint, p0, p1, value, -1)
            cv2.rectangle(alpha, p0, p1, 1.0, -1)
        else:
            axes = (max(1, int(size[0] / 2)), max(1, int(size[1] / 2)))
            angle = float(rng.uniform(0, 180))
            cv2.ellipse(paint, (int(cx), int(cy)), axes, angle, 0, 360, value, -1)
            cv2.ellipse(alpha, (int(cx), int(cy)), axes, angle, 0, 360, 1.0, -1)
    image = 128.0 + noise * (1 - 0.6 * alpha) + paint
    image = cv2.GaussianBlur(image, (0, 0), 0.6)
    return np.clip(image, 8, 247).astype(np.float32)


def image_texture(path, shape):
    """A user image (any format OpenCV reads) as a gray texture stretched to ``shape``."""
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ValueError(f"texture {str(path)!r} cannot be read as an image")
    h, w = shape
    interpolation = cv2.INTER_AREA if image.shape[0] * image.shape[1] > h * w else cv2.INTER_CUBIC
    return np.clip(cv2.resize(image.astype(np.float32), (w, h), interpolation=interpolation),
                   0, 255)


class TextureAtlas:
    """Padded tiles packed into one image per mip level.

    Parameters
    ----------
    tiles : list of float32 arrays
        One per face, each already padded by ``pad`` texels and with both sides a
        multiple of ``2**levels``.
    levels : int
        Mip levels above the base (level 0).
    pad : int
        Padding of each tile (texels at level 0).

    Members
    -------
    pyramid : list of float32 arrays
        The atlas at levels 0..levels.
    offsets : int array (faces, 2)
        (x, y) of each tile's inner corner (after the padding) at level 0.
    """

    def __init__(self, tiles, levels, pad):
        step = 2 ** levels
        for k, tile in enumerate(tiles):
            if tile.shape[0] % step or tile.shape[1] % step:
                raise ValueError(f"tile {k} shape {tile.shape} is not a multiple of {step}")
        width = max([ATLAS_WIDTH] + [t.shape[1] for t in tiles])
        corners, x, y, row_height = [None] * len(tiles), 0, 0, 0
        for k in sorted(range(len(tiles)), key=lambda k: -tiles[k].shape[0]):
            h, w = tiles[k].shape
            if x + w > width:
                x, y, row_height = 0, y + row_height, 0
            corners[k] = (x, y)
            x, row_height = x + w, max(row_height, h)
        height = y + row_height
        if height >= 32767 or width >= 32767:
            raise ValueError(f"the scene needs a {width}×{height} texel atlas (limit 32766); "
                             f"use a larger texel")
        self.levels, self.pad = levels, pad
        self.offsets = np.array(corners, dtype=np.int64) + pad
        self.pyramid = [np.zeros((height // 2**l, width // 2**l), np.float32)
                        for l in range(levels + 1)]
        for (cx, cy), tile in zip(corners, tiles):
            for l in range(levels + 1):
                th, tw = tile.shape
                self.pyramid[l][cy // 2**l:cy // 2**l + th, cx // 2**l:cx // 2**l + tw] = tile
                if l < levels:
                    tile = cv2.pyrDown(tile, dstsize=(tw // 2, th // 2))

    @property
    def texels(self):
        return int(sum(level.size for level in self.pyramid))

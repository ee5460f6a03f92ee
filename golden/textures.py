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

__all__ = ["procedural_texture", "FAMILIES", "FAMILY_PREFIX", "family_of", "family_texture",
           "with_contrast", "image_texture", "TextureAtlas"]

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


#: Texture families of the stress scenes (:mod:`golden.stress_scenes`), named in a scene
#: as ``"family:<name>"`` instead of an image path:
#:
#: * ``noise``: band-limited value noise only (one random band of 2–40 cm cells);
#: * ``shapes``: rectangles and lines (2–60 cm, sharp edges) on a flat background;
#: * ``low_contrast``: the default mixed texture at a tenth of its contrast;
#: * ``repetitive``: stripes or a grid with one period (4–25 cm), which aliases in a
#:   disparity or shift window;
#: * ``blank``: a flat face with a few small marks (at least 85 % blank).
FAMILIES = ("noise", "shapes", "low_contrast", "repetitive", "blank")
FAMILY_PREFIX = "family:"


def family_of(texture):
    """The family named by a face texture ``"family:<name>"``; None for an image path
    or None. Raises ValueError for an unknown family."""
    if texture is None or not str(texture).startswith(FAMILY_PREFIX):
        return None
    name = str(texture)[len(FAMILY_PREFIX):]
    if name not in FAMILIES:
        raise ValueError(f"texture family must be one of {', '.join(FAMILIES)}, not {name!r}")
    return name


def _band_noise(rng, shape, low, high):
    """Value noise with cells from ``high`` down to ``low`` texels (unit std)."""
    h, w = shape
    noise = np.zeros(shape, np.float32)
    cell = float(high)
    while cell >= low:
        grid = rng.standard_normal((int(h / cell) + 3, int(w / cell) + 3)).astype(np.float32)
        up = cv2.resize(grid, (int(grid.shape[1] * cell), int(grid.shape[0] * cell)),
                        interpolation=cv2.INTER_CUBIC)
        oy, ox = rng.integers(0, int(cell) + 1, 2)
        noise += up[oy:oy + h, ox:ox + w]
        cell /= 2
    return noise / max(float(noise.std()), 1e-6)


def _shapes(rng, shape, texel, count_per_m2, background):
    """Rectangles and lines on a flat ``background``."""
    h, w = shape
    image = np.full(shape, background, np.float32)
    for _ in range(int(rng.poisson(count_per_m2 * h * w * texel * texel)) + 1):
        size = np.exp(rng.uniform(np.log(0.02), np.log(0.6), 2)) / texel
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        value = float(rng.uniform(20, 235))
        if rng.random() < 0.5:
            cv2.rectangle(image, (int(cx - size[0] / 2), int(cy - size[1] / 2)),
                          (int(cx + size[0] / 2), int(cy + size[1] / 2)), value, -1)
        else:
            end = (int(cx + size[0] * np.cos(rng.uniform(0, np.pi))),
                   int(cy + size[0] * np.sin(rng.uniform(0, np.pi))))
            cv2.line(image, (int(cx), int(cy)), end, value, max(1, int(0.01 / texel)))
    return image


def family_texture(rng, shape, texel, family):
    """A gray texture of ``family`` (see :data:`FAMILIES`), float32 in [8, 247]."""
    h, w = shape
    if family == "noise":
        high = max(2.0, np.exp(rng.uniform(np.log(0.08), np.log(0.4))) / texel)
        image = 128.0 + 45.0 * _band_noise(rng, shape, max(2.0, high / 8), high)
    elif family == "shapes":
        image = _shapes(rng, shape, texel, 10.0, float(rng.uniform(60, 200)))
    elif family == "low_contrast":
        image = 128.0 + 0.1 * (procedural_texture(rng, shape, texel) - 128.0)
    elif family == "repetitive":
        period = np.exp(rng.uniform(np.log(0.04), np.log(0.25))) / texel
        angle = rng.uniform(0, np.pi)
        y, x = np.mgrid[0:h, 0:w].astype(np.float32)
        phase = 2 * np.pi * (x * np.cos(angle) + y * np.sin(angle)) / period
        image = np.sign(np.sin(phase))
        if rng.random() < 0.5:                              # a grid: both directions
            across = 2 * np.pi * (-x * np.sin(angle) + y * np.cos(angle)) / period
            image = image * np.sign(np.sin(across))
        image = 128.0 + 70.0 * image
    elif family == "blank":
        image = _shapes(rng, shape, texel, 0.5, float(rng.uniform(60, 200)))
    else:
        raise ValueError(f"family must be one of {', '.join(FAMILIES)}, not {family!r}")
    image = cv2.GaussianBlur(np.asarray(image, np.float32), (0, 0), 0.6)
    return np.clip(image, 8, 247).astype(np.float32)


def with_contrast(texture, factor):
    """``texture`` with its contrast about its mean scaled by ``factor``, in [8, 247]."""
    mean = float(texture.mean())
    return np.clip(mean + factor * (texture - mean), 8, 247).astype(np.float32)


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

"""The simulated environment: a textured room with axis-aligned boxes.

The room is the inside of a box (floor at z = 0, centred on the z axis; world z is up);
boxes inside it are furniture, pillars or — with zero thickness on one axis — flat
panels. Every face carries a texture: procedural by default (from the scene seed), or a
user image. Axis-aligned geometry keeps ray casting to a handful of multiplies per
pixel (slab test), which is what makes rendering every row at its own pose fast.
"""

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .checks import check_int, check_number
from .config_files import check_keys, read_config_file
from .textures import (TextureAtlas, family_of, family_texture, image_texture,
                       procedural_texture, with_contrast)

__all__ = ["Box", "SceneSpec", "Scene", "default_scene_spec", "scene_from_config",
           "load_scene_spec", "build_scene"]

#: In-plane (u, v) world axes of a face whose normal is along axis 0, 1, 2; v is up on
#: walls.
FACE_AXES = {0: (1, 2), 1: (0, 2), 2: (0, 1)}


def _vector3(name, value):
    array = np.asarray(value, dtype=float)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be 3 finite numbers, not {value!r}")
    return tuple(array.tolist())


@dataclass(frozen=True, kw_only=True)
class Box:
    """An axis-aligned box (or, with one zero extent, a two-sided panel) in world metres.

    ``texture``: None (procedural from the scene seed), an image path, or
    ``"family:<name>"`` (a procedural family of :data:`golden.textures.FAMILIES`)."""
    lo: tuple
    hi: tuple
    texture: str | None = None

    def __post_init__(self):
        lo, hi = _vector3("lo", self.lo), _vector3("hi", self.hi)
        extent = np.subtract(hi, lo)
        if np.any(extent < 0) or np.sum(extent == 0) > 1:
            raise ValueError(f"box hi must exceed lo on at least two axes and equal it on "
                             f"the others, not lo={lo}, hi={hi}")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)
        family_of(self.texture)


@dataclass(frozen=True, kw_only=True)
class SceneSpec:
    """What to build; :func:`build_scene` turns it into a renderable :class:`Scene`.

    Parameters
    ----------
    room : 3-tuple
        Room size (m) along x, y, z.
    boxes : tuple of Box
        Inside the room.
    texel : float
        Texture resolution (m per texel).
    seed : int
        Seed of the procedural textures.
    room_texture : str or None
        Image (or ``"family:<name>"``) for all six room faces (procedural if None).
    mip_levels : int
        Mip levels above the base texture.
    contrast_range : 2-tuple
        Each face's contrast is scaled by a factor drawn log-uniformly in this range
        from the seed ((1, 1): unchanged).
    """
    room: tuple = (7.0, 6.0, 3.0)
    boxes: tuple = ()
    texel: float = 0.005
    seed: int = 0
    room_texture: str | None = None
    mip_levels: int = 5
    contrast_range: tuple = (1.0, 1.0)

    def __post_init__(self):
        room = _vector3("room", self.room)
        if min(room) <= 0:
            raise ValueError(f"room must have positive sizes, not {room}")
        object.__setattr__(self, "room", room)
        boxes = tuple(self.boxes)
        if not all(isinstance(b, Box) for b in boxes):
            raise TypeError(f"boxes must be Box objects, not {self.boxes!r}")
        lo, hi = self.room_lo, self.room_hi
        for k, box in enumerate(boxes):
            if np.any(np.array(box.lo) < lo) or np.any(np.array(box.hi) > hi):
                raise ValueError(f"box {k} ({box.lo} – {box.hi}) must lie inside the room "
                                 f"({tuple(lo)} – {tuple(hi)})")
        object.__setattr__(self, "boxes", boxes)
        check_number("texel", self.texel, 0, low_open=True)
        check_int("seed", self.seed, 0)
        check_int("mip_levels", self.mip_levels, 0, 8)
        family_of(self.room_texture)
        contrast = tuple(self.contrast_range)
        if len(contrast) != 2:
            raise ValueError(f"contrast_range must be two numbers, not {self.contrast_range!r}")
        check_number("contrast_range[0]", contrast[0], 0, low_open=True)
        check_number("contrast_range[1]", contrast[1], contrast[0])
        object.__setattr__(self, "contrast_range", tuple(float(c) for c in contrast))

    @property
    def room_lo(self):
        return np.array([-self.room[0] / 2, -self.room[1] / 2, 0.0])

    @property
    def room_hi(self):
        return np.array([self.room[0] / 2, self.room[1] / 2, self.room[2]])

    def clearance(self, points):
        """Distance (m) of points (N, 3) to the nearest surface; ≤ 0 outside the room or
        inside a box."""
        points = np.asarray(points, dtype=float)
        nearest = np.minimum(points - self.room_lo, self.room_hi - points).min(axis=1)
        for box in self.boxes:
            gap = np.maximum(np.maximum(np.array(box.lo) - points, points - np.array(box.hi)), 0.0)
            nearest = np.minimum(nearest, np.linalg.norm(gap, axis=1))
        return nearest

    def with_textures(self, paths):
        """This scene with user images assigned round-robin to the room, then each box."""
        paths = [str(p) for p in paths]
        if not paths:
            return self
        boxes = tuple(Box(lo=b.lo, hi=b.hi, texture=paths[(k + 1) % len(paths)])
                      for k, b in enumerate(self.boxes))
        return SceneSpec(room=self.room, boxes=boxes, texel=self.texel, seed=self.seed,
                         room_texture=paths[0], mip_levels=self.mip_levels,
                         contrast_range=self.contrast_range)

    def to_dict(self):
        return {"room": list(self.room), "texel": self.texel, "seed": self.seed,
                "room_texture": self.room_texture, "mip_levels": self.mip_levels,
                "contrast_range": list(self.contrast_range),
                "boxes": [{"lo": list(b.lo), "hi": list(b.hi), "texture": b.texture}
                          for b in self.boxes]}


#: Furniture of the default room (7 × 6 × 3 m): cabinet, table top, crates, a pillar, a
#: wall shelf and a ceiling lamp, 1–3.5 m from the room centre where rigs start.
DEFAULT_BOXES = (
    Box(lo=(2.6, -1.5, 0.0), hi=(3.5, 0.5, 1.9)),
    Box(lo=(-1.2, 1.6, 0.72), hi=(0.6, 2.6, 0.78)),
    Box(lo=(-3.5, -3.0, 0.0), hi=(-2.5, -2.0, 1.0)),
    Box(lo=(-1.9, -1.7, 0.0), hi=(-1.5, -1.3, 3.0)),
    Box(lo=(1.0, -3.0, 0.0), hi=(1.8, -2.3, 0.7)),
    Box(lo=(-3.5, 0.5, 0.9), hi=(-3.2, 2.5, 2.2)),
    Box(lo=(-0.4, -0.4, 2.7), hi=(0.4, 0.4, 2.75)),
)


def default_scene_spec(seed=0, **changes):
    """The default furnished room with textures from ``seed``."""
    return SceneSpec(boxes=DEFAULT_BOXES, seed=seed, **changes)


_SCENE_KEYS = {"room", "boxes", "texel", "seed", "room_texture", "mip_levels",
               "contrast_range"}


def scene_from_config(config, source="scene config", base_dir=None):
    """A SceneSpec from plain data; relative texture paths are taken from ``base_dir``."""
    check_keys(config, _SCENE_KEYS, source)

    def resolve(path):
        if path is None or base_dir is None or family_of(path):
            return path
        return str((Path(base_dir) / path)) if not Path(path).is_absolute() else path

    boxes = []
    for k, entry in enumerate(config.get("boxes", [])):
        if not isinstance(entry, dict) or set(entry) - {"lo", "hi", "texture"} \
                or not {"lo", "hi"} <= set(entry):
            raise ValueError(f"box {k} of {source} must have lo, hi and optionally texture, "
                             f"not {entry!r}")
        boxes.append(Box(lo=entry["lo"], hi=entry["hi"], texture=resolve(entry.get("texture"))))
    kwargs = {k: config[k] for k in ("room", "texel", "seed", "mip_levels", "contrast_range")
              if k in config}
    return SceneSpec(boxes=tuple(boxes), room_texture=resolve(config.get("room_texture")),
                     **kwargs)


def load_scene_spec(path):
    """A SceneSpec from a YAML/TOML file."""
    return scene_from_config(read_config_file(path), str(path), Path(path).parent)


@dataclass(frozen=True, eq=False)
class Scene:
    """Geometry and texture tables ready for :mod:`golden.render`.

    Faces are numbered ``3·surface + axis``: surfaces 0/1 are the room's low/high walls
    on each axis, surfaces 2 + 2b and 3 + 2b the low/high sides of box b. A point P on
    face f has atlas coordinates ``(P_u·scale + face_x[f], −P_v·scale + face_y[f])``.
    """
    spec: SceneSpec
    room_lo: np.ndarray
    room_hi: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray
    atlas: TextureAtlas
    scale: float
    face_x: np.ndarray = field(repr=False)
    face_y: np.ndarray = field(repr=False)

    @property
    def box_centre(self):
        return (self.box_lo + self.box_hi) / 2

    @property
    def box_radius(self):
        return np.linalg.norm(self.box_hi - self.box_lo, axis=1) / 2


def _faces(spec):
    """(lo, hi, texture) of every surface pair: the room, then each box."""
    yield spec.room_lo, spec.room_hi, spec.room_texture
    for box in spec.boxes:
        yield np.array(box.lo), np.array(box.hi), box.texture


@functools.lru_cache(maxsize=4)
def build_scene(spec):
    """Generate the textures of ``spec`` and pack them (cached: a few seconds each)."""
    step = 2 ** spec.mip_levels
    pad = 2 * step
    tiles, face_x, face_y = [], [], []
    face_index = 0
    for lo, hi, texture in _faces(spec):
        for side in (0, 1):
            for axis in range(3):
                u, v = FACE_AXES[axis]
                w = max(1, int(np.ceil((hi[u] - lo[u]) / spec.texel)))
                h = max(1, int(np.ceil((hi[v] - lo[v]) / spec.texel)))
                shape = (-(-(h + 2 * pad) // step) * step, -(-(w + 2 * pad) // step) * step)
                rng = np.random.default_rng([spec.seed, face_index])
                if texture is None:
                    tile = procedural_texture(rng, shape, spec.texel)
                elif family_of(texture):
                    tile = family_texture(rng, shape, spec.texel, family_of(texture))
                else:
                    inner = image_texture(texture, (h, w))
                    tile = np.pad(inner, ((pad, shape[0] - h - pad),
                                          (pad, shape[1] - w - pad)), mode="reflect")
                if spec.contrast_range != (1.0, 1.0):
                    low, high = np.log(spec.contrast_range)
                    factor = np.exp(np.random.default_rng([spec.seed, face_index, 1])
                                    .uniform(low, high))
                    tile = with_contrast(tile, factor)
                tiles.append(tile)
                face_x.append(-0.5 - lo[u] / spec.texel)
                face_y.append(-0.5 + hi[v] / spec.texel)
                face_index += 1
    atlas = TextureAtlas(tiles, spec.mip_levels, pad)
    boxes = [(b.lo, b.hi) for b in spec.boxes]
    return Scene(spec=spec, room_lo=spec.room_lo, room_hi=spec.room_hi,
                 box_lo=np.array([b[0] for b in boxes]).reshape(-1, 3),
                 box_hi=np.array([b[1] for b in boxes]).reshape(-1, 3),
                 atlas=atlas, scale=1.0 / spec.texel,
                 face_x=(np.array(face_x) + atlas.offsets[:, 0]).astype(np.float32),
                 face_y=(np.array(face_y) + atlas.offsets[:, 1]).astype(np.float32))

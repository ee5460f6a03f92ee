"""Camera rigs: the papers' presets and user rigs from YAML/TOML files.

Every rig is checked on construction (:mod:`golden.observability`): a rig that cannot
observe one of the six degrees of freedom is rejected unless ``allow_unobservable`` is
set, and the verdict travels with the rig (``rig.observability``) into every dataset.

Rig frame: x right, y down, z forward (a head looking ahead).
"""

from dataclasses import dataclass, field, fields
from pathlib import Path

from .checks import check_int, check_number
from .camera import Camera, focal_for_vfov
from .config_files import check_keys, read_config_file
from .lens import LENS_PRESETS
import numpy as np

from .observability import Observability, analyze, row_constraints
from .rotations import orientation_ypr

__all__ = ["Rig", "PRESETS", "preset", "load_rig", "rig_from_config", "scaled_rig",
           "slot_conditions"]


@dataclass(frozen=True, kw_only=True)
class Rig:
    """A rigid cluster of rolling-shutter cameras.

    Parameters
    ----------
    name : str
    cameras : tuple of Camera
        Unique names.
    row_points : int
        Shift measurements per camera per row the tracker takes (1 for the stereo-pair
        tracker of TVCG 2016, K segments for the radial tracker of CVPR 2018); the
        observability check stacks that many equations per camera.
    nominal_depth : float
        Scene depth (m) assumed by the observability check.
    allow_unobservable : bool
        Accept a rig that cannot observe every degree of freedom (the verdict stays in
        ``observability``).

    Raises
    ------
    ValueError
        If the rig cannot observe a degree of freedom and ``allow_unobservable`` is off;
        the message names the lost direction(s).
    """
    name: str
    cameras: tuple
    row_points: int = 1
    nominal_depth: float = 2.0
    allow_unobservable: bool = False
    observability: Observability = field(init=False, compare=False, repr=False)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise TypeError(f"name must be a non-empty string, not {self.name!r}")
        cameras = tuple(self.cameras)
        if not cameras or not all(isinstance(c, Camera) for c in cameras):
            raise TypeError(f"cameras must be a non-empty sequence of Camera, not {self.cameras!r}")
        names = [c.name for c in cameras]
        if len(set(names)) != len(names):
            raise ValueError(f"cameras must have unique names, not {names}")
        check_int("row_points", self.row_points, 1)
        check_number("nominal_depth", self.nominal_depth, 0, low_open=True)
        object.__setattr__(self, "cameras", cameras)
        verdict = analyze(cameras, self.row_points, self.nominal_depth)
        object.__setattr__(self, "observability", verdict)
        if not verdict.complete and not self.allow_unobservable:
            raise ValueError(
                f"rig {self.name!r} cannot observe {', '.join(verdict.unobservable)} "
                f"(rank {verdict.rank} of 6, condition {verdict.condition:.3g} at "
                f"{verdict.worst_row_fraction:.0%} of the image height): rows measure shifts "
                f"only along themselves, so add cameras facing up/down, rolled 90° or "
                f"tilted, or set allow_unobservable to accept the rig")

    def to_config(self):
        """Plain data that :func:`rig_from_config` turns back into this rig."""
        return {"name": self.name, "row_points": self.row_points,
                "nominal_depth": self.nominal_depth,
                "allow_unobservable": self.allow_unobservable,
                "cameras": [c.to_dict() for c in self.cameras]}

    def replace_cameras(self, **changes):
        """The same rig with ``changes`` applied to every camera."""
        return Rig(name=self.name, cameras=tuple(c.replace(**changes) for c in self.cameras),
                   row_points=self.row_points, nominal_depth=self.nominal_depth,
                   allow_unobservable=self.allow_unobservable)


# --- presets ---------------------------------------------------------------------------

#: stereo20 pair orientations (yaw, pitch, roll in degrees): four pairs around the
#: horizon, four tilted 45° up on the diagonals, one facing up and one down; every
#: other pair rolled 90° so that rows run both horizontally and vertically.
STEREO20_PAIRS = ((0, 0, 0), (90, 0, 90), (180, 0, 0), (270, 0, 90), (45, 45, 90),
                  (135, 45, 0), (225, 45, 90), (315, 45, 0), (0, 90, 0), (0, -90, 90))

#: radial rig cameras (position in m, (yaw, pitch, roll) in degrees), after CVPR 2018
#: §3.3: mostly forward-looking with overlap, even-numbered cameras rolled 90°, small
#: translations and rotations in all three directions between neighbours.
RADIAL_CAMERAS = (
    ((-0.06, 0.00, 0.00), (-25, 0, 0)),
    ((-0.02, -0.03, 0.01), (-8, 12, 90)),
    ((0.02, 0.03, 0.00), (8, -12, 0)),
    ((0.06, 0.00, 0.01), (25, 0, 90)),
    ((-0.09, 0.02, -0.01), (-40, -15, 0)),
    ((0.09, -0.02, -0.01), (40, 15, 90)),
)


def _stereo20(lens):
    """10 stereo pairs, 10 cm baseline, 640×480, 60° vertical FoV, 120 fps (TVCG 2016)."""
    cameras = []
    for k, (yaw, pitch, roll) in enumerate(STEREO20_PAIRS):
        rotation = orientation_ypr(yaw, pitch, roll)
        centre = 0.10 * rotation[:, 2]  # pairs sit on a 10 cm head radius
        for side, sign in (("L", -1), ("R", 1)):
            cameras.append(Camera.from_fov(
                name=f"pair{k}{side}", lens=lens, rotation=rotation,
                position=centre + sign * 0.05 * rotation[:, 0]))
    return Rig(name="stereo20", cameras=tuple(cameras), row_points=1)


#: stereo8 pairs (yaw, pitch, roll in degrees) facing front, left, back and right
#: (issue 18's rig): the side pairs rolled 90° so that their rows run vertically, the
#: front pair tilted 30° up and the back pair 30° down.
STEREO8_PAIRS = ((0, 30, 0), (-90, 0, 90), (180, -30, 0), (90, 0, 90))

#: stereo8 trigger offset per pair index (s).
STEREO8_TRIGGER_STEP = 0.5e-3


def _stereo8(lens, fps, name):
    """4 stereo pairs, 8 cm baseline along each camera's x axis, pair centres 10 cm out,
    640×480, 60° vertical FoV, readout 80 % of the frame period, pair k triggered
    k × 0.5 ms after pair 0."""
    cameras = []
    for k, (yaw, pitch, roll) in enumerate(STEREO8_PAIRS):
        rotation = orientation_ypr(yaw, pitch, roll)
        centre = 0.10 * rotation[:, 2]
        for side, sign in (("L", -1), ("R", 1)):
            cameras.append(Camera.from_fov(
                name=f"pair{k}{side}", lens=lens, rotation=rotation, fps=fps,
                t_f=0.2 / fps, trigger_offset=k * STEREO8_TRIGGER_STEP,
                position=centre + sign * 0.04 * rotation[:, 0]))
    return Rig(name=name, cameras=tuple(cameras), row_points=8)


def _radial(count, lens):
    cameras = tuple(
        Camera.from_fov(name=f"cam{k + 1}", lens=lens, position=position,
                        rotation=orientation_ypr(*ypr))
        for k, (position, ypr) in enumerate(RADIAL_CAMERAS[:count]))
    return Rig(name=f"radial{count}", cameras=cameras, row_points=8)


#: preset name -> (builder(lens), default lens)
PRESETS = {
    "stereo20": (_stereo20, "Pinhole"),
    "radial4": (lambda lens: _radial(4, lens), "GoPro4"),
    "radial6": (lambda lens: _radial(6, lens), "GoPro4"),
    "stereo8": (lambda lens: _stereo8(lens, 100.0, "stereo8"), "Pinhole"),
    "stereo8-board": (lambda lens: _stereo8(lens, 120.0, "stereo8-board"), "Pinhole"),
}


def preset(name, lens=None):
    """Preset rig ``name`` (see :data:`PRESETS`), optionally with another lens preset."""
    if name not in PRESETS:
        raise ValueError(f"rig must be one of {', '.join(PRESETS)} or a .yaml/.toml file, "
                         f"not {name!r}")
    builder, default_lens = PRESETS[name]
    lens = default_lens if lens is None else lens
    if lens not in LENS_PRESETS:
        raise ValueError(f"lens must be one of {', '.join(LENS_PRESETS)}, not {lens!r}")
    return builder(lens)


def scaled_rig(rig, factor):
    """``rig`` with every image scaled by ``factor`` (same field of view, frame rate,
    blanking share and trigger offsets; rows ``round(H·factor)``), for fast runs."""
    check_number("factor", factor, 0, 1, low_open=True)
    cameras = []
    for cam in rig.cameras:
        width, height = round(cam.width * factor), round(cam.height * factor)
        sx, sy = width / cam.width, height / cam.height
        cameras.append(cam.replace(
            width=width, height=height, fx=cam.fx * sx, fy=cam.fy * sy,
            cx=(cam.cx + 0.5) * sx - 0.5, cy=(cam.cy + 0.5) * sy - 0.5,
            t_r=(1 / cam.fps - cam.t_f - cam.t_e) / height))
    name = rig.name if factor == 1 else f"{rig.name}@{factor:g}"
    return Rig(name=name, cameras=tuple(cameras), row_points=rig.row_points,
               nominal_depth=rig.nominal_depth, allow_unobservable=rig.allow_unobservable)


def slot_conditions(rig, row_points=None, depth=None):
    """Condition number of the stacked constraints of every row slot of one frame, with
    each camera at the row its trigger offset puts in the slot (:func:`analyze` assumes
    synchronized cameras); returns (conditions, cameras reading) per slot, slots with
    no camera reading left out. Needs cameras of one row time."""
    row_points = rig.row_points if row_points is None else row_points
    depth = rig.nominal_depth if depth is None else depth
    cams = rig.cameras
    offsets = [round(c.trigger_offset / cams[0].t_r) for c in cams]
    conditions, reading = [], []
    for slot in range(max(c.height + o for c, o in zip(cams, offsets))):
        rows = [(c, slot - o) for c, o in zip(cams, offsets) if 0 <= slot - o < c.height]
        if not rows:
            continue
        sigma = np.linalg.svd(np.concatenate([row_constraints(c, y, row_points, depth)
                                              for c, y in rows]), compute_uv=False)
        conditions.append(sigma[0] / sigma[-1] if len(sigma) == 6 and sigma[-1] > 0
                          else np.inf)
        reading.append(len(rows))
    return np.array(conditions), np.array(reading)


# --- config files ----------------------------------------------------------------------

_CAMERA_FIELDS = {f.name for f in fields(Camera)}
_CONVENIENCE = {"vfov_deg", "lens", "yaw_deg", "pitch_deg", "roll_deg"}
_RIG_KEYS = {"name", "row_points", "nominal_depth", "allow_unobservable", "defaults", "cameras"}


def _camera_from_config(entry, where):
    """A Camera from one config entry (camera fields plus vfov_deg, lens, yaw/pitch/roll)."""
    check_keys(entry, _CAMERA_FIELDS | _CONVENIENCE, where)
    entry = dict(entry)
    lens = entry.pop("lens", None)
    if lens is not None:
        if lens not in LENS_PRESETS:
            raise ValueError(f"lens in {where} must be one of {', '.join(LENS_PRESETS)}, "
                             f"not {lens!r}")
        if "k1" in entry or "k2" in entry:
            raise ValueError(f"{where} gives both lens and k1/k2; give one of them")
        entry["k1"], entry["k2"] = LENS_PRESETS[lens]
    entry.setdefault("width", 640)
    entry.setdefault("height", 480)
    vfov = entry.pop("vfov_deg", 60.0)
    if "fx" not in entry:
        entry["fx"] = focal_for_vfov(vfov, entry["height"], entry.get("k1", 0.0),
                                     entry.get("k2", 0.0))
    entry.setdefault("fy", entry["fx"])
    entry.setdefault("cx", (entry["width"] - 1) / 2)
    entry.setdefault("cy", (entry["height"] - 1) / 2)
    ypr = [entry.pop(k, 0.0) for k in ("yaw_deg", "pitch_deg", "roll_deg")]
    if "rotation" not in entry:
        entry["rotation"] = orientation_ypr(*ypr)
    elif any(ypr):
        raise ValueError(f"{where} gives both rotation and yaw/pitch/roll; give one of them")
    if "t_r" not in entry:
        fps = entry.get("fps", 120.0)
        readout = 1.0 / fps - entry.get("t_f", 0.0) - entry.get("t_e", 0.0)
        if readout <= 0:
            raise ValueError(f"infeasible timing in {where}: t_f + t_e leave no readout "
                             f"time in 1/fps = {1 / fps:.9g} s (fps, t_f, t_e)")
        entry["t_r"] = readout / entry["height"]
    try:
        return Camera(**entry)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{where}: {exc}") from None


def rig_from_config(config, source="config", allow_unobservable=None):
    """A Rig from plain data (see ``docs/simulator.md`` for the keys)."""
    check_keys(config, _RIG_KEYS, source)
    defaults = config.get("defaults", {})
    check_keys(defaults, _CAMERA_FIELDS | _CONVENIENCE, f"defaults of {source}")
    entries = config.get("cameras")
    if not isinstance(entries, list) or not entries:
        raise ValueError(f"cameras in {source} must be a non-empty list")
    cameras = []
    for k, entry in enumerate(entries):
        merged = {**defaults, **entry} if isinstance(entry, dict) else entry
        if isinstance(merged, dict):
            merged.setdefault("name", f"cam{k}")
        cameras.append(_camera_from_config(merged, f"camera {k} of {source}"))
    allow = config.get("allow_unobservable", False) if allow_unobservable is None \
        else allow_unobservable
    return Rig(name=config.get("name", Path(source).stem), cameras=tuple(cameras),
               row_points=config.get("row_points", 1),
               nominal_depth=config.get("nominal_depth", 2.0), allow_unobservable=allow)


def load_rig(spec, lens=None, allow_unobservable=None):
    """A preset by name, or a rig from a YAML/TOML file path."""
    if str(spec) in PRESETS:
        rig = preset(str(spec), lens)
        if allow_unobservable:
            rig = Rig(name=rig.name, cameras=rig.cameras, row_points=rig.row_points,
                      nominal_depth=rig.nominal_depth, allow_unobservable=True)
        return rig
    if lens is not None:
        raise ValueError("lens applies to the preset rigs; set lens or k1/k2 in the rig file")
    if Path(spec).suffix.lower() not in (".yaml", ".yml", ".toml"):
        raise ValueError(f"rig must be one of {', '.join(PRESETS)} or a .yaml/.toml file, "
                         f"not {str(spec)!r}")
    return rig_from_config(read_config_file(spec), str(spec), allow_unobservable)


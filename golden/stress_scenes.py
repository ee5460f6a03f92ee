"""Randomized scenes for the tracker's stress suite (issue 18, item 5).

Every scene comes from one seed (the same seed gives the same scene, texture for
texture): a room 3–10 m on a side whose longer side keeps one wall beyond the stereo
range (``far_wall`` from the start), 3–5 pieces of furniture, 2–5 pieces of clutter
close to the rig, and boxes textured with every family of
:data:`golden.textures.FAMILIES` (band-limited noise, rectangles and lines, low
contrast, repetitive patterns, large blank areas), the room with any family but
``blank`` (six blank faces leave nothing to track rather than stress the tracker),
and a contrast drawn per face. The
rig starts at a random height (1.1–1.9 m) and heading, clear of every surface by
``keep_clear`` so that the simulator's clearance check passes for short runs.

:func:`stress_dataset` renders one run: scene from ``seed``, a rig (optionally scaled
down for speed), a motion (``head`` or ``paper``) from the scene's start pose.
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from .checks import check_int, check_number
from .rig import scaled_rig
from .rotations import exp_so3
from .scene import Box, SceneSpec
from .simulator import check_clearance, schedule, simulate
from .textures import FAMILIES, FAMILY_PREFIX
from .trajectory import START_ROTATION, HeadMotion, ScrewTrajectory, PAPER_AXIS, \
    PAPER_DIRECTION, SpeedProfile

__all__ = ["STRESS_MOTIONS", "StressParams", "StressScene", "stress_scene",
           "stress_trajectory", "stress_dataset"]

#: Motions of the stress suite.
STRESS_MOTIONS = ("head", "paper")


def _pair(name, value, low, integer=False):
    """Check a (min, max) range."""
    value = tuple(value)
    if len(value) != 2:
        raise ValueError(f"{name} must be two numbers (min, max), not {value!r}")
    check = check_int if integer else check_number
    check(f"{name}[0]", value[0], low)
    check(f"{name}[1]", value[1], value[0])
    return value


@dataclass(frozen=True, kw_only=True)
class StressParams:
    """What a stress scene may contain.

    Parameters
    ----------
    room : (float, float)
        Range of the room's horizontal sides (m).
    height : (float, float)
        Range of the room's height (m).
    far_wall : float
        The start is at least this far from one wall (m): beyond the stereo range.
    furniture : (int, int)
        Range of the number of furniture boxes (0.3–1 m wide, up to 2.2 m tall).
    clutter : (int, int)
        Range of the number of small boxes and panels (0.1–0.4 m) near the rig.
    clutter_distance : (float, float)
        Range of the clutter's distance from the start (m).
    keep_clear : float
        No surface nearer the start than this (m).
    contrast_range : (float, float)
        Range of the per-face contrast factor.
    texel : float
        Texture resolution (m).
    """
    room: tuple = (3.0, 10.0)
    height: tuple = (2.5, 3.5)
    far_wall: float = 3.5
    furniture: tuple = (3, 5)
    clutter: tuple = (2, 5)
    clutter_distance: tuple = (0.7, 1.5)
    keep_clear: float = 0.6
    contrast_range: tuple = (0.4, 1.6)
    texel: float = 0.008

    def __post_init__(self):
        object.__setattr__(self, "room", _pair("room", self.room, 1.0))
        object.__setattr__(self, "height", _pair("height", self.height, 2.0))
        check_number("keep_clear", self.keep_clear, 0.2)
        check_number("far_wall", self.far_wall, 0, low_open=True)
        if self.far_wall + self.keep_clear + 0.4 > self.room[1]:
            raise ValueError(f"far_wall {self.far_wall} m plus keep_clear {self.keep_clear} m "
                             f"and 0.4 m do not fit in rooms of at most {self.room[1]} m")
        object.__setattr__(self, "furniture", _pair("furniture", self.furniture, 0, True))
        object.__setattr__(self, "clutter", _pair("clutter", self.clutter, 0, True))
        if self.furniture[0] + self.clutter[0] < len(FAMILIES):
            raise ValueError(f"furniture[0] + clutter[0] must be at least {len(FAMILIES)} "
                             f"so that every texture family appears on a box")
        object.__setattr__(self, "clutter_distance",
                           _pair("clutter_distance", self.clutter_distance, self.keep_clear))
        object.__setattr__(self, "contrast_range",
                           _pair("contrast_range", self.contrast_range, 0.01))
        check_number("texel", self.texel, 0, low_open=True)

    replace = replace


@dataclass(frozen=True, eq=False)
class StressScene:
    """A generated scene: ``spec`` for :func:`golden.simulator.simulate`, the rig's start
    pose (world-from-rig rotation, position) and the family of the room and of each box."""
    seed: int
    spec: SceneSpec
    start_rotation: np.ndarray
    start_position: np.ndarray
    families: tuple


def _box_around(centre, size, room_lo, room_hi):
    """An axis-aligned box of ``size`` centred at ``centre``, moved inside the room."""
    lo = np.clip(centre - size / 2, room_lo, room_hi - size)
    return lo, np.minimum(lo + size, room_hi)


def stress_scene(seed, params=StressParams(), max_tries=200):
    """The stress scene of ``seed`` (see the module docstring).

    Raises
    ------
    ValueError
        If ``max_tries`` draws cannot place the boxes clear of the start.
    """
    check_int("seed", seed, 0)
    rng = np.random.default_rng([seed, 0x57E55])
    p = params
    sides = rng.uniform(*p.room, 2)
    sides[0] = rng.uniform(max(p.room[0], p.far_wall + p.keep_clear + 0.4), p.room[1])
    rng.shuffle(sides)
    long_axis = int(np.argmax(sides))
    height = rng.uniform(*p.height)
    room_lo = np.array([-sides[0] / 2, -sides[1] / 2, 0.0])
    room_hi = np.array([sides[0] / 2, sides[1] / 2, height])
    start = np.empty(3)
    margin = p.keep_clear + 0.4
    for axis in range(2):
        start[axis] = rng.uniform(room_lo[axis] + margin, room_hi[axis] - margin)
    # one wall of the long axis at least far_wall away
    start[long_axis] = room_lo[long_axis] + rng.uniform(
        margin, sides[long_axis] - p.far_wall)
    if rng.random() < 0.5:
        start[long_axis] = -start[long_axis]
    start[2] = rng.uniform(1.1, min(1.9, height - margin))
    yaw = rng.uniform(0, 2 * math.pi)
    rotation = exp_so3(np.array([0.0, 0.0, yaw])) @ START_ROTATION

    boxes, tries = [], 0
    wanted = [("furniture", k) for k in range(rng.integers(p.furniture[0], p.furniture[1] + 1))]
    wanted += [("clutter", k) for k in range(rng.integers(p.clutter[0], p.clutter[1] + 1))]
    for kind, _ in wanted:
        while True:
            tries += 1
            if tries > max_tries:
                raise ValueError(f"seed {seed}: cannot place {len(wanted)} boxes clear of "
                                 f"the start in {max_tries} tries")
            if kind == "furniture":
                size = np.array([*rng.uniform(0.3, 1.0, 2), rng.uniform(0.3, 2.2)])
                centre = np.array([*rng.uniform(room_lo[:2], room_hi[:2]), size[2] / 2])
            else:
                size = rng.uniform(0.1, 0.4, 3)
                size[rng.integers(3)] *= rng.choice([1.0, 0.0])   # a panel half the time
                direction = rng.standard_normal(3)
                direction /= np.linalg.norm(direction)
                centre = start + rng.uniform(*p.clutter_distance) * direction
            lo, hi = _box_around(centre, size, room_lo, room_hi)
            trial = SceneSpec(room=tuple(sides) + (height,), boxes=(Box(lo=tuple(lo), hi=tuple(hi)),))
            if trial.clearance(start[None])[0] >= p.keep_clear:
                boxes.append((lo, hi))
                break
    # every family on some box; the room (all six faces) never blank, which would leave
    # no tracker anything to see rather than stress it
    boxes_families = [FAMILIES[k % len(FAMILIES)] for k in range(len(boxes))]
    rng.shuffle(boxes_families)
    families = [str(rng.choice([f for f in FAMILIES if f != "blank"]))] + boxes_families
    spec = SceneSpec(room=(float(sides[0]), float(sides[1]), float(height)),
                     boxes=tuple(Box(lo=tuple(lo), hi=tuple(hi),
                                     texture=FAMILY_PREFIX + family)
                                 for (lo, hi), family in zip(boxes, families[1:])),
                     texel=p.texel, seed=seed, room_texture=FAMILY_PREFIX + families[0],
                     contrast_range=p.contrast_range)
    return StressScene(seed=seed, spec=spec, start_rotation=rotation, start_position=start,
                       families=tuple(families))


def stress_trajectory(scene, motion, *, linear_speed=1.4, angular_speed=math.radians(120)):
    """``head`` (smooth random motion from the scene's seed, RMS speeds) or ``paper`` (the
    papers' constant screw motion) from the scene's start pose."""
    if motion == "head":
        return HeadMotion(seed=scene.seed, linear_rms=linear_speed, angular_rms=angular_speed,
                          start_position=scene.start_position,
                          start_rotation=scene.start_rotation)
    if motion == "paper":
        return ScrewTrajectory(direction=PAPER_DIRECTION,
                               linear_speed=SpeedProfile.constant(linear_speed),
                               axis=PAPER_AXIS, angular_speed=SpeedProfile.constant(angular_speed),
                               start_position=scene.start_position,
                               start_rotation=scene.start_rotation, kind="paper")
    raise ValueError(f"motion must be one of {', '.join(STRESS_MOTIONS)}, not {motion!r}")


def stress_dataset(seed, rig, motion, duration=0.25, *, scale=1.0, noise=2.0,
                   params=StressParams()):
    """Render the stress run ``seed`` of ``rig`` (scaled by ``scale``, sensor noise
    ``noise`` gray levels) with ``motion`` for ``duration`` s; a
    :class:`golden.dataset.Dataset` whose info also holds ``stress`` (seed, families).

    Raises
    ------
    ValueError
        If the motion takes a camera within the simulator's clearance of a surface
        (a shorter duration or a larger ``keep_clear`` avoids it).
    """
    check_number("noise", noise, 0)
    scene = stress_scene(seed, params)
    rig = scaled_rig(rig, scale).replace_cameras(noise_sigma=noise)
    trajectory = stress_trajectory(scene, motion)
    check_clearance(rig, scene.spec, trajectory, schedule(rig, duration, seed))
    dataset = simulate(rig, scene.spec, trajectory, duration, seed=seed)
    dataset.info["stress"] = {"seed": seed, "motion": motion, "scale": scale,
                              "families": list(scene.families)}
    return dataset

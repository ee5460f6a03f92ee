"""Continuous-time 6-DoF rig trajectories with closed-form poses and velocities.

A trajectory gives, at any time t (s), the rig pose in the world — rotation R(t)
(rig → world) and position p(t) of the rig origin — and its derivatives: the linear
velocity p'(t) and the angular velocity ω(t) in the world frame (R' = [ω]× R). Both are
exact closed forms, so the per-row ground truth needs no numerical integration.

* :class:`ScrewTrajectory`: straight-line translation and rotation about a fixed axis,
  each with its own speed profile. Covers the papers' test case (v = 1.4 m/s,
  ω = 120°/s), static, pure rotation and pure translation.
* :class:`HeadMotion`: smooth random motion (sums of sinusoids, 0.2–3 Hz) from a seed,
  scaled to given RMS linear and angular speeds.
"""

import math
from dataclasses import dataclass

import numpy as np

from .rotations import exp_so3, left_jacobian

__all__ = ["SpeedProfile", "ScrewTrajectory", "HeadMotion", "START_ROTATION",
           "START_POSITION", "make_trajectory", "MOTIONS"]

#: Rig looking along world +y, level (rig x → world x, rig y (down) → world −z).
START_ROTATION = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
#: Head height at the centre of the default room.
START_POSITION = np.array([0.0, 0.0, 1.6])


@dataclass(frozen=True)
class SpeedProfile:
    """A piecewise-linear speed s(t) through (times, speeds), constant outside.

    ``integral(t)`` is exact (piecewise quadratic), so positions and angles follow the
    profile without integration error.
    """
    times: tuple
    speeds: tuple

    def __post_init__(self):
        times = tuple(float(t) for t in self.times)
        speeds = tuple(float(s) for s in self.speeds)
        if not times or len(times) != len(speeds):
            raise ValueError("speed profile needs as many times as speeds, at least one")
        if any(b <= a for a, b in zip(times, times[1:])):
            raise ValueError(f"speed profile times must increase strictly, not {times}")
        if any(s < 0 or not math.isfinite(s) for s in speeds):
            raise ValueError(f"speed profile speeds must be finite and non-negative, not {speeds}")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "speeds", speeds)

    @classmethod
    def constant(cls, speed):
        return cls((0.0,), (speed,))

    @classmethod
    def parse(cls, text, name="speed"):
        """``"1.4"`` (constant) or ``"0:0,0.05:1.4"`` (time:speed knots)."""
        try:
            if ":" not in text:
                return cls.constant(float(text))
            knots = [part.split(":") for part in text.split(",")]
            return cls(tuple(float(t) for t, _ in knots), tuple(float(s) for _, s in knots))
        except ValueError as exc:
            raise ValueError(f"{name} must be a number or time:value pairs like "
                             f"'0:0,0.05:1.4' ({exc}), not {text!r}") from None

    def scaled(self, factor):
        return SpeedProfile(self.times, tuple(s * factor for s in self.speeds))

    def value(self, t):
        return np.interp(t, self.times, self.speeds)

    def integral(self, t):
        """∫₀ᵗ s(τ) dτ (negative for t < 0)."""
        knots, speeds = np.array(self.times), np.array(self.speeds)
        slopes = np.append(np.diff(speeds) / np.diff(knots), 0.0)  # 0: constant after
        at_knots = np.concatenate([[0.0], np.cumsum(np.diff(knots) * (speeds[1:] + speeds[:-1]) / 2)])

        def from_first_knot(x):
            k = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, len(knots) - 1)
            dx = x - knots[k]
            slope = np.where(x < knots[0], 0.0, slopes[k])  # constant before, too
            return at_knots[k] + speeds[k] * dx + slope * dx * dx / 2

        return from_first_knot(np.asarray(t, dtype=float)) - from_first_knot(0.0)

    def to_dict(self):
        return {"times": list(self.times), "speeds": list(self.speeds)}


def _unit(name, vector):
    vector = np.asarray(vector, dtype=float)
    norm = np.linalg.norm(vector)
    if vector.shape != (3,) or not norm > 0:
        raise ValueError(f"{name} must be a non-zero 3-vector, not {vector!r}")
    return vector / norm


class ScrewTrajectory:
    """p(t) = p0 + u·∫v, R(t) = exp(a·∫ω) R0: translation along the unit vector u and
    rotation about the world axis a, with speed profiles v (m/s) and ω (rad/s)."""

    def __init__(self, *, direction=(1.0, 0.0, 0.0), linear_speed=SpeedProfile.constant(0.0),
                 axis=(0.0, 0.0, 1.0), angular_speed=SpeedProfile.constant(0.0),
                 start_position=START_POSITION, start_rotation=START_ROTATION, kind="screw"):
        self.direction = _unit("direction", direction)
        self.axis = _unit("axis", axis)
        self.linear_speed, self.angular_speed = linear_speed, angular_speed
        self.start_position = np.asarray(start_position, dtype=float)
        self.start_rotation = np.asarray(start_rotation, dtype=float)
        self.kind = kind

    def pose(self, t):
        """(R (n, 3, 3), p (n, 3)) at times ``t``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        angle = self.angular_speed.integral(t)
        rotation = exp_so3(angle[:, None] * self.axis) @ self.start_rotation
        position = self.start_position + self.linear_speed.integral(t)[:, None] * self.direction
        return rotation, position

    def velocity(self, t):
        """(linear velocity (n, 3), angular velocity (n, 3)), world frame."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return (self.linear_speed.value(t)[:, None] * self.direction,
                self.angular_speed.value(t)[:, None] * self.axis)

    def to_dict(self):
        return {"kind": self.kind, "direction": self.direction.tolist(),
                "linear_speed": self.linear_speed.to_dict(), "axis": self.axis.tolist(),
                "angular_speed": self.angular_speed.to_dict(),
                "start_position": self.start_position.tolist(),
                "start_rotation": self.start_rotation.tolist()}


class HeadMotion:
    """Smooth random motion from a seed: p(t) = p0 + Σ a_k (sin(2πf_k t + φ_k) − sin φ_k)
    and R(t) = exp(r(t)) R0 with r(t) the same kind of sum, both starting at the start
    pose. Frequencies are log-uniform in 0.2–3 Hz with amplitudes ∝ 1/f (every
    component moves about equally fast, as in head motion), scaled so that the RMS of
    the linear speed is ``linear_rms`` (m/s) and the RMS of r'(t) — the angular speed
    for small angles — is ``angular_rms`` (rad/s) over all time.
    """

    COMPONENTS = 6

    def __init__(self, *, seed, linear_rms=1.4, angular_rms=math.radians(120),
                 start_position=START_POSITION, start_rotation=START_ROTATION):
        if linear_rms < 0 or angular_rms < 0:
            raise ValueError("linear_rms and angular_rms must be non-negative")
        rng = np.random.default_rng([seed, 0x4EAD])
        self.seed, self.linear_rms, self.angular_rms = seed, linear_rms, angular_rms
        self.start_position = np.asarray(start_position, dtype=float)
        self.start_rotation = np.asarray(start_rotation, dtype=float)
        self._terms = [self._random_terms(rng, rms) for rms in (linear_rms, angular_rms)]

    def _random_terms(self, rng, rms):
        freq = np.exp(rng.uniform(np.log(0.2), np.log(3.0), (self.COMPONENTS, 3)))
        omega = 2 * np.pi * freq
        phase = rng.uniform(0, 2 * np.pi, (self.COMPONENTS, 3))
        amplitude = rng.normal(1.0, 0.3, (self.COMPONENTS, 3)) / omega
        # Mean square of Σ a ω cos(...) over all time: Σ (a ω)² / 2 (distinct frequencies).
        amplitude *= rms / math.sqrt(np.sum((amplitude * omega) ** 2) / 2)
        return amplitude, omega, phase

    @staticmethod
    def _sum(terms, t):
        amplitude, omega, phase = terms
        arg = omega * t[:, None, None] + phase
        value = np.sum(amplitude * (np.sin(arg) - np.sin(phase)), axis=1)
        rate = np.sum(amplitude * omega * np.cos(arg), axis=1)
        return value, rate

    def pose(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        offset, _ = self._sum(self._terms[0], t)
        rotvec, _ = self._sum(self._terms[1], t)
        return exp_so3(rotvec) @ self.start_rotation, self.start_position + offset

    def velocity(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        _, velocity = self._sum(self._terms[0], t)
        rotvec, rate = self._sum(self._terms[1], t)
        return velocity, np.einsum("nij,nj->ni", left_jacobian(rotvec), rate)

    def to_dict(self):
        return {"kind": "head", "seed": self.seed, "linear_rms": self.linear_rms,
                "angular_rms": self.angular_rms,
                "start_position": self.start_position.tolist(),
                "start_rotation": self.start_rotation.tolist()}


#: The papers' test case directions (world frame): a general direction and a general
#: axis so that every degree of freedom moves.
PAPER_DIRECTION = (0.8, 0.5, 0.2)
PAPER_AXIS = (0.3, 0.4, 1.0)

#: Motion names of :func:`make_trajectory` (and ``rowtrack simulate --motion``).
MOTIONS = ("head", "paper", "static", "rotation", "translation")


def make_trajectory(motion, *, seed=0, linear_speed=None, angular_speed=None):
    """A trajectory by name (see :data:`MOTIONS`).

    ``linear_speed`` (m/s) and ``angular_speed`` (rad/s) are SpeedProfiles (RMS targets,
    their first speed, for ``head``); by default the papers' 1.4 m/s and 120°/s.
    """
    linear = linear_speed or SpeedProfile.constant(1.4)
    angular = angular_speed or SpeedProfile.constant(math.radians(120))
    if motion == "head":
        return HeadMotion(seed=seed, linear_rms=linear.speeds[0], angular_rms=angular.speeds[0])
    if motion == "paper":
        return ScrewTrajectory(direction=PAPER_DIRECTION, linear_speed=linear, axis=PAPER_AXIS,
                               angular_speed=angular, kind="paper")
    if motion == "static":
        return ScrewTrajectory(kind="static")
    if motion == "rotation":
        return ScrewTrajectory(axis=PAPER_AXIS, angular_speed=angular, kind="rotation")
    if motion == "translation":
        return ScrewTrajectory(direction=PAPER_DIRECTION, linear_speed=linear,
                               kind="translation")
    raise ValueError(f"motion must be one of {', '.join(MOTIONS)}, not {motion!r}")


"""The per-row linear system of the tracker and its float64 least-squares solution.

This module is the specification that :mod:`emulator.pose_solver` and
:mod:`hdl.pose_solver` are measured against, and the building block of the golden
tracker.

Model
-----
The rig (body) pose is world-from-body ``(R, p)``: ``X_world = R X_body + p``. A small
rig motion between two rows is ``Y = [Tx Ty Tz θx θy θz]`` in the body frame of the
earlier row: the new pose is ``(R exp([θ]×), p + R T)``. A static point at body
coordinates ``X`` then moves, to first order, by ``dX = −T + X × θ``.

Camera ``n`` is mounted with body-from-camera rotation ``R_n`` and centre ``c_n``. A
point seen at pixel ``(px, py)`` of the (distorted) image has undistorted normalized
coordinates ``p = (x, y)``, ``q = (x, y, 1)``, and depth ``Z`` (camera z). The tracker
measures the *shift* ``s``: the displacement in pixels, along the sensor row (pixel x),
of the point's image. With ``J`` the Jacobian of pixel position with respect to ``p``
(intrinsics times the Brown lens Jacobian) and ``v = Jᵀ e_x``,
``a = (v_x, v_y, −v·p)`` (note ``a·q = 0``), ``g = R_n a`` and ``w = 1/Z``::

    s = w · (a_T · T + a_C · θ) + a_R · θ
    a_T = −g,   a_C = g × c_n,   a_R = R_n (a × q).

So a row of the design matrix is ``[w a_T, a_R + w a_C]``: the nine coefficients
``(a_T, a_C, a_R)`` depend only on calibration and pixel position and are precomputed
(the hardware's coefficient store); the depth enters through one multiply by ``w``.
With a stereo pair, ``w = disparity / (f·baseline)``; the constant folds into ``a_T``
and ``a_C`` (``cue_scale``) so that the hardware multiplies by the disparity itself.
For a lens-distorted row (CVPR 2018's "virtual cameras"), each of the K segments of a
row is one equation at its own pixel position; ``v`` then follows the bent row.

Each equation is weighted by its confidence ``c``; the step is the weighted least-squares
solution of ``N Y = r`` with ``N = Σ c AᵀA`` and ``r = Σ c Aᵀ s``. The residual is in
pixels, the unit of the measurement noise (the papers multiply through by ``Z``, which
reweights equations by depth). Its conditioning is judged scale-free, on the Jacobi-
scaled ``N̂ = S N S`` with ``S = diag(N_ii^-1/2)`` (by van der Sluis' theorem within a
factor 6 of the best diagonal scaling).
"""

from dataclasses import dataclass

import numpy as np

from .checks import check_int
from .rotations import exp_so3

__all__ = ["UNKNOWNS", "COEFFICIENTS", "ShiftCoefficients", "shift_coefficients",
           "segment_columns", "design_rows", "normal_equations", "StepSolution",
           "solve_normal", "solve_step", "scaled_condition", "quat_multiply",
           "quat_to_matrix", "quat_from_rotvec", "quat_from_matrix", "integrate",
           "integrate_steps", "body_step", "project_shift", "ROOM", "rig_slots",
           "rig_coefficient_table", "room_depth", "SyntheticRows", "simulate_rows"]

#: The unknowns of a step, body frame (x right, y down, z forward): metres and radians.
UNKNOWNS = ("Tx", "Ty", "Tz", "θx", "θy", "θz")

#: Names of the nine stored coefficients, in table order.
COEFFICIENTS = ("aTx", "aTy", "aTz", "aCx", "aCy", "aCz", "aRx", "aRy", "aRz")

#: Condition number of the Jacobi-scaled normal matrix above which a row gives no step.
DEFAULT_MAX_CONDITION = 1e6


@dataclass(frozen=True)
class ShiftCoefficients:
    """Coefficients of shift equations ``s = w (a_T·T + a_C·θ) + a_R·θ``.

    Members
    -------
    a_t, a_c, a_r : ndarray (..., 3)
        Pixels per metre per unit of cue, pixels per radian per unit of cue, pixels per
        radian.
    """
    a_t: np.ndarray
    a_c: np.ndarray
    a_r: np.ndarray

    def table(self):
        """The nine coefficients as one array (..., 9), in :data:`COEFFICIENTS` order."""
        return np.concatenate([self.a_t, self.a_c, self.a_r], axis=-1)

    @classmethod
    def from_table(cls, table):
        table = np.asarray(table, dtype=float)
        if table.shape[-1] != 9:
            raise ValueError(f"table must have 9 coefficients on its last axis, not "
                             f"shape {table.shape}")
        return cls(table[..., 0:3], table[..., 3:6], table[..., 6:9])


def _lens_gradient(camera, xu, yu, axis):
    """``v = Jᵀ e_axis``: gradient of the pixel column (``axis`` 0) or row (1) with respect
    to undistorted (x, y)."""
    r2 = xu * xu + yu * yu
    factor = 1.0 + r2 * (camera.k1 + camera.k2 * r2)
    slope = camera.k1 + 2.0 * camera.k2 * r2  # d factor / d r²
    if axis == 0:
        return camera.fx * np.stack([factor + 2.0 * slope * xu * xu, 2.0 * slope * xu * yu],
                                    axis=-1)
    return camera.fy * np.stack([2.0 * slope * xu * yu, factor + 2.0 * slope * yu * yu],
                                axis=-1)


def shift_coefficients(camera, px, py, cue_scale=1.0, axis=0):
    """Coefficients of the shift equations at pixel positions ``(px, py)`` of ``camera``.

    Parameters
    ----------
    camera : golden.camera.Camera
        Needs ``fx, fy, cx, cy, k1, k2`` and the mounting ``R`` (body from camera), ``c``.
    px, py : array_like
        Pixel positions on the sensor (distorted image), broadcast together.
    cue_scale : float or array_like
        ``1/Z = cue_scale · cue``: 1 when the cue is the inverse depth in 1/m,
        ``1/(f·baseline)`` when it is a stereo disparity in pixels.
    axis : int
        0: the shift along the row (what the matcher measures); 1: the displacement
        across rows (current minus previous pixel row, for the reference row to read).
    """
    if axis not in (0, 1):
        raise ValueError(f"axis must be 0 or 1, not {axis!r}")
    px, py = np.broadcast_arrays(np.asarray(px, dtype=float), np.asarray(py, dtype=float))
    xu, yu = camera.pixel_to_normalized(px, py)
    v = _lens_gradient(camera, xu, yu, axis)
    a = np.stack([v[..., 0], v[..., 1], -(v[..., 0] * xu + v[..., 1] * yu)], axis=-1)
    q = np.stack([xu, yu, np.ones_like(xu)], axis=-1)
    rotation, centre = camera.R, camera.c
    g = a @ rotation.T
    scale = np.asarray(cue_scale, dtype=float)[..., None]
    return ShiftCoefficients(a_t=-g * scale, a_c=np.cross(g, centre) * scale,
                             a_r=np.cross(a, q) @ rotation.T)


def segment_columns(width, segments):
    """Pixel columns of the centres of ``segments`` equal parts of a row (one segment:
    the centre column)."""
    check_int("segments", segments, 1)
    return (np.arange(segments) + 0.5) * width / segments - 0.5


def design_rows(coefficients, cue):
    """Rows ``[w a_T, a_R + w a_C]`` (..., 6) of the design matrix for cues ``cue``."""
    w = np.asarray(cue, dtype=float)[..., None]
    return np.concatenate([w * coefficients.a_t, coefficients.a_r + w * coefficients.a_c],
                          axis=-1)


def normal_equations(rows, shifts, weights):
    """``N = Σ c AᵀA`` (..., 6, 6) and ``r = Σ c Aᵀ s`` (..., 6) over the equation axis.

    ``rows`` is (..., M, 6), ``shifts`` and ``weights`` (..., M).
    """
    rows = np.asarray(rows, dtype=float)
    weighted = rows * np.asarray(weights, dtype=float)[..., None]
    normal = np.einsum("...mi,...mj->...ij", weighted, rows)
    rhs = np.einsum("...mi,...m->...i", weighted, np.asarray(shifts, dtype=float))
    return normal, rhs


def scaled_condition(normal):
    """2-norm condition number of the Jacobi-scaled normal matrices (..., 6, 6); inf
    where a diagonal entry is not positive or the scaled matrix is singular."""
    normal = np.asarray(normal, dtype=float)
    diag = np.diagonal(normal, axis1=-2, axis2=-1)
    positive = np.all(diag > 0, axis=-1)
    scale = 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0))
    scaled = normal * scale[..., :, None] * scale[..., None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = np.linalg.svd(scaled, compute_uv=False)
        condition = sigma[..., 0] / sigma[..., -1]
    return np.where(positive & np.isfinite(condition), condition, np.inf)


@dataclass(frozen=True)
class StepSolution:
    """Solutions of per-row systems.

    Members
    -------
    step : ndarray (..., 6)
        ``[Tx Ty Tz θx θy θz]`` (m, rad); zero where ``ok`` is false.
    condition : ndarray (...)
        Condition number of the Jacobi-scaled normal matrix (inf if a column is empty).
    ok : ndarray of bool (...)
        The system was solved: every unknown is constrained and the condition is at most
        ``max_condition``.
    """
    step: np.ndarray
    condition: np.ndarray
    ok: np.ndarray


def solve_normal(normal, rhs, max_condition=DEFAULT_MAX_CONDITION):
    """Solve ``N Y = r`` for stacks of systems; ill-conditioned or empty ones give no
    step (``ok`` false, step zero)."""
    normal = np.asarray(normal, dtype=float)
    rhs = np.asarray(rhs, dtype=float)
    condition = scaled_condition(normal)
    ok = condition <= max_condition
    safe = np.where(ok[..., None, None], normal, np.eye(6))
    step = np.linalg.solve(safe, np.where(ok[..., None], rhs, 0.0)[..., None])[..., 0]
    return StepSolution(step=np.where(ok[..., None], step, 0.0), condition=condition, ok=ok)


def solve_step(coefficients, cue, shifts, weights, max_condition=DEFAULT_MAX_CONDITION):
    """The weighted least-squares step of rows of measurements (equation axis last)."""
    normal, rhs = normal_equations(design_rows(coefficients, cue), shifts, weights)
    return solve_normal(normal, rhs, max_condition)


# --- orientation and integration ------------------------------------------------------

def quat_multiply(a, b):
    """Hamilton products ``a ⊗ b`` of quaternions (..., 4) in (w, x, y, z) order."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    w = aw * bw - np.sum(av * bv, axis=-1, keepdims=True)
    v = aw * bv + bw * av + np.cross(av, bv)
    return np.concatenate([w, v], axis=-1)


def quat_to_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def quat_from_rotvec(rotvec):
    """Unit quaternions of rotation vectors (..., 3) (exponential map)."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    half = angle / 2
    # sin(θ/2)/θ, with its series near zero.
    sinc = np.where(angle < 1e-6, 0.5 - angle**2 / 48, np.sin(half) / np.where(angle > 0, angle, 1))
    return np.concatenate([np.cos(half), sinc * rotvec], axis=-1)


def integrate(quaternion, position, step):
    """Compose one body-frame step into a world-from-body pose.

    ``(q, p) → (q ⊗ exp(θ), p + R(q) T)``; the quaternion is renormalized.
    """
    step = np.asarray(step, dtype=float)
    position = np.asarray(position, dtype=float) + quat_to_matrix(quaternion) @ step[:3]
    q = quat_multiply(quaternion, quat_from_rotvec(step[3:]))
    return q / np.linalg.norm(q), position


def integrate_steps(quaternion, position, steps):
    """Poses after each of ``steps`` (n, 6): quaternions (n, 4) and positions (n, 3)."""
    steps = np.asarray(steps, dtype=float)
    quats, positions = np.empty((len(steps), 4)), np.empty((len(steps), 3))
    q, p = np.asarray(quaternion, dtype=float), np.asarray(position, dtype=float)
    for k, step in enumerate(steps):
        q, p = integrate(q, p, step)
        quats[k], positions[k] = q, p
    return quats, positions


# --- exact motion, for checks and synthetic measurements -------------------------------

def body_step(rotation_a, position_a, rotation_b, position_b):
    """The body-frame step ``[T θ]`` (..., 6) from pose a to pose b (exact: θ is the
    rotation vector of ``R_aᵀ R_b``)."""
    rotation_a, rotation_b = np.asarray(rotation_a, float), np.asarray(rotation_b, float)
    relative = np.swapaxes(rotation_a, -1, -2) @ rotation_b
    translation = np.einsum("...ji,...j->...i", rotation_a,
                            np.asarray(position_b, float) - np.asarray(position_a, float))
    return np.concatenate([translation, _log_so3(relative)], axis=-1)


def _log_so3(rotation):
    """Rotation vectors of rotation matrices (angles below π)."""
    trace = np.trace(rotation, axis1=-2, axis2=-1)
    angle = np.arccos(np.clip((trace - 1) / 2, -1.0, 1.0))
    axis = np.stack([rotation[..., 2, 1] - rotation[..., 1, 2],
                     rotation[..., 0, 2] - rotation[..., 2, 0],
                     rotation[..., 1, 0] - rotation[..., 0, 1]], axis=-1)
    scale = np.where(angle < 1e-6, 0.5 + angle**2 / 12,
                     angle / (2 * np.sin(np.where(angle < 1e-6, 1.0, angle))))
    return axis * scale[..., None]


def project_shift(camera, px, py, depth, step, axis=0):
    """Exact pixel-x (``axis`` 0) or pixel-y (1) displacement of the static point seen at
    ``(px, py)`` with camera depth ``depth`` when the rig makes the finite body-frame
    ``step`` (..., 6).

    The nonlinear counterpart of :func:`shift_coefficients`/:func:`design_rows`.
    """
    step = np.asarray(step, dtype=float)
    xu, yu = camera.pixel_to_normalized(np.asarray(px, float), np.asarray(py, float))
    depth = np.asarray(depth, dtype=float)
    point_cam = np.stack([xu * depth, yu * depth, depth], axis=-1)
    point_body = point_cam @ camera.R.T + camera.c
    moved_body = np.einsum("...ji,...j->...i", exp_so3(step[..., 3:]), point_body - step[..., :3])
    moved_cam = (moved_body - camera.c) @ camera.R
    new = camera.project(moved_cam)[..., axis]
    return new - np.broadcast_to(np.asarray((px, py)[axis], float), new.shape)


# --- synthetic row sequences ------------------------------------------------------------

#: The box room (world metres, z up) whose walls give the depths of synthetic rows.
ROOM = ((-3.0, -3.0, 0.0), (3.0, 3.0, 3.0))


def rig_slots(rig):
    """(camera index, pixel column) of every measurement slot of a rig: ``row_points``
    segments per camera, camera-major."""
    return [(n, float(px)) for n, cam in enumerate(rig.cameras)
            for px in segment_columns(cam.width, rig.row_points)]


def rig_coefficient_table(rig, cue_scale):
    """Coefficient table (slots, rows, 9) of every slot and row of ``rig`` (cameras must
    share the height); ``cue_scale`` per camera (or one) folds the depth cue's unit."""
    heights = {cam.height for cam in rig.cameras}
    if len(heights) != 1:
        raise ValueError(f"rig cameras must share one height, not {sorted(heights)}")
    scales = np.broadcast_to(np.asarray(cue_scale, dtype=float), (len(rig.cameras),))
    rows = np.arange(heights.pop(), dtype=float)
    return np.stack([shift_coefficients(rig.cameras[n], px, rows, scales[n]).table()
                     for n, px in rig_slots(rig)])


def room_depth(camera, rotation, position, px, py, room=ROOM):
    """Camera depth of the room wall seen at pixels ``(px, py)`` (...) with the rig at
    world poses ``rotation`` (..., 3, 3), ``position`` (..., 3)."""
    xu, yu = camera.pixel_to_normalized(np.asarray(px, float), np.asarray(py, float))
    ray_body = np.stack([xu, yu, np.ones_like(xu)], axis=-1) @ camera.R.T
    ray = np.einsum("...ij,...j->...i", rotation, ray_body)
    origin = np.asarray(position) + np.einsum("...ij,j->...i", rotation, camera.c)
    lo, hi = (np.asarray(v, dtype=float) for v in room)
    with np.errstate(divide="ignore", invalid="ignore"):
        exits = np.where(ray > 0, (hi - origin) / ray,
                         np.where(ray < 0, (lo - origin) / ray, np.inf))
    depth = np.min(exits, axis=-1)
    if not np.all(np.isfinite(depth) & (depth > 0)):
        raise ValueError("the rig left the room: a ray has no wall in front of it")
    return depth


@dataclass(frozen=True)
class SyntheticRows:
    """Per-row measurements of a rig moving through the room, float64.

    Members
    -------
    table : ndarray (slots, rows, 9)
        Coefficient table (with the cue scale folded in).
    slot, shift, cue, weight : ndarray (n, slots)
        Every slot measures in every row: shift (pixels, with noise), depth cue
        (``1/Z = cue_scale · cue``), confidence weight.
    row, time : ndarray (n,)
        Row index in the frame and time (s) of each row.
    true_step : ndarray (n, 6)
        The exact body-frame step from the previous row to this one.
    start : (ndarray (4,), ndarray (3,))
        Quaternion and position before the first row.
    """
    table: np.ndarray
    slot: np.ndarray
    shift: np.ndarray
    cue: np.ndarray
    weight: np.ndarray
    row: np.ndarray
    time: np.ndarray
    true_step: np.ndarray
    start: tuple


def quat_from_matrix(rotation):
    """Unit quaternion (w, x, y, z) of one rotation matrix (Shepperd's method: from the
    largest of w, x, y, z, so no component is recovered by a small division)."""
    m = np.asarray(rotation, dtype=float)
    trace = np.trace(m)
    candidates = [trace, m[0, 0], m[1, 1], m[2, 2]]
    k = int(np.argmax(candidates))
    if k == 0:
        w = np.sqrt(1 + trace) / 2
        q = [w, (m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w),
             (m[1, 0] - m[0, 1]) / (4 * w)]
    else:
        i, j, l = k - 1, k % 3, (k + 1) % 3
        s = np.sqrt(1 + m[i, i] - m[j, j] - m[l, l]) * 2
        q = [0.0] * 4
        q[0] = (m[l, j] - m[j, l]) / s
        q[1 + i] = s / 4
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + l] = (m[l, i] + m[i, l]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def simulate_rows(rig, trajectory, duration, *, cue_scale, rng, shift_noise=0.0,
                  weight_range=(0.5, 2.0), zero_weight_fraction=0.0, room=ROOM):
    """Every row of ``rig`` over ``duration`` seconds of ``trajectory``.

    Each slot's shift is the exact (nonlinear) pixel-x displacement of the room point it
    sees, over the step from the previous row's time, plus Gaussian noise of
    ``shift_noise`` pixels; the cue is the exact ``1/(cue_scale·Z)``; weights are
    uniform in ``weight_range`` and zero with probability ``zero_weight_fraction``.
    Cameras are assumed synchronized (row y of every camera at the same time).
    """
    cam0 = rig.cameras[0]
    count = int(round(duration / cam0.t_r))
    frame_rows = cam0.height
    index = np.arange(count)
    rows = index % frame_rows
    times = cam0.trigger_offset + (index // frame_rows) / cam0.fps + rows * cam0.t_r
    previous = np.concatenate([[times[0] - cam0.t_r], times[:-1]])
    rot_a, pos_a = trajectory.pose(previous)
    rot_b, pos_b = trajectory.pose(times)
    steps = body_step(rot_a, pos_a, rot_b, pos_b)
    scales = np.broadcast_to(np.asarray(cue_scale, dtype=float), (len(rig.cameras),))
    slots = rig_slots(rig)
    shift = np.empty((count, len(slots)))
    cue = np.empty((count, len(slots)))
    for k, (n, px) in enumerate(slots):
        cam = rig.cameras[n]
        depth = room_depth(cam, rot_a, pos_a, np.full(count, px), rows.astype(float), room)
        shift[:, k] = project_shift(cam, np.full(count, px), rows.astype(float), depth, steps)
        cue[:, k] = 1.0 / (scales[n] * depth)
    shift += rng.normal(0.0, shift_noise, shift.shape) if shift_noise else 0.0
    weight = rng.uniform(*weight_range, shift.shape)
    weight[rng.random(shift.shape) < zero_weight_fraction] = 0.0
    start = (quat_from_matrix(rot_a[0]), pos_a[0])
    return SyntheticRows(table=rig_coefficient_table(rig, scales), slot=np.broadcast_to(
        np.arange(len(slots)), shift.shape).copy(), shift=shift, cue=cue, weight=weight,
        row=rows, time=times, true_step=steps, start=start)

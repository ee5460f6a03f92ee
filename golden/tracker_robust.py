"""Robust pieces of a slot's solve (issue 18): measurements weighted by their depth
sensitivity, a consistency test between camera groups, and the partial step of a slot
that determines only some directions.

* **Depth sensitivity.** A segment's predicted shift depends on the inverse depth ``w``
  through the translation part of its design row only (``a_T = w b_T``), so an error
  ``σ_w`` in ``w`` moves it by ``|b_T · T̂| σ_w`` at the forecast translation ``T̂``.
  Stereo depth with a disparity error of ``σ_d`` pixels has ``σ_w = σ_d / (f B)``, the
  same at every depth: segments whose shifts are dominated by translation (near
  surfaces, fast translation) carry that error into the solution. Their weight is
  ``1 / (1 + (σ_shift / shift_sigma)²)``.
* **Consistency between groups.** A wrong depth map of one stereo pair builds a coherent
  but shifted reference: all that pair's measurements are biased the same way, each one
  passes the Huber test, and the least-squares solution follows them. Each group is
  judged against the solution of the *other* groups; the group whose mean residual is
  most standard errors off is dropped if that exceeds ``k``.
* **Partial step.** A system beyond ``max_condition`` is still well determined in some
  directions; the step is solved in the span of the eigen-directions (unknowns scaled
  by a typical slot's information) within ``max_condition`` of the largest and is zero
  in the others (the forecast stands there).
"""

import numpy as np

from .pose_lsq import normal_equations, scaled_condition

__all__ = ["depth_weights", "group_misfits", "GroupConsistency", "reference_condition",
           "partial_solve"]


def depth_weights(unit_translation, translation, inverse_depth_sigma, shift_sigma):
    """Weights (M,) of measurements whose design rows at unit inverse depth have the
    translation parts ``unit_translation`` (M, 3), at the forecast translation
    ``translation`` (3,), with inverse-depth errors ``inverse_depth_sigma`` (M,) 1/m."""
    moved = np.abs(np.asarray(unit_translation) @ np.asarray(translation))
    ratio = moved * np.asarray(inverse_depth_sigma) / shift_sigma
    return 1.0 / (1.0 + ratio**2)


def group_misfits(design, residual, weight, group, max_condition, essential=0.1,
                  minimum=3):
    """Signed weighted mean misfit (pixels) of each group's measurements against the
    solution of the other groups: ``{group: misfit}`` for the groups that can be judged.

    Parameters
    ----------
    design : (M, 6)
    residual : (M,) innovations (shift minus the forecast's prediction)
    weight : (M,) confidences (0: unused)
    group : (M,) int, group of each measurement
    max_condition : float
        A leave-one-out system beyond this condition is not a reference.
    essential : float
        Nor is one that keeps less than this share of an unknown's information (the
        Jacobi-scaled condition does not see a direction only this group measures).
    minimum : int
        Fewest groups with measurements for any group to be judged.
    """
    used = weight > 0
    groups = np.unique(group[used])
    if len(groups) < max(minimum, 3):
        return {}
    full, _ = normal_equations(design[used], residual[used], weight[used])
    misfits = {}
    for g in groups:
        mine = used & (group == g)
        others = used & ~mine
        normal, rhs = normal_equations(design[others], residual[others], weight[others])
        if (not scaled_condition(normal) <= max_condition**2
                or np.any(np.diag(normal) < essential * np.diag(full))):
            continue
        misfit = residual[mine] - design[mine] @ np.linalg.solve(normal, rhs)
        misfits[int(g)] = float(np.sum(weight[mine] * misfit) / np.sum(weight[mine]))
    return misfits


class GroupConsistency:
    """Persistent disagreement of camera groups: an exponential average of each group's
    leave-one-out misfit (:func:`group_misfits`) over the slots. Random misfits of a
    weakly determined leave-one-out solution average out; a coherent bias (one pair's
    wrong depth map) does not. The group whose average exceeds ``bound`` pixels by the
    most is dropped from the slot.

    Parameters
    ----------
    groups : int
        Number of group ids (0 … groups − 1).
    bound : float
        Largest average misfit (pixels) of a consistent group.
    smoothing : float
        Weight of a new slot in the average.
    essential : float
        Share of every unknown's information the other groups must keep
        (:func:`group_misfits`).
    minimum : int
        Fewest groups in a slot for the test.
    """

    def __init__(self, groups, bound, smoothing, essential=0.1, minimum=3):
        self.average = np.zeros(groups)
        self.bound, self.smoothing = float(bound), float(smoothing)
        self.essential, self.minimum = float(essential), minimum

    def judge(self, design, residual, weight, group, max_condition):
        """Update the averages with this slot's misfits; the group to drop (one judged in
        this slot: a group the others cannot stand in for is never dropped), or None."""
        misfits = group_misfits(design, residual, weight, group, max_condition,
                                self.essential, self.minimum)
        for g, misfit in misfits.items():
            self.average[g] += self.smoothing * (misfit - self.average[g])
        judged = np.array(sorted(misfits), dtype=int)
        if not len(judged) or np.abs(self.average[judged]).max() <= self.bound:
            return None
        return int(judged[np.argmax(np.abs(self.average[judged]))])


def _reference_eigen(normal, reference):
    """Eigen-decomposition of ``normal`` with the unknowns scaled by the diagonal of
    ``reference``: ``(values, vectors, d)`` with ``d`` the scale, or None when
    ``reference`` has an empty diagonal entry."""
    diagonal = np.diag(reference)
    if not np.all(diagonal > 0):
        return None
    d = 1.0 / np.sqrt(diagonal)
    values, vectors = np.linalg.eigh(normal * d[:, None] * d[None, :])
    return values, vectors, d


def reference_condition(normal, reference):
    """Condition number (of the normal matrix, i.e. squared) of ``normal`` with the
    unknowns scaled by the diagonal of ``reference`` (a typical slot's information); inf
    when an unknown has no information.

    The Jacobi-scaled condition (:func:`golden.pose_lsq.scaled_condition`) scales each
    unknown by the system's *own* diagonal: an unknown that the slot does not measure at
    all (a column of rounding noise, 1e-14 px/m: the rolled side pairs of the 4-pair rig
    see nothing of Tz) scales to unit length and looks as determined as the others; on
    the 4-pair rig such slots passed at condition 62 and stepped Tz by 2.6e14 m.
    Scaled by a typical slot's information instead, that unknown's eigenvalue is ~1e-32
    of the others'.
    """
    eigen = _reference_eigen(normal, reference)
    if eigen is None or not np.any(np.diag(normal) > 0):
        return np.inf
    values = eigen[0]
    return float(values.max() / values.min()) if values.min() > 0 else np.inf


def partial_solve(normal, rhs, max_condition, reference=None):
    """Step and the information it uses, in the directions a system determines.

    The unknowns are scaled by the diagonal of ``reference`` (the information of a
    typical slot; the system's own diagonal if None) and the step is solved in the span of
    the scaled eigen-directions within ``max_condition`` of the best one. Scaling by the
    system's own diagonal would make a barely measured unknown look as determined as the
    others (a tiny column scales to unit length) and give it a huge step.

    Returns ``(step, normal_used)`` with ``normal_used`` the normal matrix restricted to
    the kept directions (for the information-weighted gains), or ``(None, None)`` when
    no direction is determined.
    """
    eigen = _reference_eigen(normal, normal if reference is None else reference)
    if eigen is None or not np.any(np.diag(normal) > 0):
        return None, None
    values, vectors, d = eigen
    keep = values >= values.max() / max_condition**2
    v, lam = vectors[:, keep], values[keep]
    step = d * (v @ ((v.T @ (d * rhs)) / lam))
    return step, ((v * lam) @ v.T) / d[:, None] / d[None, :]

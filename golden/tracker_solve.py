"""The robust solve of one row slot of :mod:`golden.tracker` (issue 18's measurement
rules; ``docs/tracker.md``).

Per slot: Huber verdicts of the innovations against the forecast and the channels'
robust scales (after a loss, with no forecast worth judging against: reweighted solves
about the slot's own solution, the scale shrinking from the widened window's size),
the depth-sensitivity weights and the consistency test between camera groups of
:mod:`golden.tracker_robust`, then the conditioned solve, or the partial step of a slot
that determines only some directions (``boundary="partial"``).
"""

from types import SimpleNamespace

import numpy as np

from .depth import stereo_pairs
from .pose_lsq import normal_equations, scaled_condition, solve_normal
from .temporal_filter import RobustScale, huber_weight
from .tracker_robust import GroupConsistency, depth_weights, partial_solve, reference_condition

__all__ = ["SlotSolver", "camera_groups", "RECOVERY_SCALES", "TYPICAL_SMOOTHING"]

#: Weight of each new solved system in the running "typical information" that scales
#: the filter gains (about the last 50 solved slots).
TYPICAL_SMOOTHING = 0.02

#: Robust scales (pixels) of the reweighted solves of a re-acquisition after a loss,
#: from a gross start to the matcher's precision.
RECOVERY_SCALES = (8.0, 4.0, 2.0, 1.0, 0.5)


def camera_groups(rig, params, oracle):
    """Consistency group of every camera (its stereo pair, else itself) and its
    inverse-depth error (1/m): ``disparity_sigma / (f · baseline)`` with the baseline to
    the nearest camera, 0 for the oracle."""
    cams = rig.cameras
    group = np.arange(len(cams))
    for k, (left, right, _) in enumerate(stereo_pairs(rig)):
        group[[left, right]] = len(cams) + k
    centres = np.array([c.c for c in cams])
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    nearest = gaps.min(axis=1) if len(cams) > 1 else np.full(1, np.inf)
    sigma = params.disparity_sigma / (np.array([c.fx for c in cams]) * nearest)
    return group, (np.zeros(len(cams)) if oracle else sigma)


class SlotSolver:
    """Robust scales, consistency averages and typical information across slots.

    Parameters
    ----------
    rig : golden.rig.Rig
    params : golden.tracker_params.TrackerParams
    oracle : bool
        The depth is the simulator's (no depth error to weigh).
    """

    def __init__(self, rig, params, oracle):
        self.params, self.cameras = params, len(rig.cameras)
        self.scale = RobustScale(self.cameras * params.segments, initial=params.scale_initial,
                                 floor=params.scale_floor, smoothing=params.scale_smoothing,
                                 k=params.huber_k, ceiling=params.scale_ceiling)
        self.group, self.inverse_depth_sigma = camera_groups(rig, params, oracle)
        self.consistency = GroupConsistency(int(self.group.max()) + 1,
                                            params.consistency_k * params.shift_sigma,
                                            params.consistency_smoothing,
                                            params.consistency_share)
        self.typical = None
        #: Unit-weight information of every segment with a design row in the current
        #: block (:meth:`set_geometry`): the reference scaling until a typical exists.
        self.geometry = None

    def set_geometry(self, design):
        """The block's design rows (M, 6), matched or not: what the cameras could
        measure. Before the first solved slot it stands in for the typical information
        when judging which unknowns a slot determines (only its diagonal counts)."""
        finite = np.all(np.isfinite(design), axis=1)
        self.geometry, _ = normal_equations(design[finite], np.zeros(finite.sum()),
                                            np.ones(finite.sum()))

    @property
    def reference(self):
        """The information the unknowns are scaled by: the typical slot's, else the
        block's geometry."""
        return self.typical if self.typical is not None else self.geometry

    def solve(self, residual, design, ratio, camera, channel, unit, translation, recovering,
              usable=None):
        """The slot's step from its measurements (innovations ``residual`` (M,) at the
        forecast, design rows (M, 6), peak ratios, cameras, channels, depth gains ``unit``
        (M, 3), forecast ``translation``); ``recovering``: no forecast to judge against;
        ``usable`` (M,) bool: the segments that could measure, matched or not (a usable
        reference and depth; None: every segment with a finite design row).

        Returns a namespace: ``step`` (None: no step), ``normal`` (the information it
        used), ``condition``, ``partial``, ``used`` (confident measurements), ``judged``,
        ``outliers``, ``confidence`` and ``outlier`` (M,), ``camera_confidence`` (best per
        camera, NaN: no row), ``dropped`` group (-1: none), ``beyond`` (a step refused
        because it moves some segment further than the search window reaches: the
        matches cannot have measured it), ``determinable`` (:meth:`determinable`: had
        every usable segment matched, the slot could have stepped).
        """
        p = self.params
        m = len(residual)
        solved = SimpleNamespace(step=None, normal=None, condition=np.nan, partial=False,
                                 dropped=-1, beyond=False, confidence=np.zeros(m),
                                 outlier=np.zeros(m, dtype=bool),
                                 camera_confidence=np.full(self.cameras, np.nan))
        finite = np.all(np.isfinite(design), axis=1)
        solved.determinable = self.determinable(
            design, camera, finite if usable is None else finite & usable)
        ok = np.isfinite(residual) & finite & (ratio > 0)
        confidence, outlier = solved.confidence, solved.outlier
        weight = np.ones(np.count_nonzero(ok))
        if not recovering:
            x, weight = self.scale.judge(channel[ok], residual[ok])
            outlier[ok] = np.abs(x) > p.huber_k
        confidence[ok] = ratio[ok] * weight
        best = np.zeros(self.cameras)
        np.maximum.at(best, camera, confidence)
        present = np.unique(camera)
        solved.camera_confidence[present] = best[present]
        cameras = len(np.unique(camera[confidence > 0]))
        if m and confidence.max() >= p.min_confidence and cameras >= p.min_cameras:
            self._robust(solved, ok, residual, design, camera, unit, translation, recovering)
        solved.used, solved.judged = int(np.count_nonzero(confidence)), int(ok.sum())
        solved.outliers = int(outlier.sum())
        return solved

    def determinable(self, design, camera, usable):
        """Could the slot determine the motion if every ``usable`` segment matched: the
        unit-weight system of their design rows from at least ``min_cameras`` cameras
        within ``max_condition`` (both scalings, as :meth:`_system`). A slot that could not
        (a readout gap, frame-boundary rows without a reference: the rig's timing, not the
        scene or the estimate) tells nothing about whether tracking holds."""
        p = self.params
        if len(np.unique(camera[usable])) < p.min_cameras:
            return False
        normal, _ = normal_equations(design[usable], np.zeros(usable.sum()),
                                     np.ones(usable.sum()))
        return bool(self._condition(normal) <= p.max_condition**2)

    def _condition(self, normal):
        """Squared condition of ``normal``: the larger of the Jacobi-scaled one and the
        one scaled by :attr:`reference`."""
        condition = scaled_condition(normal)
        if self.reference is not None:
            condition = max(condition, reference_condition(normal, self.reference))
        return condition

    def _robust(self, solved, ok, residual, design, camera, unit, translation, recovering):
        p = self.params
        confidence, outlier = solved.confidence, solved.outlier
        confidence[ok] *= depth_weights(unit[ok], translation,
                                        self.inverse_depth_sigma[camera[ok]], p.shift_sigma)
        solved.cleaned = cleaned = np.where(outlier | ~ok, 0.0, residual)  # outlier -> forecast
        if p.consistency_k > 0 and (recovering or p.consistency_always):
            group = self.group[camera]
            bad = self.consistency.judge(design[ok], cleaned[ok], confidence[ok], group[ok],
                                         p.max_condition)
            if bad is not None:
                confidence[group == bad] = 0.0
                solved.dropped = bad
        self._system(solved, design[ok], cleaned[ok], confidence[ok])
        if recovering:
            base = confidence[ok]
            for size in RECOVERY_SCALES:
                if solved.step is None:
                    break
                x = (cleaned[ok] - design[ok] @ solved.step) / size
                outlier[ok] = np.abs(x) > p.huber_k
                confidence[ok] = base * huber_weight(x, p.huber_k)
                self._system(solved, design[ok], cleaned[ok], confidence[ok])
            if outlier.sum() > p.lost_outlier_fraction * ok.sum():
                solved.step = None      # most measurements disagree: not re-acquired
            elif solved.partial:
                # a re-acquisition resets the motion filter to this one slot's solution:
                # it must determine every direction (a partial step keeps the forecast,
                # i.e. the motion before the loss, in the others, and its kept but weakly
                # determined directions took 0.3–0.4 rad per frame on the 4-pair rig)
                solved.step, solved.normal, solved.partial = None, None, False
        reach = p.recovery_window if recovering else p.window
        if solved.step is not None and np.abs(design[ok] @ solved.step).max() > reach:
            solved.step = None          # shifts beyond the search: not what was matched
            solved.beyond = True

    def _system(self, solved, design, residual, confidence):
        """Solve the weighted system into ``solved``: the full step if it is well
        conditioned, else (``boundary="partial"``) the step in its determined directions.

        Well conditioned means both Jacobi-scaled (the unknowns against each other within
        the slot) and scaled by the typical information (once there is one): an unknown
        the slot barely measures is not determined however its own column scales
        (:func:`golden.tracker_robust.reference_condition`; before the first solved slot,
        scaled by the block's geometry). ``condition`` reports the larger of the two."""
        p = self.params
        normal, rhs = normal_equations(design, residual, confidence)
        solution = solve_normal(normal, rhs, p.max_condition**2)
        condition = self._condition(normal)
        solved.condition = float(np.sqrt(condition))
        solved.step, solved.normal, solved.partial = None, None, False
        if solution.ok and condition <= p.max_condition**2:
            solved.step, solved.normal = solution.step, normal
            self.typical = normal if self.typical is None else \
                (1 - TYPICAL_SMOOTHING) * self.typical + TYPICAL_SMOOTHING * normal
        elif p.boundary == "partial":
            solved.step, solved.normal = partial_solve(normal, rhs, p.max_condition,
                                                       self.reference)
            solved.partial = solved.step is not None

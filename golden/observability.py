"""Which motions a rig can see: rank and condition of its stacked per-row constraints.

A row measures image shifts *along the row* only. For a point at normalized position
(x, y) and depth Z in camera n, a shift s along the unit row tangent u (in undistorted
normalized coordinates) constrains the small rig motion Y = [Tx Ty Tz θx θy θz] by

    s·Z = [u_x, u_y, −(u_x x + u_y y)] · R_nᵀ · Q(X) · Y,
    Q(X) = [[−1,0,0, 0,−z,y], [0,−1,0, z,0,−x], [0,0,−1, −y,x,0]]

with X = (x, y, z) the point in the rig frame (CVPR 2018 supp. eq. 3; at the principal
point this is the paper's ρ1(ⁿT_cl)·Q_n). Each camera contributes ``row_points`` such
equations per row (one per segment of the row). Stacking them over the cameras for the
same row index gives the per-row matrix A that the tracker solves; a rig whose A is
rank deficient, or so ill-conditioned that a direction is lost in noise, cannot track.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["UNKNOWNS", "MAX_CONDITION", "Observability", "row_constraints", "analyze"]

#: The unknowns, in the rig frame (x right, y down, z forward).
UNKNOWNS = ("Tx", "Ty", "Tz", "θx", "θy", "θz")

#: A direction whose singular value is below σ_max / MAX_CONDITION counts as unobservable.
MAX_CONDITION = 1e6

#: Row positions (fractions of the image height) at which the stack is evaluated.
ROW_FRACTIONS = np.linspace(0.0, 1.0, 9)


def _q_matrix(points):
    """Q(X) for points (N, 3) -> (N, 3, 6)."""
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    zero, one = np.zeros_like(x), np.ones_like(x)
    return np.stack([
        np.stack([-one, zero, zero, zero, -z, y], axis=-1),
        np.stack([zero, -one, zero, z, zero, -x], axis=-1),
        np.stack([zero, zero, -one, -y, x, zero], axis=-1),
    ], axis=1)


def row_constraints(camera, row, points, depth):
    """Constraint rows (points, 6) of ``points`` equally spaced segments of one row of
    ``camera``, for scene points at camera depth ``depth`` (m)."""
    px = (np.arange(points) + 0.5) * camera.width / points - 0.5
    py = np.full_like(px, float(row))
    xu, yu = camera.pixel_to_normalized(px, py)
    ahead_x, ahead_y = camera.pixel_to_normalized(px + 0.5, py)
    behind_x, behind_y = camera.pixel_to_normalized(px - 0.5, py)
    tangent = np.stack([ahead_x - behind_x, ahead_y - behind_y], axis=-1)
    tangent /= np.linalg.norm(tangent, axis=-1, keepdims=True)
    a_cam = np.stack([tangent[:, 0], tangent[:, 1],
                      -(tangent[:, 0] * xu + tangent[:, 1] * yu)], axis=-1)
    points_rig = (camera.R @ (depth * np.stack([xu, yu, np.ones_like(xu)], axis=0))).T + camera.c
    a_rig = a_cam @ camera.R.T
    return np.einsum("ni,nij->nj", a_rig, _q_matrix(points_rig))


def describe_direction(vector):
    """A readable name for a direction of Y, e.g. ``Ty`` or ``0.71·Tx − 0.71·θz``."""
    vector = vector / np.linalg.norm(vector)
    vector = vector * np.sign(vector[np.argmax(np.abs(vector))])
    if np.max(np.abs(vector)) > 0.99:
        return UNKNOWNS[int(np.argmax(np.abs(vector)))]
    order = np.argsort(-np.abs(vector))
    terms = [(vector[i], UNKNOWNS[i]) for i in order if abs(vector[i]) >= 0.05]
    text = f"{terms[0][0]:.2f}·{terms[0][1]}"
    for value, name in terms[1:]:
        text += f" {'+' if value > 0 else '−'} {abs(value):.2f}·{name}"
    return text


def describe_subspace(basis):
    """Names for an unobservable subspace (rows of ``basis`` orthonormal): first every
    single unknown that lies in it (e.g. ``Ty``), then combinations for what remains."""
    if not len(basis):
        return ()
    inside = np.linalg.norm(basis, axis=0)  # length of each unknown's axis in the subspace
    pure = [i for i in range(6) if inside[i] > 0.99]
    rest = basis.copy()
    rest[:, pure] = 0  # the subspace without the pure axes
    _, sigma, vt = np.linalg.svd(rest)
    extra = vt[:len(basis) - len(pure)][sigma[:len(basis) - len(pure)] > 1e-6]
    return tuple(UNKNOWNS[i] for i in pure) + tuple(describe_direction(v) for v in extra)


@dataclass(frozen=True)
class Observability:
    """Worst case over the evaluated rows of the per-row stacked constraints.

    Members
    -------
    rank : int
        Smallest numerical rank (of 6).
    condition : float
        Largest condition number σ_max/σ_min (inf when rank deficient).
    worst_row_fraction : float
        Row position (fraction of the height) where the condition is worst.
    unobservable : tuple of str
        Named directions with σ < σ_max / MAX_CONDITION at the worst row.
    """
    rank: int
    condition: float
    worst_row_fraction: float
    unobservable: tuple

    @property
    def complete(self):
        return not self.unobservable

    def to_dict(self):
        finite = self.condition if np.isfinite(self.condition) else None  # JSON has no inf
        return {"rank": self.rank, "condition": finite,
                "worst_row_fraction": self.worst_row_fraction,
                "unobservable": list(self.unobservable)}


def analyze(cameras, row_points=1, depth=2.0):
    """Rank and condition of the stacked per-row constraints of ``cameras``.

    Every camera reads the same row position at once (a synchronized rig); the stack is
    evaluated at :data:`ROW_FRACTIONS` of each camera's height, with all scene points at
    ``depth`` metres (rank does not depend on it for generic rigs; the condition number
    does, through the unit mix of metres and radians).
    """
    worst = None
    for fraction in ROW_FRACTIONS:
        a = np.concatenate([row_constraints(cam, round(fraction * (cam.height - 1)),
                                            row_points, depth) for cam in cameras])
        _, sigma, vt = np.linalg.svd(a, full_matrices=True)
        sigma = np.concatenate([sigma, np.zeros(6 - len(sigma))])
        with np.errstate(divide="ignore"):
            condition = sigma[0] / sigma[-1] if sigma[-1] > 0 else np.inf
        if worst is None or condition > worst[0]:
            worst = (condition, fraction, sigma, vt)
    condition, fraction, sigma, vt = worst
    rank = int(np.sum(sigma > sigma[0] * 1e-12))
    lost = describe_subspace(vt[sigma < sigma[0] / MAX_CONDITION])
    return Observability(rank=rank, condition=float(condition),
                         worst_row_fraction=float(fraction), unobservable=lost)

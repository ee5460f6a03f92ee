"""Bit-accurate model of the measurement router: row-descriptor lanes → pose solver.

The row-descriptor lanes (:mod:`emulator.row_descriptor`) give, per row, K segment
measurements of every camera's temporal lane (current row against the same row of the
previous frame) and of every stereo pair's lane (camera A's row against camera B's).
The pose solver (:mod:`emulator.pose_solver`) takes one transfer per equation:
``slot, row, time, shift, cue, conf, last`` (``hdl/pose_accumulator.py``). This module
is the glue, integers only, every narrowing through :func:`hdl.fixed.resize`.

Decisions (each one is a choice the HDL router must copy):

* **Slot.** ``camera · K + segment``: camera-major, as :func:`golden.pose_lsq.rig_slots`
  orders the coefficient store (``rig.row_points`` must equal the lanes' K).
* **Shift.** ``shift + subpixel`` (exact sum of the lane's ``SQ(s, 0)`` and
  ``SQ(1, f)``), rounded half-even and saturated into the solver's ``shift_fmt``. Same
  sign: the lane's ``cur[x] ≈ ref[x − d]`` is the image displacement from the reference
  row to the current one, which is the solver's shift.
* **Cue.** The disparity of the camera's stereo pair in the same (frame, row), from
  the stereo segment ``k · K_s // K`` for temporal segment ``k`` (K_s stereo segments,
  K temporal ones: equal parts of the row, a constant table in hardware; with the
  default K_s = 1 one disparity serves the whole row): ``shift + subpixel`` of the
  stereo lane, half-even, saturated into ``cue_fmt``. Both cameras of a pair use it
  (camera B sees the same points ``d`` pixels further left; the depth difference is
  neglected), so the coefficient table is built with ``cue_scale = 1/(f·b)``. Every
  camera must belong to exactly one pair: the depth-map cue of the radial rigs is not
  modelled.
* **Confidence.** The temporal lane's peak ratio, half-even and saturated into
  ``conf_fmt``. It is set to zero (the measurement adds nothing to the normal
  equations) when the temporal segment hit the shift-window edge (its shift is a
  bound, not a measurement), when the pair has no stereo measurement of this row and
  segment, or when that stereo measurement is unusable (zero confidence, window edge,
  or disparity ≤ 0, i.e. no finite depth). The lanes already give zero confidence to
  textureless, bad and reference-less segments.
* **Rows.** Every temporal measurement of a row is sent, zero-weight ones included,
  in slot order, ``last`` on the final one: the stream stays one transfer per
  (camera, segment) and never exceeds ``slots`` (no OVERRUN). A row none of whose
  measurements carries weight reaches the solver as an EMPTY row: it gets a flagged
  record with no step. Cameras without this row contribute no transfers; a row no
  camera delivered produces nothing.
* **Time.** ``t_first`` of the lowest-numbered camera present, masked to the solver's
  ``time_bits``.
"""

from dataclasses import dataclass, field

import numpy as np

from hdl.fixed import Overflow, Rounding, add, resize
from hdl.pose_params import PoseSolverParams
from hdl.row_descriptor_params import RowDescriptorParams

from .pose_solver import PoseRows

__all__ = ["RouterParams", "measured_shifts", "route_row", "route", "pose_rows"]


@dataclass(frozen=True, kw_only=True)
class RouterParams:
    """What the router needs: the two blocks' parameters and the stereo pairing.

    Parameters
    ----------
    cameras : int
        Number of cameras (temporal lanes); slots are ``cameras × segments``.
    pairs : tuple of (int, int)
        Stereo pairs ``(A, B)`` in stereo-lane order (A: the camera whose row is the
        lane's current row). Every camera belongs to exactly one pair.
    temporal, stereo : RowDescriptorParams
        The temporal and the stereo lanes' parameters (segments, shift and sub-pixel
        formats).
    solver : PoseSolverParams
        The solver's parameters (``slots``, input formats, ``time_bits``).

    Raises
    ------
    TypeError, ValueError
        Naming the parameter.
    """
    cameras: int
    pairs: tuple
    temporal: RowDescriptorParams
    stereo: RowDescriptorParams
    solver: PoseSolverParams
    pair_of: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if isinstance(self.cameras, bool) or not isinstance(self.cameras, int):
            raise TypeError(f"cameras must be an integer, not {self.cameras!r}")
        if self.cameras < 1:
            raise ValueError(f"cameras must be a positive integer, not {self.cameras}")
        for name in ("temporal", "stereo"):
            if not isinstance(getattr(self, name), RowDescriptorParams):
                raise TypeError(f"{name} must be a RowDescriptorParams, not "
                                f"{getattr(self, name)!r}")
        if not isinstance(self.solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {self.solver!r}")
        slots = self.cameras * self.temporal.segments
        if self.solver.slots != slots:
            raise ValueError(f"solver.slots must be cameras × segments = {slots}, not "
                             f"{self.solver.slots}")
        pair_of = {}
        for index, pair in enumerate(self.pairs):
            if len(pair) != 2 or pair[0] == pair[1]:
                raise ValueError(f"pairs[{index}] must be two different cameras, not {pair!r}")
            for camera in pair:
                if not 0 <= camera < self.cameras:
                    raise ValueError(f"pairs[{index}] names camera {camera}, outside "
                                     f"0 … {self.cameras - 1}")
                if camera in pair_of:
                    raise ValueError(f"pairs: camera {camera} is in more than one pair")
                pair_of[camera] = pair[0]
        missing = sorted(set(range(self.cameras)) - set(pair_of))
        if missing:
            raise ValueError(f"pairs must give every camera a stereo pair; cameras "
                             f"{missing} have none")
        object.__setattr__(self, "pair_of", pair_of)


def _field(records, name):
    return np.array([m[name] for m in records], dtype=np.int64)


def _exact_shifts(records, lane):
    """``shift + subpixel`` of lane measurements, exact: ``(raw array, format)``."""
    return add(_field(records, "shift"), lane.shift_fmt,
               _field(records, "subpixel"), lane.subpixel_fmt)


def measured_shifts(records, lane, dst):
    """``shift + subpixel`` of measurements of a lane with parameters ``lane``, rounded
    half-even and saturated into ``dst`` (raw int array)."""
    return resize(*_exact_shifts(records, lane), dst, Rounding.HALF_EVEN, Overflow.SATURATE)


def _cues(params, stereo):
    """``{(camera A, segment): raw cue}`` of the stereo measurements that give a depth."""
    if not stereo:
        return {}
    exact, _ = _exact_shifts(stereo, params.stereo)
    cue = measured_shifts(stereo, params.stereo, params.solver.cue_fmt)
    return {(m["camera"], m["segment"]): int(c) for m, c, e in zip(stereo, cue, exact)
            if m["confidence"] and not m["edge_hit"] and e > 0}


def route_row(params, temporal, stereo):
    """Solver transfers of one row: ``temporal`` and ``stereo`` are the lanes'
    measurement dicts of that (frame, row), any order; returns dicts in stream order."""
    d, s = params.temporal, params.solver
    ordered = sorted(temporal, key=lambda m: (m["camera"], m["segment"]))
    if not ordered:
        return []
    cues = _cues(params, stereo)
    time = ordered[0]["t_first"] & ((1 << s.time_bits) - 1)
    shift = measured_shifts(ordered, d, s.shift_fmt)
    conf = resize(_field(ordered, "confidence"), d.confidence_fmt, s.conf_fmt,
                  Rounding.HALF_EVEN, Overflow.SATURATE)
    out = []
    for m, shift_raw, conf_raw in zip(ordered, shift, conf):
        segment = m["segment"] * params.stereo.segments // d.segments
        cue = cues.get((params.pair_of[m["camera"]], segment))
        usable = cue is not None and not m["edge_hit"]
        out.append({"slot": m["camera"] * d.segments + m["segment"], "row": m["row"],
                    "time": time, "shift": int(shift_raw), "cue": cue or 0,
                    "conf": int(conf_raw) if usable else 0, "last": 0})
    out[-1]["last"] = 1
    return out


def _by_row(records):
    """Group measurement dicts by (frame, row), keeping first-arrival order."""
    groups = {}
    for m in records:
        groups.setdefault((m["frame"], m["row"]), []).append(m)
    return groups


def route(params, temporal, stereo):
    """Solver transfers of whole measurement streams (all temporal lanes' records and
    all stereo lanes' records), row by row in the order rows first arrive."""
    pairs = _by_row(stereo)
    return [t for key, group in _by_row(temporal).items()
            for t in route_row(params, group, pairs.get(key, []))]


def pose_rows(params, transfers):
    """The transfers as :class:`emulator.pose_solver.PoseRows` (one row per ``last``),
    for :func:`emulator.pose_solver.pose_solver_model`."""
    rows, current = [], []
    for t in transfers:
        current.append(t)
        if t["last"]:
            rows.append(current)
            current = []
    if current:
        raise ValueError("transfers must end with a last transfer")
    width = params.solver.slots
    fields = {name: np.zeros((len(rows), width), dtype=np.int64)
              for name in ("slot", "shift", "cue", "conf")}
    present = np.zeros((len(rows), width), dtype=bool)
    for r, row in enumerate(rows):
        for k, t in enumerate(row):
            for name in fields:
                fields[name][r, k] = t[name]
            present[r, k] = True
    return PoseRows(**fields, present=present,
                    row=np.array([row[0]["row"] for row in rows], dtype=np.int64),
                    time=np.array([row[0]["time"] for row in rows], dtype=np.int64))

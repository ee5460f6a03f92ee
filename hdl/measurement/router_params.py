"""Parameters of the measurement router (row-descriptor lanes → pose solver).

Plain Python, no Amaranth: :mod:`emulator.measurement.router` (the bit-accurate model)
and :mod:`hdl.measurement.router` (the gateware) build from the same object.
"""

from dataclasses import dataclass, field

from golden.checks import check_int

from hdl.pose.params import PoseSolverParams
from hdl.descriptor.params import RowDescriptorParams
from hdl.measurement.cue_map_params import CueMap

__all__ = ["RouterParams"]


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
    cue_fallback : bool
        A stereo segment whose match fails lends its pair's last usable cue of the same
        row (the closed loop's, issue 16 item 4): a store of ``pairs × K_s × height``
        cues. Default off (no store).

    Attributes
    ----------
    pair_of : dict
        Each camera's pair, by its camera A.
    cue_map : hdl.measurement.cue_map_params.CueMap
        How each temporal segment's cue comes from its pair's stereo cues.

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
    cue_fallback: bool = False
    pair_of: dict = field(init=False, repr=False, compare=False)
    cue_map: CueMap = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        check_int("cameras", self.cameras, 1)
        for name in ("temporal", "stereo"):
            if not isinstance(getattr(self, name), RowDescriptorParams):
                raise TypeError(f"{name} must be a RowDescriptorParams, not "
                                f"{getattr(self, name)!r}")
        if not isinstance(self.solver, PoseSolverParams):
            raise TypeError(f"solver must be a PoseSolverParams, not {self.solver!r}")
        if not isinstance(self.cue_fallback, bool):
            raise TypeError(f"cue_fallback must be a bool, not {self.cue_fallback!r}")
        for name in ("frame_bits", "row_bits"):
            if getattr(self.stereo, name) != getattr(self.temporal, name):
                raise ValueError(f"stereo.{name} must equal temporal.{name} = "
                                 f"{getattr(self.temporal, name)}, not "
                                 f"{getattr(self.stereo, name)}")
        if self.solver.row_bits < self.temporal.row_bits:
            raise ValueError(f"solver.row_bits must be at least temporal.row_bits = "
                             f"{self.temporal.row_bits}, not {self.solver.row_bits}")
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
        object.__setattr__(self, "cue_map", CueMap.for_lanes(self.temporal, self.stereo,
                                                             self.solver.cue_fmt))

"""hdl.top: TopParams checks (naming the parameter) and the top's ports."""

import pytest

from hdl.camera_input import CameraParams
from hdl.pose_params import PoseSolverParams
from hdl.top import RowtrackTop
from hdl.top_params import TopParams


def test_defaults_wire_four_cameras_in_two_pairs():
    params = TopParams()
    assert params.pairs == ((0, 1), (2, 3))
    assert params.solver.slots == params.camera.n_cameras * params.segments == 16
    assert params.engine.cameras == 4 and params.engine.pairs == params.pairs
    assert params.engine.temporal.segments == params.segments
    assert params.engine.aligned_layout() == params.camera.aligned_layout()


def test_for_pairs_sizes_the_solver_and_output():
    params = TopParams.for_pairs(((1, 0),), segments=2,
                                 camera=CameraParams(max_width=256, max_height=8))
    assert params.camera.n_cameras == 2 and params.solver.slots == 4
    assert params.solver.rows == 8 and params.engine.pairs == ((1, 0),)


@pytest.mark.parametrize("changes, error, message", [
    ({"pairs": ((0, 1), (2, 2))}, ValueError, r"pairs\[1\] must be two different cameras"),
    ({"pairs": ((0, 1),)}, ValueError, r"pairs must give every camera a stereo pair; "
                                       r"cameras \[2, 3\] have none"),
    ({"pairs": ((0, 1), (1, 2))}, ValueError, "pairs: camera 1 is in more than one pair"),
    ({"pairs": ((0, 1), (2, 4))}, ValueError, r"pairs\[1\] names camera 4"),
    ({"segments": 0}, ValueError, "segments must be an integer at least 1, not 0"),
    ({"segments": 2}, ValueError, "solver.slots must be cameras × segments = 8, not 16"),
    ({"solver": PoseSolverParams(slots=8)}, ValueError,
     "solver.slots must be cameras × segments = 16, not 8"),
    ({"solver": "x"}, TypeError, "solver must be a PoseSolverParams"),
    ({"clk_hz": 1.5e8}, TypeError, "clk_hz must be an integer"),
])
def test_bad_parameters_name_the_parameter(changes, error, message):
    with pytest.raises(error, match=message):
        TopParams(**changes)


def test_the_top_only_wires_blocks():
    """No stream ports left over: rows and measurements stay inside the top."""
    ports = set(RowtrackTop(TopParams()).signature.members)
    assert ports == {"axi", "dvp", "trigger", "expose", "fsin", "uart_tx"}

"""hdl.top: TopParams checks (naming the parameter), the top's ports, and the rule that
the top only wires blocks."""

import ast
import inspect
import textwrap

import pytest

from hdl.front_end.params import CameraParams
from hdl.pose.params import PoseSolverParams
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


def test_no_stream_port_is_left_over():
    """Rows and measurements stay inside the top."""
    ports = set(RowtrackTop(TopParams()).signature.members)
    assert ports == {"axi", "dvp", "trigger", "expose", "fsin", "uart_tx"}


def _is_port(node):
    """A port or a part of one: ``name``, ``a.b.c``, ``a[k]``, nothing computed."""
    while isinstance(node, (ast.Attribute, ast.Subscript)):
        if isinstance(node, ast.Subscript) and not isinstance(node.slice, (ast.Name,
                                                                           ast.Constant)):
            return False
        node = node.value
    return isinstance(node, ast.Name)


def logic_in(source):
    """What in an ``elaborate`` is more than wiring, as ``"line N: what"`` strings: a
    ``with`` block (If/Switch/FSM), a synchronous or other non-``comb`` domain, an
    operator or a conditional expression, a new Signal or Const, and an ``.eq`` whose
    sides are not plain ports."""
    found = []
    for node in ast.walk(ast.parse(textwrap.dedent(source))):
        where = f"line {getattr(node, 'lineno', '?')}"
        if isinstance(node, (ast.With, ast.If, ast.While)):
            found.append(f"{where}: control flow ({type(node).__name__})")
        elif isinstance(node, (ast.BinOp, ast.UnaryOp, ast.BoolOp, ast.Compare, ast.IfExp)):
            found.append(f"{where}: an operator ({ast.unparse(node)})")
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute) \
                and node.value.attr == "d" and node.attr != "comb":
            found.append(f"{where}: the {node.attr} domain")
        elif isinstance(node, ast.Call):
            name = ast.unparse(node.func)
            if name.split(".")[-1] in ("Signal", "Const", "Mux", "Cat"):
                found.append(f"{where}: {name}(...)")
            elif isinstance(node.func, ast.Attribute) and node.func.attr == "eq" and not (
                    _is_port(node.func.value) and len(node.args) == 1
                    and _is_port(node.args[0])):
                found.append(f"{where}: {ast.unparse(node)} is not port to port")
    return found


WIRING_METHODS = ("elaborate", "_wire_solver_registers", "_wire_solver", "_wire_loop")


@pytest.mark.parametrize("name", WIRING_METHODS)
def test_the_top_only_wires_blocks(name):
    """RowtrackTop.elaborate and the back ends it wires (open or closed loop, chosen when
    the top is built) instantiate blocks and connect ports, nothing else: every
    assignment is a port driven by a port, no logic, registers or control flow."""
    found = logic_in(inspect.getsource(getattr(RowtrackTop, name)))
    assert not found, f"RowtrackTop.{name} holds logic: " + "; ".join(found)


def test_every_method_of_the_top_is_checked_for_logic():
    """A new method of the top is either wiring (checked above) or plumbing of Python
    values, never a place to hide logic."""
    methods = {name for name, value in vars(RowtrackTop).items()
               if inspect.isfunction(value) or isinstance(value, staticmethod)}
    assert methods - {"__init__"} == set(WIRING_METHODS)


@pytest.mark.parametrize("body, what", [
    ("m.d.comb += link.ready.eq(out.pop.stb & out.pop.data)", "an operator"),
    ("m.d.sync += a.eq(b)", "the sync domain"),
    ("m.d.comb += a.eq(b.c[k + 1])", "an operator"),
    ("m.d.comb += a.eq(Const(1))", "Const(...)"),
    ("with m.If(a):\n    m.d.comb += b.eq(c)", "control flow"),
])
def test_the_wiring_rule_catches_logic(body, what):
    source = "def elaborate(self, platform):\n" + textwrap.indent(body, "    ")
    assert any(what in item for item in logic_in(source))


def test_the_wiring_rule_passes_port_to_port():
    source = ("def elaborate(self, platform):\n    m.d.comb += [a.b.eq(c.d[k]), x.eq(y)]\n"
              "    wiring.connect(m, a.o, b.i)\n")
    assert logic_in(source) == []

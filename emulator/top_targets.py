"""The closed-loop tops the project targets, each on its Zynq-7000, and their resources.

Issue 17 sets two targets from the one parameterised top (:func:`hdl.top.closed_loop_top`):
the board rig on the xc7z020 (``rowtrack build --board microzed-7020``) and stereo20 on a
larger Zynq-7000, the xc7z045, each within 80 % of its device's LUTs, BRAM and DSP48.
``rowtrack synth-report`` and ``rowtrack bench --only top`` both measure them here.
"""

from dataclasses import dataclass

from emulator.synth import XC7Z020, synth_report
from emulator.synth_partitions import lane_groups, synth_partitioned

__all__ = ["DEVICES", "FIT_PCT", "TopTarget", "TARGETS", "target", "top_resources"]

#: Programmable-logic capacity of the Zynq-7000 devices (AMD DS190, "Zynq-7000 All
#: Programmable SoC Overview", table 1; a RAMB36 is one 36 Kb block RAM).
DEVICES = {
    "xc7z020": XC7Z020,
    "xc7z045": {"lut": 218600, "ff": 437200, "bram36": 545, "dsp48": 900},
}
#: The share of a device's LUTs, BRAM and DSP48 a top may take (issue 17).
FIT_PCT = 80.0


@dataclass(frozen=True)
class TopTarget:
    """A rig's closed-loop top on a device.

    ``board``: the ``rowtrack build --board`` name that carries it (its pins), or None
    when no supported board does. ``partitioned``: synthesized in partitions
    (:mod:`emulator.synth_partitions`), because the WebAssembly Yosys cannot flatten it
    within 4 GiB.
    """
    rig: str
    device: str
    board: str = None
    partitioned: bool = False


TARGETS = (
    TopTarget("stereo8-board", "xc7z020", board="microzed-7020"),
    TopTarget("stereo20", "xc7z045", partitioned=True),
)


def target(rig):
    """The :class:`TopTarget` of ``rig``."""
    for t in TARGETS:
        if t.rig == rig:
            return t
    raise ValueError(f"rig must be one of {', '.join(t.rig for t in TARGETS)}, not {rig!r}")


def top_resources(top_target, progress=None):
    """LUT (logic and memory, :func:`emulator.synth.synth_verilog`), FF, BRAM36, DSP48
    and LUT levels of the target's closed-loop top, with each resource's share of its
    device (``*_pct``) and ``fits`` (every one of LUT, BRAM36 and DSP48 at most
    :data:`FIT_PCT`). Synthesized in ``build/synth/top_closed`` (the board
    rig, flattened) or ``build/synth/top_closed_<rig>`` (partitioned); an unchanged
    Verilog reuses its figures."""
    from hdl.top import closed_loop_top
    top = closed_loop_top(top_target.rig)
    if top_target.partitioned:
        synth = synth_partitioned(top, f"top_closed_{top_target.rig}", lane_groups(top.params),
                                  progress=progress)["total"]
    else:
        synth = synth_report(top, "top_closed")
    capacity = DEVICES[top_target.device]
    figures = {key: synth[key] for key in ("lut", "lut_logic", "lut_memory", "ff", "bram36",
                                           "dsp48", "lut_levels")}
    for key, value in capacity.items():
        figures[f"{key}_pct"] = round(100 * synth[key] / value, 2)
    figures["fits"] = all(figures[f"{key}_pct"] <= FIT_PCT for key in ("lut", "bram36", "dsp48"))
    return figures

"""Partitioned synthesis (emulator/synth_partitions.py), the way stereo20's top is counted:
the Verilog is cut into modules correctly, identical instances are recognized and
different ones refused, and on a small design the partitions add up to exactly what
the whole design synthesizes to."""

import pytest
from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from emulator.synth import synth_verilog
from emulator.synth_partitions import (breakdown_groups, instance_modules, lane_groups,
                                       split_modules, synth_partitioned)
from hdl.top_params import TopParams
from hdl.verilog import to_verilog, write_verilog


class _Step(wiring.Component):
    """A register stepping through x → 3x + 1 while enabled (some LUTs and a carry)."""

    def __init__(self, width):
        self.width = width
        super().__init__({"en": In(1), "value": Out(width)})

    def elaborate(self, platform):
        m = Module()
        with m.If(self.en):
            m.d.sync += self.value.eq(self.value * 3 + 1)
        return m


class _Lanes(wiring.Component):
    """``lane<k>`` of the given widths and the sum of their values, registered."""

    def __init__(self, widths):
        self.widths = widths
        super().__init__({"en": In(len(widths)), "total": Out(16)})

    def elaborate(self, platform):
        m = Module()
        total = 0
        for k, width in enumerate(self.widths):
            m.submodules[f"lane{k}"] = lane = _Step(width)
            m.d.comb += lane.en.eq(self.en[k])
            total = total + lane.value
        m.d.sync += self.total.eq(total)
        return m


def test_split_modules_finds_every_module_with_its_attributes():
    text = to_verilog(_Lanes((8, 8, 12)), "lanes")
    modules, header = split_modules(text)
    assert set(modules) == {"lanes", "lanes.lane0", "lanes.lane1", "lanes.lane2"}
    assert all(body.rstrip().endswith("endmodule") for body in modules.values())
    assert '(* generator = "Amaranth" *)' in modules["lanes.lane1"]
    assert "module" not in header
    # Nothing is lost or doubled: the pieces hold every module line once.
    assert sum(body.count("\nendmodule") + body.startswith("endmodule")
               for body in modules.values()) == text.count("endmodule")
    assert set(instance_modules(modules, "lanes.lane1")) == {"lanes.lane1"}


def test_split_modules_refuses_an_unterminated_module():
    with pytest.raises(ValueError, match="module broken has no endmodule"):
        split_modules("module broken(a);\n  input a;\n")


def test_partitions_add_up_to_the_whole(tmp_path):
    design = _Lanes((8, 8, 8, 12))
    parts = synth_partitioned(design, "lanes", {"lane": ["lane0", "lane1", "lane2"]},
                              work_dir=tmp_path / "parts")
    whole = synth_verilog(write_verilog(_Lanes((8, 8, 8, 12)), "lanes", tmp_path / "whole"),
                          "lanes", tmp_path / "whole")
    assert parts["copies"] == {"lane": 3, "rest": 1}
    # Each part synthesized something, and the lane is counted three times.
    assert parts["parts"]["lane"]["ff"] == 8 and parts["parts"]["rest"]["ff"] > 8
    for key in ("lut", "ff", "dsp48", "carry4", "bram36"):
        assert parts["total"][key] == whole[key], key
    assert parts["total"]["lut_levels"] == whole["lut_levels"]


def test_different_instances_are_not_counted_as_copies(tmp_path):
    with pytest.raises(ValueError, match="instance 'lane2' of group 'lane' differs from 'lane0'"):
        synth_partitioned(_Lanes((8, 8, 12)), "lanes", {"lane": ["lane0", "lane2"]},
                          work_dir=tmp_path)


def test_missing_instances_and_empty_groups_are_refused(tmp_path):
    with pytest.raises(ValueError, match="lanes has no instance 'lane7' \\(group 'lane'\\)"):
        synth_partitioned(_Lanes((8, 8)), "lanes", {"lane": ["lane0", "lane7"]},
                          work_dir=tmp_path)
    with pytest.raises(ValueError, match="group 'lane' has no instances"):
        synth_partitioned(_Lanes((8, 8)), "lanes", {"lane": []}, work_dir=tmp_path)


def test_groups_that_would_count_an_instance_twice_are_refused(tmp_path):
    with pytest.raises(ValueError, match="instance 'lane0' is in two groups"):
        synth_partitioned(_Lanes((8, 8)), "lanes", {"a": ["lane0"], "b": ["lane0", "lane1"]},
                          work_dir=tmp_path)
    with pytest.raises(ValueError, match="must not be called 'rest'"):
        synth_partitioned(_Lanes((8, 8)), "lanes", {"rest": ["lane0"]}, work_dir=tmp_path)


def test_lane_groups_name_every_lane_of_the_top():
    params = TopParams()
    groups = lane_groups(params)
    assert groups["temporal_lane"] == [f"engine.temporal{k}"
                                       for k in range(params.camera.n_cameras)]
    assert groups["stereo_lane"] == [f"engine.stereo{j}" for j in range(len(params.pairs))]
    assert groups["temporal_matcher_1_ports"] == [f"engine.temporal_matcher{k}"
                                                  for k in range(params.camera.n_cameras)]
    assert groups["stereo_matcher_1_ports"] == ["engine.stereo_matcher0",
                                                "engine.stereo_matcher1"]


def test_lane_groups_group_shared_matchers_by_their_ports():
    """Eight cameras, three lanes per matcher: temporal matchers of 3, 3 and 2 ports (the
    last differs, so it is a group of its own), one stereo matcher of 3 pairs and one of 1."""
    params = TopParams.for_pairs(((0, 1), (2, 3), (4, 5), (6, 7)), matcher_ports=3)
    groups = lane_groups(params)
    assert groups["temporal_matcher_3_ports"] == ["engine.temporal_matcher0",
                                                  "engine.temporal_matcher1"]
    assert groups["temporal_matcher_2_ports"] == ["engine.temporal_matcher2"]
    assert groups["stereo_matcher_3_ports"] == ["engine.stereo_matcher0"]
    assert groups["stereo_matcher_1_ports"] == ["engine.stereo_matcher1"]


def test_breakdown_groups_find_the_identical_instances():
    modules, _ = split_modules(to_verilog(_Lanes((8, 12, 8, 8)), "lanes"))
    groups = breakdown_groups(modules, "lanes", depth=1)
    assert groups == {"lane0": ["lane0", "lane2", "lane3"], "lane1": ["lane1"]}


def test_groups_can_be_formed_from_the_design_s_own_modules(tmp_path):
    parts = synth_partitioned(_Lanes((8, 12, 8)), "lanes",
                              lambda modules: breakdown_groups(modules, "lanes", depth=1),
                              work_dir=tmp_path)
    assert parts["copies"] == {"lane0": 2, "lane1": 1, "rest": 1}


def test_breakdown_table_totals_each_group_over_its_copies():
    """The breakdown's rows: per-copy LUTs and every total over the copies (the LUTs
    used as memory too), largest total first, then the sum."""
    from emulator.commands.synth_report import breakdown_table
    part = {"lut": 10, "lut_memory": 4, "ff": 7, "bram36": 0.5, "dsp48": 1, "lut_levels": 3}
    other = {"lut": 25, "lut_memory": 0, "ff": 2, "bram36": 0.0, "dsp48": 0, "lut_levels": 5}
    total = {"lut": 55, "lut_memory": 12, "ff": 23, "bram36": 1.5, "dsp48": 3,
             "lut_levels": 5}
    table = breakdown_table({"parts": {"lane": part, "rest": other},
                             "copies": {"lane": 3, "rest": 1}, "total": total})
    lines = table.splitlines()
    assert "lut_memory total" in lines[0]
    assert lines[2] == "| lane | 3 | 10 | 30 | 12 | 21 | 1.5 | 3 | 3 |"
    assert lines[3] == "| rest | 1 | 25 | 25 | 0 | 2 | 0.0 | 0 | 5 |"
    assert lines[4] == "| sum | | | 55 | 12 | 23 | 1.5 | 3 | 5 |"

"""The stereo lanes' window (hdl/measurement/router_params.py ``StereoWindow``): derived
from a rig as the golden tracker's stereo depth derives its own, and its rules in the
router model at their boundaries (the gateware's are checked bit for bit in
test_measurement_router_hdl.py)."""

import dataclasses

import pytest

from golden.depth import DEFAULT_RANGE, MIN_PEAK_RATIO, DepthRange, StereoDepth
from golden.descriptor import STEREO_MATCH, DescriptorParams
from golden.rig import preset
from emulator.measurement.router import usable_cues
from hdl.fixed import UQ
from hdl.measurement.router_params import StereoWindow
from hdl.pipeline_config import PipelineConfig
from sim_tests.measurement.measurement_router.stimulus import GUARDED, NARROW, measurement


def test_default_is_the_fixed_window_without_extra_rules():
    window = StereoWindow()
    assert (window.shift_min, window.shift_max) == (STEREO_MATCH.shift_min,
                                                    STEREO_MATCH.shift_max)
    assert window.accepted == (10, 70)
    assert window.min_confidence_raw(UQ(2, 6)) == 1       # only textureless (0) rejected


@pytest.mark.parametrize("rig_name", ["stereo20", "stereo8-board", "stereo8"])
def test_a_rigs_window_is_the_golden_stereo_depths(rig_name):
    """The hardware searches and accepts what golden (b)'s StereoDepth does: the same
    window per pair (every pair of these rigs has one f·b) and the same accepted
    disparities; the golden's peak-ratio bound only when asked for."""
    rig = preset(rig_name)
    golden = StereoDepth(rig, DescriptorParams())
    window = PipelineConfig.for_rig(rig).top.stereo_window
    for params, (_, _, fb) in zip(golden.windows, golden.pairs):
        assert (window.shift_min, window.shift_max) == (params.shift_min, params.shift_max)
        assert window.accepted == DEFAULT_RANGE.accepted(fb)
    assert (window.guard, window.min_ratio) == (DEFAULT_RANGE.guard, 0.0)
    fb = [fb for _, _, fb in golden.pairs]
    assert StereoWindow.for_pairs(fb, min_ratio=MIN_PEAK_RATIO) == \
        window.replace(min_ratio=golden.min_peak_ratio)
    lanes = PipelineConfig.for_rig(rig).router.stereo.match
    assert (lanes.shift_min, lanes.shift_max) == (window.shift_min, window.shift_max)


def test_stereo20_window_reaches_the_far_walls():
    """f·b = 41.6 px: [−2, 86] (89 shifts) instead of [10, 70], so a surface beyond
    4.2 m (disparity below 10) has its minimum inside the window."""
    window = PipelineConfig.for_rig(preset("stereo20")).top.stereo_window
    assert (window.shift_min, window.shift_max, window.accepted) == (-2, 86, (0, 84))


def test_pairs_of_different_baselines_share_the_union():
    near = DepthRange(near=1.0, far=4.0, guard=1)
    window = StereoWindow.for_pairs([40.0, 20.0], near, min_ratio=1.5)
    # per pair: [10 − 1, 40 + 1] and [5 − 1, 20 + 1]
    assert (window.shift_min, window.shift_max, window.guard, window.min_ratio) == \
        (4, 41, 1, 1.5)


@pytest.mark.parametrize("shift, confidence, gives", [
    (11, 200, False),       # in the low guard band
    (12, 200, True),        # the first accepted disparity
    (68, 200, True),        # the last
    (69, 200, False),       # in the high guard band
    (40, 76, False),        # peak ratio 76/64 < 1.2
    (40, 77, True),         # 77/64 ≥ 1.2
])
def test_router_model_rules_at_their_boundaries(shift, confidence, gives):
    m = measurement(1, 0, 0, 0, shift=shift, confidence=confidence)
    assert GUARDED.stereo_window.min_confidence_raw(GUARDED.stereo.confidence_fmt) == 77
    assert bool(usable_cues(GUARDED, [m])) == gives
    assert usable_cues(NARROW, [m])                 # the default window takes them all


def test_edge_and_non_positive_disparity_stay_unusable():
    for m in (measurement(1, 0, 0, 0, shift=40, confidence=200, edge_hit=1),
              measurement(1, 0, 0, 0, shift=0, subpixel=0, confidence=200)):
        assert not usable_cues(dataclasses.replace(
            GUARDED, stereo_window=StereoWindow(guard=0, min_ratio=1.2)), [m])


@pytest.mark.parametrize("kwargs, error, message", [
    ({"shift_min": 1.5}, TypeError, "shift_min must be an integer"),
    ({"shift_max": 12}, ValueError, "shift_max must be an integer at least 13"),
    ({"guard": -1}, ValueError, "guard must be an integer at least 0"),
    ({"guard": 31}, ValueError, r"guard 31 leaves no disparity of the window \[10, 70\]"),
    ({"min_ratio": -0.5}, ValueError, "min_ratio"),
])
def test_parameter_checks(kwargs, error, message):
    with pytest.raises(error, match=message):
        StereoWindow(**kwargs)


def test_for_pairs_checks():
    with pytest.raises(ValueError, match="focal_baselines must name at least one"):
        StereoWindow.for_pairs([])
    with pytest.raises(TypeError, match="depth_range must be a DepthRange"):
        StereoWindow.for_pairs([40.0], depth_range=(0.5, 10))


def test_router_checks_the_window_against_its_lanes():
    with pytest.raises(ValueError, match=r"stereo_window \[-2, 86\] must be the stereo "
                                         r"lanes' window \[10, 70\]"):
        dataclasses.replace(NARROW, stereo_window=StereoWindow(shift_min=-2, shift_max=86))
    with pytest.raises(TypeError, match="stereo_window must be a StereoWindow"):
        dataclasses.replace(NARROW, stereo_window=(10, 70))
    with pytest.raises(ValueError, match="min_ratio 9.0 is beyond the stereo lanes' "
                                         "confidence_fmt"):
        dataclasses.replace(NARROW, stereo_window=StereoWindow(min_ratio=9.0))


def test_a_window_wider_than_the_image_is_refused_naming_it():
    """A pair whose near limit needs more disparity than a 640-px row can compare."""
    from hdl.front_end.params import CameraParams
    from hdl.measurement.engine_params import EngineParams
    from hdl.pose.params import PoseSolverParams
    camera = CameraParams(n_cameras=2)
    solver = PoseSolverParams(slots=8, rows=camera.max_height)
    with pytest.raises(ValueError, match=r"cannot size a stereo lane with segments=1 and "
                                         r"shifts \[-2, 802\]"):
        EngineParams.for_cameras(camera, solver, ((0, 1),),
                                 stereo_window=StereoWindow.for_pairs([400.0]))
    with pytest.raises(TypeError, match="stereo_window must be a StereoWindow"):
        EngineParams.for_cameras(camera, solver, ((0, 1),), stereo_window=(10, 70))

"""The motion track's model (emulator/pose/motion_track.py) against its float recursion,
and its edge cases: a constant motion stays put, a gap longer than a frame, saturation
counted, bad parameters named."""

import numpy as np
import pytest

from golden.rig import preset
from hdl.pipeline_config import PipelineConfig
from emulator.pose.motion_track import MotionTrackModel, track_float

SEED = 20261206


@pytest.fixture(scope="module")
def params():
    return PipelineConfig.for_rig(preset("stereo8-board")).forecast()


def _stream(params, rng, frame_rows, rows, skip_every=50, skip=7):
    """(slot, level, trend, target or None) raw, and the same in float."""
    fmt = params.motion_fmt
    motion = np.array([0.01, -0.002, 0.005, 0.004, -0.016, 0.006])
    raw, real, slot = [], [], 0
    for i in range(rows):
        slot += skip if i and i % skip_every == 0 else 1
        level = fmt.quantize(motion + rng.normal(0, 1e-4, 6))
        trend = fmt.quantize(rng.normal(0, 1e-6, 6))
        target = None if rng.random() < 0.2 else fmt.quantize(motion + rng.normal(0, 5e-4, 6))
        raw.append((slot, level, trend, target))
        real.append((slot, fmt.to_float(level), fmt.to_float(trend),
                     None if target is None else fmt.to_float(target)))
    return motion, raw, real


@pytest.mark.parametrize("frame_rows", [40, 600])
def test_the_model_is_its_float_recursion_in_fixed_point(params, frame_rows):
    """Fed the same values, the fixed-point track follows the float recursion to the
    formats' rounding: the start's P increments each within half an ulp of level/P, then
    each row's carry and pull rounded (motion_fmt ulp 1.8e-12)."""
    rng = np.random.default_rng(SEED)
    print(f"seed {SEED}")
    motion, raw, real = _stream(params, rng, frame_rows, 400)
    fmt = params.motion_fmt
    model = MotionTrackModel(params, frame_rows, fmt.quantize(motion))
    fixed = np.array([fmt.to_float(model.update(*row)) for row in raw])
    alpha = params.track_alpha_raw / 2 ** params.gain_fmt.frac_bits
    reference = track_float(frame_rows, alpha, fmt.to_float(fmt.quantize(motion)), real)
    ulp = 2.0 ** -fmt.frac_bits
    assert np.abs(fixed - reference).max() <= 2 * frame_rows * ulp
    assert model.saturated == 0


def test_a_constant_motion_stays_put(params):
    """Level, targets and the start all at Y, no trend: Y stays within P/2 ulp of Y (the
    rounding of Y/P) over frames, solved rows or not."""
    fmt = params.motion_fmt
    y = np.array([0.012, 0.003, -0.004, 0.002, 0.015, -0.006])
    frame_rows = 480
    model = MotionTrackModel(params, frame_rows, fmt.quantize(y))
    zero = np.zeros(6, dtype=np.int64)
    for slot in range(3 * frame_rows):
        target = fmt.quantize(y) if slot % 3 else None
        out = model.update(slot, fmt.quantize(y), zero, target)
    assert np.abs(fmt.to_float(out) - y).max() <= frame_rows * 2.0 ** -fmt.frac_bits


def test_a_gap_longer_than_a_frame_leaves_only_the_carry(params):
    """After more than P row periods without a row, every increment is the carry: Y is
    P times it, whatever came before."""
    fmt = params.motion_fmt
    frame_rows = 40
    model = MotionTrackModel(params, frame_rows, fmt.quantize(np.full(6, 0.01)))
    level = fmt.quantize(np.full(6, 0.02))
    zero = np.zeros(6, dtype=np.int64)
    model.update(0, level, zero, fmt.quantize(np.full(6, 0.05)))
    model.update(5, level, zero, fmt.quantize(np.full(6, 0.03)))
    out = model.update(3 * frame_rows, level, zero)
    carry = int(np.round(level[0] * params.reciprocal_raw(frame_rows)
                         / 2 ** params.reciprocal_fmt.frac_bits))
    assert np.all(model.ring == carry)
    assert np.all(out == frame_rows * carry)


def test_saturation_is_counted_never_silent(params):
    """Steps at the format's ends drive Y out of motion_fmt: it saturates and the row is
    counted."""
    fmt = params.motion_fmt
    frame_rows = 4
    model = MotionTrackModel(params, frame_rows, fmt.quantize(np.full(6, fmt.max_value / 2)))
    top = np.full(6, fmt.max_raw, dtype=np.int64)
    level = np.full(6, fmt.max_raw, dtype=np.int64)
    trend = np.full(6, fmt.max_raw, dtype=np.int64)
    for slot in range(8):
        out = model.update(slot, level, trend, top)
        assert np.all(out <= fmt.max_raw)
    assert model.saturated > 0


def test_bad_parameters_are_named(params):
    fmt = params.motion_fmt
    with pytest.raises(ValueError, match="frame_rows"):
        MotionTrackModel(params, 0, np.zeros(6, dtype=np.int64))
    model = MotionTrackModel(params, 10, np.zeros(6, dtype=np.int64))
    model.update(5, fmt.quantize(np.zeros(6)), fmt.quantize(np.zeros(6)))
    with pytest.raises(ValueError, match="slot"):
        model.update(5, fmt.quantize(np.zeros(6)), fmt.quantize(np.zeros(6)))
    with pytest.raises(ValueError, match="track_alpha"):
        params.replace(track_alpha=0.0)
    with pytest.raises(ValueError, match="track_alpha"):
        params.replace(track_alpha=1e-7)
    with pytest.raises(ValueError, match="reciprocal_fmt"):
        params.replace(reciprocal_fmt=fmt)

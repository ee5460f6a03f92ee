"""emulator.pose.forecast (the fixed-point motion forecast) against the golden tracker's
forecast: the scalar Holt–Winters, the loop delay, window centres and row addresses from
the coefficient stores, saturation flags, parameter checks.

The loop test runs golden (b) on the stereo20 rig cut to its 32 middle rows (three
frames). Set SEED to replay the randomized tests; the seed in use is printed.
"""

import os

import numpy as np
import pytest

from golden.pose_lsq import ShiftCoefficients, design_rows
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.temporal_filter import HoltWinters
from golden.tracker import TrackerParams, track
from golden.trajectory import make_trajectory
from hdl.fixed import SQ, UQ
from hdl.pipeline_config import PipelineConfig
from emulator.pose.forecast import ForecastModel, MotionFilter

SEED = int(os.environ.get("SEED", "3"))
ROWS = 32

#: The fixed-point forecast may differ from the golden float forecast (same scalar gains,
#: same delay, same measured values) by this much per axis (metres, radians): α and β are
#: 18-bit constants (relative error 1.5e-5), the state has 39 fraction bits. Measured on
#: the test's run: 1.2e-8; on full-size stereo20 (3 frames, noise 2 px): 1.6e-8.
TOLERANCE = 1e-7
#: With the quantized gains in the float filter too, only the state's rounding (2**-39 per
#: update) remains.
ROUNDING = 1e-10


@pytest.fixture(scope="module")
def config():
    rig = preset("stereo20")
    return PipelineConfig.for_rig(rig.replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                                      t_r=1 / (120 * ROWS)))


def test_motion_filter_is_the_golden_scalar_holt_winters_in_fixed_point(config):
    """The golden filter with the gains as quantized: the fixed-point state follows it
    within its rounding over 300 updates (a ramp with noise and missing values)."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    params = config.forecast()
    start = rng.normal(scale=1e-2, size=6)
    fixed = MotionFilter(params, params.motion_fmt.quantize(start))
    gains = params.gain_fmt.to_float([params.alpha_raw, params.beta_raw])
    golden = HoltWinters(params.motion_fmt.to_float(fixed.level), alpha=gains[0],
                         beta=gains[1])
    for t in range(300):
        value = None if rng.random() < 0.2 else start + 1e-4 * t + rng.normal(scale=1e-3,
                                                                               size=6)
        golden.update(value)
        fixed.update(None if value is None else params.solver.step_fmt.quantize(value))
        error = np.abs(params.motion_fmt.to_float(fixed.level) - golden.level)
        assert error.max() < ROUNDING, t
    assert np.abs(golden.trend).max() > 1e-5          # the trend took part


def test_forecast_follows_golden_b_with_the_same_loop_delay(config):
    """Golden (b) with the hardware's simplification (scalar gains) and the HDL's delay of
    one row: the model, fed the values golden's filter took (quantized to the solver's
    step format), forecasts every slot within TOLERANCE of golden's forecast."""
    rig = preset("stereo20").replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                             t_r=1 / (120 * ROWS))
    dataset = simulate(rig, default_scene_spec(1), make_trajectory("paper"), 3 / 120, seed=1)
    result = track(dataset, TrackerParams(reference="previous", motion_gain="scalar",
                                          loop_delay_rows=1))
    params = config.forecast(loop_delay_rows=1)
    slots = np.rint((result.times - result.times[0]) / rig.cameras[0].t_r).astype(int)
    tracked = np.flatnonzero(result.tracked)
    model = ForecastModel(params, config.coef_raw, config.row_coef_raw,
                          params.motion_fmt.quantize(result.forecast[tracked[0]]))
    errors = []
    for i in tracked:
        errors.append(params.motion_fmt.to_float(model.motion(slots[i])) - result.forecast[i])
        value = result.measured[i]
        model.take(slots[i], None if np.isnan(value).any()
                   else params.solver.step_fmt.quantize(value))
    errors = np.abs(errors)
    print("max |fixed - golden| per axis", errors.max(axis=0))
    assert errors.max() < TOLERANCE
    # the forecast moved with the measurements (the comparison is not of constants)
    assert np.ptp(result.forecast[tracked], axis=0).min() > 100 * TOLERANCE


def test_centres_and_row_addresses_are_the_rounded_float_predictions(config):
    """Random motions and cues: each camera's window centre and row address are the
    float mean prediction of its segments (the stores' tables, exact arithmetic) rounded,
    except within 0.01 px of a rounding tie (quantization)."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    params = config.forecast(loop_delay_rows=0)
    k, cameras = params.segments, params.cameras
    for _ in range(20):
        motion = rng.normal(scale=[1e-2, 1e-2, 1e-2, 5e-3, 5e-3, 5e-3])
        cue = rng.uniform(10, 60, size=params.solver.slots)
        row = int(rng.integers(ROWS))
        model = ForecastModel(params, config.coef_raw, config.row_coef_raw,
                              params.motion_fmt.quantize(motion))
        out = model.predict(0, row, params.solver.cue_fmt.quantize(cue))
        for table, got, sign in ((config.table, out["centre"], 1),
                                 (config.row_table, row - out["source_row"], -1)):
            mean = (design_rows(ShiftCoefficients.from_table(table[:, row]), cue)
                    @ motion).reshape(cameras, k).mean(axis=1)
            near_tie = np.abs(np.abs(mean - np.floor(mean)) - 0.5) < 0.01
            inside = ~(out["centre_saturated"] | out["row_saturated"])
            check = inside & ~near_tie
            assert np.array_equal(got[check], np.floor(mean[check] + 0.5)), (sign, row)


def test_saturation_is_flagged_never_silent(config):
    params = config.forecast(loop_delay_rows=0)
    motion = np.array([0.0, 0.3, 0.0, 0.0, 0.4, 0.0])     # far beyond one frame's motion
    model = ForecastModel(params, config.coef_raw, config.row_coef_raw,
                          params.motion_fmt.quantize(motion))
    out = model.predict(0, 0, params.solver.cue_fmt.quantize(np.full(params.solver.slots, 30.0)))
    assert out["centre_saturated"].any() and out["row_saturated"].any()
    assert np.all(np.abs(out["centre"][out["centre_saturated"]]) == params.centre_range)
    assert np.all(np.isin(out["source_row"][out["row_saturated"]], [0, ROWS - 1]))
    assert np.all(np.abs(out["centre"]) <= params.centre_range)


def test_a_solved_step_is_withheld_for_the_loop_delay(config):
    """Delay 2: the step of slot 10 reaches slot 13's forecast, not slot 12's."""
    params = config.forecast(loop_delay_rows=2, beta=0.0)
    zero = np.zeros(6, dtype=np.int64)
    model = ForecastModel(params, config.coef_raw, config.row_coef_raw, zero)
    model.take(10, params.solver.step_fmt.quantize(np.full(6, 0.01)))
    assert np.array_equal(model.motion(11), zero)
    model.take(11)
    assert np.array_equal(model.motion(12), zero)
    assert model.motion(13).min() > 0


@pytest.mark.parametrize("changes, error, message", [
    (dict(segments=3), ValueError, "segments 3 must divide the solver's 80 slots"),
    (dict(alpha=0.0), ValueError, "alpha must be a number greater than 0"),
    (dict(alpha=1e-7), ValueError, "alpha 1e-07 rounds to 0"),
    (dict(beta=1.5), ValueError, "beta must be a number between 0 and 1"),
    (dict(loop_delay_rows=-1), ValueError, "loop_delay_rows must be an integer at least 0"),
    (dict(height=10_000), ValueError, "height must be an integer between 1 and"),
    (dict(gain_fmt=SQ(2, 16)), ValueError, "gain_fmt must be unsigned"),
    (dict(motion_fmt=UQ(1, 39)), ValueError, "motion_fmt must be signed"),
    (dict(displacement_fmt="SQ(10, 8)"), TypeError, "displacement_fmt must be a QFormat"),
])
def test_bad_parameters_are_named(config, changes, error, message):
    with pytest.raises(error, match=message):
        config.forecast(**changes)


def test_the_filter_takes_a_gain_only_with_the_information_gain(config):
    """A scalar-gain filter refuses a gain; the information gain's is a move (6,), not
    golden's matrix."""
    zero = np.zeros(6, dtype=np.int64)
    for params, gain in ((config.forecast(motion_gain="scalar"), zero),
                         (config.forecast(motion_gain="information"), np.eye(6))):
        with pytest.raises(ValueError, match="gain must be None"):
            MotionFilter(params, zero).update(zero, gain)

"""emulator.measurement.consistency (the fixed-point robust consistency stage) against its
float original golden.temporal_filter.RobustScale: scales, Huber weights, outlier
replacement, the depth weight (against golden.tracker_robust.depth_weights), the reference-time factor, the row gates, saturation at the formats'
extremes and the parameter checks.

SEED replays the randomized test (printed).
"""

import os

import numpy as np
import pytest

from golden.temporal_filter import RobustScale
from golden.tracker_robust import depth_weights
from hdl.fixed import SQ, UQ
from hdl.measurement.consistency_params import ConsistencyParams
from hdl.pose.params import PoseSolverParams
from emulator.measurement.consistency import ConsistencyModel

SEED = int(os.environ.get("SEED", "5"))
CAMERAS, K, ROWS = 4, 4, 32
SOLVER = PoseSolverParams(slots=CAMERAS * K, rows=ROWS)

#: Fixed point vs float over the randomized sequence below (16 channels × 400 rows).
#: The scale's square root is rounded to 2**-11 px each update and the recursion passes
#: an error on almost unchanged (factor ≈ 1), so errors add up as a random walk:
#: measured at most 2.0e-3 px (SEED 5); 1e-2 px is 20 updates' worth of a whole LSB
#: each, beyond what 400 random half-LSB steps reach.
SCALE_TOLERANCE = 1e-2
#: Huber weights kσ/|r| of outliers: the quotient's floor (2**-15) plus kδσ/|r| < δσ/σ.
#: Measured at most 5.0e-3 (SEED 5; 3.9e-3 … 5.6e-3 at SEED 1–3; smallest scale 0.19 px,
#: printed); 2e-2 is 4× that (δσ at SCALE_TOLERANCE would allow 5e-2).
WEIGHT_TOLERANCE = 2e-2


def params(**changes):
    return ConsistencyParams(**{"solver": SOLVER, "segments": K, "frame_rows": 40.0,
                                **changes})


def transfers(shift, conf, cameras=range(CAMERAS)):
    return [{"slot": n * K + k, "row": 0, "time": 0, "shift": int(shift[n * K + k]),
             "cue": 1, "conf": int(conf[n * K + k]), "last": 0}
            for n in cameras for k in range(K)]


def test_scales_and_weights_follow_the_golden_robust_scale():
    """Noisy innovations (σ 0.3 px) with 10 % gross outliers and 10 % missing
    measurements on every channel: the fixed-point scales, weights and outlier verdicts
    against RobustScale with the same (quantized) parameters, fed the innovations the
    stage computed."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    p = params()
    model = ConsistencyModel(p)
    lam = 1 - p.gain_fmt.to_float(p.keep_raw)
    golden = RobustScale(p.channels, initial=p.scale_fmt.to_float(p.initial_raw),
                         floor=p.scale_fmt.to_float(p.floor_raw), smoothing=lam,
                         k=p.k_fmt.to_float(p.k_raw),
                         ceiling=p.scale_fmt.to_float(p.ceiling_raw))
    # λ·c_k is its own register: its c_k differs from the golden's by 7e-5 (relative)
    assert abs(p.gain_fmt.to_float(p.lam_ck_raw) / lam / p.biweight_ck - 1) < 1e-4
    s = SOLVER
    scale_err, weight_err, boundary, outliers, smallest = 0.0, 0.0, 0, 0, np.inf
    for _ in range(400):
        predicted = p.predicted_fmt.quantize(rng.uniform(-10, 10, p.channels))
        innovation = rng.normal(scale=0.3, size=p.channels)
        gross = rng.random(p.channels) < 0.1
        innovation[gross] = rng.choice([-1, 1], gross.sum()) * rng.uniform(2, 15, gross.sum())
        shift = s.shift_fmt.quantize(p.predicted_fmt.to_float(predicted) + innovation)
        conf = np.where(rng.random(p.channels) < 0.1, 0, s.conf_fmt.quantize(1.5))
        channel = np.arange(p.channels)
        verdict = model.judge(channel, shift, predicted, conf)
        r = p.innovation_fmt.to_float(verdict["innovation"])
        ok = conf > 0
        x, weight = golden.judge(channel[ok], r[ok])
        fixed_scale = p.scale_fmt.to_float(model.scale)
        scale_err = max(scale_err, np.abs(fixed_scale - golden.scale).max())
        smallest = min(smallest, golden.scale.min())
        fixed_weight = p.ratio_fmt.to_float(verdict["weight"][ok])
        weight_err = max(weight_err, np.abs(fixed_weight - weight).max())
        near = np.abs(np.abs(x) - p.huber_k) < 0.05
        agree = verdict["outlier"][ok] == (np.abs(x) > p.huber_k)
        assert np.all(agree | near)
        boundary += int(np.count_nonzero(near))
        outliers += int(np.count_nonzero(verdict["outlier"]))
        # an outlier's shift is the prediction, the others' pass unchanged
        np.testing.assert_array_equal(
            verdict["shift"], np.where(verdict["outlier"], predicted << 4, shift))
    print(f"worst scale error {scale_err:.2e} px, weight error {weight_err:.2e}, "
          f"{outliers} outliers, {boundary} verdicts within 0.05 of k, smallest scale "
          f"{smallest:.3f} px")
    assert outliers > 300
    assert scale_err < SCALE_TOLERANCE
    assert weight_err < WEIGHT_TOLERANCE


def test_confidence_is_peak_ratio_times_weight():
    p = params()
    model = ConsistencyModel(p)
    sigma = p.scale_fmt.to_float(p.initial_raw)
    shift = SOLVER.shift_fmt.quantize([0.0, 4 * sigma * p.huber_k, 0.5, 0.0])
    out = model.judge(np.arange(4), shift, [0, 0, 0, 0],
                      SOLVER.conf_fmt.quantize([1.5, 1.5, 2.0, 0.0]))
    conf = SOLVER.conf_fmt.to_float(out["conf"])
    # inliers keep their confidence, the outlier at 4 kσ gets a quarter, none stays 0
    np.testing.assert_allclose(conf, [1.5, 1.5 / 4, 2.0, 0.0], atol=2 ** -9)
    assert list(out["outlier"]) == [False, True, False, False]
    assert out["shift"][1] == 0 and out["shift"][2] == shift[2]


#: Depth weight, fixed point vs float, for cues of 4–250 px: the operands on a 1/16-px
#: grid move w = d²/(d² + v²) by at most |∂w/∂d|·δ + |∂w/∂v|·δ ≤ δ/d per operand
#: (δ = 1/32 px, the grid's half step), 0.016 at the smallest cue, plus the quotient's
#: floor (2**-15). Measured 1.6e-3 … 5.0e-3 (SEED 1, 2, 3, 5).
DEPTH_WEIGHT_TOLERANCE = 0.016


def test_the_depth_weight_follows_the_golden_depth_weights():
    """Random cues (disparities, 4–250 px) and translation parts of the predicted shift
    (±60 px): the model's weight against :func:`depth_weights` with the cue as the
    inverse depth in units of 1/(f·B) (so σ_w = σ_d) at the same ``σ_d/s``."""
    print(f"SEED={SEED}")
    rng = np.random.default_rng(SEED)
    p = params()
    model = ConsistencyModel(p)
    cue = rng.uniform(4, 250, 2000)
    translation = rng.uniform(-60, 60, 2000)
    translation[:100] = 0
    got = p.ratio_fmt.to_float(model.depth_weight(
        SOLVER.cue_fmt.quantize(cue), p.predicted_fmt.quantize(translation)))
    ratio = p.depth_ratio_fmt.to_float(p.depth_ratio_raw)
    want = depth_weights((translation / cue)[:, None], np.array([1.0]), np.full(2000, ratio),
                         1.0)
    error = np.abs(got - want).max()
    print(f"largest depth-weight error {error:.2e}, weights {want.min():.3f} … {want.max()}")
    assert error < DEPTH_WEIGHT_TOLERANCE
    assert want.min() < 0.05 and np.all(got[:100] == 1.0)


def test_the_depth_weight_at_the_formats_extremes():
    """No overflow at the extremes of the cue, the translation and the ratio: a zero
    translation weighs one (a zero ratio: every measurement), a zero cue with a translation nothing (no depth:
    any shift), the largest translation against the smallest cue nothing, against the
    largest cue the float's weight."""
    s = SOLVER
    one = 1 << params().ratio_fmt.frac_bits
    fmt = params().predicted_fmt
    cue = np.array([0, 0, s.cue_fmt.max_raw, 1, 1, s.cue_fmt.max_raw, s.cue_fmt.max_raw])
    translation = np.array([0, fmt.min_raw, 0, fmt.max_raw, fmt.min_raw, fmt.min_raw,
                            fmt.max_raw])
    top = params(depth_ratio=params().depth_ratio_fmt.max_value)
    for p in (params(), top):
        w = ConsistencyModel(p).depth_weight(cue, translation)
        assert list(w[:3]) == [one, 0, one] and list(w[3:5]) == [0, 0]
        ratio = p.depth_ratio_fmt.to_float(p.depth_ratio_raw)
        want = 1 / (1 + (ratio * fmt.to_float(translation[5:]) / s.cue_fmt.max_value) ** 2)
        np.testing.assert_allclose(p.ratio_fmt.to_float(w[5:]), want, atol=2 ** -10)
    off = ConsistencyModel(params(depth_ratio=0)).depth_weight(cue, translation)
    assert list(off) == [one] * len(cue)                 # the weight off


def test_the_confidence_takes_the_depth_weight_then_the_huber_weight():
    """A translation part of ``d·s/σ_d`` (ρ = 1) halves the confidence; an outlier at
    4 kσ then takes a quarter of that; the scale is updated as without the weight."""
    p = params()
    ratio = p.depth_ratio_fmt.to_float(p.depth_ratio_raw)
    cue, conf = 40.0, 3.0          # halved, still above min_confidence (no gate)
    sigma = p.scale_fmt.to_float(p.initial_raw)
    shift = SOLVER.shift_fmt.quantize([0.0, 4 * sigma * p.huber_k] + [0.0] * (p.channels - 2))
    ones = SOLVER.conf_fmt.quantize(np.full(p.channels, conf))
    rows = transfers(shift, ones)
    for t in rows:
        t["cue"] = int(SOLVER.cue_fmt.quantize(cue))
    translation = p.predicted_fmt.quantize(np.full(p.channels, cue / ratio))
    zero = np.zeros(p.channels, dtype=int)
    weighed, plain = ConsistencyModel(p), ConsistencyModel(p)
    out, verdict = weighed.apply(rows, zero, zero, translation)
    got = SOLVER.conf_fmt.to_float([t["conf"] for t in out])
    np.testing.assert_allclose(got[:2], [conf / 2, conf / 8], atol=2 ** -7)
    np.testing.assert_allclose(p.ratio_fmt.to_float(verdict["depth_weight"]), 0.5,
                               atol=2e-3)
    plain.apply(rows, zero, zero, zero)
    assert list(weighed.scale) == list(plain.scale)


def test_the_reference_time_factor_is_p_over_p_minus_delta():
    """A row compared with a stored row Δ rows later in the previous frame saw the motion
    of P − Δ row periods: its shift is scaled by P/(P − Δ), within half an LSB."""
    p = params(max_row_offset=20)
    model = ConsistencyModel(p)
    delta = np.arange(-20, 21)
    factor = p.time_fmt.to_float(model.time_factor(delta))
    assert np.abs(factor - 40 / (40 - delta)).max() <= 0.5 * p.time_fmt.lsb
    shift = SOLVER.shift_fmt.quantize(np.full(41, 3.0))
    scaled = SOLVER.shift_fmt.to_float(model.to_one_frame(shift, delta))
    np.testing.assert_allclose(scaled, 3.0 * 40 / (40 - delta), atol=2 ** -11)


def test_row_gates_need_a_confident_measurement_and_three_cameras():
    p = params()
    ones = SOLVER.conf_fmt.quantize(np.full(p.channels, 1.5))
    zero = np.zeros(p.channels, dtype=int)
    near = [0] * p.channels                 # every segment read its own row
    # three cameras, confident: passes
    out, verdict = ConsistencyModel(p).apply(transfers(zero, ones, range(3)), zero, near, zero)
    assert not verdict["gated"] and all(t["conf"] for t in out)
    # two cameras: gated, every confidence 0
    model = ConsistencyModel(p)
    out, verdict = model.apply(transfers(zero, ones, range(2)), zero, near, zero)
    assert verdict["gated"] and not any(t["conf"] for t in out)
    assert model.counts["gated_rows"] == 1
    # four cameras but no confidence reaches min_confidence 1
    weak = SOLVER.conf_fmt.quantize(np.full(p.channels, 0.75))
    _, verdict = ConsistencyModel(p).apply(transfers(zero, weak), zero, near, zero)
    assert verdict["gated"]
    _, verdict = ConsistencyModel(p.replace(min_confidence=0.5)).apply(
        transfers(zero, weak), zero, near, zero)
    assert not verdict["gated"]


def test_a_camera_compared_too_far_off_gets_no_confidence():
    p = params(max_row_offset=4, min_cameras=2)
    model = ConsistencyModel(p)
    ones = SOLVER.conf_fmt.quantize(np.full(p.channels, 1.5))
    zero = np.zeros(p.channels, dtype=int)
    out, _ = model.apply(transfers(zero, ones), zero, np.repeat([0, 5, -4, -5], K), zero)
    conf = np.array([t["conf"] for t in out]).reshape(CAMERAS, K)
    assert conf[[0, 2]].all() and not conf[[1, 3]].any()
    assert model.counts["far_rows"] == 2
    # per segment: one segment of camera 0 read a row too far off, camera 1's are near
    delta = np.repeat([0, 1, 0, 0], K)
    delta[1] = 5
    out, _ = model.apply(transfers(zero, ones), zero, delta, zero)
    conf = np.array([t["conf"] for t in out])
    assert not conf[1] and np.delete(conf, 1).all()
    assert model.counts["far_rows"] == 3


def test_saturation_at_the_format_extremes_is_counted_not_raised():
    """Largest shift against the most negative prediction (innovation beyond ±64 px),
    a prediction beyond the shift format replacing an outlier, the largest scale with the
    largest factor, the largest shift times the largest time factor."""
    p = params(huber_k=1.5, max_row_offset=ROWS - 1, frame_rows=float(ROWS),
               time_fmt=UQ(6, 16), scale_ceiling=UQ(5, 11).max_value)
    s = SOLVER
    model = ConsistencyModel(p)
    model.scale[:] = p.scale_fmt.max_raw
    shift = np.array([s.shift_fmt.max_raw, s.shift_fmt.min_raw, 0, 0])
    predicted = np.array([p.predicted_fmt.min_raw, p.predicted_fmt.max_raw, 0, 0])
    conf = np.full(4, s.conf_fmt.quantize(1.0))
    out = model.judge(np.arange(4), shift, predicted, conf)
    assert list(out["innovation"][:2]) == [p.innovation_fmt.max_raw, p.innovation_fmt.min_raw]
    assert model.counts["innovation_saturated"] == 2
    # |r| = 64 px > kσ = 48 px: outliers, replaced by a saturated prediction
    assert list(out["shift"][:2]) == [s.shift_fmt.min_raw, s.shift_fmt.max_raw]
    assert model.counts["shift_saturated"] == 2
    # σ at its maximum, |r| ≥ kσ: the biweight is at its bound, σ grows and saturates
    assert model.scale[0] == p.scale_fmt.max_raw and model.counts["scale_saturated"] == 2
    # inliers at σ = max shrink by √(1 − λ) and do not saturate
    assert model.scale[2] < p.scale_fmt.max_raw
    scaled = model.to_one_frame([s.shift_fmt.max_raw, s.shift_fmt.min_raw], [ROWS - 1] * 2)
    assert list(scaled) == [s.shift_fmt.max_raw, s.shift_fmt.min_raw]
    assert model.counts["time_saturated"] == 2


def test_a_persistent_bias_stays_an_outlier_beyond_the_ceiling():
    """A channel whose innovations keep a bias of 3 px: without a ceiling (the format's
    largest) the scale grows until the bias is accepted with full weight; with the
    default ceiling (1 px, k = 2) every one stays an outlier, replaced by the prediction,
    and the scale stops at the ceiling (each capped update counted)."""
    bias = SOLVER.shift_fmt.quantize(np.full(1, 3.0))
    conf = SOLVER.conf_fmt.quantize(np.full(1, 1.5))
    verdicts = {}
    for name, p in (("uncapped", params(scale_ceiling=UQ(5, 11).max_value)),
                    ("capped", params())):
        model = ConsistencyModel(p)
        verdicts[name] = [bool(model.judge([0], bias, [0], conf)["outlier"][0])
                          for _ in range(100)]
        verdicts[name + " scale"] = p.scale_fmt.to_float(model.scale[0])
        verdicts[name + " count"] = model.counts["scale_saturated"]
    print(verdicts["uncapped scale"], verdicts["capped scale"])
    assert not any(verdicts["uncapped"][-50:]) and verdicts["uncapped scale"] > 1.5
    assert verdicts["uncapped count"] == 0
    assert all(verdicts["capped"]) and verdicts["capped scale"] == 1.0
    assert verdicts["capped count"] > 50


def test_the_starting_scale_is_within_floor_and_ceiling():
    assert params(scale_initial=3.0).initial_raw == params().ceiling_raw
    assert params(scale_initial=0.05).initial_raw == params().floor_raw


@pytest.mark.parametrize("changes, error, message", [
    ({"solver": 3}, TypeError, "solver must be a PoseSolverParams, not 3"),
    ({"segments": 0}, ValueError, "segments must be an integer at least 1, not 0"),
    ({"segments": 3}, ValueError, "segments 3 must divide the solver's 16 slots"),
    ({"predicted_fmt": UQ(10, 8)}, ValueError, r"predicted_fmt must be signed, not UQ\(10, 8\)"),
    ({"innovation_fmt": 7}, TypeError, "innovation_fmt must be a QFormat, not 7"),
    ({"scale_fmt": SQ(5, 11)}, ValueError, r"scale_fmt must be unsigned, not SQ\(5, 11\)"),
    ({"ratio_fmt": UQ(0, 16)}, ValueError, r"ratio_fmt must hold 1, not UQ\(0, 16\)"),
    ({"huber_k": 0}, ValueError, "huber_k must be a number greater than 0, not 0"),
    ({"scale_initial": -1.0}, ValueError, "scale_initial must be a number greater than 0"),
    ({"scale_floor": "0.1"}, TypeError, "scale_floor must be a number, not '0.1'"),
    ({"smoothing": 1.5}, ValueError,
     "smoothing must be a number greater than 0 and at most 1, not 1.5"),
    ({"biweight_ck": 0.0}, ValueError, "biweight_ck must be a number greater than 0"),
    ({"min_confidence": -1.0}, ValueError, "min_confidence must be a number at least 0"),
    ({"min_cameras": 5}, ValueError, "min_cameras must be an integer between 1 and 4, not 5"),
    ({"frame_rows": 31.0}, ValueError, "frame_rows must be a number between 32 and"),
    ({"max_row_offset": 32}, ValueError,
     "max_row_offset must be an integer between 0 and 31, not 32"),
    ({"frame_rows": 32.0, "max_row_offset": 31}, ValueError,
     r"time_fmt UQ\(2, 16\) cannot hold the largest reference-time factor 32.000"),
    ({"huber_k": 9.0}, ValueError, r"huber_k must be at most 7.99609375 \(UQ\(3, 8\)\), not 9.0"),
    ({"min_confidence": 5.0}, ValueError, r"min_confidence must be at most 3.99609375"),
    ({"scale_floor": 1e-5}, ValueError, r"scale_floor 1e-05 rounds to 0 in UQ\(5, 11\)"),
    ({"scale_ceiling": 0.05}, ValueError,
     "scale_ceiling must be a number at least 0.1, not 0.05"),
    ({"scale_ceiling": 40.0}, ValueError, r"scale_ceiling must be at most 31.99951171875"),
    ({"smoothing": 1e-6}, ValueError, r"smoothing·biweight_ck .* rounds to 0 in gain_fmt"),
    ({"depth_ratio": -1.0}, ValueError, "depth_ratio must be a number between 0 and"),
    ({"depth_ratio": 16.0}, ValueError, "depth_ratio must be a number between 0 and 15.996"),
    ({"depth_frac_bits": 17}, ValueError,
     "depth_frac_bits must be an integer between 0 and 16, not 17"),
])
def test_bad_parameters_are_named(changes, error, message):
    with pytest.raises(error, match=message):
        params(**changes)


def test_the_model_takes_only_its_parameters():
    with pytest.raises(TypeError, match="params must be a ConsistencyParams, not 3"):
        ConsistencyModel(3)

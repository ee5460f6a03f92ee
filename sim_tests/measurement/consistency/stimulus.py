"""Stimulus and checks shared by the consistency stage's Amaranth-simulator tests
(sim_tests/measurement/test_consistency_hdl.py) and its cocotb bench: small parameter sets,
random rows at the formats' extremes, and the comparison with
:class:`emulator.measurement.consistency.ConsistencyModel`."""

import dataclasses

import numpy as np

from emulator.measurement.consistency import ConsistencyModel
from hdl.measurement.consistency import COUNTER_BITS
from hdl.measurement.consistency_params import ConsistencyParams
from hdl.pose.params import PoseSolverParams

#: A small stage for the random rows: 4 cameras × 2 segments, P = 40, offsets up to 16,
#: the default scale ceiling (1 px: gross innovations reach it).
SMALL = ConsistencyParams(solver=PoseSolverParams(slots=8, rows=32, row_bits=6),
                          segments=2, frame_rows=40.0, huber_k=1.0, min_cameras=3)
#: ... and with scales started near the top of ``scale_fmt``, the ceiling that top:
#: outliers saturate them.
LARGE = dataclasses.replace(SMALL, scale_initial=31.0,
                            scale_ceiling=SMALL.scale_fmt.max_value)


def check_against_model(params, rows, got):
    """Every transfer, the row verdicts (``gated``, and ``determinable`` where ``got``
    has it: the row's on ``last``, 0 before), the counters and the scales equal the
    model's; the per-measurement ``judged`` and ``outlier`` bits too where ``got`` has
    them."""
    model = ConsistencyModel(params)
    n = 0
    for r, (transfers, predicted, delta, translation) in enumerate(rows):
        want, verdict = model.apply(transfers, predicted, delta, translation)
        row_gated = got["gated"][n + len(want) - 1]        # the verdict rides on `last`
        assert row_gated == verdict["gated"], f"row {r} gated"
        if "determinable" in got:
            bits = got["determinable"][n:n + len(want)]
            assert bits == [0] * (len(want) - 1) + [int(verdict["determinable"])], \
                f"row {r} determinable: hardware {bits}, model {verdict['determinable']}"
        for k, w in enumerate(want):
            g = got["transfers"][n]
            assert g == {**w, "conf": int(verdict["conf"][k])}, \
                f"row {r} transfer {k}: hardware {g}, model {w} {verdict}"
            assert (0 if row_gated else g["conf"]) == w["conf"], f"row {r} transfer {k}"
            if "judged" in got:
                far = abs(int(delta[w["slot"]])) > params.max_row_offset
                assert got["judged"][n] == int(transfers[k]["conf"] != 0 and not far), \
                    f"row {r} transfer {k} judged"
                assert got["outlier"][n] == int(verdict["outlier"][k]), \
                    f"row {r} transfer {k} outlier"
            n += 1
    assert n == len(got["transfers"])
    mask = (1 << COUNTER_BITS) - 1
    assert got["counts"] == {k: v & mask for k, v in model.counts.items()}
    if "scale" in got:
        assert got["scale"] == model.scale.tolist()
    return model


def judge_inputs(params, rows):
    """The stage's input transfers of rows ``(transfers, predicted, delta,
    translation)``: each transfer with its slot's ``predicted`` shift, ``delta`` and
    ``translation``."""
    return [{**t, "predicted": int(predicted[t["slot"]]), "delta": int(delta[t["slot"]]),
             "translation": int(translation[t["slot"]])}
            for transfers, predicted, delta, translation in rows for t in transfers]


def random_rows(params, rng, count):
    """Rows ``(transfers, predicted, delta, translation)`` of distinct slots in slot
    order, every field over its format's range (and beyond for the offsets: far
    cameras), confidences often 0 or the largest."""
    s = params.solver
    rows = []
    for r in range(count):
        slots = np.sort(rng.choice(params.channels, rng.integers(1, params.channels + 1),
                                   replace=False))
        conf = rng.integers(0, s.conf_fmt.max_raw + 1, len(slots))
        conf[rng.random(len(slots)) < 0.2] = 0
        conf[rng.random(len(slots)) < 0.1] = s.conf_fmt.max_raw
        shift = rng.integers(s.shift_fmt.min_raw, s.shift_fmt.max_raw + 1, len(slots))
        near = rng.random(len(slots)) < 0.5
        shift[near] //= 256                         # small shifts: inliers too
        predicted = rng.integers(params.predicted_fmt.min_raw,
                                 params.predicted_fmt.max_raw + 1, params.channels)
        small = rng.random(params.channels) < 0.6
        predicted[small] = rng.integers(-64, 64, small.sum())
        predicted[rng.random(params.channels) < 0.05] = params.predicted_fmt.min_raw
        # translation parts: small (weights near one), about the cue (near a half), at
        # the format's extremes (near zero), or 0 (one)
        fmt = params.predicted_fmt
        translation = rng.integers(-1 << fmt.frac_bits, 1 << fmt.frac_bits, params.channels)
        pick = rng.random(params.channels)
        translation[pick < 0.4] = rng.integers(fmt.min_raw, fmt.max_raw + 1,
                                               (pick < 0.4).sum())
        translation[pick > 0.9] = 0
        translation[(pick > 0.85) & (pick <= 0.9)] = fmt.min_raw
        translation[(pick > 0.8) & (pick <= 0.85)] = fmt.max_raw
        delta = rng.integers(-s.rows + 1, s.rows, params.cameras)
        delta[rng.random(params.cameras) < 0.6] = 0
        delta = np.repeat(delta, params.segments)   # per segment: the camera's, or near it
        apart = rng.random(params.channels) < 0.3
        delta[apart] = np.clip(delta[apart] + rng.integers(-2, 3, apart.sum()),
                               -s.rows + 1, s.rows - 1)
        row = int(rng.integers(0, s.rows))
        transfers = [{"slot": int(sl), "row": row, "time": int(rng.integers(0, 1 << 32)),
                      "shift": int(sh), "cue": int(rng.integers(s.cue_fmt.min_raw,
                                                              s.cue_fmt.max_raw + 1)),
                      "conf": int(c), "last": int(k == len(slots) - 1)}
                     for k, (sl, sh, c) in enumerate(zip(slots, shift, conf))]
        rows.append((transfers, predicted, delta, translation))
    return rows

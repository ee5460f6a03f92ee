"""Stimulus and expected outputs of the forecast's tests: a small random case with
coefficients up to their formats' extremes, and a real closed loop (stereo20 cut to 32
rows, three frames of the papers' motion, ``emulator.pipeline.run`` with the forecast at
delay 1): its rows' slots, cues and solver records, replayed through
:class:`emulator.pose.forecast.ForecastModel` for the expected outputs.

A case is a dict: ``params``, ``coefficients``, ``row_coefficients`` (the stores'
contents in their layouts: polynomial terms or every row), ``coef_raw``,
``row_coef_raw`` (what they give every row: the model's tables), ``initial`` (raw
``motion_fmt``), ``requests`` and ``records`` (payload dicts, one each per row, in
order), ``expected`` (per row the list of per-camera output dicts) and ``motion`` (per
row the forecast ``Ŷ``, raw).
"""

import pickle
from functools import lru_cache
from pathlib import Path

import numpy as np

from hdl.fixed import SQ
from hdl.pose.forecast_params import ForecastParams
from hdl.pose.params import PoseFlag, PoseSolverParams
from hdl.pose.row_polynomials import evaluate_polynomials
from emulator.pose.forecast import ForecastModel, output_transfers

__all__ = ["random_case", "closed_loop_case", "expected_outputs", "record", "saturations",
           "cached", "CACHE"]

CACHE = Path(__file__).resolve().parents[3] / "build" / "forecast_stimulus"
#: Part of the cached cases' names: bumped when a case's keys or the models behind it
#: change (v2: the stores' contents and the model's tables apart; v3: the consistency
#: stage's scale ceiling; v4: the forecast bench asks for the scalar gain, the default is
#: the information gain; v6: each segment's row address, ``segment_rows``).
VERSION = "v8"


def record(params, step=None, row=0, time=0, flags=0):
    """A pose record payload with ``step`` (raw (6,), zero if None) and ``flags``."""
    step = np.zeros(6, dtype=np.int64) if step is None else np.asarray(step)
    return {"row": int(row), "time": int(time), "flags": int(flags), "q": [0, 0, 0, 0],
            "p": [0, 0, 0], "step": [int(v) for v in step]}


def run_model(params, coefficients, row_coefficients, initial, requests, records,
              restart=None):
    """The model in the gateware's order (predict the row, then take its record): per
    request the per-camera outputs and Ŷ, and the model at the end. With ``restart``
    (request index, raw motion) the model restarts at the motion before that request."""
    model = ForecastModel(params, coefficients, row_coefficients, initial)
    outputs, motions = [], []
    for n, (request, rec) in enumerate(zip(requests, records)):
        if restart is not None and n == restart[0]:
            model.restart(restart[1])
        out = model.predict(request["slot"], request["row"], np.array(request["cue"]))
        outputs.append(output_transfers(params, out, request["row"]))
        motions.append([int(v) for v in out["motion"]])
        model.take(request["slot"], np.array(rec["step"]) if rec["flags"] == 0 else None)
    return outputs, motions, model


def expected_outputs(params, coefficients, row_coefficients, initial, requests, records):
    """Per request, the per-camera outputs and Ŷ of the model (:func:`run_model`)."""
    return run_model(params, coefficients, row_coefficients, initial, requests, records)[:2]


def saturations(outputs, motion=0):
    """The block's saturation counters after ``outputs`` (per-camera output dicts) and
    ``motion`` saturated filter updates and forecasts."""
    return {"centre": sum(o["centre_saturated"] for o in outputs),
            "row": sum(o["row_saturated"] for o in outputs),
            "segment": sum(bin(o["shift_saturated"]).count("1")
                           + bin(o["across_saturated"]).count("1") for o in outputs),
            "motion": motion}


def _finish(case):
    case["expected"], case["motion"] = expected_outputs(
        case["params"], case["coef_raw"], case["row_coef_raw"], case["initial"],
        case["requests"], case["records"])
    return case


def model_table(store, contents):
    """What a store of ``store``'s layout with ``contents`` gives every row (raw
    coefficients, the gateware's saturation): the model's table."""
    if not store.coef_terms:
        return contents
    return evaluate_polynomials(store, contents, np.arange(store.rows))


def small_params(**changes):
    """Two cameras of two segments, eight rows, the scalar gain (the scalar filter's
    benches); ``changes`` to any field."""
    fields = dict(solver=PoseSolverParams(slots=4, rows=8), row_coef_t_fmt=SQ(4, 14),
                  row_coef_c_fmt=SQ(2, 16), row_coef_r_fmt=SQ(9, 9), segments=2, height=8,
                  centre_range=6, motion_gain="scalar")
    return ForecastParams(**{**fields, **changes})


def polynomial_params(**changes):
    """:func:`small_params` with polynomial stores: the solver's of degree 1, the
    across-rows store of degree 2 (as ``PipelineConfig``), terms with three fraction
    bits more than the coefficient per power of the (3-bit) row and room to overflow
    the coefficient formats."""
    solver = PoseSolverParams(slots=4, rows=8, coef_poly_fmts=(
        (SQ(6, 16), SQ(3, 19), SQ(12, 10)), (SQ(3, 16), SQ(2, 19), SQ(5, 10))))
    rows = ((SQ(5, 20), SQ(3, 22), SQ(10, 15)), (SQ(3, 20), SQ(2, 22), SQ(5, 15)),
            (SQ(2, 20), SQ(2, 22), SQ(3, 15)))
    return small_params(**{"solver": solver, "row_coef_poly_fmts": rows, **changes})


def _store(rng, solver):
    """Random contents: mostly a few pixels per unit motion, some at the extremes (per
    row, or per polynomial term)."""
    shape = (solver.slots, solver.entries_per_slot, 9)
    out = np.empty(shape, dtype=np.int64)
    for k in range(9):
        for t in range(solver.coef_terms) if solver.coef_terms else (None,):
            fmt = solver.coef_fmt(k, t)
            where = (slice(None), slice(None) if t is None else t, k)
            size = out[where].shape
            shift = rng.integers(0, fmt.width - 1, size=size)
            out[where] = rng.integers(fmt.min_raw, fmt.max_raw + 1, size=size) >> shift
    return out


def random_case(seed, rows=40, params=None, scale=1e-2, slot_gaps=(1, 1, 1, 2, 5)):
    """Random rows (slots ``slot_gaps`` apart, cues, steps, some flagged) on random
    stores (per row, or polynomial terms when ``params``' stores are polynomials);
    ``scale`` is the motion's size (m, rad)."""
    rng = np.random.default_rng(seed)
    params = small_params() if params is None else params
    s = params.solver
    slots = np.cumsum(rng.choice(slot_gaps, size=rows))
    requests = [{"slot": int(slot), "row": int(slot % params.height),
                 "cue": [int(v) for v in rng.integers(0, s.cue_fmt.max_raw + 1, s.slots)
                         >> rng.integers(0, 8)]} for slot in slots]
    step_fmt = s.step_fmt
    records = [record(params, step_fmt.quantize(np.clip(rng.normal(scale=scale, size=6),
                                                        -0.99, 0.99)),
                      flags=int(rng.choice([0, 0, 0, PoseFlag.ILL, PoseFlag.EMPTY])))
               for _ in slots]
    for r in records:
        if r["flags"]:
            r["step"] = [0] * 6
    initial = params.motion_fmt.quantize(np.clip(rng.normal(scale=scale, size=6), -0.9, 0.9))
    stores = _store(rng, s), _store(rng, params.row_store)
    return _finish({"params": params, "coefficients": stores[0], "row_coefficients": stores[1],
                    "coef_raw": model_table(s, stores[0]),
                    "row_coef_raw": model_table(params.row_store, stores[1]),
                    "initial": initial, "requests": requests, "records": records})


@lru_cache(maxsize=None)
def closed_loop_case(rows=32, frames=3, seed=1, delay=1):
    """The closed loop of ``emulator.pipeline.run`` on stereo20 cut to ``rows`` rows:
    per row set in order its slot, row, the cues the loop's forecast used and the
    solver's record (flag EMPTY for a row without measurements). Cached under build/."""
    return cached(CACHE / f"stereo20_r{rows}_f{frames}_s{seed}_d{delay}_{VERSION}.pkl",
                  lambda: _closed_loop(rows, frames, seed, delay))


def cached(path, build):
    """The case pickled at ``path``, or ``build()``'s, pickled there."""
    if path.exists():
        with open(path, "rb") as f:
            return pickle.load(f)
    case = build()
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        pickle.dump(case, f)
    return case


def _closed_loop(rows, frames, seed, delay):
    from emulator.e2e import true_steps
    from emulator.pipeline import run
    from golden.rig import preset
    from golden.scene import default_scene_spec
    from golden.simulator import simulate
    from golden.trajectory import make_trajectory
    from hdl.pipeline_config import PipelineConfig

    rig = preset("stereo20").replace_cameras(height=rows, cy=(rows - 1) / 2,
                                             t_r=1 / (120 * rows))
    dataset = simulate(rig, default_scene_spec(seed), make_trajectory("paper"), frames / 120,
                       seed=seed)
    config = PipelineConfig.for_rig(rig)
    params = config.forecast(loop_delay_rows=delay, motion_gain="scalar")   # the scalar bench
    initial = true_steps(dataset, [1], [0])[0]
    out = run(config, dataset, forecast=params, initial_motion=initial)
    loop, rec = out.loop, out.records
    by_row = {(int(f), int(r)): k for k, (f, r) in enumerate(zip(out.frame, rec["row"]))}
    measured = {}
    for r in range(len(out.rows)):
        key = (int(out.frame[r]), int(out.rows.row[r]))
        present = out.rows.present[r]
        measured[key] = list(zip(out.rows.slot[r][present], out.rows.cue[r][present]))
    cues = np.zeros((params.solver.slots, params.height), dtype=np.int64)
    requests, records = [], []
    for frame, row, slot in zip(loop["frame"], loop["row"], loop["slot"]):
        key = (int(frame), int(row))
        requests.append({"slot": int(slot), "row": int(row),
                         "cue": [int(v) for v in cues[:, row]]})
        if key in by_row:
            k = by_row[key]
            records.append({"row": int(rec["row"][k]), "time": int(rec["time"][k]),
                            "flags": int(rec["flags"][k]), "q": [int(v) for v in rec["q"][k]],
                            "p": [int(v) for v in rec["p"][k]],
                            "step": [int(v) for v in rec["step"][k]]})
        else:
            records.append(record(params, row=row, flags=PoseFlag.EMPTY))
        for channel, cue in measured.get(key, []):
            if cue:                     # as the loop: 0 is no stereo cue
                cues[channel, row] = cue
    case = _finish({"params": params, "coefficients": config.coef_store,
                    "row_coefficients": config.row_coef_store, "coef_raw": config.coef_raw,
                    "row_coef_raw": config.row_coef_raw,
                    "initial": params.motion_fmt.quantize(initial),
                    "requests": requests, "records": records})
    # the replay is the loop's own forecast (else the cues or records were rebuilt wrong)
    centres = np.array([[o["centre"] for o in outs] for outs in case["expected"]])
    sources = np.array([[o["source_row"] for o in outs] for outs in case["expected"]])
    if not (np.array_equal(centres, loop["centre"]) and np.array_equal(sources, loop["source_row"])):
        raise AssertionError("replayed forecast differs from the closed loop's")
    return case

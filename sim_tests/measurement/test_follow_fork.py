"""The closed-loop engine's forecast path in the Amaranth simulator: ForecastRows
(hdl/measurement/forecast_rows.py) into the row-set fork with ``follow``
(hdl/measurement/row_set_fork.py), against the models forecast_rows, join_forecasts and
fork_row_sets (emulator/measurement/engine.py): random row sets (cameras missing,
``enable`` 0, rows numbered beyond the height) and a forecast stream with lost, stale,
mislabelled and malformed rows, with and without random valid gaps and ready
backpressure on every port.

SEED replays a run (printed).
"""

import os
import random

import pytest
from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.sim import Simulator

from emulator.hdl_sim.payload import pack, unpack
from emulator.measurement.engine import (fork_row_sets, forecast_rows, join_forecasts,
                                         row_set_columns)
from hdl.measurement.engine_params import EngineParams
from hdl.measurement.forecast_rows import ForecastRows
from hdl.measurement.row_set_fork import RowSetFork
from sim_tests.measurement.test_measurement_engine import (CAMERA, PAIRS, SOLVER, _row,
                                                           stereo_beats)

SEED = int(os.environ.get("SEED", "3"))
HEIGHT = CAMERA.max_height


@pytest.fixture(scope="module")
def params():
    return EngineParams.for_cameras(CAMERA, SOLVER, PAIRS, follow=True)


def _forecast_row(params, rng, row):
    return [{"camera": k, "centre": rng.randint(-40, 40),
             "segment_rows": [rng.randrange(HEIGHT) for _ in range(params.temporal.segments)],
             "row": row, "last": int(k == params.cameras - 1)} for k in range(params.cameras)]


def stimulus(params, rng, count):
    """Row sets, their configurations and the forecast transfers (one row per set, with
    faults)."""
    sets, configs, forecast = [], [], []
    for n in range(count):
        row = n % HEIGHT if rng.random() > 0.05 else HEIGHT + 1
        present = [k for k in range(params.cameras) if rng.random() < 0.8] or [0]
        sets.append({k: _row(k, row, rng.randint(1, 4), frame=n // HEIGHT) for k in present})
        configs.append({"stereo": [0] * len(params.pairs), "enable": int(rng.random() > 0.15)})
        fault = rng.random()
        if fault < 0.06:                                   # lost
            continue
        if fault < 0.12:                                   # a stale one first
            forecast += _forecast_row(params, rng, (row - 1) % HEIGHT)
        elif fault < 0.17:                                 # mislabelled
            row = rng.randrange(HEIGHT + 3)
        rows = _forecast_row(params, rng, row % (1 << SOLVER.row_bits))
        if 0.17 <= fault < 0.21:                           # malformed
            rows[rng.randrange(len(rows))]["camera"] ^= 1
        forecast += rows
    return sets, configs, forecast + _forecast_row(params, rng, 0) * 3


def simulate(params, sets, configs, forecast, rng, busy):
    """ForecastRows → RowSetFork; returns every output's transfers, the final status
    and malformed count."""
    rows, fork = ForecastRows(params), RowSetFork(params)
    m = Module()
    m.submodules.rows, m.submodules.fork = rows, fork
    wiring.connect(m, rows.o, fork.forecast)
    columns = [(column, cfg["enable"]) for row_set, cfg in zip(sets, configs)
               for column in row_set_columns(params, row_set)]
    ports = [("temporal", k, p) for k, p in enumerate(fork.temporal)] + \
        [("tickets", 0, fork.tickets)]
    out = {name: {} for name in ("temporal", "tickets")}
    record = {}

    async def forecasts(ctx):
        """Offers the transfers until the bench is done (spare rows stay unread)."""
        pending = list(forecast)
        while pending and "status" not in record:
            valid = busy or rng.random() < 0.6
            ctx.set(rows.i.payload.as_value(), pack(params.forecast_layout(), pending[0]))
            ctx.set(rows.i.valid, valid)
            taken = valid and ctx.get(rows.i.ready)
            await ctx.tick()
            if taken:
                pending.pop(0)

    def take_outputs(ctx):
        for name, n, port in ports:
            ready = busy or rng.random() < 0.5
            ctx.set(port.ready, ready)
            if ready and ctx.get(port.valid):
                layout = port.payload.shape()
                out[name].setdefault(n, []).append(
                    unpack(layout, ctx.get(port.payload.as_value())))

    async def bench(ctx):
        i, cycle, offering = 0, 0, False
        while i < len(columns):
            assert cycle < 40 * len(columns) + 1000, "the fork stopped taking columns"
            offering = offering or busy or rng.random() < 0.7
            column, enable = columns[i]
            ctx.set(fork.i.valid, offering)
            ctx.set(fork.i.payload, column)
            ctx.set(fork.enable, enable)
            take_outputs(ctx)
            taken = offering and ctx.get(fork.i.ready)
            await ctx.tick()
            cycle += 1
            if taken:
                i, offering = i + 1, False
        ctx.set(fork.i.valid, 0)
        # the fork's input register drains: every set opened, no column left for an output
        while ctx.get(fork.status.row_sets) < len(sets) or \
                any(ctx.get(port.valid) for _, _, port in ports):
            assert cycle < 40 * len(columns) + 1000, "the fork stopped handing columns on"
            take_outputs(ctx)
            await ctx.tick()
            cycle += 1
        status = ctx.get(fork.status)
        record["status"] = {name: int(getattr(status, name)) for name in
                            ("row_sets", "dropped", "forecast_skipped", "unforecast")}
        record["stereo_skipped"] = [int(v) for v in status.stereo_skipped]
        record["malformed"] = ctx.get(rows.malformed)

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(forecasts, background=True)
    sim.add_testbench(bench)
    sim.run()
    return out, record


@pytest.mark.parametrize("busy", [True, False], ids=["full_rate", "gaps_and_backpressure"])
def test_forecast_join_matches_model(params, busy):
    print(f"SEED={SEED}")
    rng = random.Random(SEED)
    sets, configs, forecast = stimulus(params, rng, 80)
    rows, malformed = forecast_rows(params, forecast)
    joined, join_status = join_forecasts(params, sets, configs, rows)
    model = fork_row_sets(params, sets, configs, joined)
    out, record = simulate(params, sets, configs, forecast, rng, busy)
    print(join_status, model.status, f"malformed {malformed}")
    assert out["tickets"].get(0, []) == model.tickets
    for k, (beats, centres, sources) in enumerate(model.temporal):
        got = out["temporal"].get(k, [])
        assert len(got) == len(beats), f"temporal lane {k}"
        for g, b, c, s in zip(got, beats, centres, sources):
            assert {name: g[name] for name in b} == b, f"temporal lane {k}"
            if b["first"]:          # the lane samples centre and source with it
                source = [g["source"][n] for n in range(len(s))]
                assert (g["centre"], source) == (c, list(s)), f"temporal lane {k}, {b}"
    temporal = [out["temporal"].get(k, []) for k in range(params.cameras)]
    for j, (beats_a, _, beats_b) in enumerate(model.stereo):
        assert stereo_beats(params, temporal, j) == [beats_a, beats_b], f"stereo lane {j}"
    assert record["status"] == {"row_sets": model.status["row_sets"],
                                "dropped": model.status["dropped"], **join_status}
    assert record["stereo_skipped"] == model.status["stereo_skipped"]
    assert record["malformed"] == malformed
    # the stimulus reached every decision
    assert min(join_status.values()) > 0 and malformed > 0 and model.status["dropped"] > 0
    assert any(row_set[min(row_set)][0]["row"] >= HEIGHT for row_set in sets)

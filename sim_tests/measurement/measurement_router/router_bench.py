"""cocotb bench for hdl.measurement.router.MeasurementRouter: every output transfer
and the status counters against :func:`emulator.measurement.router.route_tickets`.

The streams come from ``ROUTER_STIMULUS`` (a pickle of ``(tickets, temporal, stereo)``
written by the pytest file, e.g. real rows through the lane models) or, without it,
from :func:`stimulus.synthetic` seeded by ``cocotb.RANDOM_SEED``. Each lane, the
tickets and the output run with their own random gaps and backpressure.
"""

import os
import pickle
import random

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles

from hdl.measurement.router import router_status_layout, ticket_layout
from hdl.pose_solver import measurement_layout
from emulator.hdl_sim.cocotb_env import load_params
from emulator.hdl_sim.clocking import reset, start_clock
from emulator.hdl_sim.payload import unpack
from emulator.hdl_sim.streams import StreamSink, StreamSource

from sim_tests.measurement.measurement_router.stimulus import expected, synthetic


def _stimulus(params):
    path = os.environ.get("ROUTER_STIMULUS")
    if path:
        with open(path, "rb") as f:
            return pickle.load(f)
    return synthetic(params, np.random.default_rng(cocotb.RANDOM_SEED), 80)


@cocotb.parametrize(traffic=["full_rate", "gaps_and_backpressure"])
async def router_matches_model(dut, traffic):
    params = load_params()
    rng = random.Random(cocotb.RANDOM_SEED)
    prob = 1.0 if traffic == "full_rate" else 0.6
    tickets, temporal, stereo = _stimulus(params)
    want, want_status = expected(params, tickets, temporal, stereo)

    clock = start_clock(dut)
    lanes = [(StreamSource(dut, "tickets", ticket_layout(params), clock,
                           rng=random.Random(rng.random()), valid_prob=prob), tickets)]
    lanes += [(StreamSource(dut, f"temporal__{c}", params.temporal.measurement_layout(),
                            clock, rng=random.Random(rng.random()), valid_prob=prob), items)
              for c, items in enumerate(temporal)]
    lanes += [(StreamSource(dut, f"stereo__{j}", params.stereo.measurement_layout(),
                            clock, rng=random.Random(rng.random()), valid_prob=prob), items)
              for j, items in enumerate(stereo)]
    sink = StreamSink(dut, "o", measurement_layout(params.solver), clock, rng=rng,
                      ready_prob=1.0 if traffic == "full_rate" else 0.5)
    await reset(dut)
    for source, items in lanes:
        cocotb.start_soon(source.send(items))
    measurements = sum(map(len, temporal)) + sum(map(len, stereo))
    await sink.wait_for(len(want), timeout_cycles=10 * (measurements + len(want)) + 1000)
    await ClockCycles(dut.clk, 20)          # nothing after the last expected transfer
    got = [payload for _, payload in sink.received]
    assert len(got) == len(want), f"{len(got)} transfers, model {len(want)}"
    for n, (g, w) in enumerate(zip(got, want)):
        assert g == w, f"transfer {n}: hardware {g}, model {w}"
    status = unpack(router_status_layout(params), dut.status.value)
    assert status == want_status, f"status {status}, model {want_status}"
    dut._log.info(f"{len(got)} transfers of {len(tickets)} tickets bit-exact; "
                  f"status {status}")

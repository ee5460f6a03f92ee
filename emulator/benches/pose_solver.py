"""Benchmark of the pose solver: clocks per row and latency from the Amaranth simulation
of the block, resources from synth_xilinx, and the fixed-point trajectory against the
float64 golden trajectory over one second of the papers' test motion on the stereo20
and radial4 rigs."""

import math

import numpy as np

from emulator import pose_solver as E
from emulator.synth import XC7Z020, synth_report
from golden import pose_lsq as G

#: Clock the row-rate figures assume (MHz).
CLOCK_MHZ = 150
#: Targets of issue 8.
TARGETS = {"clocks_per_row": 750, "latency_clocks": 300, "dsp48": 40,
           "traj_err_cm": 0.02, "traj_err_deg": 0.002}
SECOND = 1.0


#: Stereo baseline of the stereo20 pairs (m): the disparity cue's scale 1/(f·b).
STEREO_BASELINE = 0.10
#: Inverse-depth cue scale of the radial rigs: cue = 64/Z fills cue_fmt well.
RADIAL_CUE_SCALE = 1 / 64
#: Pairs of stereo20 whose left camera makes the eight-camera rig (the two cameras of a
#: pair give near-duplicate equations, so four whole pairs would be rank 4).
EIGHT_CAMERA_PAIRS = (0, 1, 2, 3, 4, 5, 8, 9)
#: Rig cases of the bench and the tests.
RIGS = ("stereo8", "stereo20", "radial4")


def rig_case(name):
    """``(params, raw coefficients, float table, rig, cue scale)`` of rig case ``name``:
    a preset, or ``stereo8`` (one camera of each of eight stereo20 pairs), with an
    18-bit coefficient store and the pair's disparity (stereo) or 64/Z (radial) as cue."""
    from golden.rig import Rig, preset
    if name not in RIGS:
        raise ValueError(f"rig must be one of {', '.join(RIGS)}, not {name!r}")
    rig = preset("stereo20" if name == "stereo8" else name)
    if name == "stereo8":
        rig = Rig(name="stereo8", row_points=1,
                  cameras=tuple(rig.cameras[2 * k] for k in EIGHT_CAMERA_PAIRS))
    scale = ([1 / (cam.fx * STEREO_BASELINE) for cam in rig.cameras]
             if name.startswith("stereo") else RADIAL_CUE_SCALE)
    params, coefficients, table = E.rig_solver(rig, scale)
    return params, coefficients, table, rig, scale


def _quaternion_angle_deg(a, b):
    relative = G.quat_multiply(np.asarray(a) * [1, -1, -1, -1], b / np.linalg.norm(b, axis=-1,
                                                                                     keepdims=True))
    return np.degrees(2 * np.arcsin(np.minimum(1, np.linalg.norm(relative[..., 1:], axis=-1))))


def trajectory_error(name, duration=SECOND, seed=1):
    """Fixed point against float64 over ``duration`` s of the papers' motion on preset
    rig ``name``, both fed the same quantized rows (noise-free shifts, 5 % zero
    weights). The golden steps use the exact (float) coefficients, so the figure
    includes the coefficient store's quantization."""
    from golden.trajectory import make_trajectory
    params, coefficients, table, rig, scale = rig_case(name)
    rng = np.random.default_rng(seed)
    synthetic = G.simulate_rows(rig, make_trajectory("paper"), duration, cue_scale=scale,
                                rng=rng, zero_weight_fraction=0.05)
    rows = E.rows_from_float(params, synthetic.slot, synthetic.shift, synthetic.cue,
                             synthetic.weight, synthetic.row,
                             np.round(synthetic.time * CLOCK_MHZ * 1e6).astype(np.int64))
    result = E.solve_rows(params, coefficients, rows)
    exact = G.ShiftCoefficients.from_table(table[rows.slot, rows.row[:, None]])
    golden = G.solve_step(exact, params.cue_fmt.to_float(rows.cue),
                          params.shift_fmt.to_float(rows.shift), params.conf_fmt.to_float(rows.conf))
    start = (params.quat_fmt.quantize(synthetic.start[0]),
             params.position_fmt.quantize(synthetic.start[1]))
    # every row's step composed in one slot: 57,600 compositions in a second, where a
    # slot of the pose ring makes one per frame — the integrator's arithmetic, stressed
    quats, positions = E.integrate_rows(params, result, np.zeros(len(rows), dtype=np.int64),
                                        start)
    q_float, p_float = G.integrate_steps(params.quat_fmt.to_float(start[0]),
                                         params.position_fmt.to_float(start[1]), golden.step)
    q_true, p_true = G.integrate_steps(params.quat_fmt.to_float(start[0]),
                                       params.position_fmt.to_float(start[1]), synthetic.true_step)
    q_fixed = params.quat_fmt.to_float(quats)
    p_fixed = params.position_fmt.to_float(positions)
    step = params.step_fmt.to_float(result.step)
    solved = (result.flags == 0) & golden.ok
    relative = (np.linalg.norm(step - golden.step, axis=1)[solved]
                / np.linalg.norm(golden.step[solved], axis=1))
    return {
        "rows": len(rows),
        "traj_err_cm": float(np.max(np.linalg.norm(p_fixed - p_float, axis=1)) * 100),
        "traj_err_deg": float(np.max(_quaternion_angle_deg(q_float, q_fixed))),
        "flagged_rows": int(np.sum(result.flags != 0)),
        "golden_unsolved_rows": int(np.sum(~golden.ok)),
        "step_rel_err_median": float(np.median(relative)),
        "step_rel_err_max": float(np.max(relative)),
        "condition_max": float(np.max(golden.condition[golden.ok])),
        "golden_vs_truth_cm": float(np.max(np.linalg.norm(p_float - p_true, axis=1)) * 100),
        "golden_vs_truth_deg": float(np.max(_quaternion_angle_deg(q_true, q_float))),
    }


def frame_chain_error(duration=SECOND, row_stride=8):
    """The pose ring's integration alone: every ``row_stride``-th row slot of a
    480-row, 120 fps rolling-shutter camera (stereo20 timing) composes the true
    one-frame motions of the papers' trajectory (quantized into ``step_fmt``) for
    ``duration`` s. Fixed point against the float64 composition of the same quantized
    steps (exact exponential). A one-frame step is 480 times a row's, so the increment
    must be third-order accurate: ``cubic_bound_deg`` is what a first-order
    ``δq = (1, θ/2)`` would lose (``|θ|³/12`` of rotation per step)."""
    from golden.rig import preset
    from golden.trajectory import make_trajectory
    from hdl.pose.params import PoseSolverParams
    params = PoseSolverParams()
    camera = preset("stereo20").cameras[0]
    frame = 1 / camera.fps
    slots = np.arange(0, camera.height, row_stride)
    frames = int(round(duration / frame)) + 1
    times = np.arange(frames)[:, None] * frame + slots[None, :] * camera.t_r
    rotation, position = make_trajectory("paper").pose(times.ravel())
    rotation = rotation.reshape(frames, len(slots), 3, 3)
    position = position.reshape(frames, len(slots), 3)
    steps = G.body_step(rotation[:-1], position[:-1], rotation[1:], position[1:])
    raw = params.step_fmt.quantize(steps.reshape(-1, 6))
    result = E.StepResult(step=raw, flags=np.zeros(len(raw), dtype=np.int64))
    quats, positions = E.integrate_rows(params, result, np.tile(slots, frames - 1))
    quats = params.quat_fmt.to_float(quats).reshape(frames - 1, len(slots), 4)
    positions = params.position_fmt.to_float(positions).reshape(frames - 1, len(slots), 3)
    quantized = params.step_fmt.to_float(raw).reshape(frames - 1, len(slots), 6)
    cm, deg = 0.0, 0.0
    for k in range(len(slots)):
        q_float, p_float = G.integrate_steps([1.0, 0, 0, 0], np.zeros(3), quantized[:, k])
        cm = max(cm, float(np.max(np.linalg.norm(positions[:, k] - p_float, axis=1))) * 100)
        deg = max(deg, float(np.max(_quaternion_angle_deg(q_float, quats[:, k]))))
    angle = np.linalg.norm(steps[..., 3:], axis=-1)
    return {"slots": len(slots), "steps_per_slot": frames - 1, "traj_err_cm": cm,
            "traj_err_deg": deg, "step_angle_max_deg": float(np.degrees(angle.max())),
            "cubic_bound_deg": float(np.degrees(np.max(np.sum(angle ** 3, axis=0)) / 12))}


#: Value classes of the solve (trace name prefixes) and what they are.
CLASSES = {"N": "scaled normal matrix N̂", "b": "scaled right-hand side b̂",
           "D": "pivots", "W": "Schur complements", "seed": "D^-1/2 seeds",
           "h": "D·seed", "e": "Newton factors", "rho": "D^-1/2", "P": "W·seed",
           "G": "Cholesky factor", "L": "G·ρ", "c": "forward sums", "z": "forward z",
           "w": "back w = z·ρ", "u": "back substitution", "Y": "step"}


def dynamic_range(name, count=3000, seed=2):
    """Largest magnitude of every value class of the solve over ``count`` rows of rig
    ``name`` (papers' motion, 0.01 px noise, 5 % zero weights), the smallest pivot,
    and the headroom: bits between the largest magnitude and the format's limit."""
    from golden.trajectory import make_trajectory
    params, coefficients, _, rig, scale = rig_case(name)
    synthetic = G.simulate_rows(rig, make_trajectory("paper"), count * rig.cameras[0].t_r,
                                cue_scale=scale, rng=np.random.default_rng(seed),
                                shift_noise=0.01, zero_weight_fraction=0.05)
    rows = E.rows_from_float(params, synthetic.slot, synthetic.shift, synthetic.cue,
                             synthetic.weight, synthetic.row, np.arange(count))
    solved = E.solve_rows(params, coefficients, rows).flags == 0
    trace = E.solve_trace(params, coefficients, rows)
    figures = {}
    for prefix in CLASSES:
        names = [n for n in trace if n.startswith(prefix) and n[len(prefix):][:1].isdigit()]
        values = [np.abs(trace[n].fmt.to_float(np.asarray(trace[n].raw, dtype=object)
                                               .astype(float)))[solved] for n in names]
        largest = float(max(v.max() for v in values))
        limit = trace[names[0]].fmt.max_value
        figures[f"{prefix}.max"] = largest
        figures[f"{prefix}.headroom_bits"] = round(math.log2(limit / largest), 1)
    pivots = [trace[f"D{j}"].fmt.to_float(np.asarray(trace[f"D{j}"].raw, dtype=object)
                                          .astype(float))[solved] for j in range(6)]
    figures["D.min"] = float(min(p.min() for p in pivots))
    return figures


def _timing(params, coefficients, rows):
    """Latency (first row, solver idle) and clocks between records of rows sent back to
    back at full rate once the pose ring is cleared after reset, from an Amaranth
    simulation checked against the model."""
    from amaranth.sim import Simulator
    from hdl.pose_solver import PoseSolver
    dut = PoseSolver(params, coefficients)
    transfers = rows.transfers()
    ends, outs, records = [], [], []

    async def bench(ctx):
        ctx.set(dut.o.ready, 1)
        queue = list(transfers)
        cycle = 0
        while len(outs) < len(rows):
            ctx.set(dut.i.valid, int(bool(queue) and cycle >= dut.clear_clocks))
            if queue:
                ctx.set(dut.i.payload, queue[0])
            taken = ctx.get(dut.i.valid) and ctx.get(dut.i.ready)
            if ctx.get(dut.o.valid):
                outs.append(cycle)
                records.append([ctx.get(dut.o.payload.step[k]) for k in range(6)])
            await ctx.tick()
            if taken and queue.pop(0)["last"]:
                ends.append(cycle)
            cycle += 1

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    model = E.solve_rows(params, coefficients, rows)
    if records != [list(s) for s in model.step]:
        raise AssertionError("pose solver simulation differs from emulator.pose_solver")
    gaps = np.diff(outs[1:])  # steady state: from the second row on
    return {"latency_clocks": outs[0] - ends[0], "clocks_per_row": int(np.max(gaps)),
            "declared_latency": dut.latency, "declared_row_interval": dut.row_interval}


def _timing_case(name, count=6):
    from golden.trajectory import make_trajectory
    params, coefficients, _, rig, scale = rig_case(name)
    synthetic = G.simulate_rows(rig, make_trajectory("paper"), count * rig.cameras[0].t_r,
                                cue_scale=scale, rng=np.random.default_rng(0))
    rows = E.rows_from_float(params, synthetic.slot, synthetic.shift, synthetic.cue,
                             synthetic.weight, synthetic.row, np.arange(count))
    return params, coefficients, _timing(params, coefficients, rows)


def measure():
    from hdl.pose_solver import PoseSolver
    figures = {}
    params8, coefficients8, timing = _timing_case("stereo8")
    figures.update(timing)
    figures["row_rate_khz"] = round(CLOCK_MHZ * 1e3 / timing["clocks_per_row"], 1)
    figures["latency_us"] = round(timing["latency_clocks"] / CLOCK_MHZ, 3)
    for name, key in (("stereo20", "cameras20"), ("radial4", "radial4")):
        params, coefficients, other = _timing_case(name)
        figures[f"{key}.clocks_per_row"] = other["clocks_per_row"]
        figures[f"{key}.latency_clocks"] = other["latency_clocks"]
        synth = synth_report(PoseSolver(params, coefficients), f"pose_solver_{name}")
        figures.update({f"{key}.{k}": synth[k] for k in ("lut", "bram36", "dsp48")})
    synth = synth_report(PoseSolver(params8, coefficients8), "pose_solver")
    figures.update({key: synth[key] for key in ("lut", "ff", "bram36", "dsp48", "carry4",
                                                "lutram", "lut_levels")})
    worst = {"traj_err_cm": 0.0, "traj_err_deg": 0.0}
    for name in ("stereo20", "radial4"):
        result = trajectory_error(name)
        for key, value in result.items():
            figures[f"{name}.{key}"] = value
        for key in worst:
            worst[key] = max(worst[key], result[key])
    figures.update(worst)
    figures.update({f"frame_chain.{k}": v for k, v in frame_chain_error().items()})
    for name in ("stereo20", "radial4"):
        for key, value in dynamic_range(name).items():
            figures[f"range.{name}.{key}"] = value
    return figures


def report(figures):
    def row(label, key, unit="", target=None):
        value = figures[key]
        text = f"{value:.3g}" if isinstance(value, float) else str(value)
        if key.endswith(".bram36"):  # the other builds: BRAM36 / LUT / DSP48 in one cell
            build = key[:-len(".bram36")]
            text = f"{value:g} / {figures[build + '.lut']} / {figures[build + '.dsp48']}"
        goal = f"≤ {target}" if target is not None else ""
        met = "" if target is None else (" ✓" if value <= target else " ✗")
        return f"| {label} | {text} {unit} | {goal}{met} |"

    main = "\n".join([
        row("clocks per row, 8 cameras", "clocks_per_row", "", TARGETS["clocks_per_row"]),
        row("row rate at 150 MHz, 8 cameras", "row_rate_khz", "kHz"),
        row("clocks per row, 20 cameras (stereo20)", "cameras20.clocks_per_row"),
        row("clocks per row, radial4 (32 segments)", "radial4.clocks_per_row"),
        row("latency, last measurement → pose record", "latency_clocks", "clocks",
            TARGETS["latency_clocks"]),
        row("latency at 150 MHz", "latency_us", "µs"),
        row("DSP48E1", "dsp48", "", TARGETS["dsp48"]),
        row("LUT", "lut"), row("FF", "ff"), row("BRAM36", "bram36"),
        row("LUT RAM cells (RAM64M, 4 LUTs each)", "lutram"), row("CARRY4", "carry4"),
        row("LUT levels (longest path)", "lut_levels"),
        row("BRAM36 / LUT / DSP48, 20 cameras", "cameras20.bram36"),
        row("BRAM36 / LUT / DSP48, radial4", "radial4.bram36"),
        row("trajectory error, worst rig (one slot, every row)", "traj_err_cm", "cm",
            TARGETS["traj_err_cm"]),
        row("orientation error, worst rig (one slot, every row)", "traj_err_deg", "°",
            TARGETS["traj_err_deg"]),
        row("position error, per-slot chains of one-frame steps", "frame_chain.traj_err_cm",
            "cm", TARGETS["traj_err_cm"]),
        row("orientation error, per-slot chains of one-frame steps",
            "frame_chain.traj_err_deg", "°", TARGETS["traj_err_deg"]),
    ])
    chain = {k[len("frame_chain."):]: v for k, v in figures.items()
             if k.startswith("frame_chain.")}
    rigs = []
    for name in ("stereo20", "radial4"):
        f = {k[len(name) + 1:]: v for k, v in figures.items() if k.startswith(name + ".")}
        rigs.append(f"| {name} | {f['rows']} | {f['traj_err_cm']:.3g} | {f['traj_err_deg']:.3g} | "
                    f"{f['step_rel_err_median']:.2g} / {f['step_rel_err_max']:.2g} | "
                    f"{f['flagged_rows']} | {f['condition_max']:.3g} | "
                    f"{f['golden_vs_truth_cm']:.3g} cm, {f['golden_vs_truth_deg']:.3g}° |")
    ranges = [f"| {CLASSES[c]} (`{c}`) | {figures[f'range.stereo20.{c}.max']:.3g} | "
              f"{figures[f'range.stereo20.{c}.headroom_bits']} | "
              f"{figures[f'range.radial4.{c}.max']:.3g} | "
              f"{figures[f'range.radial4.{c}.headroom_bits']} |" for c in CLASSES]
    return f"""# Pose solver

`hdl/pose_solver.py` (coefficient store, accumulator, Cholesky engine; see
`docs/pose/pose_solver.md`). Clocks per row and latency come from an Amaranth simulation of
the block with rows sent back to back at full rate (records checked against
`emulator/pose_solver.py`): 8 cameras (one camera of each of eight stereo20 pairs,
18-bit coefficient store, 480 rows), the full stereo20 rig (20 cameras) and radial4
(4 cameras × 8 segments). Resources are Yosys `synth_xilinx -family xc7` of each
build, the main figures for the 8-camera one (xc7z020: {XC7Z020['lut']} LUTs, {XC7Z020['dsp48']} DSP48E1,
{XC7Z020['bram36']} BRAM36); there is no vendor timing, so logic depth stands in for it.

| figure | value | target |
|---|---|---|
{main}

## Fixed point against float64 over {SECOND:g} s

The papers' test motion (1.4 m/s, 120°/s, `golden.trajectory.make_trajectory("paper")`)
through the box room, every row of every camera, noise-free shifts, 5 % of the
weights zero. Both the emulator and the golden float64 solver get the same quantized
rows; the golden solver uses the exact coefficients, so the error includes the 18-bit
coefficient store. "Step error" is |Y_fixed − Y_float| / |Y_float| per solved row;
"golden vs truth" checks the float tracker itself against the true motion.

| rig | rows | position error (cm) | orientation error (°) | step error median / max | flagged rows | worst condition | golden vs truth |
|---|---|---|---|---|---|---|---|
{chr(10).join(rigs)}

## The pose ring's chains over {SECOND:g} s

Each row slot composes one step per frame: the rig's motion since the same row one
frame earlier (`docs/pose/pose_solver.md`, "Pose ring"). {chain['slots']} slots (every 8th
row of a 480-row, 120 fps camera) each compose {chain['steps_per_slot']} true
one-frame steps of the papers' motion (up to {chain['step_angle_max_deg']:.3g}° each),
quantized into the step format, in fixed point (`emulator.pose_solver.integrate_rows`)
and in float64 with the exact exponential: worst {chain['traj_err_cm']:.3g} cm and
{chain['traj_err_deg']:.3g}°. The increment `δq = (1 − |θ|²/12, θ/2)` turns by
`|θ| + O(|θ|⁵)`; the first-order `(1, θ/2)` would turn `|θ|³/12` too little per step,
{chain['cubic_bound_deg']:.3g}° summed over a slot's steps — negligible for one row's
step, not for one frame's.
(The rows above with "one slot, every row" compose every row's solved step in one
slot — 57,600 compositions of small steps: the solve and the arithmetic, not the
ring's semantics.)

## Dynamic range of the solve

Largest magnitude of each value class over 3,000 rows of each rig (papers' motion,
0.01 px shift noise, 5 % zero weights, solved rows), and the headroom: bits between it
and the limit of the value's format (`docs/fixed_point.md`). Smallest pivot: stereo20
{figures['range.stereo20.D.min']:.3g}, radial4 {figures['range.radial4.D.min']:.3g} (the
pivot check's threshold is 2^-20 ≈ 9.5e-7).

| value | stereo20 max | headroom (bits) | radial4 max | headroom (bits) |
|---|---|---|---|---|
{chr(10).join(ranges)}
"""

"""Robust consistency stage: router → consistency → pose solver (issue 16 item 3).

The gateware twin of :class:`emulator.measurement.consistency.ConsistencyModel` (its
docstring lists every step and rounding; formats in
:class:`hdl.measurement.consistency_params.ConsistencyParams`). Inside:

* a *judge* that takes one measurement at a time: its segment's reference-time factor
  ``P/(P − Δ)`` (one division, only when the camera or the row offset Δ differs from
  the previous measurement's: a camera's segments that read the same row share one),
  the products (in the DSPs' registers), the scaled shift, the innovation, the outlier
  test with ``kσ`` (a register after each, for the 8 LUT levels of ``docs/timing.md``)
  and the ratio division, then the output register. The two divisions share one
  :class:`SerialDivider`;
* beside it, the *depth weight* ``d² / (d² + ((σ_d/s) p_T)²)``: the product and the
  squares in registers while the judge scales the shift, then its own
  :class:`SerialDivider`, started a clock before the ratio division so that the
  confidence times the weight is registered when the ratio arrives (no clock added);
* an *updater* that runs the scale recursion (four product stages, a
  :class:`SerialSqrt`, rounding, ceiling, floor) of the previous measurement while the judge works
  on the next one; the judge waits only if the next measurement's channel is the one
  being updated (a row's channels are distinct, so only across rows);
* per-channel ``σ`` in a ``slots``-word memory, written with ``min(max(scale_initial,
  scale_floor), scale_ceiling)`` after reset (``slots`` clocks, the stage is not ready meanwhile).

Measurements are forwarded as they are judged (not buffered per row: a row of 80 would
add 80 judge periods, ~9 µs, to the loop's latency). The row gates need all of a row,
so the verdict ``gated`` comes with the row's ``last`` transfer; the solver must then
treat the row as the model's zeroed confidences make it: flag it EMPTY, no step
(``docs/measurement/consistency.md``).
"""

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from golden.checks import check_int
from hdl.fixed import SQ, Overflow, QFormat, Rounding, hdl_add, hdl_mul, hdl_resize
from hdl.measurement.consistency_params import ConsistencyParams
from hdl.measurement.serial_units import SerialDivider, SerialSqrt
from hdl.pose.accumulator import measurement_layout

__all__ = ["ConsistencyStage", "judge_layout", "settings_layout", "counts_layout",
           "COUNTS", "settings_init", "default_consistency_stage", "confidence_floor"]

#: The counters, as :attr:`ConsistencyModel.counts` names them (16-bit, wrapping).
COUNTS = ("far_rows", "time_saturated", "innovation_saturated", "scale_saturated",
          "shift_saturated", "outliers", "gated_rows")
COUNTER_BITS = 16
HE, SAT, WRAP, ERR = Rounding.HALF_EVEN, Overflow.SATURATE, Overflow.WRAP, Overflow.ERROR


def judge_layout(params):
    """One measurement with what the forecast says about it: the solver's
    ``measurement_layout`` fields, its ``predicted`` shift (``predicted_fmt``, the
    forecast's ``a·Ŷ`` with the measurement's own cue), that shift's ``translation``
    part (``predicted_fmt``, ``a_T·T̂``) and its segment's row offset
    ``delta = source − row`` (signed, ``row_bits + 1``: the previous frame's row its
    lane segment read)."""
    fields = dict(measurement_layout(params.solver).members)
    fields.update(predicted=params.predicted_fmt.shape(),
                  translation=params.predicted_fmt.shape(),
                  delta=signed(params.solver.row_bits + 1))
    return data.StructLayout(fields)


def settings_layout(params):
    """The run-time registers, raw in their formats (``keep = 1 − λ``, ``lam_ck = λ·c_k``)."""
    return data.StructLayout({
        "frame_rows": params.frame_rows_fmt.width, "max_row_offset": params.solver.row_bits,
        "huber_k": params.k_fmt.width, "scale_initial": params.scale_fmt.width,
        "scale_floor": params.scale_fmt.width, "scale_ceiling": params.scale_fmt.width,
        "keep": params.gain_fmt.width, "lam_ck": params.gain_fmt.width,
        "min_confidence": params.solver.conf_fmt.width, "min_cameras": range(params.cameras + 1),
        "depth_ratio": params.depth_ratio_fmt.width})


def settings_init(params):
    """The registers' reset values: the parameters'."""
    return {"frame_rows": params.frame_rows_raw, "max_row_offset": params.max_row_offset,
            "huber_k": params.k_raw, "scale_initial": params.initial_raw,
            "scale_floor": params.floor_raw, "scale_ceiling": params.ceiling_raw,
            "keep": params.keep_raw,
            "lam_ck": params.lam_ck_raw, "min_confidence": params.min_confidence_raw,
            "min_cameras": params.min_cameras, "depth_ratio": params.depth_ratio_raw}


def counts_layout():
    return data.StructLayout({name: COUNTER_BITS for name in COUNTS})


def _narrowed(m, value, src, dst, name):
    """(saturated, wrapped) half-even narrowings, as nets: they differ when it saturated
    (the model's count), a comparison the judge's pipeline makes a clock later."""
    value = _net(m, value, f"{name}_exact")
    return (_net(m, hdl_resize(value, src, dst, HE, SAT), name),
            _net(m, hdl_resize(value, src, dst, HE, WRAP), f"{name}_wrapped"))


def _saturated(m, value, src, dst, name):
    """(saturated narrowing, whether it saturated) of a half-even narrowing, as nets."""
    out, wrapped = _narrowed(m, value, src, dst, name)
    return out, _net(m, out != wrapped, f"{name}_saturated")


def confidence_floor(least, shift):
    """The least ``x`` whose half-even rounding by ``shift`` bits is at least ``least``
    (an unsigned value): ``least·2^shift − half``, one more for an odd ``least`` (its tie
    rounds down to the even ``least − 1``), 0 for 0. The row gates compare the
    confidence product with it instead of rounding first; for ``least`` = 1 it is
    ``half + 1``."""
    return Mux(least == 0, 0, (least << shift) - (1 << (shift - 1)) + least[0])


def _net(m, value, name):
    """``value`` as a named combinational signal: shared subexpressions stay shared (the
    simulator and RTLIL back ends would otherwise copy them at every use)."""
    from amaranth.hdl import Value
    value = Value.cast(value)
    sig = Signal(value.shape(), name=name)
    m.d.comb += sig.eq(value)
    return sig


def _popcount(bits):
    return sum(bits[k] for k in range(len(bits)))


class ConsistencyStage(wiring.Component):
    """Bit-exact with :meth:`ConsistencyModel.apply` row by row.

    Parameters
    ----------
    params : ConsistencyParams
    bits_per_clock : int
        Quotient and root bits per clock of the iterative units (1 … 4).

    Members
    -------
    i : In(stream.Signature(judge_layout(params)))
        The router's transfers with their predicted shifts and row offsets; a row's
        slots distinct, ``last`` on its final one.
    o : Out(stream.Signature(measurement_layout(params.solver)))
        The same transfers, ``shift`` and ``conf`` judged (the model's verdict before the
        row gates); one per input transfer.
    judged, outlier : Out(1)
        With ``o.valid``: the measurement's confidence into the judge was not 0 (after a
        far camera's zeroing; its scale was updated), and it was an outlier whose shift
        was replaced by the prediction (the model's ``verdict["outlier"]``). With
        ``o.payload.conf != 0`` these are the per-measurement verdict bits the tracking
        status counts (``measurement_verdicts``).
    gated : Out(1)
        With ``o.valid`` and ``o.payload.last``: the row failed the gates (the model sets
        all its confidences to 0).
    determinable : Out(1)
        With ``o.valid`` and ``o.payload.last``: at least ``min_cameras`` of the row's
        cameras are near (``|delta| ≤ max_row_offset``), the model's ``determinable``
        (0 on the row's other transfers).
    settings : In(settings_layout(params)), reset to the parameters'
        Change them between rows.
    counts : Out(counts_layout())
        The model's counters, modulo 2**16 (``gated_rows`` counts a row the clock after
        its last ``o.valid`` rises).

    Timing: :attr:`latency` clocks from a measurement's transfer to its ``o.valid`` when
    its time factor is known (the previous measurement had the same camera and row
    offset), :attr:`time_clocks` more otherwise; a new transfer
    may be taken the clock after ``o.valid`` when ``o`` is ready. With confidence, the
    updater needs :attr:`update_clocks` per measurement, which bounds the rate.
    """

    def __init__(self, params, *, bits_per_clock=2):
        if not isinstance(params, ConsistencyParams):
            raise TypeError(f"params must be a ConsistencyParams, not {params!r}")
        check_int("bits_per_clock", bits_per_clock, 1, 4)
        self.params, self.bits_per_clock = params, bits_per_clock
        self._formats()
        #: Per-channel σ (raw ``scale_fmt``); tests read its final contents.
        self.scale_memory = Memory(shape=params.scale_fmt.width, depth=params.channels,
                                   init=[])
        layout = measurement_layout(params.solver)
        super().__init__({
            "i": In(stream.Signature(judge_layout(params))),
            "o": Out(stream.Signature(layout)), "gated": Out(1), "determinable": Out(1),
            "judged": Out(1), "outlier": Out(1),
            "settings": In(settings_layout(params), init=settings_init(params)),
            "counts": Out(counts_layout())})

    def _formats(self):
        p, s = self.params, self.params.solver
        self.ks_fmt = QFormat(False, p.k_fmt.int_bits + p.scale_fmt.int_bits,
                              p.k_fmt.frac_bits + p.scale_fmt.frac_bits)
        self.frac = max(self.ks_fmt.frac_bits, p.innovation_fmt.frac_bits)
        self.cmp_width = max(self.ks_fmt.width, p.innovation_fmt.width + self.frac
                             - p.innovation_fmt.frac_bits)
        fr = p.frame_rows_fmt
        self.den_width = max(fr.width, s.row_bits + fr.frac_bits) + 2
        num_width = max(fr.width + p.time_fmt.frac_bits, self.cmp_width + p.ratio_fmt.frac_bits)
        quotient_bits = max(p.time_fmt.width, p.ratio_fmt.frac_bits + 1)
        self.divider = SerialDivider(num_width, max(self.den_width, self.cmp_width),
                                     quotient_bits, self.bits_per_clock)
        square = QFormat(False, 2 * p.scale_fmt.int_bits, 2 * p.scale_fmt.frac_bits)
        self.square_fmt = square
        self.wide_fmt = QFormat(False, square.int_bits + p.gain_fmt.int_bits, square.frac_bits)
        self.sqrt = SerialSqrt(self.wide_fmt.width, self.bits_per_clock)
        term = p.depth_term_fmt
        self.depth_square_width = 2 * (term.width - 1)
        self.depth_divider = SerialDivider(self.depth_square_width + p.ratio_fmt.frac_bits,
                                           self.depth_square_width + 1,
                                           p.ratio_fmt.frac_bits + 1, self.bits_per_clock)
        # its quotient has no more bits than the ratio division's (which also holds
        # the time factor), so a clock's lead makes it ready first
        # clocks: TAKE, CAMERA (the products), SCALE, INNOVATION, JUDGE (starts the
        # divider), its steps, the verdict; a measurement with a new camera or row offset
        # goes CAMERA (starts the division P/(P − Δ)), its steps, the factor, then CAMERA
        # again
        self.time_clocks = self.divider.steps + 2
        self.latency = self.divider.steps + 6
        self.update_clocks = self.sqrt.steps + 6

    def elaborate(self, platform):
        m = Module()
        p, s = self.params, self.params.solver
        m.submodules.divider = div = self.divider
        m.submodules.depth_divider = depth_div = self.depth_divider
        m.submodules.sqrt = sqrt = self.sqrt
        m.submodules.scale = scale = self.scale_memory
        read, write = scale.read_port(domain="comb"), scale.write_port()
        cfg = self.settings
        one = 1 << p.ratio_fmt.frac_bits
        camera_of = Array(Const(slot // p.segments, range(p.cameras))
                          for slot in range(p.channels))

        # --- judge state -----------------------------------------------------------
        meas = Signal(judge_layout(p))
        camera = Signal(range(p.cameras))
        cached, cached_camera = Signal(), Signal(range(p.cameras))
        cached_delta = Signal.like(meas.delta)
        factor = Signal(p.time_fmt.width)
        far_seen, conf_cams, near_cams = (Signal(p.cameras) for _ in range(3))
        far_r = Signal()                         # ``far`` of the measurement being judged
        max_conf = Signal(s.conf_fmt.width)
        sigma = Signal(p.scale_fmt.width)
        conf = Signal(s.conf_fmt.width)
        outlier = Signal()
        counts = self.counts

        delta = _net(m, meas.delta, "delta")
        far = _net(m, Mux(delta < 0, -delta, delta) > cfg.max_row_offset, "far")
        # P / (P − Δ): numerator and denominator (Δ = 0 for a far camera)
        fr = p.frame_rows_fmt
        offset = Mux(far, 0, delta) << fr.frac_bits
        time_den = _net(m, (cfg.frame_rows - offset)[:self.den_width], "time_den")
        time_num = cfg.frame_rows << p.time_fmt.frac_bits
        q_time, r_time = div.quotient, div.remainder
        held_den = Signal(self.den_width)        # time_den, for the rounding at the end
        m.d.sync += held_den.eq(time_den)
        up = _net(m, (r_time << 1 > held_den) | ((r_time << 1 == held_den) & q_time[0]), "up")
        time_factor = _net(m, (q_time + up)[:p.time_fmt.width], "time_factor")

        # the innovation, kσ and the outlier test of the latched measurement, a register
        # after each step (free-running: each holds while the measurement and its factor
        # do). 1: the products, in the DSPs' output registers
        product, product_fmt = hdl_mul(meas.shift, s.shift_fmt, factor, p.time_fmt)
        product_r = Signal(product.shape())
        ks = Signal(self.ks_fmt.width)
        m.d.sync += [product_r.eq(product),
                     ks.eq(hdl_mul(cfg.huber_k, p.k_fmt, read.data, p.scale_fmt)[0])]
        # 2: the shift at the reference time, saturated and wrapped
        scaled_now, scaled_wrapped_now = _narrowed(m, product_r, product_fmt, s.shift_fmt,
                                                   "scaled")
        scaled, scaled_wrapped = Signal(s.shift_fmt.shape()), Signal(s.shift_fmt.shape())
        m.d.sync += [scaled.eq(scaled_now), scaled_wrapped.eq(scaled_wrapped_now)]
        # 3: the innovation, saturated and wrapped; whether the shift saturated
        predicted = _net(m, meas.predicted, "predicted")
        negated = SQ(p.predicted_fmt.int_bits + 1, p.predicted_fmt.frac_bits)
        exact, exact_fmt = hdl_add(scaled, s.shift_fmt, -predicted, negated)
        inn = p.innovation_fmt
        r_now, r_wrapped_now = _narrowed(m, exact, exact_fmt, inn, "r")
        r, r_wrapped, time_sat = Signal(inn.shape()), Signal(inn.shape()), Signal()
        m.d.sync += [r.eq(r_now), r_wrapped.eq(r_wrapped_now),
                     time_sat.eq(scaled != scaled_wrapped)]
        innovation_sat = _net(m, r != r_wrapped, "innovation_sat")
        # 4: the outlier test a = |r|·2^e > b, without |r| in front of the comparison,
        # and the division's operands (max(a, b) is 0 only when r and kσ are)
        abs_r = _net(m, Mux(r < 0, -r, r).as_unsigned()[:inn.width], "abs_r")
        a = _net(m, abs_r << (self.frac - inn.frac_bits), "a")
        b = _net(m, ks << (self.frac - self.ks_fmt.frac_bits), "b")
        r_aligned = r << (self.frac - inn.frac_bits)
        is_outlier = _net(m, Mux(r < 0, r_aligned + b < 0, r_aligned > b), "is_outlier")
        ratio_den = _net(m, Mux((r == 0) & (ks == 0), 1, Mux(is_outlier, a, b)), "ratio_den")

        # the depth weight, from the latched measurement and the setting (they hold from
        # CAMERA on): 1: the cue on the weight's grid and (σ_d/s)·p_T exact; 2: the
        # second rounded, both squared (the judge's SCALE); the division started in
        # INNOVATION
        term = p.depth_term_fmt
        d_u = Signal(term.shape())
        v_product, v_fmt = hdl_mul(meas.translation, p.predicted_fmt, cfg.depth_ratio,
                                   p.depth_ratio_fmt)
        d_v = Signal(v_product.shape())
        m.d.sync += [d_u.eq(hdl_resize(meas.cue, s.cue_fmt, term, HE, ERR)),
                     d_v.eq(v_product)]
        v_rounded = _net(m, hdl_resize(d_v, v_fmt, term, HE, ERR), "depth_v")
        d_a, d_b = (Signal(self.depth_square_width, name=n) for n in ("depth_a", "depth_b"))
        m.d.sync += [d_a.eq(d_u * d_u), d_b.eq(v_rounded * v_rounded)]
        d_a1 = _net(m, Mux((d_a == 0) & (d_b == 0), 1, d_a), "depth_a1")
        depth_w = _net(m, depth_div.quotient[:p.ratio_fmt.width], "depth_w")
        conf_d = Signal(s.conf_fmt.width)        # conf · w_d, ready with the ratio
        m.d.sync += conf_d.eq(hdl_resize(*hdl_mul(conf, s.conf_fmt, depth_w, p.ratio_fmt),
                                         s.conf_fmt, HE, ERR))

        # the verdict of the division
        q = _net(m, div.quotient[:p.ratio_fmt.width], "q")
        weight = _net(m, Mux(outlier, q, one), "weight")
        t = _net(m, Mux(outlier, one, q), "t")
        ok = _net(m, conf != 0, "ok")
        judged, judged_fmt = hdl_mul(conf_d, s.conf_fmt, weight, p.ratio_fmt)
        judged = _net(m, judged, "judged")
        conf_out = _net(m, Mux(ok, hdl_resize(judged, judged_fmt, s.conf_fmt, HE, ERR), 0),
                        "conf_out")
        replacement, replacement_sat = _saturated(m, predicted, p.predicted_fmt, s.shift_fmt,
                                                  "replacement")
        replaced = ok & outlier
        this_camera = (Const(1, p.cameras) << camera)[:p.cameras]
        # The row gates, max(conf_out, max_conf) < min_confidence and
        # popcount(conf_cams | camera if conf_out ≠ 0) < min_cameras, split so that only
        # two comparisons of the product ``judged`` wait for the division: the rest are
        # registers of the row so far (free-running; the row's state changes the clock
        # after a verdict, ``post``). conf_out is ``judged`` rounded (0 when not ok: conf
        # is 0 then): conf_out < m when judged < confidence_floor(m), ≠ 0 when > half.
        shift = judged_fmt.frac_bits - s.conf_fmt.frac_bits
        below, fresh, short, short_more = Signal(), Signal(), Signal(), Signal()
        low = Signal(judged_fmt.width + 1)
        cams = _net(m, _popcount(conf_cams), "cams")
        m.d.sync += [below.eq(max_conf < cfg.min_confidence),
                     low.eq(confidence_floor(cfg.min_confidence, shift)),
                     fresh.eq(~conf_cams.bit_select(camera, 1)),
                     short.eq(cams < cfg.min_cameras), short_more.eq(cams + 1 < cfg.min_cameras)]
        gated_now = _net(m, (below & (judged < low))
                         | Mux((judged > (1 << (shift - 1))) & fresh, short_more, short),
                         "gated_now")
        # determinable: popcount(near_cams | camera unless far) ≥ min_cameras, split the
        # same way (only ``far_r`` and the verdict's camera are of this measurement)
        near_short, near_short_more, near_fresh = Signal(), Signal(), Signal()
        near = _net(m, _popcount(near_cams), "near")
        m.d.sync += [near_fresh.eq(~near_cams.bit_select(camera, 1)),
                     near_short.eq(near < cfg.min_cameras),
                     near_short_more.eq(near + 1 < cfg.min_cameras)]
        determinable_now = _net(m, ~Mux(~far_r & near_fresh, near_short_more, near_short),
                                "determinable_now")
        post = Signal()
        out_conf = self.o.payload.conf

        # --- updater state -------------------------------------------------------------
        u_busy, u_slot = Signal(), Signal(range(p.channels))
        u_sigma, u_t = Signal(p.scale_fmt.width), Signal(p.ratio_fmt.width)
        u_v, u_v2 = Signal(p.ratio_fmt.width), Signal(p.ratio_fmt.width)
        u_factor = Signal(p.gain_fmt.width)
        clearing = Signal(init=1)
        clear_addr = Signal(range(p.channels))
        handoff = Signal()

        o_free = ~self.o.valid | self.o.ready
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        m.d.comb += read.addr.eq(meas.slot)

        with m.FSM(name="judge"):
            with m.State("TAKE"):
                hazard = u_busy & (u_slot == self.i.payload.slot)
                m.d.comb += self.i.ready.eq(~clearing & ~hazard)
                with m.If(self.i.valid & self.i.ready):
                    m.d.sync += [meas.eq(self.i.payload),
                                 camera.eq(camera_of[self.i.payload.slot])]
                    m.next = "CAMERA"
            with m.State("CAMERA"):
                with m.If(cached & (cached_camera == camera) & (cached_delta == meas.delta)):
                    m.next = "SCALE"
                with m.Else():
                    m.d.comb += [div.start.eq(1), div.num.eq(time_num), div.den.eq(time_den)]
                    with m.If(far & ~far_seen.bit_select(camera, 1)):
                        m.d.sync += far_seen.eq(far_seen | this_camera)
                    m.next = "TIME"
            with m.State("TIME"):
                with m.If(~div.busy):
                    m.d.sync += [factor.eq(time_factor), cached.eq(1),
                                 cached_camera.eq(camera), cached_delta.eq(meas.delta)]
                    m.next = "CAMERA"           # now cached: the products of the factor
            with m.State("SCALE"):
                m.next = "INNOVATION"
            with m.State("INNOVATION"):
                m.d.comb += [depth_div.start.eq(1),
                             depth_div.num.eq(d_a1 << p.ratio_fmt.frac_bits),
                             depth_div.den.eq(d_a1 + d_b)]
                m.next = "JUDGE"
            with m.State("JUDGE"):
                m.d.comb += [div.start.eq(1), div.num.eq(Mux(is_outlier, b, a)
                                                         << p.ratio_fmt.frac_bits),
                             div.den.eq(ratio_den)]
                m.d.sync += [outlier.eq(is_outlier), sigma.eq(read.data), far_r.eq(far),
                             conf.eq(Mux(far, 0, meas.conf)),
                             counts.time_saturated.eq(counts.time_saturated + time_sat),
                             counts.innovation_saturated.eq(
                                 counts.innovation_saturated + innovation_sat)]
                m.next = "DIVIDE"
            with m.State("DIVIDE"):
                with m.If(~div.busy & o_free & ~(ok & u_busy)):
                    m.d.comb += handoff.eq(ok)
                    m.d.sync += [self.o.valid.eq(1), post.eq(1),
                                 *[getattr(self.o.payload, n).eq(getattr(meas, n))
                                   for n in self.o.payload.shape().members],
                                 self.o.payload.shift.eq(Mux(replaced, replacement, scaled)),
                                 out_conf.eq(conf_out),
                                 self.gated.eq(meas.last & gated_now),
                                 self.determinable.eq(meas.last & determinable_now),
                                 self.judged.eq(ok), self.outlier.eq(replaced),
                                 counts.outliers.eq(counts.outliers + replaced),
                                 counts.shift_saturated.eq(counts.shift_saturated
                                                           + (replaced & replacement_sat))]
                    with m.If(meas.last):
                        m.d.sync += [far_seen.eq(0), cached.eq(0),
                                     counts.far_rows.eq(counts.far_rows
                                                        + _popcount(far_seen))]
                    m.next = "TAKE"

        # the row so far, from the verdict just registered (``camera`` is the verdict's
        # until the next transfer's clock ends)
        with m.If(post):
            m.d.sync += post.eq(0)
            with m.If(self.o.payload.last):
                m.d.sync += [conf_cams.eq(0), max_conf.eq(0), near_cams.eq(0),
                             counts.gated_rows.eq(counts.gated_rows + self.gated)]
            with m.Else():
                m.d.sync += [conf_cams.eq(conf_cams | Mux(out_conf != 0, this_camera, 0)),
                             near_cams.eq(near_cams | Mux(far_r, 0, this_camera)),
                             max_conf.eq(Mux(out_conf > max_conf, out_conf, max_conf))]

        # --- updater: σ' = max(min(round(√(σ² f)), ceiling), floor) -------------------------
        rf, gf = p.ratio_fmt, p.gain_fmt

        def ratio(x, y):
            return hdl_resize(*hdl_mul(x, rf, y, rf), rf, HE, ERR)

        v3 = _net(m, ratio(u_v2, u_v), "v3")
        gained = _net(m, hdl_resize(*hdl_mul(cfg.lam_ck, gf, one - v3, rf), gf, HE, ERR),
                      "gained")
        square = _net(m, hdl_mul(u_sigma, p.scale_fmt, u_sigma, p.scale_fmt)[0], "square")
        n = _net(m, hdl_resize(*hdl_mul(square, self.square_fmt, u_factor, gf), self.wide_fmt,
                               HE, ERR), "n")
        root = Signal(sqrt.bits + 1)
        top = cfg.scale_ceiling
        capped = _net(m, Mux(root > top, top, root), "capped")
        raised = _net(m, Mux(cfg.scale_initial > cfg.scale_floor, cfg.scale_initial,
                             cfg.scale_floor), "raised")
        initial = _net(m, Mux(raised > top, top, raised), "initial")

        def take_handoff():
            with m.If(handoff):
                m.d.sync += [u_busy.eq(1), u_slot.eq(meas.slot), u_sigma.eq(sigma),
                             u_t.eq(t)]
                m.next = "V"

        with m.FSM(name="updater"):
            with m.State("CLEAR"):
                m.d.comb += [write.en.eq(1), write.addr.eq(clear_addr), write.data.eq(initial)]
                m.d.sync += clear_addr.eq(clear_addr + 1)
                with m.If(clear_addr == p.channels - 1):
                    m.d.sync += clearing.eq(0)
                    m.next = "IDLE"
            with m.State("IDLE"):
                take_handoff()
            with m.State("V"):
                m.d.sync += u_v.eq(one - ratio(u_t, u_t))
                m.next = "V2"
            with m.State("V2"):
                m.d.sync += u_v2.eq(ratio(u_v, u_v))
                m.next = "FACTOR"
            with m.State("FACTOR"):
                m.d.sync += u_factor.eq(cfg.keep + gained)
                m.next = "SQUARE"
            with m.State("SQUARE"):
                m.d.comb += [sqrt.start.eq(1), sqrt.n.eq(n)]
                m.next = "ROOT"
            with m.State("ROOT"):
                # the rounded root registered; the channel is free: the judge reads σ
                # the clock after it takes a measurement, when WRITE has written it
                with m.If(~sqrt.busy):
                    m.d.sync += [u_busy.eq(0),
                                 root.eq(sqrt.root + (sqrt.remainder > sqrt.root))]
                    m.next = "WRITE"
            with m.State("WRITE"):
                m.d.comb += [write.en.eq(1), write.addr.eq(u_slot),
                             write.data.eq(Mux(capped < cfg.scale_floor, cfg.scale_floor,
                                               capped))]
                m.d.sync += counts.scale_saturated.eq(counts.scale_saturated + (root > top))
                m.next = "IDLE"
                take_handoff()
        return m


def default_consistency_stage():
    """The stage of the board's closed-loop top (:func:`hdl.top.closed_loop_top`, the
    ``stereo8-board`` rig) as its tracking loop builds it: the catalog's build, for
    Verilog and synthesis."""
    from golden.rig import preset
    from hdl.top import board_config
    return ConsistencyStage(board_config(preset("stereo8-board")).top.consistency)

"""The forecast's per-row predictor: from the forecast ``Ŷ``, a camera row and the depth
cue of each of its segments, each camera's window centre and source row addresses
(:meth:`emulator.pose.forecast.ForecastModel.predict` in gateware, bit for bit).

Two lanes run side by side, one per coefficient store: the solver's store (the shift
along the row) and the across-rows store (the displacement across rows), each in
the solver's store layout — polynomials in
the row evaluated by Horner (``PipelineConfig.coef_store``, ``.row_coef_store``), or
every row — as a :class:`hdl.pose.coef_term_store.TermStore`: only the two coefficients
of the term in progress are evaluated, without the run-time write port. The lane of the
faster store has its address delayed so both lanes' coefficients arrive together. Per
segment and
lane, six terms, one per clock: the design entry ``a_i`` of the solver's arithmetic
(``w·a_T`` or ``a_R + w·a_C``, rounded half-even into ``a_fmt``, saturated), then
``a_i·Ŷ_i`` summed exactly and rounded once into ``displacement_fmt`` (saturation
flagged per segment). Per camera the K segment values are summed; the mean is rounded
half-up (a shift: K must be a power of two) and saturated with a flag. Each segment's
displacement across rows is also rounded half-up on its own: the row its lane segment
reads (``segment_rows``), saturated to the frame with a flag.

Each lane has two multipliers: ``coef × cue`` (18 × 18 bits, one DSP48) and
``a × Ŷ`` (``a_fmt`` × ``motion_fmt``, 25 × 40 bits, two DSP48 and an adder), each
with registered operands and product.
"""

from amaranth.hdl import Array, Cat, Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out, connect, flipped

from hdl.fixed import SQ, Overflow, QFormat, Rounding, hdl_add, hdl_mul, hdl_resize, mul_format
from hdl.pose.coef_term_store import TermStore, term_read_signature
from hdl.pose.forecast_params import ForecastParams

__all__ = ["RowPredictor", "output_layout", "counters_layout", "term_tag",
           "displacement_terms", "TERM_STAGES"]

#: Registered stages of a term after its coefficients arrive, up to the camera's output
#: (:func:`displacement_terms` and the camera sum).
TERM_STAGES = 6


def counters_layout(params):
    """Saturations since reset (wrapping, ``solver.counter_bits`` each): window centres,
    row addresses, segment values (shift or across-rows displacement, each counted), and
    the motion filter's updates and forecasts with a value saturated into ``motion_fmt``
    (the loop diverging)."""
    bits = params.solver.counter_bits
    return data.StructLayout({"centre": bits, "row": bits, "segment": bits, "motion": bits})


def output_layout(params):
    """One camera's forecast for the row; a row is ``cameras`` transfers, camera 0
    first, ``last`` on the final one.

    Fields
    ------
    camera : unsigned
    row : unsigned(row_bits)
        The camera row the forecast is for (the request's).
    centre : signed
        Window centre (pixels), saturated to ``±centre_range``.
    source_row : unsigned(row_bits)
        The previous frame's row the camera's mean displacement names, saturated to
        ``[0, height − 1]`` (a diagnostic: the lanes and the consistency stage use
        ``segment_rows``; its saturations are ``counters.row``).
    centre_saturated, row_saturated : 1
        The centre or the row address was saturated.
    shift_saturated, across_saturated : K bits
        Segment ``k``'s predicted shift or across-rows displacement left
        ``displacement_fmt`` (bit ``k``; saturated before the mean).
    segment_rows : ArrayLayout(unsigned(row_bits), K)
        The previous frame's row each segment reads: ``row`` minus the segment's
        displacement across rows rounded half-up, saturated to ``[0, height − 1]``.
    segment_rows_saturated : K bits
        Segment ``k``'s row address was saturated (bit ``k``).
    last : 1
    """
    return data.StructLayout({
        "camera": range(params.cameras), "row": params.solver.row_bits,
        "centre": signed(params.centre_range.bit_length() + 1),
        "source_row": params.solver.row_bits, "centre_saturated": 1, "row_saturated": 1,
        "shift_saturated": params.segments, "across_saturated": params.segments,
        "segment_rows": data.ArrayLayout(params.solver.row_bits, params.segments),
        "segment_rows_saturated": params.segments, "last": 1,
    })


class RowPredictor(wiring.Component):
    """Window centres and source rows of one camera row.

    Parameters
    ----------
    params : ForecastParams
    coefficients, row_coefficients : ndarray (slots, entries_per_slot, 9)
        Raw contents of the solver's store and of the across-rows store in their
        layouts (``params.solver``, ``params.row_store``): polynomial terms
        (``PipelineConfig.coef_store``, ``.row_coef_store``) or every row.

    Members
    -------
    start : In(1)
        Take ``row`` and ``cue`` (when ``idle``); the row runs once ``motion_valid``.
    row : In(row_bits)
    cue : In(ArrayLayout(cue_fmt, slots))
    motion : In(ArrayLayout(motion_fmt, 6)); motion_valid : In(1)
        The forecast ``Ŷ`` for the row.
    motion_saturated : In(1)
        The motion filter's strobe (:attr:`hdl.pose.forecast_filter.MotionFilter.saturated`),
        counted in ``counters.motion``.
    idle : Out(1)
    o : Out(stream.Signature(output_layout(params)))
    counters : Out(counters_layout(params))
    coef : In(term_read_signature(solver))
        With ``shared_port``: the second read port of the solver's store (the shift along
        the row; the memories' second port and its own Horner datapath), data
        ``solver.coef_latency`` clocks after the (slot, row, term):
        :class:`hdl.pose.measured_shift.MeasuredShift` reads it.

    Timing: a camera takes ``6K`` issue clocks, its result appears :attr:`drain` clocks
    after its last term, and the next camera starts the clock after its transfer
    (:attr:`camera_clocks` per camera).
    """

    def __init__(self, params, coefficients, row_coefficients, *, shared_port=False):
        if not isinstance(params, ForecastParams):
            raise TypeError(f"params must be a ForecastParams, not {params!r}")
        k = params.segments
        if k & (k - 1):
            raise ValueError(f"segments must be a power of two in the gateware (the "
                             f"camera mean is a shift), not {k}")
        self.params = params
        s = params.solver
        self.stores = (TermStore(s, coefficients, name="coefficients",
                                 second_read=shared_port),
                       TermStore(params.row_store, row_coefficients, name="row_coefficients"))
        #: Clocks from a term's (slot, row) to its coefficients, both lanes.
        self.store_latency = max(store.params.coef_latency for store in self.stores)
        self.shared_port = shared_port
        shared = {"coef": In(term_read_signature(s))} if shared_port else {}
        super().__init__({
            **shared,
            "start": In(1), "row": In(s.row_bits),
            "cue": In(data.ArrayLayout(s.cue_fmt.shape(), s.slots)),
            "motion": In(data.ArrayLayout(params.motion_fmt.shape(), 6)),
            "motion_valid": In(1),
            "motion_saturated": In(1),
            "idle": Out(1),
            "o": Out(stream.Signature(output_layout(params))),
            "counters": Out(counters_layout(params)),
        })

    @property
    def drain(self):
        """Clocks from a camera's last issued term to its output: the stores' latency,
        then coef × cue, a, a × Ŷ, exact sum, rounding and camera sum, mean and
        saturation."""
        return self.store_latency + TERM_STAGES

    @property
    def camera_clocks(self):
        """Clocks per camera when its output is taken at once (the next camera's first
        term issues the clock after the transfer)."""
        return 6 * self.params.segments + self.drain

    def elaborate(self, platform):
        p = self.params
        s = p.solver
        m = Module()
        k, cameras = p.segments, p.cameras

        # --- the row: taken at start, run once the forecast arrives
        row = Signal(s.row_bits)
        cue = Signal(data.ArrayLayout(s.cue_fmt.shape(), s.slots))
        motion = Signal(data.ArrayLayout(p.motion_fmt.shape(), 6))
        waiting, active = Signal(), Signal()     # for Ŷ; a row is in progress
        m.d.comb += self.idle.eq(~active)
        with m.If(self.start & ~active):
            m.d.sync += [row.eq(self.row), cue.eq(self.cue), waiting.eq(1), active.eq(1)]

        # --- issue: camera by camera, segment by segment, six terms each
        camera, segment, term = Signal(range(cameras)), Signal(range(k)), Signal(range(6))
        issuing = Signal()
        with m.If(waiting & self.motion_valid):
            m.d.sync += [motion.eq(self.motion), waiting.eq(0), issuing.eq(1),
                         camera.eq(0), segment.eq(0), term.eq(0)]
        channel = camera * k + segment
        end_of_camera = (segment == k - 1) & (term == 5)
        with m.If(issuing):
            m.d.sync += term.eq(term + 1)
            with m.If(term == 5):
                m.d.sync += [term.eq(0), segment.eq(segment + 1)]
            with m.If(end_of_camera):
                m.d.sync += [segment.eq(0), issuing.eq(0)]

        # stage tags: valid, term, segment, end of camera (stages 1 .. latency + 5); the
        # coefficients of the term issued at stage 0 arrive at stage ``latency``
        latency = self.store_latency
        tags = [Signal(term_tag(p), name=f"tag{n}") for n in range(latency + TERM_STAGES)]
        m.d.comb += [tags[0].valid.eq(issuing), tags[0].term.eq(term),
                     tags[0].segment.eq(segment), tags[0].end.eq(end_of_camera)]
        m.d.sync += [tags[n + 1].eq(tags[n]) for n in range(len(tags) - 1)]
        stages = tags[latency - 1:]     # stages[1]: the coefficients are there
        cue1 = Signal(s.cue_fmt.shape())
        m.d.sync += cue1.eq(Array(cue)[camera * k + stages[0].segment])
        y2 = Signal(p.motion_fmt.shape())
        m.d.sync += y2.eq(motion[stages[1].term])

        means, flags, values = [], [], []
        for lane, store in enumerate(self.stores):
            m.submodules[f"store{lane}"] = store
            slot, at, index = channel, row, tags[0].term
            for n in range(latency - store.params.coef_latency):   # meet the slower lane
                slot, at, index = (_delayed(m, slot, f"slot{lane}_{n}"),
                                   _delayed(m, at, f"row{lane}_{n}"),
                                   _delayed(m, index, f"term{lane}_{n}"))
            m.d.comb += [store.slot.eq(slot), store.row.eq(at), store.term.eq(index)]
            mean, flag, value = self._lane(m, lane, store, stages, cue1, y2)
            means.append(mean)
            flags.append(flag)
            values.append(value)
        if self.shared_port:
            connect(m, flipped(self.coef), self.stores[0].second_port)

        # --- the camera's result: saturate, hold until taken
        centre, source = means[0], row - means[1]
        centre_over = (centre < -p.centre_range) | (centre > p.centre_range)
        row_over = (source < 0) | (source > p.height - 1)
        segments_over = sum(flag[n] for flag in flags for n in range(k))
        # each segment's own row: its displacement across rows, rounded half-up
        dst = p.displacement_fmt
        whole_fmt = SQ(dst.int_bits + 1, 0)
        across = Array(Signal(whole_fmt.shape(), name=f"across{n}") for n in range(k))
        with m.If(stages[5].valid & (stages[5].term == 5)):
            m.d.sync += across[stages[5].segment].eq(
                hdl_resize(values[1], dst, whole_fmt, Rounding.HALF_UP, Overflow.ERROR))
        segment_sources = [row - value for value in across]
        last_camera = camera == cameras - 1
        counters = self.counters
        with m.If(stages[6].valid & stages[6].end):
            m.d.sync += [
                self.o.valid.eq(1), self.o.p.camera.eq(camera), self.o.p.last.eq(last_camera),
                self.o.p.row.eq(row),
                self.o.p.centre.eq(_clamp(centre, -p.centre_range, p.centre_range)),
                self.o.p.centre_saturated.eq(centre_over),
                self.o.p.source_row.eq(_clamp(source, 0, p.height - 1)),
                self.o.p.row_saturated.eq(row_over),
                self.o.p.shift_saturated.eq(flags[0]), self.o.p.across_saturated.eq(flags[1]),
                *[self.o.p.segment_rows[n].eq(_clamp(source, 0, p.height - 1))
                  for n, source in enumerate(segment_sources)],
                self.o.p.segment_rows_saturated.eq(
                    Cat((source < 0) | (source > p.height - 1) for source in segment_sources)),
                counters.centre.eq(counters.centre + centre_over),
                counters.row.eq(counters.row + row_over),
                counters.segment.eq(counters.segment + segments_over),
            ]
        with m.If(self.motion_saturated):
            m.d.sync += counters.motion.eq(counters.motion + 1)
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += [self.o.valid.eq(0), camera.eq(camera + 1)]
            with m.If(last_camera):
                m.d.sync += active.eq(0)
            with m.Else():
                m.d.sync += issuing.eq(1)
        return m

    def _lane(self, m, lane, store, tags, cue1, y2):
        """One store's datapath from its coefficients; returns (the camera mean of its
        displacements, rounded half-up to pixels; the per-segment saturation flags; each
        segment's displacement, valid while ``tags[5]`` holds its sixth term)."""
        p, k = self.params, self.params.segments
        value, over = displacement_terms(m, p, store.params, store.first, store.second, tags,
                                         cue1, y2, f"{lane}")
        dst = p.displacement_fmt
        shift = (k - 1).bit_length()
        camera_fmt = QFormat(True, dst.int_bits + shift + 1, dst.frac_bits + shift)
        camera_sum = Signal(camera_fmt.shape(), name=f"camera_sum{lane}")
        flags = Signal(k, name=f"saturated{lane}")
        first = tags[5].segment == 0
        with m.If(tags[5].valid & (tags[5].term == 5)):
            m.d.sync += [camera_sum.eq(Mux(first, 0, camera_sum) + value),
                         flags.eq(Mux(first, 0, flags) | (over << tags[5].segment))]
        # the mean: ⌊sum / (K·2**frac) + 1/2⌋
        mean = hdl_resize(camera_sum, camera_fmt, SQ(camera_fmt.int_bits, 0), Rounding.HALF_UP,
                          Overflow.ERROR)
        return mean, flags, value


def term_tag(params):
    """A term's tag along :func:`displacement_terms`' stages: valid, which of the six
    terms, the segment and the end of a camera (the row predictor's)."""
    return data.StructLayout({"valid": 1, "term": range(6), "segment": range(params.segments),
                              "end": 1})


def displacement_terms(m, params, store, first, second, tags, cue1, y2, name):
    """A segment's predicted displacement ``a·Ŷ``, one term per clock: the design entry
    ``a_i`` of the solver's arithmetic from the store's coefficients of the term,
    ``first`` and ``second`` (a :class:`hdl.pose.coef_term_store.TermStore` port's data,
    there while ``tags[1]`` holds the term), the product ``a_i·Ŷ_i`` summed exactly and
    rounded once, half-even, into ``displacement_fmt`` (saturated).

    ``tags`` are ``TERM_STAGES + 1`` registered stages of :func:`term_tag` (``tags[n]``
    the term ``n`` clocks after the clock before its coefficients arrive: its issue for a
    store of latency 1); ``cue1`` is the segment's cue and ``y2`` the term's ``Ŷ_i``,
    valid with ``tags[1]`` and ``tags[2]``. Returns (value, saturated), combinational,
    valid while ``tags[5]`` holds the sixth term."""
    p, a_fmt = params, params.solver.a_fmt
    width = store.coef_width
    # stage 1 → 2: coef × cue, and a_R for the rotation terms
    t_fmt = mul_format(store.coef_t_fmt, store.cue_fmt)
    c_fmt = mul_format(store.coef_c_fmt, store.cue_fmt)    # the same raw width
    product = Signal(t_fmt.shape(), name=f"coef_cue{name}")
    rotation = Signal(signed(width), name=f"coef_r{name}")
    m.d.sync += [product.eq(hdl_mul(first, store.coef_t_fmt, cue1, store.cue_fmt)[0]),
                 rotation.eq(second)]
    # stage 2 → 3: the design entry a (the solver's rounding and saturation)
    total, total_fmt = hdl_add(rotation, store.coef_r_fmt, product, c_fmt)
    a = Signal(a_fmt.shape(), name=f"a{name}")
    y3 = Signal(p.motion_fmt.shape(), name=f"y3_{name}")
    m.d.sync += [a.eq(Mux(tags[2].term < 3,
                           hdl_resize(product, t_fmt, a_fmt, Rounding.HALF_EVEN,
                                      Overflow.SATURATE),
                           hdl_resize(total, total_fmt, a_fmt, Rounding.HALF_EVEN,
                                      Overflow.SATURATE))),
                 y3.eq(y2)]
    # stage 3 → 4: a × Ŷ; 4 → 5: exact sum of the six terms
    term_value, term_fmt = hdl_mul(a, a_fmt, y3, p.motion_fmt)
    term = Signal(term_fmt.shape(), name=f"term{name}")
    m.d.sync += term.eq(term_value)
    sum_fmt = QFormat(True, term_fmt.int_bits + 4, term_fmt.frac_bits)
    acc = Signal(sum_fmt.shape(), name=f"sum{name}")
    with m.If(tags[4].valid):
        m.d.sync += acc.eq(Mux(tags[4].term == 0, 0, acc) + term)
    # stage 5: one half-even rounding into displacement_fmt, flagged
    dst = p.displacement_fmt
    wide_fmt = SQ(max(sum_fmt.int_bits, dst.int_bits) + 2, dst.frac_bits)
    wide = hdl_resize(acc, sum_fmt, wide_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
    over = (wide > dst.max_raw) | (wide < dst.min_raw)
    return hdl_resize(wide, wide_fmt, dst, Rounding.FLOOR, Overflow.SATURATE), over


def _clamp(value, low, high):
    return Mux(value < low, low, Mux(value > high, high, value))


def _delayed(m, value, name):
    held = Signal.like(value, name=name)
    m.d.sync += held.eq(value)
    return held

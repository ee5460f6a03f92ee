"""The one description of a pipeline built for a rig: :class:`PipelineConfig`.

Everything that must agree between the HDL top, the board tops, the bit-accurate
pipeline, the co-simulation, ``rowtrack run`` and the benches is derived here once, from
the rig: the cameras and their stereo pairs, the temporal segments per row (K), the row
width and height, every lane and solver format, the coefficient store and the system
clock. The HDL's parameters are a :class:`hdl.top_params.TopParams`; the emulator reads
the same object (``config.router`` is ``config.top.engine.router``), so no width or K is
typed twice.

No Amaranth at import time.
"""

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from golden.checks import check_int
from golden.depth import stereo_pairs
from golden.descriptor import segment_bounds
from golden.pose_lsq import shift_coefficients
from golden.tracker_params import DEFAULT_MOTION_GAIN

from hdl.front_end.params import CameraParams
from hdl.measurement.consistency_params import ConsistencyParams
from hdl.measurement.router_params import StereoWindow
from hdl.pose.forecast_params import ForecastParams
from hdl.fixed import Overflow, Rounding
from hdl.pose.params import (DEFAULT_COEF_WIDTH, PoseSolverParams, coefficient_formats,
                             quantize_coefficients)
from hdl.pose.row_polynomials import (evaluate_polynomials, fit_row_polynomials,
                                      polynomial_formats, quantize_polynomials,
                                      shift_polynomials)
from hdl.top_params import DEFAULT_SEGMENTS, TopParams

__all__ = ["PipelineConfig", "segment_centres", "coefficient_table", "DEFAULT_COEF_DEGREE",
           "DEFAULT_ROW_COEF_DEGREE"]

#: System clock (FCLK_CLK0) the time stamps count.
DEFAULT_CLK_HZ = 100_000_000
#: Degree of the solver store's polynomials in the row: a rectified pinhole camera's
#: coefficients along the row are exactly linear in it (:mod:`hdl.pose.row_polynomials`).
DEFAULT_COEF_DEGREE = 1
#: Degree of the forecast's across-rows store: the displacement across rows of a rotation
#: is quadratic in the row (``1 + y²``), so degree 1 would miss it by many LSB.
DEFAULT_ROW_COEF_DEGREE = 2
#: Largest difference (LSB of the coefficient formats) a polynomial store may make
#: against the per-row store of the same table: the terms' rounding plus the fit.
COEF_POLYNOMIAL_TOLERANCE_LSB = 1


def segment_centres(lane):
    """Pixel columns of the centres of a lane's segments (run-time centre 0): where the
    coefficient of each segment's equation is evaluated."""
    return np.array([(lo + hi - 1) / 2 for lo, hi in
                     segment_bounds(lane.width, lane.descriptor, lane.match)])


def coefficient_table(rig, lane, cue_scales, axis=0):
    """Float coefficient table (cameras · K, rows, 9), camera-major, at the lane's
    segment centres, each camera with its cue scale ``1/(f·b)``; ``axis`` 0: the shift
    along the row (the solver's), 1: the displacement across rows (the forecast's)."""
    rows = np.arange(lane.height, dtype=float)[None, :]
    centres = segment_centres(lane)[:, None]
    return np.concatenate([shift_coefficients(cam, centres, rows, scale, axis).table()
                           for cam, scale in zip(rig.cameras, cue_scales)])


@dataclass(frozen=True, eq=False)
class PipelineConfig:
    """A pipeline for one rig (build it with :meth:`for_rig`).

    Members
    -------
    top : TopParams
        The HDL top's parameters: cameras, pairs, K, lane and solver formats, clock.
    table : ndarray (slots, rows, 9)
        The rig's float coefficients at the lanes' segment centres.
    coef_raw : ndarray (slots, rows, 9)
        The coefficients the solver uses for every row, raw in its formats (the
        emulator's table): the polynomial store evaluated at each row, or ``table``
        quantized when the store holds every row.
    coef_store : ndarray (slots, entries_per_slot, 9)
        The solver's coefficient store contents (the HDL's): polynomial terms, or
        ``coef_raw`` itself.
    coef_error_lsb : int
        Largest difference between ``coef_raw`` and ``table`` quantized directly, in
        LSB of the coefficient formats (0 for a store of every row).
    row_table, row_coef_raw, row_coef_store, row_coef_error_lsb
        The same for the displacement across rows (the forecast's second store), in the
        formats of :attr:`row_store`: polynomials of ``row_coef_degree`` in the row.
    row_store : PoseSolverParams
        The across-rows store's formats (``ForecastParams.row_store`` of
        :meth:`forecast`).
    rig_name : str
    frame_rows : float
        Row periods per frame period (``1/(fps·t_r)``, blanking included): the
        consistency stage's reference-time correction.
    trigger_skew_rows : float
        Largest difference of the cameras' trigger offsets, in row periods: how far
        apart in time the cameras read the same row index (0 for synchronized triggers;
        stereo8-board: 1.5 ms = 108 rows). :meth:`alignment_shortfall` compares it with
        what the front end's row aligner holds.
    """
    top: TopParams
    table: np.ndarray
    coef_raw: np.ndarray
    coef_store: np.ndarray
    coef_error_lsb: int
    row_table: np.ndarray
    row_coef_raw: np.ndarray
    row_coef_store: np.ndarray
    row_coef_error_lsb: int
    row_store: PoseSolverParams
    rig_name: str
    frame_rows: float
    trigger_skew_rows: float

    @classmethod
    def for_rig(cls, rig, *, segments=DEFAULT_SEGMENTS, coef_width=DEFAULT_COEF_WIDTH,
                coef_degree=DEFAULT_COEF_DEGREE, row_coef_degree=DEFAULT_ROW_COEF_DEGREE,
                clk_hz=DEFAULT_CLK_HZ,
                camera=CameraParams(), closed_loop=False, motion_gain=DEFAULT_MOTION_GAIN,
                **top_changes):
        """The pipeline for ``rig``: its cameras (one image size), each in the rectified
        stereo pair :func:`golden.depth.stereo_pairs` finds, temporal lanes of
        ``segments`` segments, a ``coef_width``-bit coefficient store whose formats hold
        the rig's table — as polynomials of ``coef_degree`` in the row (``None``: every
        row stored) —, the forecast's across-rows store likewise with ``row_coef_degree``,
        time stamps in clocks of ``clk_hz``. ``camera`` gives the front
        end's other widths (its count and size come from the rig); ``top_changes`` go to
        :class:`TopParams` (e.g. ``pose_output``, ``uart``, ``baud``); the stereo lanes'
        ``stereo_window`` defaults to the pairs' (:meth:`StereoWindow.for_pairs`: the
        golden tracker's depth range and guard bands). ``closed_loop``:
        the top closes the measurement loop with the default :meth:`forecast` and
        :meth:`consistency` of the rig (``TopParams.forecast``/``.consistency``), the forecast's
        filter with ``motion_gain`` (``ForecastParams``; the open-loop pipeline takes it
        in :meth:`forecast`).

        Raises
        ------
        ValueError
            Naming what the rig or a parameter cannot meet: cameras of different sizes,
            a camera without a rectified stereo partner (the hardware's only depth cue).
        """
        check_int("segments", segments, 1)
        check_int("clk_hz", clk_hz)
        sizes = {(cam.width, cam.height) for cam in rig.cameras}
        if len(sizes) != 1:
            raise ValueError(f"rig cameras must share one image size, not {sorted(sizes)}")
        (width, height), = sizes
        pairs = stereo_pairs(rig)
        scales = np.full(len(rig.cameras), np.nan)
        for left, right, focal_baseline in pairs:
            scales[[left, right]] = 1.0 / focal_baseline
        if np.isnan(scales).any():
            missing = [n for n in range(len(rig.cameras)) if np.isnan(scales[n])]
            raise ValueError(f"rig {rig.name!r}: cameras {missing} have no rectified stereo "
                             f"partner, the hardware's only depth cue")
        camera = replace(camera, n_cameras=len(rig.cameras), max_width=width,
                         max_height=height)
        top_changes.setdefault("stereo_window",
                               StereoWindow.for_pairs([fb for _, _, fb in pairs]))
        pairs = tuple((a, b) for a, b, _ in pairs)
        shape = TopParams.for_pairs(pairs, segments=segments, camera=camera, clk_hz=clk_hz,
                                    **top_changes)
        table = coefficient_table(rig, shape.engine.temporal, scales)
        solver = replace(shape.solver, **coefficient_formats(table, coef_width))
        solver, coef_store, coef_raw, error = _store(solver, table, coef_degree, rig.name,
                                                     "coef_degree")
        top = TopParams.for_pairs(pairs, segments=segments, camera=camera, solver=solver,
                                  clk_hz=clk_hz, **top_changes)
        row_table = coefficient_table(rig, shape.engine.temporal, scales, axis=1)
        row_store = replace(solver, **coefficient_formats(row_table, coef_width),
                            coef_poly_fmts=())
        row_store, row_coef_store, row_coef_raw, row_error = _store(
            row_store, row_table, row_coef_degree, rig.name, "row_coef_degree")
        config = cls(top=top, table=table, coef_raw=coef_raw, coef_store=coef_store,
                     coef_error_lsb=error, row_table=row_table, row_coef_raw=row_coef_raw,
                     row_coef_store=row_coef_store, row_coef_error_lsb=row_error,
                     row_store=row_store, rig_name=rig.name,
                     frame_rows=1.0 / (rig.cameras[0].fps * rig.cameras[0].t_r),
                     trigger_skew_rows=_trigger_skew_rows(rig))
        if not closed_loop:
            return config
        return replace(config, top=top.closing(config.forecast(motion_gain=motion_gain),
                                               config.consistency()))

    def store_window(self, first_row, rows, store="solver"):
        """The contents of a store for a window of ``rows`` camera rows from
        ``first_row`` (:meth:`window`): the polynomials in the window's row index, or the
        window's rows. ``store``: ``"solver"`` (:attr:`coef_store`, also the forecast's
        shift store) or ``"row"`` (:attr:`row_coef_store`, the forecast's across-rows
        store)."""
        stores = {"solver": (self.top.solver, self.coef_store),
                  "row": (self.row_store, self.row_coef_store)}
        if store not in stores:
            raise ValueError(f"store must be 'solver' or 'row', not {store!r}")
        params, contents = stores[store]
        check_int("first_row", first_row, 0, params.rows - 1)
        check_int("rows", rows, 1, params.rows - first_row)
        if not params.coef_terms:
            return contents[:, first_row:first_row + rows]
        return shift_polynomials(contents, first_row)

    @property
    def forecast_stores(self):
        """The closed-loop top's ``forecast_stores``: the shift store's contents (the
        solver's, :attr:`coef_store`) and the across-rows store's
        (:attr:`row_coef_store`)."""
        return self.coef_store, self.row_coef_store

    def forecast(self, **changes):
        """The motion forecast of this pipeline (:class:`ForecastParams`): its solver,
        segments, rows and the lanes' centre range, the across-rows store's formats;
        ``changes`` set the others (e.g. ``loop_delay_rows``, ``alpha``)."""
        if self.top.closed_loop:
            return replace(self.top.forecast, **changes)
        row, lane = self.row_store, self.router.temporal
        derived = dict(solver=self.top.solver, segments=self.segments, height=lane.height,
                       centre_range=lane.centre_range, row_coef_t_fmt=row.coef_t_fmt,
                       row_coef_c_fmt=row.coef_c_fmt, row_coef_r_fmt=row.coef_r_fmt,
                       row_coef_poly_fmts=row.coef_poly_fmts)
        return ForecastParams(**{**derived, **changes})

    def consistency(self, **changes):
        """The robust consistency stage of this pipeline (:class:`ConsistencyParams`): its
        solver and segments, the forecast's predicted-shift format; ``changes`` set the
        others (e.g. ``huber_k``, ``min_cameras``)."""
        if self.top.closed_loop:
            return replace(self.top.consistency, **changes)
        derived = dict(solver=self.top.solver, segments=self.segments,
                       predicted_fmt=self.forecast().displacement_fmt,
                       frame_rows=self.frame_rows, max_row_offset=self._row_offset_bound())
        return ConsistencyParams(**{**derived, **changes})

    def _row_offset_bound(self):
        """The consistency stage's default ``max_row_offset``: its field default, at most
        ``rows − 1``, and small enough that the reference-time factor ``P/(P − Δ)`` fits
        its ``time_fmt`` (a rig cut to a few rows without blanking, ``P`` = rows, would
        need a factor of ``rows``)."""
        frame_fmt = fields_default(ConsistencyParams, "frame_rows_fmt")
        top = fields_default(ConsistencyParams, "time_fmt").max_value
        period = int(frame_fmt.quantize(self.frame_rows, Rounding.HALF_EVEN, Overflow.ERROR))
        # Δ·2**f ≤ P_raw·(1 − 1/top), so that P_raw / (P_raw − Δ·2**f) ≤ top
        held = math.floor(period * (1 - 1 / top)) >> frame_fmt.frac_bits
        return min(fields_default(ConsistencyParams, "max_row_offset"),
                   self.top.solver.rows - 1, held)

    def window(self, rows, **top_changes):
        """The top of this pipeline built for cameras of ``rows`` rows (a co-simulated
        window): the same lanes' arithmetic, router and solver formats; the memories
        indexed by row hold ``rows`` rows."""
        top = self.top
        check_int("rows", rows, 1, top.camera.max_height)
        kept = {f.name: getattr(top, f.name) for f in fields(top)
                if f.init and f.name not in ("camera", "pairs", "segments", "solver")}
        kept.update(forecast=None, consistency=None)
        window = TopParams.for_pairs(top.pairs, segments=top.segments,
                                     camera=replace(top.camera, max_height=rows),
                                     solver=top.solver, **{**kept, **top_changes})
        if not top.closed_loop:
            return window
        # the loop's solver is the window's; the forecast and the stage address its rows
        stage = top.consistency
        return window.closing(replace(top.forecast, solver=window.solver, height=rows),
                              replace(stage, solver=window.solver,
                                      max_row_offset=min(stage.max_row_offset, rows - 1)))

    def alignment_shortfall(self):
        """``None`` when the front end's row aligner can form this pipeline's row sets
        (row ``y`` of every camera, what the emulator's pipeline feeds the lanes), else
        a sentence saying why not: the rig's trigger skew in rows against
        :meth:`hdl.front_end.params.CameraParams.skew_rows_held` and the buffer and row
        queue the skew would need."""
        camera, width = self.top.camera, self.router.temporal.width
        held = camera.skew_rows_held(width)
        skew = math.ceil(self.trigger_skew_rows - 1e-9)
        if skew <= held:
            return None
        return (f"the rig's trigger offsets read the same row {self.trigger_skew_rows:.1f} "
                f"row periods apart, the row aligner holds {held} (buffer_depth "
                f"{camera.buffer_depth} pixels, row_queue_depth {camera.row_queue_depth} at "
                f"{width}-pixel rows): row sets of row y need buffer_depth ≥ {skew * width} "
                f"and row_queue_depth ≥ {skew + 1} per camera")

    # --- the parts each model reads ------------------------------------------------------

    @property
    def router(self):
        """Lanes, pairs and solver of the measurement engine (the emulator's input)."""
        return self.top.engine.router

    @property
    def segments(self):
        return self.top.segments

    @property
    def clk_hz(self):
        return self.top.clk_hz


def fields_default(cls, name):
    """The default of dataclass ``cls``'s field ``name``."""
    return next(f.default for f in fields(cls) if f.name == name)


def _trigger_skew_rows(rig):
    """Largest difference of ``rig``'s trigger offsets, each in its camera's row
    periods."""
    offsets = [cam.trigger_offset / cam.t_r for cam in rig.cameras]
    return float(max(offsets) - min(offsets))


def _store(solver, table, degree, rig_name, name):
    """A store's parameters (the solver's, or the across-rows store's) with its formats,
    the store contents, the coefficients it gives every row and their largest difference
    (LSB) from ``table`` quantized per row; ``name`` is the degree's parameter."""
    direct = quantize_coefficients(solver, table)
    if degree is None:
        return solver, direct, direct, 0
    poly, _ = fit_row_polynomials(table, degree)
    solver = replace(solver, coef_poly_fmts=polynomial_formats(poly, solver.coef_group_fmts,
                                                               solver.rows))
    store = quantize_polynomials(solver, poly)
    coef_raw = evaluate_polynomials(solver, store, np.arange(solver.rows), Overflow.ERROR)
    error = int(np.abs(coef_raw - direct).max())
    if error > COEF_POLYNOMIAL_TOLERANCE_LSB:
        raise ValueError(f"{name} {degree}: rig {rig_name!r}'s coefficients differ from "
                         f"polynomials of that degree in the row by up to {error} LSB (at "
                         f"most {COEF_POLYNOMIAL_TOLERANCE_LSB} allowed); raise {name} "
                         f"or store every row ({name}=None)")
    return solver, store, coef_raw, error

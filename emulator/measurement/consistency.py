"""Bit-accurate model of the robust consistency stage: router → consistency → pose solver
(issue 16 item 3): the specification of the gateware
:class:`hdl.measurement.consistency.ConsistencyStage` (bit-exact with it,
``sim_tests/measurement/test_consistency_hdl.py`` and the cocotb bench).

The float original is :class:`golden.temporal_filter.RobustScale` as the golden tracker
uses it (``golden.tracker.Tracker._step``); the parameters and formats are
:class:`hdl.measurement.consistency_params.ConsistencyParams`. Integers only, every
narrowing through :func:`hdl.fixed.resize`. Per measurement of a row (one channel =
one solver slot; a measurement with zero confidence is passed on untouched and leaves
its channel's scale alone), after the camera's reference-time factor
``P/(P − Δ)`` (``Δ = source − row``, one division per camera, half-even into
``time_fmt``) has scaled its shift (half-even, saturated into ``shift_fmt``, counted);
a camera with ``|Δ| > max_row_offset`` gets zero confidence (counted):

0. depth weight (:meth:`ConsistencyModel.depth_weight`): ``u = d`` the cue and ``v =
   (σ_d/s)·p_T`` the register ``depth_ratio`` times the translation part of the
   predicted shift, each half-even into ``depth_term_fmt``; ``w_d = ⌊u²·2^F / (u² +
   v²)⌋`` into ``ratio_fmt`` (one when both are 0); the confidence becomes ``conf ·
   w_d`` (half-even into ``conf_fmt``);
1. innovation ``r = shift − predicted`` (exact, then half-even and saturated into
   ``innovation_fmt``, counted);
2. ``kσ`` (exact product); ``outlier = |r| > kσ``;
3. one division, floor into ``ratio_fmt``: ``q = min(|r|, kσ) / max(|r|, kσ)``. An
   inlier has ``|r|/kσ = q`` and weight 1; an outlier has ``|r|/kσ ≥ 1`` and the Huber
   weight ``kσ/|r| = q``;
4. confidence ``conf · w_d · weight`` (each product half-even into ``conf_fmt``); an outlier's shift is
   replaced by the prediction (half-even, saturated into ``shift_fmt``, counted);
5. scale: ``u = min(|r|/kσ, 1)²``, ``ρ/c_k = 1 − (1 − u)³`` (each product half-even
   into ``ratio_fmt``), factor ``f = (1 − λ) + λc_k · ρ/c_k`` (half-even into
   ``gain_fmt``), ``σ'² = σ² f`` (half-even to twice ``scale_fmt``'s fraction bits), ``σ'`` its square
   root rounded to nearest, at most the ceiling ``scale_ceiling`` (≤ the format's
   largest; an update beyond it is counted ``scale_saturated``), at least the floor.

Per row, the golden's gates: unless some confidence reaches ``min_confidence`` and at
least ``min_cameras`` cameras have a confidence, every confidence of the row is set to 0
(the solver then flags the row EMPTY and the forecast stands). The scales are updated
either way, as the golden's are. The row is *determinable* when at least
``min_cameras`` of its cameras are near (``|Δ| ≤ max_row_offset``), matched or not: the
tracking status counts its update fraction over those rows only (a readout gap, where
the cameras' rows are too far apart in time, is no evidence of a loss).
"""

import math

import numpy as np

from hdl.fixed import QFormat, SQ, Overflow, Rounding, add, mul, resize
from hdl.measurement.consistency_params import ConsistencyParams

__all__ = ["ConsistencyParams", "ConsistencyModel"]


def _divide_half_even(num, den):
    """``num / den`` rounded half-even (``den > 0``; integer arrays)."""
    q, r = np.divmod(num, den)
    return q + ((2 * r > den) | ((2 * r == den) & (q & 1 == 1)))


def _nearest_sqrt(n):
    """``round(√n)`` of non-negative integers (ties cannot occur: √n = m + ½ is never
    an integer's root)."""
    root = np.array([math.isqrt(int(v)) for v in n], dtype=np.int64)
    return root + (n - root * root > root)


class ConsistencyModel:
    """The stage with its per-channel state (``scale``, raw ``scale_fmt``).

    Parameters
    ----------
    params : ConsistencyParams
    """

    def __init__(self, params):
        if not isinstance(params, ConsistencyParams):
            raise TypeError(f"params must be a ConsistencyParams, not {params!r}")
        self.params = params
        self.scale = np.full(params.channels, params.initial_raw, dtype=np.int64)
        self.counts = {"far_rows": 0, "time_saturated": 0, "innovation_saturated": 0,
                       "scale_saturated": 0, "shift_saturated": 0, "outliers": 0,
                       "gated_rows": 0}

    def depth_weight(self, cue, translation):
        """Depth weights (raw ``ratio_fmt``) of measurements with cues ``cue`` (raw
        ``solver.cue_fmt``) whose predicted shifts have the translation parts
        ``translation`` (raw ``predicted_fmt``): step 0 of the module docstring."""
        p, term = self.params, self.params.depth_term_fmt
        u = resize(np.asarray(cue, dtype=np.int64), p.solver.cue_fmt, term,
                   Rounding.HALF_EVEN, Overflow.ERROR)
        v = resize(*mul(np.asarray(translation, dtype=np.int64), p.predicted_fmt,
                        p.depth_ratio_raw, p.depth_ratio_fmt), term,
                   Rounding.HALF_EVEN, Overflow.ERROR)
        a = np.where((u == 0) & (v == 0), 1, u * u)
        return (a << p.ratio_fmt.frac_bits) // (a + v * v)

    def judge(self, channel, shift, predicted, conf, depth_weight=None):
        """The verdict on measurements of distinct channels (raw int arrays: ``shift``
        ``solver.shift_fmt``, ``predicted`` ``predicted_fmt``, ``conf``
        ``solver.conf_fmt``, ``depth_weight`` ``ratio_fmt`` from :meth:`depth_weight`;
        None: one); updates those channels' scales. Returns a dict of raw
        arrays: ``shift``, ``conf`` (after the weights and replacement, before the row's
        gates), ``innovation`` (``innovation_fmt``), ``outlier`` and ``weight``
        (the Huber weight, ``ratio_fmt``)."""
        p, s = self.params, self.params.solver
        channel, conf = np.asarray(channel), np.asarray(conf, dtype=np.int64)
        weighted = conf if depth_weight is None else resize(
            *mul(conf, s.conf_fmt, np.asarray(depth_weight, dtype=np.int64), p.ratio_fmt),
            s.conf_fmt, Rounding.HALF_EVEN, Overflow.ERROR)
        predicted = np.asarray(predicted, dtype=np.int64)
        negated = SQ(p.predicted_fmt.int_bits + 1, p.predicted_fmt.frac_bits)
        exact, exact_fmt = add(np.asarray(shift, dtype=np.int64), s.shift_fmt, -predicted,
                               negated)
        r = resize(exact, exact_fmt, p.innovation_fmt, Rounding.HALF_EVEN, Overflow.SATURATE)
        self.counts["innovation_saturated"] += int(np.count_nonzero(
            (r != resize(exact, exact_fmt, p.innovation_fmt, Rounding.HALF_EVEN,
                         Overflow.WRAP))))
        sigma = self.scale[channel]
        ks, ks_fmt = mul(p.k_raw, p.k_fmt, sigma, p.scale_fmt)
        frac = max(ks_fmt.frac_bits, p.innovation_fmt.frac_bits)
        a = np.abs(r) << (frac - p.innovation_fmt.frac_bits)
        b = ks << (frac - ks_fmt.frac_bits)
        outlier = a > b
        q = (np.minimum(a, b) << p.ratio_fmt.frac_bits) // np.maximum(np.maximum(a, b), 1)
        one = 1 << p.ratio_fmt.frac_bits
        weight = np.where(outlier, q, one)
        t = np.where(outlier, one, q)
        ok = conf > 0
        out_conf = resize(*mul(weighted, s.conf_fmt, weight, p.ratio_fmt), s.conf_fmt,
                          Rounding.HALF_EVEN, Overflow.ERROR)
        replacement = resize(predicted, p.predicted_fmt, s.shift_fmt, Rounding.HALF_EVEN,
                             Overflow.SATURATE)
        replaced = ok & outlier
        self.counts["shift_saturated"] += int(np.count_nonzero(replaced & (
            replacement != resize(predicted, p.predicted_fmt, s.shift_fmt,
                                  Rounding.HALF_EVEN, Overflow.WRAP))))
        self.counts["outliers"] += int(np.count_nonzero(replaced))
        self.scale[channel[ok]] = self._update(sigma[ok], t[ok])
        return {"shift": np.where(replaced, replacement, shift),
                "conf": np.where(ok, out_conf, 0), "innovation": r,
                "outlier": replaced, "weight": np.where(ok, weight, 0)}

    def _ratio(self, raw, fmt):
        return resize(raw, fmt, self.params.ratio_fmt, Rounding.HALF_EVEN, Overflow.ERROR)

    def _update(self, sigma, t):
        """New scales (raw) from the scales ``sigma`` and ``t = min(|r|/kσ, 1)``."""
        p = self.params
        rf = p.ratio_fmt
        one = 1 << rf.frac_bits
        v = one - self._ratio(*mul(t, rf, t, rf))                  # 1 − u
        v3 = self._ratio(*mul(self._ratio(*mul(v, rf, v, rf)), rf, v, rf))
        gained = resize(*mul(p.lam_ck_raw, p.gain_fmt, one - v3, rf), p.gain_fmt,
                        Rounding.HALF_EVEN, Overflow.ERROR)
        factor = p.keep_raw + gained                               # < 1 + λ(c_k − 1) < 4
        square, square_fmt = mul(sigma, p.scale_fmt, sigma, p.scale_fmt)
        wide = QFormat(False, square_fmt.int_bits + p.gain_fmt.int_bits, square_fmt.frac_bits)
        n = resize(*mul(square, square_fmt, factor, p.gain_fmt), wide, Rounding.HALF_EVEN,
                   Overflow.ERROR)
        root = _nearest_sqrt(n)
        self.counts["scale_saturated"] += int(np.count_nonzero(root > p.ceiling_raw))
        return np.maximum(np.minimum(root, p.ceiling_raw), p.floor_raw)

    def time_factor(self, delta):
        """Raw ``time_fmt`` factors ``P/(P − Δ)`` of row offsets ``delta`` (integers)."""
        p = self.params
        frac = p.frame_rows_fmt.frac_bits
        offset = np.asarray(delta, dtype=np.int64) << frac
        return _divide_half_even(np.int64(p.frame_rows_raw) << p.time_fmt.frac_bits,
                                 p.frame_rows_raw - offset)

    def to_one_frame(self, shift, delta):
        """Shifts (raw ``shift_fmt``) of rows compared ``delta`` rows off, scaled to one
        frame period."""
        p, fmt = self.params, self.params.solver.shift_fmt
        product = mul(np.asarray(shift, dtype=np.int64), fmt, self.time_factor(delta),
                      p.time_fmt)
        out = resize(*product, fmt, Rounding.HALF_EVEN, Overflow.SATURATE)
        self.counts["time_saturated"] += int(np.count_nonzero(
            out != resize(*product, fmt, Rounding.HALF_EVEN, Overflow.WRAP)))
        return out

    def apply(self, transfers, predicted, delta, translation):
        """One row of router transfers (dicts in stream order, the row's slots distinct)
        with the forecast's predicted shift of every slot and its translation part (raw
        ``predicted_fmt``, (slots,) each) and each segment's row offset ``delta = source −
        row`` (slots,): the
        transfers the solver gets (copies) and the verdict of :meth:`judge` plus
        ``depth_weight`` (raw ``ratio_fmt``), ``gated`` (the row failed the gates), ``conf_in`` (the confidences the judge
        took: a channel whose source row was too far enters with 0) and
        ``determinable`` (at least ``min_cameras`` cameras have transfers and a source
        row within ``max_row_offset``: the row could step had they matched, the
        hardware's stand-in for :meth:`golden.tracker_solve.SlotSolver.determinable`)."""
        if not transfers:
            return [], None
        p = self.params
        channel = np.array([t["slot"] for t in transfers])
        delta = np.asarray(delta, dtype=np.int64)[channel]
        far = np.abs(delta) > p.max_row_offset
        self.counts["far_rows"] += len(np.unique(channel[far] // p.segments))
        delta = np.where(far, 0, delta)
        shift = self.to_one_frame([t["shift"] for t in transfers], delta)
        conf_in = np.where(far, 0, [t["conf"] for t in transfers])
        depth = self.depth_weight([t["cue"] for t in transfers],
                                  np.asarray(translation)[channel])
        verdict = self.judge(channel, shift, np.asarray(predicted)[channel], conf_in, depth)
        conf = verdict["conf"]
        cameras = np.unique(channel[conf > 0] // p.segments)
        gated = conf.max() < p.min_confidence_raw or len(cameras) < p.min_cameras
        self.counts["gated_rows"] += int(gated)
        near = np.unique(channel[~far] // p.segments)
        out = [{**t, "shift": int(sh), "conf": 0 if gated else int(c)}
               for t, sh, c in zip(transfers, verdict["shift"], conf)]
        return out, {**verdict, "gated": gated, "conf_in": conf_in, "depth_weight": depth,
                     "determinable": len(near) >= p.min_cameras}

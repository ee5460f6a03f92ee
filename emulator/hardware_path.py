"""The hardware path: the bit-accurate emulator's closed measurement loop (issue 16), as
``rowtrack run`` and ``rowtrack bench --only hw_tracking`` both run it.

:func:`hardware_config` (:meth:`hdl.pipeline_config.PipelineConfig.for_rig` with a
disparity per temporal segment), :func:`emulator.pipeline.run` closed through the
configuration's forecast, with the consistency stage and the stereo cue fallback,
started at the true one-frame motion of the first tracked row (the papers' "first frame
given", :func:`first_frame_motion`). Its estimate of each row's one-frame motion is the
motion track's ``Y`` (:meth:`HardwarePath.estimate`, :mod:`emulator.pose.motion_track`,
the gateware loop's ``track`` output); the forecast filter's level after each row's step
and the solver's raw steps are beside it (:meth:`HardwarePath.levels`,
:meth:`HardwarePath.steps`). Golden (b) with the same loop delay
and gain law is :func:`golden_b_params`. The comparisons and tolerances are
:mod:`emulator.e2e`'s.
"""

from dataclasses import dataclass

import numpy as np

from emulator.e2e import true_steps
from golden.tracker_params import DEFAULT_MOTION_GAIN

__all__ = ["first_frame_motion", "hardware_config", "golden_b_params", "HardwarePath",
           "closed_loop"]


def first_frame_motion(dataset, camera=0):
    """The true one-frame motion of the first tracked row (frame 1, row 0 of ``camera``):
    the loop's start, the papers' "first frame given". ``ValueError`` when the dataset's
    ground-truth poses of those rows are missing (not finite)."""
    if min(len(c.rows) for c in dataset.cameras) < 2:
        raise ValueError("the hardware path needs at least 2 frames")
    motion = true_steps(dataset, [1], [0], camera)[0]
    if not np.all(np.isfinite(motion)):
        raise ValueError(f"the dataset has no ground-truth pose for row 0 of frames 0 and 1 "
                         f"(camera {camera}); the hardware path starts from the true motion "
                         f"of the first tracked row (the papers' first frame given)")
    return motion


def hardware_config(rig):
    """The pipeline the hardware path runs: :meth:`PipelineConfig.for_rig` with golden
    (b)'s segments (:class:`golden.tracker_params.TrackerParams`' ``segments``, K = 8),
    temporal and stereo alike, so that the two compare like with like and each temporal
    segment's depth cue is interpolated from stereo segments as fine as it (the cue
    map, :mod:`hdl.measurement.cue_map_params`). ``ValueError`` for a rig the pipeline
    cannot take."""
    from golden.tracker_params import TrackerParams
    from hdl.pipeline_config import PipelineConfig
    segments = TrackerParams().segments
    return PipelineConfig.for_rig(rig, segments=segments, stereo_segments=segments)


def golden_b_params(loop_delay_rows, motion_gain=DEFAULT_MOTION_GAIN):
    """Golden reference (b) with the hardware's loop delay and gain law
    (:class:`hdl.pose.forecast_params.ForecastParams`' ``motion_gain``)."""
    from golden.tracker import TrackerParams
    return TrackerParams(reference="previous", follow_rows=True, motion_gain=motion_gain,
                         loop_delay_rows=loop_delay_rows)


@dataclass(frozen=True)
class HardwarePath:
    """The hardware path's closed loop on a dataset (:func:`closed_loop`).

    Members
    -------
    config : hdl.pipeline_config.PipelineConfig
    forecast : hdl.pose.forecast_params.ForecastParams
    result : emulator.pipeline.PipelineResult
        With its loop history ``result.loop``.
    """
    config: object
    forecast: object
    result: object

    @property
    def loop_delay_rows(self):
        return self.forecast.loop_delay_rows

    def levels(self, name="level"):
        """``(frame, row, level)`` of the loop's rows of frames ≥ 1: the forecast
        filter's level after each row's step (n, 6; m, rad), the hardware path's
        estimate of the one-frame motion; ``name="track"``: the motion track's ``Y``
        instead (:mod:`emulator.pose.motion_track`; KeyError where the frame is not a
        whole number of row periods)."""
        loop = self.result.loop
        scored = loop["frame"] > 0
        return (loop["frame"][scored], loop["row"][scored],
                self.forecast.motion_fmt.to_float(loop[name][scored]))

    def estimate(self):
        """``(frame, row, Y, label)`` of the loop's rows of frames ≥ 1: the hardware
        path's estimate of the one-frame motion, the motion track's ``Y`` (``label``
        "motion track"), or the filter's level ("filter level") where the rig's frame is
        not a whole number of row periods (no track: the gateware loop cannot be built
        for it)."""
        if "track" in self.result.loop:
            return (*self.levels("track"), "motion track")
        return (*self.levels(), "filter level")

    def steps(self):
        """``(frame, row, step)`` of the solver's records of frames ≥ 1: the raw solved
        steps (n, 6; m, rad), NaN where not solved."""
        result = self.result
        later = result.frame > 0
        return (result.frame[later], result.records["row"][later],
                result.steps(self.config)[later])


def closed_loop(dataset, frames=None, *, config=None, forecast_changes=None,
                progress=False):
    """Run the hardware path's closed loop on the first ``frames`` frames of
    ``dataset`` (default all): :func:`hardware_config` (or ``config``), its forecast
    (``forecast_changes`` go to :meth:`PipelineConfig.forecast`), the consistency stage,
    the cue fallback, started at :func:`first_frame_motion`. Returns :class:`HardwarePath`."""
    from emulator.pipeline import run
    config = hardware_config(dataset.rig) if config is None else config
    forecast = config.forecast(**(forecast_changes or {}))
    result = run(config, dataset, frames, progress=progress, forecast=forecast,
                 initial_motion=first_frame_motion(dataset),
                 consistency=config.consistency(), cue_fallback=True)
    return HardwarePath(config=config, forecast=forecast, result=result)

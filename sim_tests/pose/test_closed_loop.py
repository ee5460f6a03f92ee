"""The bit-accurate closed measurement loop (emulator/pipeline.py with a forecast, the
consistency stage, per-segment stereo depth and the cue fallback) tracks: per-row
one-frame motion against truth and against the golden tracker's reference (b) with the
same loop delay, gain law and segments K (the float twin of the scheme the loop
implements), on the stereo20 rig cut to its 32 middle rows, three frames of the papers'
motion (seed 1), as in docs/e2e.md.
"""

import os

import numpy as np
import pytest

from emulator.e2e import agreement, golden_steps, true_steps
from emulator.pipeline import run
from golden.pose_lsq import UNKNOWNS
from golden.rig import preset
from golden.scene import default_scene_spec
from golden.simulator import simulate
from golden.tracker import TrackerParams, track
from golden.trajectory import make_trajectory
from hdl.pipeline_config import PipelineConfig

SEED = int(os.environ.get("SEED", "1"))
ROWS, FRAMES, K = 32, 3, 4

#: Per axis, the loop's filter level may be this many times golden (b)'s error against
#: truth, both reading a row per segment with a reference-time factor per segment.
#: Measured at seed 1 against golden (b) with K = 4: 0.87 (Tx), 1.63 (Ty), 1.88 (Tz),
#: 1.54 (θx), 1.11 (θy), 1.00 (θz). Against golden (b)'s default K = 8 (the issue's
#: yardstick, docs/results/hw_tracking.md at full size) θy is 5.5× here: narrower
#: segments follow the rows better. Before the loop read a row per segment it was, against
#: the golden (b) of one row per camera row, 1.47 / 0.47 / 1.49 / 0.97 / 1.55 / 2.12; 2.5
#: holds what was measured with room for a seed's variation (seeds 1 and 2 differed by
#: up to 0.4 in a ratio). It failed clearly with one disparity per row (Tx 7.6×, Tz 5.2×,
#: θx 4.9×) or without the reference-time correction (θz 9.6×, Tx 6.2×); the consistency
#: stage is checked by sim_tests/measurement/test_consistency.py.
RATIO_TO_GOLDEN = 2.5
#: ... and must be at most this share of the true one-frame motion's RMS on each axis
#: (measured at most 0.11, Ty, whose motion is the smallest: 2.5 mm per frame).
SHARE_OF_MOTION = 0.2


@pytest.fixture(scope="module")
def dataset():
    print(f"SEED={SEED}")
    rig = preset("stereo20").replace_cameras(height=ROWS, cy=(ROWS - 1) / 2,
                                             t_r=1 / (120 * ROWS))
    return simulate(rig, default_scene_spec(SEED), make_trajectory("paper"), FRAMES / 120,
                    seed=SEED)


@pytest.fixture(scope="module")
def golden_b(dataset):
    return track(dataset, TrackerParams(reference="previous", follow_rows=True, segments=K,
                                        loop_delay_rows=1, motion_gain="scalar"))


@pytest.fixture(scope="module")
def config(dataset):
    return PipelineConfig.for_rig(dataset.rig, segments=K, stereo_segments=K)


@pytest.fixture(scope="module")
def closed(config, dataset, golden_b):
    """Started at golden (b)'s first forecast (both from the papers' given first frame)."""
    initial = golden_b.forecast[golden_b.tracked][0]
    return run(config, dataset, forecast=config.forecast(loop_delay_rows=1),
               initial_motion=initial, consistency=config.consistency(), cue_fallback=True)


def _rms(steps, truth):
    figures = agreement(steps, truth)
    return np.array([figures[f"rms.{name}"] for name in UNKNOWNS]), figures["rows"]


def _figures(config, dataset, golden_b, closed):
    """Per-row Y RMS against truth of the loop's filter level, of golden (b) and of the
    true motion itself, and the share of rows solved."""
    frames, rows = closed.frame, closed.records["row"]
    later = frames > 0
    truth = true_steps(dataset, frames[later], rows[later])
    solved = closed.records["flags"][later] == 0
    level = config.forecast().motion_fmt.to_float(closed.loop["level"])[later]
    emulator, n = _rms(np.where(solved[:, None], level, np.nan), truth)
    golden, n_golden = _rms(golden_steps(golden_b, dataset, frames[later], rows[later]), truth)
    motion, _ = _rms(np.zeros_like(truth), truth)
    print("per-row Y RMS (mm, mrad): emulator", np.round(1e3 * emulator, 3),
          "golden (b)", np.round(1e3 * golden, 3), "ratio", np.round(emulator / golden, 2),
          f"solved {solved.mean():.3f}")
    assert n == n_golden == (FRAMES - 1) * ROWS
    return emulator, golden, motion, solved


def test_the_closed_loop_tracks(config, dataset, golden_b, closed):
    emulator, _, motion, solved = _figures(config, dataset, golden_b, closed)
    assert solved.mean() >= 0.95
    for k, name in enumerate(UNKNOWNS):
        assert emulator[k] <= SHARE_OF_MOTION * motion[k], name


def test_the_closed_loop_tracks_like_golden_b(config, dataset, golden_b, closed):
    emulator, golden, _, _ = _figures(config, dataset, golden_b, closed)
    for k, name in enumerate(UNKNOWNS):
        assert emulator[k] <= RATIO_TO_GOLDEN * golden[k], name


def test_the_loop_judged_and_followed(closed):
    """The pieces ran: rows followed and centred by the forecast, outliers replaced,
    no innovation saturated (``scale_saturated`` counts the scales held at the stage's
    ceiling, which the loop reaches by design)."""
    loop = closed.loop
    counts = loop["counts"]
    print(counts)
    assert counts["outliers"] > 0
    assert counts["innovation_saturated"] == 0
    assert len(loop["row"]) == FRAMES * ROWS
    assert loop["centre"].any() and (loop["source_row"] != loop["row"][:, None]).any()
    rows = loop["segment_rows"]
    assert (rows != rows[..., :1]).any(), "no camera row read its segments from two rows"


def test_consistency_needs_the_forecast(config, dataset):
    with pytest.raises(ValueError, match="consistency needs forecast"):
        run(config, dataset, frames=1, consistency=config.consistency())


def test_each_temporal_segment_has_its_stereo_segment(config, dataset):
    assert config.router.stereo.segments == K
    # the window from the rig's f·b = 41.6 px and the golden depth range [0.5 m, ∞):
    # disparities 0 … 84 accepted, 2-px guard bands
    window = config.router.stereo_window
    assert (window.shift_min, window.shift_max, window.accepted) == (-2, 86, (0, 84))
    assert (config.router.stereo.match.shift_min, config.router.stereo.match.shift_max) \
        == (-2, 86)
    with pytest.raises(ValueError, match="stereo_segments must be an integer at least 1, "
                                         "not 0"):
        PipelineConfig.for_rig(dataset.rig, segments=K, stereo_segments=0)

"""Stimulus of the cue mapper tests: rows of one pair's stereo cues (raw ``cue_fmt``
integers, None where unusable), real ones from the emulator's stereo lanes and random
ones at the formats' extremes, and what the model maps them to."""


from emulator.measurement.cue_map import pair_cues
from emulator.measurement.router import usable_cues

__all__ = ["random_rows", "real_rows", "expected"]


def random_rows(cue_map, rng, count):
    """``count`` rows of random cues: a quarter unusable, the rest a mix of 0, the
    format's maximum (the extremes the arithmetic must hold) and any raw value."""
    top = cue_map.cue_fmt.max_raw
    rows = []
    for _ in range(count):
        kinds = rng.integers(4, size=cue_map.stereo_segments)
        values = rng.integers(top + 1, size=cue_map.stereo_segments)
        rows.append([None if kind == 0 else 0 if kind == 1 else top if kind == 2
                     else int(value) for kind, value in zip(kinds, values)])
    return rows


def real_rows(config, dataset, frames):
    """Every (pair, frame, row)'s cues the emulator's stereo lanes measured
    (:func:`emulator.pipeline.run` of ``config`` on ``dataset``), as the router's cue
    registers hold them before the map (no fallback)."""
    from emulator.pipeline import run
    params = config.router
    result = run(config, dataset, frames=frames)
    groups = {}
    for m in result.stereo:
        groups.setdefault((m["frame"], m["row"]), []).append(m)
    rows = []
    for records in groups.values():
        cues = usable_cues(params, records)
        rows += [[cues.get((a, j)) for j in range(params.stereo.segments)]
                 for a, _ in params.pairs]
    return rows


def expected(cue_map, rows):
    """``(camera A's, camera B's)`` mapped cues of every row."""
    return [pair_cues(cue_map, cues) for cues in rows]

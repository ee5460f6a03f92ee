"""Bit-accurate model of the cue map: each temporal segment's depth cue from its pair's
stereo cues, interpolated at the segment's centre column (the arithmetic and its
formats: :mod:`hdl.measurement.cue_map_params`; the gateware: :mod:`hdl.measurement.cue_map`).
"""

from hdl.fixed import Overflow, Rounding, add, mul, resize
from hdl.measurement.cue_map_params import B_PASSES, WEIGHT_FMT, CueMap

__all__ = ["CueMap", "map_cue", "pair_cues"]


def map_cue(cue_map, position, cues):
    """The cue at raw ``position`` (``cue_map.position_fmt``, twice camera A's column)
    from ``cues``: raw cue of each stereo segment, None where unusable. Returns the raw
    cue (``cue_map.cue_fmt``) or None."""
    s, f = cue_map.stereo, cue_map.cue_fmt.frac_bits
    if len(s) == 1:
        return cues[0]
    x = min(max(position, s[0] << f), s[-1] << f)
    j = sum(x >= (centre << f) for centre in s[1:-1])
    near, far = cues[j], cues[j + 1]
    if near is None or far is None:
        return far if near is None else near
    exact, fmt = mul(x - (s[j] << f), cue_map.distance_fmt,
                     cue_map.reciprocal[j], cue_map.reciprocal_fmt)
    weight = resize(exact, fmt, WEIGHT_FMT, Rounding.FLOOR, Overflow.ERROR)
    step, step_fmt = mul(weight, WEIGHT_FMT, far - near, cue_map.difference_fmt)
    total, total_fmt = add(near, cue_map.cue_fmt, step, step_fmt)
    return int(resize(total, total_fmt, cue_map.cue_fmt, Rounding.HALF_EVEN, Overflow.ERROR))


def pair_cues(cue_map, cues):
    """``(camera A's, camera B's)`` mapped cues of every temporal segment (lists of raw
    cue or None) from the pair's stereo cues ``cues`` (raw or None per stereo segment):
    A's at its segment centre ``T_k``, B's at ``T_k`` moved right by the cue there
    (``B_PASSES`` passes, the first with A's cue); None where the final position is not
    :meth:`~CueMap.covered` by the stereo lane."""
    if len(cues) != cue_map.stereo_segments:
        raise ValueError(f"cues must hold {cue_map.stereo_segments} stereo segments, "
                         f"not {len(cues)}")
    f = cue_map.cue_fmt.frac_bits
    own = [map_cue(cue_map, centre << f, cues) for centre in cue_map.temporal]
    moved = own
    for _ in range(B_PASSES):
        position = [None if c is None else (centre << f) + 2 * c
                    for centre, c in zip(cue_map.temporal, moved)]
        moved = [None if x is None else map_cue(cue_map, x, cues) for x in position]
    return ([c if cue_map.covered(centre << f) else None
             for centre, c in zip(cue_map.temporal, own)],
            [c if x is not None and cue_map.covered(x) else None
             for x, c in zip(position, moved)])

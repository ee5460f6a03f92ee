"""The stress suite's scene generator and texture families (issue 18, item 5).

Set SEED to replay a run; the seed in use is printed.
"""

import os

import numpy as np
import pytest

from golden.rig import preset
from golden.scene import SceneSpec, build_scene, scene_from_config
from golden.stress_scenes import (StressParams, stress_dataset, stress_scene,
                                  stress_trajectory)
from golden.textures import FAMILIES, family_of, family_texture, procedural_texture

SEED = int(os.environ.get("SEED", "7"))
SEEDS = range(SEED, SEED + 10)


def test_same_seed_same_scene_and_different_seeds_differ():
    print(f"SEED={SEED}")
    a, b = stress_scene(SEED), stress_scene(SEED)
    assert a.spec == b.spec and a.families == b.families
    assert np.array_equal(a.start_position, b.start_position)
    assert np.array_equal(a.start_rotation, b.start_rotation)
    assert stress_scene(SEED + 1).spec != a.spec
    assert scene_from_config(a.spec.to_dict()) == a.spec          # survives the dataset


@pytest.mark.parametrize("seed", SEEDS)
def test_scene_contents_follow_the_parameters(seed):
    p = StressParams()
    scene = stress_scene(seed, p)
    spec, start = scene.spec, scene.start_position
    assert set(scene.families[1:]) == set(FAMILIES)               # every family, every scene
    assert scene.families[0] != "blank"                           # the room has texture
    assert [family_of(b.texture) for b in spec.boxes] == list(scene.families[1:])
    assert family_of(spec.room_texture) == scene.families[0]
    assert all(p.room[0] <= side <= p.room[1] for side in spec.room[:2])
    assert p.height[0] <= spec.room[2] <= p.height[1] and 1.1 <= start[2] <= 1.9
    walls = np.concatenate([start[:2] - spec.room_lo[:2], spec.room_hi[:2] - start[:2]])
    assert walls.max() >= p.far_wall                              # beyond the stereo range
    assert spec.clearance(start[None])[0] >= p.keep_clear
    boxes = len(spec.boxes)
    assert p.furniture[0] + p.clutter[0] <= boxes <= p.furniture[1] + p.clutter[1]
    near = [b for b in spec.boxes
            if np.linalg.norm(np.clip(start, b.lo, b.hi) - start) <= p.clutter_distance[1]]
    assert len(near) >= p.clutter[0]                              # clutter close to the rig
    assert spec.contrast_range == p.contrast_range


@pytest.mark.parametrize("kwargs, message", [
    (dict(room=(3.0,)), r"room must be two numbers \(min, max\)"),
    (dict(room=(5.0, 4.0)), "room\\[1\\] must be a number at least 5.0, not 4.0"),
    (dict(far_wall=9.5), "far_wall 9.5 m plus keep_clear 0.6 m and 0.4 m do not fit"),
    (dict(keep_clear=0.1), "keep_clear must be a number at least 0.2, not 0.1"),
    (dict(furniture=(2, 3), clutter=(2, 3)), "every texture family appears on a box"),
    (dict(clutter_distance=(0.3, 1.0)), "clutter_distance\\[0\\] must be a number at least 0.6"),
    (dict(texel=0), "texel must be a number greater than 0, not 0"),
])
def test_stress_parameter_checks(kwargs, message):
    with pytest.raises(ValueError, match=message):
        StressParams(**kwargs)


def test_unknown_family_and_contrast_checks():
    with pytest.raises(ValueError, match="texture family must be one of noise, shapes"):
        SceneSpec(room_texture="family:plaid")
    with pytest.raises(ValueError, match="contrast_range\\[1\\] must be a number at least 1.0"):
        SceneSpec(contrast_range=(1.0, 0.5))


def _flat_share(texture):
    """Share of texels whose 3×3 neighbourhood is flat to within one gray level."""
    gy, gx = np.gradient(texture)
    return np.mean(np.hypot(gx, gy) < 0.5)


def test_texture_families_have_their_character():
    rng = np.random.default_rng(SEED)
    texel, shape = 0.008, (256, 384)
    made = {f: family_texture(np.random.default_rng([SEED, k]), shape, texel, f)
            for k, f in enumerate(FAMILIES)}
    default = procedural_texture(rng, shape, texel)
    for family, texture in made.items():
        assert texture.dtype == np.float32 and texture.min() >= 8 and texture.max() <= 247
    assert made["low_contrast"].std() < 0.15 * default.std()
    assert _flat_share(made["blank"]) > 0.85
    assert _flat_share(made["noise"]) < 0.05
    assert 0.3 < _flat_share(made["shapes"])                      # flat pieces, sharp edges
    # one period: the autocorrelation along x repeats at a lag below the image width
    rows = made["repetitive"] - made["repetitive"].mean()
    spectrum = np.abs(np.fft.rfft(rows, axis=1)).mean(axis=0)
    assert spectrum[1:].max() > 5 * np.median(spectrum[1:])
    with pytest.raises(ValueError, match="family must be one of"):
        family_texture(rng, shape, texel, "plaid")


def test_contrast_changes_per_face():
    spec = stress_scene(SEED).spec
    flat = SceneSpec(room=spec.room, boxes=spec.boxes[:1], texel=0.05, seed=SEED,
                     room_texture="family:noise", mip_levels=2)
    varied = SceneSpec(room=spec.room, boxes=spec.boxes[:1], texel=0.05, seed=SEED,
                       room_texture="family:noise", mip_levels=2, contrast_range=(0.3, 2.0))

    def face_stds(scene_spec):
        atlas = build_scene(scene_spec).atlas
        stds = []
        for x, y in atlas.offsets[:6]:                             # the room's six faces
            stds.append(atlas.pyramid[0][y:y + 20, x:x + 20].std())
        return np.array(stds)

    ratio = face_stds(varied) / face_stds(flat)
    print("per-face contrast", np.round(ratio, 2))
    assert ratio.min() >= 0.25 and ratio.max() <= 2.1 and ratio.max() / ratio.min() > 1.5


@pytest.mark.parametrize("motion", ["head", "paper"])
def test_stress_dataset_renders_a_short_small_run(motion):
    rig = preset("stereo8")
    dataset = stress_dataset(SEED, rig, motion, duration=0.02, scale=0.25)
    assert dataset.rig.cameras[0].width == 160 and dataset.rig.cameras[0].noise_sigma == 2.0
    assert dataset.info["stress"]["families"] == list(stress_scene(SEED).families)
    assert dataset.info["trajectory"]["kind"] == motion
    assert np.allclose(dataset.cameras[0].position[0, 0],
                       stress_trajectory(stress_scene(SEED), motion).pose(0.0)[1][0])
    assert all(rec.rows.std() > 1 for rec in dataset.cameras)     # something rendered
    with pytest.raises(ValueError, match="motion must be one of head, paper"):
        stress_trajectory(stress_scene(SEED), "static")

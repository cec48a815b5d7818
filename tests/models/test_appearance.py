"""Randomized appearance: drawn from the seed on its own stream, seen and unseen textures never
shared, recorded in the scene, and visible in the cameras (and only there)."""

import colorsys

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.models.appearance import (
    PALETTES,
    TEXTURE_KINDS,
    Texture,
    recolor_objects,
    sample_appearance,
    texture_image,
)
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.tasks import get_task


def test_same_seed_same_appearance_and_seeds_differ():
    assert sample_appearance(7) == sample_appearance(7)
    assert len({sample_appearance(s).model_dump_json() for s in range(20)}) == 20


@pytest.mark.parametrize("split", ["seen", "unseen"])
def test_textures_come_only_from_their_splits_palettes(split):
    other = "unseen" if split == "seen" else "seen"
    assert not set(PALETTES[split]) & set(PALETTES[other])
    used = set()
    for seed in range(200):
        a = sample_appearance(seed, split)
        for tex in (a.table, a.floor):
            assert (tex.dark, tex.light) in PALETTES[split]
            used.add((tex.dark, tex.light))
    assert used == set(PALETTES[split])  # every palette of the split is drawn


def test_lights_are_valid_colours_and_neither_dim_nor_washed_out():
    for seed in range(300):
        lights = sample_appearance(seed).lights
        assert 1 <= len(lights) <= 3
        assert 0.85 <= sum(light.intensity for light in lights) <= 1.45
        for light in lights:
            assert all(0.0 <= c <= 1.0 for c in light.color)
            assert light.direction[2] < -0.5  # shines down onto the table


def test_unknown_split_is_named():
    with pytest.raises(ValueError, match="unknown split 'train'; splits: seen, unseen"):
        sample_appearance(0, "train")


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_texture_images_are_patterned_in_their_palette_and_cached(kind, tmp_path, monkeypatch):
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path))
    tex = Texture(kind=kind, dark=(0.2, 0.1, 0.0), light=(0.8, 0.6, 0.4), seed=3)
    img = texture_image(tex)
    assert img.shape == (256, 256, 3) and img.dtype == np.uint8
    assert img.std() > 8, "a texture must show a pattern"
    assert img[..., 0].min() >= 0.2 * 255 - 1 and img[..., 0].max() <= 0.8 * 255 + 1
    path = tex.png()
    assert path.exists() and path.is_relative_to(tmp_path) and tex.png() == path


def test_randomizing_keeps_the_tasks_scene_and_survives_a_json_round_trip():
    scene = get_task("jigsaw").sample_scene(4)
    randomized = scene.randomized("unseen")
    for before, after in zip(scene.objects, randomized.objects, strict=False):  # clutter after
        assert after.model_copy(update={"color": before.color}) == before  # only colours change
    assert randomized.draws == scene.draws
    assert randomized.appearance.split == "unseen"
    assert Scene.model_validate_json(randomized.model_dump_json()) == randomized
    with pytest.raises(ValueError, match="drawn from a seed"):
        Scene(name="x").randomized()


def _hue(color) -> float:
    return colorsys.rgb_to_hsv(*color[:3])[0]


def test_recoloring_keeps_equal_colours_equal_distinct_ones_distinct_and_fixed_ones():
    red, green, white = (0.85, 0.2, 0.2, 1.0), (0.2, 0.6, 0.25, 1.0), (0.95, 0.95, 0.95, 1.0)
    objects = (
        cube("a1", 0, 0, color=red),
        cube("a2", 0.1, 0, color=red),
        cube("b", 0.2, 0, color=green),
        cube("grid", 0.3, 0, color=white),
        cube("stove", 0.4, 0, color=red).model_copy(update={"color_fixed": True}),
        cube("clutter", 0.5, 0, color=green).model_copy(update={"distractor": True}),
    )
    hues = set()
    for seed in range(12):
        new = {o.name: o.color for o in recolor_objects(seed, objects)}
        assert recolor_objects(seed, objects) == recolor_objects(seed, objects)
        assert new["a1"] == new["a2"] != new["b"]  # a cube and its same-coloured twin
        gap = (_hue(new["b"]) - _hue(new["a1"])) % 1.0
        assert gap == pytest.approx((_hue(green) - _hue(red)) % 1.0, abs=0.01)
        assert new["stove"] == red and new["clutter"] == green
        h, s, v = colorsys.rgb_to_hsv(*new["grid"][:3])
        assert s < 0.15 and v > 0.8  # white stays a light grey
        hues.add(round(_hue(new["a1"]), 2))
    assert len(hues) > 8  # the seed moves the hue


def test_spec_named_colours_survive_randomization():
    cook = get_task("cook").sample_scene(0)
    randomized = {o.name: o.color for o in cook.randomized().objects}
    for name in ("stove", "roll_0", "roll_1"):
        assert randomized[name] == cook.object(name).color
    assert randomized["skillet"] != cook.object("skillet").color


@pytest.fixture(scope="module")
def head_images():
    scene = get_task("jigsaw").sample_scene(2)
    out = {}
    for key, s in (("plain", scene), ("a", scene.randomized()), ("b", scene.randomized())):
        sim = Simulation(build_station(s, StationConfig()))
        out[key] = (sim.images()["head_camera"], sim.extrinsic_cv("head_camera"))
    other = (
        get_task("jigsaw").sample_scene(3).model_copy(update={"appearance": sample_appearance(3)})
    )
    sim = Simulation(build_station(other, StationConfig()))
    out["other"] = (sim.images()["head_camera"], sim.extrinsic_cv("head_camera"))
    return out


def test_randomized_scenes_render_differently_and_reproducibly(head_images):
    plain, a, b = head_images["plain"][0], head_images["a"][0], head_images["b"][0]
    assert np.array_equal(a, b)  # the same seed renders the same pixels
    assert np.abs(a.astype(int) - plain).mean() > 10  # the table no longer looks plain
    assert np.abs(head_images["other"][0].astype(int) - a).mean() > 10


def test_head_camera_is_jittered_by_centimetres_at_most(head_images):
    plain, jittered = head_images["plain"][1], head_images["a"][1]
    assert not np.allclose(plain, jittered)
    eye = lambda E: -E[:, :3].T @ E[:, 3]  # noqa: E731 - camera centre in world
    assert np.linalg.norm(eye(plain) - eye(jittered)) < 0.035

"""How a scene looks: table and floor textures, lights, table height, the head camera's jitter
and the task objects' colours.

An :class:`Appearance` changes nothing the physics or the expert sees: it is drawn per episode
(:func:`sample_appearance`) from the seed on its own random stream, stored in the scene (and
so in every episode file), and turned into pixels by the station (textured visuals, the
renderer's lights, the head camera's pose). Textures are procedural PNGs (wood, stone, fabric,
stripes), made once and cached on disk. The *seen* split (generation) and the *unseen* split
(evaluation) draw from disjoint palettes, so no unseen texture ever appears in training data.
"""

from __future__ import annotations

import colorsys
import hashlib
import os
import tempfile
from pathlib import Path
from typing import Literal

import numpy as np
from PIL import Image
from pydantic import BaseModel, ConfigDict, Field

from bicoord_drake.models.geometry import Rgba, mesh_cache_dir
from bicoord_drake.models.objects import SceneObject

Split = Literal["seen", "unseen"]
TextureKind = Literal["wood", "stone", "fabric", "stripes"]
TEXTURE_KINDS: tuple[TextureKind, ...] = ("wood", "stone", "fabric", "stripes")
TEXTURE_SIZE = 256

Rgb = tuple[float, float, float]

#: Two-colour palettes per split (dark, light), in [0, 1]; seen and unseen share none.
PALETTES: dict[Split, tuple[tuple[Rgb, Rgb], ...]] = {
    "seen": (
        ((0.45, 0.30, 0.18), (0.70, 0.52, 0.34)),  # oak
        ((0.30, 0.20, 0.13), (0.52, 0.37, 0.25)),  # walnut
        ((0.42, 0.42, 0.44), (0.66, 0.66, 0.68)),  # grey
        ((0.20, 0.30, 0.42), (0.40, 0.52, 0.64)),  # blue-grey
        ((0.36, 0.40, 0.26), (0.58, 0.62, 0.44)),  # olive
        ((0.50, 0.44, 0.38), (0.78, 0.72, 0.64)),  # sand
    ),
    "unseen": (
        ((0.52, 0.22, 0.18), (0.76, 0.44, 0.36)),  # brick
        ((0.18, 0.36, 0.34), (0.38, 0.58, 0.54)),  # teal
        ((0.32, 0.26, 0.40), (0.54, 0.48, 0.64)),  # plum
        ((0.58, 0.50, 0.24), (0.82, 0.74, 0.46)),  # mustard
    ),
}


class Texture(BaseModel):
    """A procedural texture: its kind, palette and pattern seed (the PNG is a pure function)."""

    model_config = ConfigDict(frozen=True)

    kind: TextureKind
    dark: Rgb
    light: Rgb
    seed: int = Field(ge=0)
    scale: float = Field(1.0, gt=0, description="pattern frequency relative to the default")

    def png(self) -> Path:
        """The texture's PNG (made on first use, cached under the mesh cache, atomic)."""
        key = hashlib.sha1(self.model_dump_json().encode()).hexdigest()[:16]
        path = mesh_cache_dir().parent / "textures" / f"{self.kind}_{key}.png"
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".png.tmp")
            os.close(fd)
            Image.fromarray(texture_image(self), "RGB").save(tmp, format="PNG")
            os.replace(tmp, path)
        return path


class Light(BaseModel):
    """A directional light fixed in the world: where it shines to, its colour and intensity."""

    model_config = ConfigDict(frozen=True)

    direction: tuple[float, float, float]
    color: Rgb = (1.0, 1.0, 1.0)
    intensity: float = Field(1.0, gt=0, le=3)


class Appearance(BaseModel):
    """Everything about a scene's look that randomization changes (None fields: the default)."""

    model_config = ConfigDict(frozen=True)

    split: Split
    table: Texture
    floor: Texture
    lights: tuple[Light, ...] = Field(min_length=1, max_length=4)
    head_camera_offset: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="added to the head camera's position, m"
    )
    head_camera_tilt: tuple[float, float] = Field(
        (0.0, 0.0), description="added to its viewing direction's pitch and yaw, rad"
    )
    table_raise: float = Field(
        0.0,
        ge=-0.03,
        le=0.03,
        description="how much higher the table (with the arms on it) stands above the floor "
        "than the default, m; the world frame stays on the table (top at z = 0.75), so the "
        "floor and the world-fixed head camera move down by this much instead",
    )


def sample_appearance(seed: int, split: Split = "seen") -> Appearance:
    """The appearance of episode `seed` for a split (its own random stream: the task's draws
    from the same seed are unaffected)."""
    if split not in PALETTES:
        raise ValueError(f"unknown split {split!r}; splits: {', '.join(PALETTES)}")
    rng = np.random.default_rng([seed, 0xA77EA])
    palettes = PALETTES[split]

    def texture(kinds: tuple[TextureKind, ...]) -> Texture:
        dark, light = palettes[int(rng.integers(len(palettes)))]
        return Texture(
            kind=kinds[int(rng.integers(len(kinds)))],
            dark=dark,
            light=light,
            seed=int(rng.integers(1_000_000)),
            scale=float(rng.uniform(0.7, 1.4)),
        )

    table = texture(("wood", "stone", "fabric", "stripes"))
    floor = texture(("stone", "fabric", "stripes"))
    lights = []
    count = int(rng.integers(1, 4))
    total = rng.uniform(0.9, 1.4)  # summed intensity: neither dim nor washed out
    shares = rng.dirichlet(np.ones(count))
    for share in shares:
        azimuth = rng.uniform(0, 2 * np.pi)
        elevation = rng.uniform(np.deg2rad(35), np.deg2rad(80))
        down = (
            -np.cos(elevation) * np.cos(azimuth),
            -np.cos(elevation) * np.sin(azimuth),
            -np.sin(elevation),
        )
        warmth = rng.uniform(-0.12, 0.12)  # > 0: warmer (less blue), < 0: cooler (less red)
        color = (1.0 - max(-warmth, 0.0), 1.0 - abs(warmth) / 2, 1.0 - max(warmth, 0.0))
        lights.append(
            Light(
                direction=tuple(round(float(c), 4) for c in down),
                color=tuple(round(float(c), 3) for c in color),
                intensity=round(float(max(total * share, 0.05)), 3),
            )
        )
    return Appearance(
        split=split,
        table=table,
        floor=floor,
        lights=tuple(lights),
        head_camera_offset=tuple(round(float(v), 4) for v in rng.uniform(-0.02, 0.02, 3)),
        head_camera_tilt=tuple(round(float(v), 4) for v in rng.uniform(-0.03, 0.03, 2)),
        table_raise=round(float(rng.uniform(-0.03, 0.03)), 4),
    )


#: Below this HSV saturation a colour is a grey (white, black, steel): only its brightness moves.
GREY_SATURATION = 0.15


def recolor_objects(seed: int, objects: tuple[SceneObject, ...]) -> tuple[SceneObject, ...]:
    """`objects` with new colours drawn from the seed (its own random stream). One hue rotation
    for the whole scene, so colours that differed keep their hue difference, and one new colour
    per old colour, so equal colours stay equal (same-colour cubes, a cube and the sign of its
    colour); saturation and brightness move a little per colour; greys (white squares, a black
    base) change brightness only. Objects marked ``color_fixed`` and distractors keep theirs."""
    rng = np.random.default_rng([seed, 0xC0102])
    rotation = rng.uniform(0.0, 1.0)
    changes = [o for o in objects if not (o.color_fixed or o.distractor)]
    new: dict[Rgba, Rgba] = {}
    for obj in changes:
        if obj.color not in new:
            new[obj.color] = _shifted(obj.color, rotation, rng)
    keep = {id(o) for o in objects} - {id(o) for o in changes}
    return tuple(
        o if id(o) in keep else o.model_copy(update={"color": new[o.color]}) for o in objects
    )


def _shifted(color: Rgba, rotation: float, rng: np.random.Generator) -> Rgba:
    """`color` with its hue rotated by `rotation` (of a turn), saturation scaled and brightness
    moved by a draw; a grey keeps its (absent) hue and saturation."""
    h, s, v = colorsys.rgb_to_hsv(*color[:3])
    scale, dv = rng.uniform(0.8, 1.15), rng.uniform(-0.1, 0.1)
    if s >= GREY_SATURATION:
        h, s = (h + rotation) % 1.0, float(np.clip(s * scale, GREY_SATURATION, 1.0))
    v = float(np.clip(v + dv, 0.05, 0.97))
    r, g, b = colorsys.hsv_to_rgb(h, s, v)
    return (round(r, 3), round(g, 3), round(b, 3), color[3])


# --------------------------------------------------------------------------- textures
def texture_image(texture: Texture, size: int = TEXTURE_SIZE) -> np.ndarray:
    """(size, size, 3) uint8 image of a texture; tileable patterns in the palette's range."""
    rng = np.random.default_rng(texture.seed)
    v, u = np.mgrid[0:size, 0:size] / size
    f = texture.scale
    if texture.kind == "wood":
        warp = 0.05 * _smooth_noise(rng, size, cells=4) + 0.01 * _smooth_noise(rng, size, 16)
        grain = np.sin(2 * np.pi * f * 12 * (u + warp))
        t = 0.5 + 0.3 * grain + 0.2 * _smooth_noise(rng, size, cells=64)
    elif texture.kind == "stone":
        t = sum(
            _smooth_noise(rng, size, cells=int(c * f) or 1) / k
            for k, c in ((1, 4), (2, 8), (4, 16), (8, 64))
        )
        t = (t - t.min()) / (np.ptp(t) + 1e-9)
    elif texture.kind == "fabric":
        n = max(int(24 * f), 4)
        weave = np.sin(2 * np.pi * n * u) * np.sin(2 * np.pi * n * v)
        t = 0.5 + 0.3 * np.sign(weave) * np.abs(weave) ** 0.5
        t = t + 0.2 * _smooth_noise(rng, size, cells=64)
    else:  # stripes
        n = max(int(6 * f), 2)
        t = 0.5 + 0.4 * np.sign(np.sin(2 * np.pi * n * (u + 0.1 * v)))
        t = t + 0.1 * _smooth_noise(rng, size, cells=16)
    t = np.clip(t, 0.0, 1.0)[..., None]
    rgb = np.asarray(texture.dark) * (1 - t) + np.asarray(texture.light) * t
    return (np.clip(rgb, 0, 1) * 255).astype(np.uint8)


def _smooth_noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Value noise on a `cells` x `cells` periodic grid, bilinearly upsampled, in [-1, 1]."""
    grid = rng.uniform(-1, 1, (cells, cells))
    x = np.arange(size) * cells / size
    i0 = np.floor(x).astype(int)
    w = x - i0
    w = w * w * (3 - 2 * w)  # smoothstep
    i1 = (i0 + 1) % cells
    rows = grid[i0][:, i0] * (1 - w)[None, :] + grid[i0][:, i1] * w[None, :]
    rows1 = grid[i1][:, i0] * (1 - w)[None, :] + grid[i1][:, i1] * w[None, :]
    return rows * (1 - w)[:, None] + rows1 * w[:, None]

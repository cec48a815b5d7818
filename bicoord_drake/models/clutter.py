"""Distractor clutter for randomized scenes: everyday objects the task does not use.

:func:`sample_clutter` draws 2-8 distractors per episode from the seed (its own random stream,
so the task's draws are unchanged) and places them collision-free in the strips of the table the
arms do not work in - along the far edge and the far ends of the sides - and at least
:data:`KEEP_OUT` from every task object. They are real free bodies in the plant with the same
contact model as task objects (an arm that hits one moves it) and obstacles in the planning
model; each is one or two primitives, and they are flagged ``distractor`` so no task counts them
(``Scene.free_objects`` leaves them out). Resting clutter costs physics time (benchmarks/
bench_clutter.md). Point contact would be cheaper, but with Drake's default point stiffness a
resting box sank 1.5 cm into the table in 0.5 s.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from bicoord_drake.models.geometry import Pose, Primitive
from bicoord_drake.models.objects import (
    BoxShape,
    CompoundShape,
    CylinderShape,
    MugShape,
    SceneObject,
    Shape,
    SphereShape,
)

DistractorKind = Literal["block", "can", "mug", "fruit", "bottle", "pack"]
DISTRACTOR_KINDS: tuple[DistractorKind, ...] = ("block", "can", "mug", "fruit", "bottle", "pack")

#: Table-centred regions (x_min, x_max, y_min, y_max) where clutter may stand: the far strip
#: and the far ends of both sides. Task objects of every task lie within |x| <= 0.32,
#: y <= 0.15; the arms' bases are at y = -0.42.
CLUTTER_ZONES: tuple[tuple[float, float, float, float], ...] = (
    (-0.52, 0.52, 0.22, 0.30),
    (-0.53, -0.45, 0.00, 0.30),
    (0.45, 0.53, 0.00, 0.30),
)
#: Minimum gap (m) between a distractor's footprint and a task object's footprint.
KEEP_OUT = 0.06
#: Half extents (m) of the table area a distractor's footprint must stay on.
TABLE_HALF = (0.58, 0.33)
#: Minimum gap (m) between two distractors.
GAP = 0.01
COUNT_RANGE = (2, 8)
#: No distractor cylinder is drawn with a length within this fraction of its diameter: Drake's
#: compliant pressure field of such a cylinder has a degenerate tetrahedron at its centre, and
#: resting on the table it stops the simulation ("Cannot instantiate plane from normal"; a mug
#: of radius 3.640 cm and height 7.277 cm did, balance_roller randomized seed 10).
SQUARE_CYLINDER_BAND = 0.02

_COLORS = (
    (0.85, 0.25, 0.2),
    (0.95, 0.6, 0.15),
    (0.9, 0.85, 0.25),
    (0.35, 0.65, 0.3),
    (0.25, 0.5, 0.8),
    (0.55, 0.35, 0.7),
    (0.92, 0.92, 0.9),
    (0.2, 0.2, 0.22),
    (0.7, 0.45, 0.3),
)


def _block(rng: np.random.Generator) -> tuple[Shape, float]:
    size = tuple(float(s) for s in rng.uniform(0.03, 0.06, 3))
    return BoxShape(size=size), size[2] / 2


def clear_of_square(radius: float, length: float) -> float:
    """`length`, moved to (1 + SQUARE_CYLINDER_BAND) diameters if it lies within the band
    around the diameter (see :data:`SQUARE_CYLINDER_BAND`)."""
    if abs(length / (2 * radius) - 1.0) < SQUARE_CYLINDER_BAND:
        return 2 * radius * (1.0 + SQUARE_CYLINDER_BAND)
    return length


def _can(rng: np.random.Generator) -> tuple[Shape, float]:
    r, h = float(rng.uniform(0.025, 0.035)), float(rng.uniform(0.07, 0.11))
    h = clear_of_square(r, h)
    return CylinderShape(radius=r, length=h), h / 2


def _mug(rng: np.random.Generator) -> tuple[Shape, float]:
    r, h = float(rng.uniform(0.03, 0.04)), float(rng.uniform(0.07, 0.09))
    return MugShape(radius=r, height=clear_of_square(r, h)), 0.0


def _fruit(rng: np.random.Generator) -> tuple[Shape, float]:
    r = float(rng.uniform(0.025, 0.04))
    return SphereShape(radius=r), r


def _bottle(rng: np.random.Generator) -> tuple[Shape, float]:
    r, h = float(rng.uniform(0.025, 0.032)), float(rng.uniform(0.1, 0.14))
    neck = 0.35 * h
    h = neck + clear_of_square(r, h - neck)
    body = Primitive(kind="cylinder", size=(r, h - neck), pose=Pose(xyz=(0, 0, (h - neck) / 2)))
    top = Primitive(
        kind="cylinder", size=(0.4 * r, neck), pose=Pose(xyz=(0, 0, h - neck + neck / 2))
    )
    return CompoundShape(parts=(body, top)), 0.0


def _pack(rng: np.random.Generator) -> tuple[Shape, float]:
    x, y = float(rng.uniform(0.08, 0.12)), float(rng.uniform(0.05, 0.08))
    z = float(rng.uniform(0.015, 0.03))
    return BoxShape(size=(x, y, z)), z / 2


_MAKERS: dict[DistractorKind, Callable[[np.random.Generator], tuple[Shape, float]]] = {
    "block": _block,
    "can": _can,
    "mug": _mug,
    "fruit": _fruit,
    "bottle": _bottle,
    "pack": _pack,
}


def footprint_radius(obj: SceneObject) -> float:
    """Radius (m) of a vertical cylinder about the object's origin that holds its xy extent."""
    return _footprint_radius(obj.shape, obj.pose.rpy)


@functools.lru_cache(maxsize=1024)
def _footprint_radius(shape: Shape, rpy: tuple[float, float, float]) -> float:
    mesh = shape.visual_mesh()
    mesh.apply_transform(Pose(rpy=rpy).matrix())
    return float(np.max(np.linalg.norm(mesh.vertices[:, :2], axis=1)))


def distractor(
    kind: DistractorKind,
    name: str,
    rng: np.random.Generator,
    xy: tuple[float, float],
    table_top: float,
    yaw: float = 0.0,
) -> SceneObject:
    """One distractor of `kind` (its size and colour drawn with `rng`) standing on the table."""
    if kind not in _MAKERS:
        raise ValueError(f"unknown distractor kind {kind!r}; kinds: {', '.join(DISTRACTOR_KINDS)}")
    shape, z_origin = _MAKERS[kind](rng)
    color = _COLORS[int(rng.integers(len(_COLORS)))]
    volume = float(sum(p.trimesh().volume for p in shape.primitives()))
    return SceneObject(
        name=name,
        shape=shape,
        color=(*color, 1.0),
        mass=float(np.clip(volume * 400.0, 0.03, 0.3)),  # light plastic and fruit, ~0.4 g/cm^3
        pose=Pose(xyz=(xy[0], xy[1], table_top + z_origin), rpy=(0.0, 0.0, yaw)),
        distractor=True,
        friction=0.8,
    )


def sample_clutter(
    seed: int, task_objects: Sequence[SceneObject], table_top: float, max_tries: int = 200
) -> tuple[SceneObject, ...]:
    """2-8 distractors for episode `seed`, collision-free with each other and at least
    :data:`KEEP_OUT` from every task object (fewer only if the zones are full)."""
    rng = np.random.default_rng([seed, 0xC1077E])
    count = int(rng.integers(COUNT_RANGE[0], COUNT_RANGE[1] + 1))
    occupied = [(np.asarray(o.pose.xyz[:2]), footprint_radius(o) + KEEP_OUT) for o in task_objects]
    areas = np.array([(x1 - x0) * (y1 - y0) for x0, x1, y0, y1 in CLUTTER_ZONES])
    placed: list[SceneObject] = []
    for _ in range(count):
        kind = DISTRACTOR_KINDS[int(rng.integers(len(DISTRACTOR_KINDS)))]
        for _ in range(max_tries):
            x0, x1, y0, y1 = CLUTTER_ZONES[
                int(rng.choice(len(CLUTTER_ZONES), p=areas / areas.sum()))
            ]
            xy = (float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)))
            yaw = float(rng.uniform(-np.pi, np.pi))
            item = distractor(kind, f"distractor_{len(placed)}", rng, xy, table_top, yaw)
            r = footprint_radius(item)
            on_table = abs(xy[0]) + r <= TABLE_HALF[0] and abs(xy[1]) + r <= TABLE_HALF[1]
            if on_table and all(np.linalg.norm(np.asarray(xy) - c) >= r + rc for c, rc in occupied):
                placed.append(item)
                occupied.append((np.asarray(xy), r + GAP))
                break
    return tuple(placed)

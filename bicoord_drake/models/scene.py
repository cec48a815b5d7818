"""The `Scene` value: what a task puts on the table, drawn from one seed.

A scene is plain data - objects with shapes, colours, masses and initial poses - so it can be
stored in an episode file and rebuilt exactly. ``build_station(scene, config)`` is the only place
that turns it into a Drake diagram.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.models.appearance import (
    Appearance,
    Split,
    recolor_objects,
    sample_appearance,
)
from bicoord_drake.models.clutter import sample_clutter
from bicoord_drake.models.geometry import Pose, Rgba
from bicoord_drake.models.objects import BowlShape, BoxShape, SceneObject

#: World height of the table top (m); objects rest on it at z = TABLE_TOP + their half height.
TABLE_TOP = 0.75
#: An object's lowest point within this distance (m) of TABLE_TOP stands on the table top
#: itself (a flat marker under it allowed), not on a shelf, in a holder or on another object.
ON_TABLE_TOP_TOLERANCE = 0.01


class Scene(BaseModel):
    """Objects on the table, in world coordinates, plus the seed that drew them."""

    model_config = ConfigDict(frozen=True)

    name: str = "empty"
    seed: int | None = None
    objects: tuple[SceneObject, ...] = ()
    draws: dict[str, float | int | str | list] = Field(
        default_factory=dict, description="every random draw, for exact rebuilds"
    )
    appearance: Appearance | None = Field(
        None, description="textures, lights, camera jitter (None: the plain default look)"
    )

    @model_validator(mode="after")
    def _unique_names(self) -> Scene:
        names = [o.name for o in self.objects]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"duplicate object names in scene: {sorted(dup)}")
        fixed_before: set[str] = set()
        for o in self.objects:
            if o.slide is not None and (o.fixed or o.slide.parent not in fixed_before):
                raise ValueError(
                    f"{o.name!r} slides on {o.slide.parent!r}: it must not be fixed, and its "
                    "parent must be a fixed object listed before it"
                )
            if o.fixed:
                fixed_before.add(o.name)
        return self

    @property
    def sliding_objects(self) -> list[SceneObject]:
        """Objects on a prismatic joint (drawers), in scene order."""
        return [o for o in self.objects if o.slide is not None]

    def slide_axis(self, name: str) -> np.ndarray:
        """World direction (3,) in which the sliding object `name` moves as its joint opens
        (its parent is fixed, so this never changes)."""
        slide = self.object(name).slide
        if slide is None:
            raise ValueError(f"object {name!r} is not on a slide joint")
        R_WP = self.object(slide.parent).pose.matrix()[:3, :3]
        return R_WP @ np.asarray(slide.axis, dtype=float)

    def randomized(self, split: Split = "seen") -> Scene:
        """This scene randomized from its seed: the appearance of `split` (textures from that
        split, lights, table height, head-camera jitter), new colours for the task's objects
        where the task does not fix them (:func:`~bicoord_drake.models.appearance.
        recolor_objects`) and 2-8 distractors placed clear of the task's objects
        (:func:`~bicoord_drake.models.clutter.sample_clutter`); the task's objects, poses,
        shapes and masses unchanged. Randomizing twice is an error."""
        if self.seed is None:
            raise ValueError("only a scene drawn from a seed can be randomized")
        if self.appearance is not None or self.distractors:
            raise ValueError(f"scene {self.name!r} (seed {self.seed}) is already randomized")
        clutter = sample_clutter(self.seed, self.objects, TABLE_TOP)
        return self.model_copy(
            update={
                "appearance": sample_appearance(self.seed, split),
                "objects": recolor_objects(self.seed, self.objects) + clutter,
            }
        )

    @property
    def free_objects(self) -> list[SceneObject]:
        """The task's movable objects (fixtures and distractors left out)."""
        return [o for o in self.objects if not o.fixed and not o.distractor]

    @property
    def distractors(self) -> list[SceneObject]:
        """Clutter added by :meth:`randomized`: real bodies no task counts."""
        return [o for o in self.objects if o.distractor]

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(
            f"no object {name!r} in scene {self.name!r}; objects: {[o.name for o in self.objects]}"
        )


def cube(
    name: str,
    x: float,
    y: float,
    size: float = 0.04,
    color=(0.85, 0.2, 0.2, 1.0),
    mass: float = 0.05,
    yaw: float = 0.0,
) -> SceneObject:
    """A cube resting on the table at table-centred (x, y)."""
    return SceneObject(
        name=name,
        shape=BoxShape(size=(size, size, size)),
        color=color,
        mass=mass,
        pose=Pose(xyz=(x, y, TABLE_TOP + size / 2), rpy=(0, 0, yaw)),
    )


#: The grey of the flat squares that mark spots on the table.
MARKER_GREY: Rgba = (0.55, 0.55, 0.55, 1.0)


def flat_marker(
    name: str,
    xy: Sequence[float],
    size: float,
    color: Rgba = MARKER_GREY,
    thickness: float = 0.001,
) -> SceneObject:
    """A flat `size` x `size` square lying on the table top, centred at table-centred `xy`: a
    spot the cameras see and the predicates measure against, fixed and never collided with."""
    return SceneObject(
        name=name,
        shape=BoxShape(size=(size, size, thickness)),
        color=color,
        fixed=True,
        collide=False,
        pose=Pose(xyz=(xy[0], xy[1], TABLE_TOP + thickness / 2)),
    )


def _empty() -> Scene:
    return Scene(name="empty")


def _cubes() -> Scene:
    colors = [
        (0.85, 0.2, 0.2, 1),
        (0.2, 0.6, 0.25, 1),
        (0.2, 0.35, 0.85, 1),
        (0.9, 0.75, 0.15, 1),
        (0.6, 0.3, 0.75, 1),
    ]
    spots = [(-0.2, -0.1), (0.2, -0.1), (0.0, 0.0), (-0.1, 0.12), (0.12, 0.12)]
    return Scene(
        name="cubes",
        objects=tuple(
            cube(f"cube_{i}", x, y, color=c)
            for i, ((x, y), c) in enumerate(zip(spots, colors, strict=True))
        ),
    )


def _demo() -> Scene:
    bowl = SceneObject(
        name="bowl",
        shape=BowlShape(radius=0.07, base_radius=0.045, height=0.05),
        color=(0.9, 0.9, 0.85, 1),
        mass=0.15,
        pose=Pose(xyz=(0.15, -0.05, TABLE_TOP)),
    )
    return Scene(
        name="demo",
        objects=(
            cube("red_cube", -0.2, -0.1),
            cube("green_cube", -0.05, 0.05, color=(0.2, 0.6, 0.25, 1)),
            cube("blue_cube", 0.0, -0.15, size=0.05, color=(0.2, 0.35, 0.85, 1)),
            bowl,
        ),
    )


#: Named example scenes for rendering and tests (tasks sample their own scenes).
DEMO_SCENES: dict[str, Callable[[], Scene]] = {"empty": _empty, "cubes": _cubes, "demo": _demo}


def demo_scene(name: str) -> Scene:
    """A named example scene; a clear error lists the valid names."""
    try:
        return DEMO_SCENES[name]()
    except KeyError:
        raise ValueError(
            f"unknown scene {name!r}; choose one of: {', '.join(DEMO_SCENES)}"
        ) from None

"""Primitive-based shapes: their collision compounds (primitives) and trimesh visuals.

Every shape collides through primitives. Concave shapes (a bowl) are primitive compounds - a
base disc and a ring of wall slabs - never a convex hull, which would close the opening. Visuals
are smooth trimesh meshes of the same solid. Scene objects, the ``Shape`` union and SDFormat
export live in :mod:`bicoord_drake.models.objects`; this module imports no other shape module, so
shape modules (pens, tools) may build on it.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.models.geometry import Pose, Primitive


class _Shape(BaseModel):
    model_config = ConfigDict(frozen=True)

    def primitives(self) -> list[Primitive]:
        raise NotImplementedError

    def visual_mesh(self) -> trimesh.Trimesh:
        return trimesh.util.concatenate([p.trimesh() for p in self.primitives()])

    def base_parts(self) -> tuple[int, ...]:
        """Indices in :meth:`primitives` of the parts that alone carry the object on a flat
        support; they stay compliant when the object is made rigid-hydroelastic, since a rigid
        flat part on the rigid table would touch it at one point (Drake's fallback) and rock."""
        return ()


class BoxShape(_Shape):
    """A box with full side lengths `size` (m)."""

    kind: Literal["box"] = "box"
    size: tuple[float, float, float] = Field(description="x, y, z side lengths, m")
    rounding: float | None = Field(
        None,
        ge=0,
        description="edge radius of the visual, m (default 6 % of the shortest side); a soap "
        "bar is a box with round edges. Collision stays the box.",
    )

    def primitives(self) -> list[Primitive]:
        return [Primitive(kind="box", size=self.size)]

    def visual_mesh(self) -> trimesh.Trimesh:
        smooth = 0.06 * min(self.size) if self.rounding is None else self.rounding
        return Primitive(kind="box", size=self.size).trimesh(smooth=smooth)


class CylinderShape(_Shape):
    """An upright cylinder (axis along the object's z)."""

    kind: Literal["cylinder"] = "cylinder"
    radius: float = Field(gt=0)
    length: float = Field(gt=0)

    def primitives(self) -> list[Primitive]:
        return [Primitive(kind="cylinder", size=(self.radius, self.length))]


class SphereShape(_Shape):
    kind: Literal["sphere"] = "sphere"
    radius: float = Field(gt=0)

    def primitives(self) -> list[Primitive]:
        return [Primitive(kind="sphere", size=(self.radius,))]


class BowlShape(_Shape):
    """An open bowl: a base disc and `segments` wall slabs flaring out from `base_radius` to
    `radius` at the rim. Its frame is at the centre of the base's underside."""

    kind: Literal["bowl"] = "bowl"
    radius: float = Field(gt=0, description="outer rim radius, m")
    base_radius: float = Field(gt=0, description="outer radius at the bottom, m")
    height: float = Field(gt=0)
    wall: float = Field(0.006, gt=0, description="wall and base thickness, m")
    segments: int = Field(16, ge=6, le=48)
    walls_on_base: bool = Field(
        False,
        description="wall slabs stand on the base disc instead of reaching down to the support: "
        "only the disc touches the table (one contact patch instead of 1 + segments)",
    )

    def primitives(self) -> list[Primitive]:
        prims = [
            Primitive(
                kind="cylinder",
                size=(self.base_radius, self.wall),
                pose=Pose(xyz=(0.0, 0.0, self.wall / 2)),
            )
        ]
        z0 = self.wall if self.walls_on_base else 0.0  # where the slabs start
        r0 = self.base_radius + (self.radius - self.base_radius) * z0 / self.height
        flare, rise = self.radius - r0, self.height - z0
        slant = float(np.hypot(flare, rise))
        tilt = float(np.arctan2(flare, rise))  # wall lean away from the axis
        r_mid = r0 + flare / 2 - self.wall / 2
        chord = 2 * (r0 + flare / 2) * np.tan(np.pi / self.segments) * 1.08
        for k in range(self.segments):
            yaw = 2 * np.pi * k / self.segments
            prims.append(
                Primitive(
                    kind="box",
                    size=(self.wall, float(chord), slant),
                    pose=Pose(
                        xyz=(r_mid * np.cos(yaw), r_mid * np.sin(yaw), (z0 + self.height) / 2),
                        rpy=(0.0, tilt, yaw),
                    ),
                )
            )
        return prims

    def base_parts(self) -> tuple[int, ...]:
        """The base disc when the walls stand on it; walls reaching down to the support
        already give a ring of contacts."""
        return (0,) if self.walls_on_base else ()

    def visual_mesh(self) -> trimesh.Trimesh:
        """A smooth solid of revolution: outer wall, rim, inner wall and base."""
        w = self.wall
        profile = np.array(
            [
                [0.0, 0.0],
                [self.base_radius, 0.0],
                [self.radius, self.height],
                [self.radius - w, self.height],
                [self.base_radius - w, w],
                [0.0, w],
            ]
        )
        return trimesh.creation.revolve(profile, sections=48)


class BinShape(_Shape):
    """An open box (a trash bin, a tray): a floor slab and four wall slabs standing on it.

    `size` is the outer x, y, z; its frame is at the centre of the floor's underside. The
    cavity (what ``inside`` checks against) is the inner box above the floor, up to the rim."""

    kind: Literal["bin"] = "bin"
    size: tuple[float, float, float] = Field(description="outer x, y, z, m")
    wall: float = Field(0.006, gt=0, description="wall thickness (and floor, unless given), m")
    floor: float | None = Field(
        None,
        gt=0,
        description="floor thickness, m (default: `wall`); a static bin standing on "
        "the table may have a solid base, which a dropped object cannot pass in one plant step",
    )

    @model_validator(mode="after")
    def _walls_fit(self) -> BinShape:
        if min(self.size[:2]) <= 2 * self.wall or self.size[2] <= self.floor_thickness:
            raise ValueError(
                f"bin size {self.size} leaves no room inside walls of {self.wall} m and a floor "
                f"of {self.floor_thickness} m"
            )
        return self

    @property
    def floor_thickness(self) -> float:
        """The floor slab's thickness, m."""
        return self.wall if self.floor is None else self.floor

    @property
    def inner_half(self) -> tuple[float, float]:
        """Half the inner x and y, m."""
        return self.size[0] / 2 - self.wall, self.size[1] / 2 - self.wall

    def primitives(self) -> list[Primitive]:
        sx, sy, h = self.size
        w, f = self.wall, self.floor_thickness
        zc = f + (h - f) / 2  # wall slabs stand on the floor slab
        return [
            Primitive(kind="box", size=(sx, sy, f), pose=Pose(xyz=(0.0, 0.0, f / 2))),
            Primitive(kind="box", size=(w, sy, h - f), pose=Pose(xyz=(sx / 2 - w / 2, 0.0, zc))),
            Primitive(kind="box", size=(w, sy, h - f), pose=Pose(xyz=(w / 2 - sx / 2, 0.0, zc))),
            Primitive(
                kind="box", size=(sx - 2 * w, w, h - f), pose=Pose(xyz=(0.0, sy / 2 - w / 2, zc))
            ),
            Primitive(
                kind="box", size=(sx - 2 * w, w, h - f), pose=Pose(xyz=(0.0, w / 2 - sy / 2, zc))
            ),
        ]

    def visual_mesh(self) -> trimesh.Trimesh:
        return trimesh.util.concatenate(
            [p.trimesh(smooth=0.4 * self.wall) for p in self.primitives()]
        )


class PotShape(_Shape):
    """A cooking pot: a flat base, straight round walls and two flat lug handles sticking out
    along the frame's -x and +x at the rim. Its frame is at the centre of the base's underside.

    Collision: a base disc, `segments` wall slabs standing on it and one box per handle
    (:meth:`handle_indices` names them in :meth:`primitives`); the visual is one smooth solid of
    revolution with rounded handle tabs."""

    kind: Literal["pot"] = "pot"
    radius: float = Field(gt=0, description="outer wall radius, m")
    height: float = Field(gt=0, description="rim height above the base's underside, m")
    wall: float = Field(0.006, gt=0, description="wall and base thickness, m")
    segments: int = Field(16, ge=6, le=48)
    handle_reach: float = Field(0.035, gt=0, description="how far a handle sticks out, m")
    handle_width: float = Field(0.05, gt=0, description="handle extent along the wall, m")
    handle_thickness: float = Field(0.012, gt=0, description="handle plate thickness, m")
    handle_drop: float = Field(0.004, ge=0, description="handle top below the rim, m")

    def handle_indices(self) -> tuple[int, int]:
        """Indices in :meth:`primitives` of the -x and the +x handle."""
        return (self.segments + 1, self.segments + 2)

    def handle_pose(self, sign: float) -> Pose:
        """Pose (object frame) of the handle on the `sign` (-1 or +1) side of x."""
        x = sign * (self.radius + self.handle_reach / 2 - 0.002)
        z = self.height - self.handle_drop - self.handle_thickness / 2
        return Pose(xyz=(float(x), 0.0, float(z)))

    def _handles(self) -> list[Primitive]:
        size = (self.handle_reach + 0.004, self.handle_width, self.handle_thickness)
        return [Primitive(kind="box", size=size, pose=self.handle_pose(s)) for s in (-1.0, 1.0)]

    def primitives(self) -> list[Primitive]:
        bowl = BowlShape(
            radius=self.radius,
            base_radius=self.radius,
            height=self.height,
            wall=self.wall,
            segments=self.segments,
            walls_on_base=True,
        )
        return bowl.primitives() + self._handles()

    def base_parts(self) -> tuple[int, ...]:
        """The base disc (the walls stand on it)."""
        return (0,)

    def visual_mesh(self) -> trimesh.Trimesh:
        r, w, h = self.radius, self.wall, self.height
        profile = np.array(
            [[0.0, 0.0], [r, 0.0], [r, h], [r - w, h], [r - w, w], [0.0, w]], dtype=float
        )
        body = trimesh.creation.revolve(profile, sections=48)
        tabs = [p.trimesh(smooth=0.4 * self.handle_thickness) for p in self._handles()]
        return trimesh.util.concatenate([body, *tabs])


class CompoundShape(_Shape):
    """A rigid union of primitives in the object frame (a skillet = bowl slabs + a handle bar,
    a microphone = a handle cylinder + a ball head, ...). Collision uses exactly these parts."""

    kind: Literal["compound"] = "compound"
    parts: tuple[Primitive, ...] = Field(min_length=1)

    def primitives(self) -> list[Primitive]:
        return list(self.parts)

    def visual_mesh(self) -> trimesh.Trimesh:
        return trimesh.util.concatenate(
            [
                p.trimesh(smooth=0.1 * min(p.size)) if p.kind == "box" else p.trimesh()
                for p in self.parts
            ]
        )


class MugShape(_Shape):
    """A mug: an open cup with a handle on its +x side; frame at the centre of its underside.

    It collides as a closed cylinder and a handle bar (a distractor nothing is put into); its
    visual shows the cavity.
    """

    kind: Literal["mug"] = "mug"
    radius: float = Field(gt=0, description="outer radius, m")
    height: float = Field(gt=0)
    wall: float = Field(0.005, gt=0)

    def _handle(self) -> Primitive:
        t = 0.012  # handle thickness
        return Primitive(
            kind="box",
            size=(0.025, t, 0.6 * self.height),
            pose=Pose(xyz=(self.radius + 0.0125 - self.wall, 0.0, 0.5 * self.height)),
        )

    def primitives(self) -> list[Primitive]:
        body = Primitive(
            kind="cylinder",
            size=(self.radius, self.height),
            pose=Pose(xyz=(0.0, 0.0, self.height / 2)),
        )
        return [body, self._handle()]

    def visual_mesh(self) -> trimesh.Trimesh:
        r, h, w = self.radius, self.height, self.wall
        profile = np.array([[0.0, 0.0], [r, 0.0], [r, h], [r - w, h], [r - w, w], [0.0, w]])
        cup = trimesh.creation.revolve(profile, sections=40)
        return trimesh.util.concatenate([cup, self._handle().trimesh(smooth=0.004)])

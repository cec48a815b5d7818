"""Procedural task objects: shapes, their collision compounds, trimesh visuals and inertia.

Every shape is collided through primitives. Concave shapes (a bowl) are primitive compounds - a
base disc and a ring of wall slabs - never a convex hull, which would close the opening. Visuals
are smooth trimesh meshes of the same solid, exported as OBJ with normals.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.models.geometry import (
    ContactProps,
    Pose,
    Primitive,
    Rgba,
    export_obj,
    sdf_collision,
    sdf_inertial,
    sdf_mesh_visual,
)
from bicoord_drake.models.pens import PenShape
from bicoord_drake.models.tools import ToolShape


class _Shape(BaseModel):
    model_config = ConfigDict(frozen=True)

    def primitives(self) -> list[Primitive]:
        raise NotImplementedError

    def visual_mesh(self) -> trimesh.Trimesh:
        return trimesh.util.concatenate([p.trimesh() for p in self.primitives()])


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
    wall: float = Field(0.006, gt=0, description="wall and floor thickness, m")

    @model_validator(mode="after")
    def _walls_fit(self) -> BinShape:
        if min(self.size[:2]) <= 2 * self.wall or self.size[2] <= self.wall:
            raise ValueError(f"bin size {self.size} leaves no room inside walls of {self.wall} m")
        return self

    @property
    def inner_half(self) -> tuple[float, float]:
        """Half the inner x and y, m."""
        return self.size[0] / 2 - self.wall, self.size[1] / 2 - self.wall

    def primitives(self) -> list[Primitive]:
        sx, sy, h = self.size
        w = self.wall
        zc = w + (h - w) / 2  # wall slabs stand on the floor slab
        return [
            Primitive(kind="box", size=(sx, sy, w), pose=Pose(xyz=(0.0, 0.0, w / 2))),
            Primitive(kind="box", size=(w, sy, h - w), pose=Pose(xyz=(sx / 2 - w / 2, 0.0, zc))),
            Primitive(kind="box", size=(w, sy, h - w), pose=Pose(xyz=(w / 2 - sx / 2, 0.0, zc))),
            Primitive(
                kind="box", size=(sx - 2 * w, w, h - w), pose=Pose(xyz=(0.0, sy / 2 - w / 2, zc))
            ),
            Primitive(
                kind="box", size=(sx - 2 * w, w, h - w), pose=Pose(xyz=(0.0, w / 2 - sy / 2, zc))
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


Shape = Annotated[
    BoxShape
    | CylinderShape
    | SphereShape
    | BowlShape
    | BinShape
    | PotShape
    | CompoundShape
    | MugShape
    | PenShape
    | ToolShape,
    Field(discriminator="kind"),
]


# ------------------------------------------------------------------ small everyday objects
def toy_car(
    length: float = 0.08,
    width: float = 0.04,
    body_height: float = 0.02,
    wheel_radius: float = 0.011,
    wheel_width: float = 0.008,
) -> CompoundShape:
    """A toy car as one rigid body: a body box on four wheel cylinders (axles along y) and a
    cabin box on top. Frame at the centre of the footprint on the support (wheels' bottom)."""
    clear = wheel_radius * 0.55  # the body's underside above the support
    body_z = clear + body_height / 2
    cabin = (length / 2, width * 0.85, body_height * 0.7)
    wheel_x = length / 2 - wheel_radius * 1.25
    wheel_y = width / 2 + wheel_width / 2
    parts = [
        Primitive(kind="box", size=(length, width, body_height), pose=Pose(xyz=(0.0, 0.0, body_z))),
        Primitive(
            kind="box",
            size=cabin,
            pose=Pose(xyz=(-length * 0.08, 0.0, clear + body_height + cabin[2] / 2)),
        ),
    ]
    for sx in (1.0, -1.0):
        for sy in (1.0, -1.0):
            parts.append(
                Primitive(
                    kind="cylinder",
                    size=(wheel_radius, wheel_width),
                    pose=Pose(
                        xyz=(sx * wheel_x, sy * wheel_y, wheel_radius), rpy=(np.pi / 2, 0, 0)
                    ),
                )
            )
    return CompoundShape(parts=tuple(parts))


def domed_box(size: tuple[float, float, float], dome_radius: float) -> CompoundShape:
    """A flat box with a rounded ridge along its length (a computer mouse, a loaf of bread):
    the box plus a capsule along x whose axis lies on the box's top face (its lower half
    within the box, so the solid is the box and a half-capsule ridge). Frame at the centre of
    the bottom face."""
    sx, sy, sz = size
    if not 0 < dome_radius <= min(sy / 2, sx / 2, sz):
        raise ValueError(f"dome radius {dome_radius} must fit on and within the box {size}")
    dome_length = sx - 2 * dome_radius - 0.004
    if dome_length <= 0:
        raise ValueError(f"box {size} too short for a dome of radius {dome_radius}")
    return CompoundShape(
        parts=(
            Primitive(kind="box", size=size, pose=Pose(xyz=(0.0, 0.0, sz / 2))),
            Primitive(
                kind="capsule",
                size=(dome_radius, dome_length),
                pose=Pose(xyz=(0.0, 0.0, sz), rpy=(0.0, np.pi / 2, 0.0)),
            ),
        )
    )


class Slide(BaseModel):
    """A prismatic joint mounting an object on a fixed `parent` object (a drawer in a
    cabinet): the object translates along `axis` (the parent's frame) from its scene pose,
    which is joint position 0, between `lower` and `upper` (m), with viscous `damping`
    (N s/m)."""

    model_config = ConfigDict(frozen=True)

    parent: str
    axis: tuple[float, float, float] = Field(description="unit direction in the parent frame")
    lower: float = 0.0
    upper: float = Field(gt=0)
    damping: float = Field(0.0, ge=0)

    @model_validator(mode="after")
    def _valid(self) -> Slide:
        if not np.isclose(np.linalg.norm(self.axis), 1.0, atol=1e-6):
            raise ValueError(f"slide axis {self.axis} must be a unit vector")
        if not self.lower <= 0.0 < self.upper:
            raise ValueError(f"slide limits [{self.lower}, {self.upper}] must contain 0")
        return self


class SceneObject(BaseModel):
    """One object of a scene: its shape, look, mass and initial pose (object frame in world)."""

    model_config = ConfigDict(frozen=True)

    name: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    shape: Shape
    color: Rgba = (0.8, 0.2, 0.2, 1.0)
    mass: float = Field(0.05, gt=0)
    pose: Pose = Pose()
    fixed: bool = Field(False, description="welded to the world (fixtures: bins, platforms)")
    collide: bool = Field(True, description="False for flat markers that are only seen")
    friction: float = Field(0.9, gt=0)
    hydroelastic_modulus: float = Field(1e6, gt=0)
    resolution_hint: float | None = Field(
        None, gt=0, description="hydroelastic mesh size, m (default: from the shape)"
    )
    distractor: bool = Field(
        False, description="clutter added by randomization: a real body, but not part of the task"
    )
    color_fixed: bool = Field(
        False,
        description="the colour is part of what the object is (a red stove, a bread roll): "
        "randomized scenes keep it",
    )
    slide: Slide | None = Field(
        None, description="mounted on a prismatic joint to a fixed object (None: free or fixed)"
    )


def object_sdf(obj: SceneObject) -> str:
    """SDFormat for one scene object (a single body named after the object)."""
    prims = obj.shape.primitives()
    mesh = obj.shape.visual_mesh()
    hint = obj.resolution_hint or _resolution_hint(obj.shape)
    props = ContactProps(
        friction=obj.friction,
        hydroelastic="compliant",
        hydroelastic_modulus=obj.hydroelastic_modulus,
        resolution_hint=hint,
        dissipation=3.0,
    )
    if obj.fixed:
        props = ContactProps(friction=obj.friction, hydroelastic="rigid", resolution_hint=hint)
    mass, com, inertia = inertial_of(prims, obj.mass)
    body = [f'<link name="{obj.name}">', sdf_inertial(mass, com, inertia)]
    if obj.collide:
        body += [sdf_collision(f"{obj.name}_collision_{i}", p, props) for i, p in enumerate(prims)]
    body.append(
        sdf_mesh_visual(f"{obj.name}_visual", export_obj(mesh, f"obj_{obj.shape.kind}"), obj.color)
    )
    accents = getattr(obj.shape, "accent_visuals", list)()  # parts in another colour
    for i, (part, rgba) in enumerate(accents):
        path = export_obj(part, f"obj_{obj.shape.kind}_accent")
        body.append(sdf_mesh_visual(f"{obj.name}_accent_{i}", path, rgba))
    body.append("</link>")
    return (
        '<?xml version="1.0"?><sdf version="1.9" xmlns:drake="http://drake.mit.edu">'
        f'<model name="{obj.name}">{"".join(body)}</model></sdf>'
    )


def inertial_of(prims: list[Primitive], mass: float) -> tuple[float, tuple, tuple]:
    """Mass, centre of mass and principal-axis-aligned inertia diagonal of a uniform compound.

    Off-diagonal terms of the symmetric shapes used here vanish in the object frame.
    """
    meshes = [p.trimesh() for p in prims]
    volumes = np.array([m.volume for m in meshes])
    density = mass / volumes.sum()
    com = sum(m.center_mass * v for m, v in zip(meshes, volumes, strict=True)) / volumes.sum()
    inertia = np.zeros((3, 3))
    for m in meshes:
        m.density = density
        inertia += m.moment_inertia_frame(_translation(com))
    diag = np.maximum(np.diag(inertia), 1e-9)
    return mass, tuple(float(c) for c in com), tuple(float(d) for d in diag)


def _translation(p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _resolution_hint(shape: _Shape) -> float:
    if isinstance(shape, SphereShape):
        return max(shape.radius / 2, 0.003)
    if isinstance(shape, CylinderShape):
        return max(min(shape.radius, shape.length) / 2, 0.003)
    return 0.01

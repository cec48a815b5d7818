"""Procedural task objects: the ``Shape`` union, scene objects, SDFormat export and inertia.

The shapes themselves (collision primitives and trimesh visuals) live in
:mod:`~bicoord_drake.models.shapes`, :mod:`~bicoord_drake.models.pens` and
:mod:`~bicoord_drake.models.tools`; the basic ones are re-exported here. Visuals are exported as
OBJ with normals.
"""

from __future__ import annotations

from typing import Annotated, get_args

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.config import RigidKind
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
from bicoord_drake.models.shapes import (
    BinShape,
    BowlShape,
    BoxShape,
    CompoundShape,
    CylinderShape,
    MugShape,
    PotShape,
    SphereShape,
)
from bicoord_drake.models.tools import ToolShape

__all__ = [
    "BinShape",
    "BowlShape",
    "BoxShape",
    "CompoundShape",
    "CylinderShape",
    "MugShape",
    "PenShape",
    "PotShape",
    "SceneObject",
    "Shape",
    "Slide",
    "SphereShape",
    "ToolShape",
    "domed_box",
    "inertial_of",
    "object_sdf",
    "toy_car",
]

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
    rigid_hydroelastic: bool = Field(
        False,
        description="a bowl or pot that is rigid-hydroelastic but for the base its walls stand "
        "on, whatever StationConfig.rigid_object_kinds says (a task whose bowls' contacts with "
        "each other dominate its physics cost: stack_bowls)",
    )

    compliant_parts: tuple[int, ...] = Field(
        (),
        description="parts (indices in the shape's primitives) of a fixed object that are "
        "compliant-hydroelastic (its hydroelastic_modulus) instead of rigid: a bin's floor that "
        "dropped objects land on. Under SAP a compliant box landing flat on a rigid face at "
        "0.3-1 m/s can be thrown back up at up to 30 m/s; on a compliant one it comes to rest "
        "(benchmarks/bench_flat_landing.md)",
    )

    contact_margin: float | None = Field(
        None,
        ge=0,
        le=0.01,
        description="hydroelastic contact margin of this object's geometries, m, in place of "
        "StationConfig.hydroelastic_margin (None: the station's): a light object whose flat base "
        "is set down on the rigid table. Under SAP such a base let go a fraction of a millimetre "
        "above the table can be thrown up (a bowl released on the table rose 1.5 cm, into the "
        "opening fingers); with a margin of a few mm the contact acts before the faces meet "
        "(benchmarks/bench_flat_landing.md). It acts on every face of the object: keep it below "
        "the gap a loosened grip leaves (handover_block_with_bowls: 3 mm)",
    )

    @model_validator(mode="after")
    def _compliant_parts(self) -> SceneObject:
        if self.compliant_parts and not self.fixed:
            raise ValueError(
                f"{self.name}: compliant_parts is for fixed objects (free ones are "
                "compliant already)"
            )
        count = len(self.shape.primitives())
        bad = [i for i in self.compliant_parts if not 0 <= i < count]
        if bad:
            raise ValueError(f"{self.name}: compliant_parts {bad} not in 0..{count - 1}")
        return self

    @model_validator(mode="after")
    def _rigid_kind(self) -> SceneObject:
        if self.rigid_hydroelastic and self.shape.kind not in get_args(RigidKind):
            raise ValueError(
                f"{self.name}: only {get_args(RigidKind)} may be rigid_hydroelastic, not a "
                f"{self.shape.kind} (a rigid flat part on the rigid table touches it at one point)"
            )
        return self


def object_sdf(obj: SceneObject, rigid: bool = False) -> str:
    """SDFormat for one scene object (a single body named after the object).

    A free object is compliant-hydroelastic (its ``hydroelastic_modulus``) unless `rigid`
    (``StationConfig.rigid_object_kinds``) or its ``rigid_hydroelastic``: then every part but
    the shape's ``base_parts()`` is rigid-hydroelastic. A fixed object is rigid-hydroelastic
    but for its ``compliant_parts``."""
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
    part_props = [props] * len(prims)
    if obj.fixed:
        fixed = ContactProps(friction=obj.friction, hydroelastic="rigid", resolution_hint=hint)
        part_props = [props if i in obj.compliant_parts else fixed for i in range(len(prims))]
    elif rigid or obj.rigid_hydroelastic:
        stiff = props.model_copy(update={"hydroelastic": "rigid"})
        base = obj.shape.base_parts()
        part_props = [props if i in base else stiff for i in range(len(prims))]
    mass, com, inertia = inertial_of(prims, obj.mass)
    body = [f'<link name="{obj.name}">', sdf_inertial(mass, com, inertia)]
    if obj.collide:
        body += [
            sdf_collision(f"{obj.name}_collision_{i}", p, c)
            for i, (p, c) in enumerate(zip(prims, part_props, strict=True))
        ]
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


def _resolution_hint(shape: Shape) -> float:
    if isinstance(shape, SphereShape):
        return max(shape.radius / 2, 0.003)
    if isinstance(shape, CylinderShape):
        return max(min(shape.radius, shape.length) / 2, 0.003)
    return 0.01

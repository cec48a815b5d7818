"""Primitive shapes for robot and object models: poses, SDFormat snippets, trimesh visuals.

Collision geometry is always a primitive (box, cylinder, capsule, sphere) so that distance queries
and contact stay fast; visual geometry is a smooth trimesh mesh exported as OBJ *with normals*
(Drake refuses normal-less meshes once a render engine is registered) into a content-addressed
cache, so repeated builds reuse the same files.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, field_validator

if TYPE_CHECKING:
    from pydrake.math import RigidTransform

Vec3 = tuple[float, float, float]
Rgba = tuple[float, float, float, float]


class Pose(BaseModel):
    """A rigid pose: translation `xyz` (m) and roll-pitch-yaw `rpy` (rad, extrinsic X-Y-Z)."""

    model_config = ConfigDict(frozen=True)

    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)

    def matrix(self) -> np.ndarray:
        """The 4x4 homogeneous transform."""
        return pose_matrix(self.xyz, self.rpy)

    def sdf(self) -> str:
        return "<pose>{} {} {} {} {} {}</pose>".format(*_fmt(self.xyz), *_fmt(self.rpy))


class Primitive(BaseModel):
    """A collision/visual primitive in its link frame.

    `size` is (x, y, z) for a box, (radius, length) for a cylinder or capsule (axis along the
    primitive's local z), (radius,) for a sphere.
    """

    model_config = ConfigDict(frozen=True)

    kind: Literal["box", "cylinder", "capsule", "sphere"]
    size: tuple[float, ...]
    pose: Pose = Pose()

    @field_validator("size")
    @classmethod
    def _positive(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if any(s <= 0 for s in v):
            raise ValueError(f"primitive sizes must be positive, got {v}")
        return v

    def sdf_geometry(self) -> str:
        s = self.size
        if self.kind == "box":
            return "<box><size>{} {} {}</size></box>".format(*_fmt(s))
        if self.kind == "cylinder":
            return f"<cylinder><radius>{s[0]:.6g}</radius><length>{s[1]:.6g}</length></cylinder>"
        if self.kind == "capsule":
            return f"<capsule><radius>{s[0]:.6g}</radius><length>{s[1]:.6g}</length></capsule>"
        return f"<sphere><radius>{s[0]:.6g}</radius></sphere>"

    def trimesh(self, smooth: float = 0.0) -> trimesh.Trimesh:
        """A closed mesh of this primitive placed at its pose; `smooth` rounds box edges (m)."""
        s = self.size
        if self.kind == "box":
            mesh = rounded_box(s, smooth) if smooth > 0 else trimesh.creation.box(extents=s)
        elif self.kind == "cylinder":
            mesh = trimesh.creation.cylinder(radius=s[0], height=s[1], sections=32)
        elif self.kind == "capsule":
            mesh = trimesh.creation.capsule(radius=s[0], height=s[1], count=[24, 24])
        else:
            mesh = trimesh.creation.icosphere(subdivisions=3, radius=s[0])
        mesh.apply_transform(self.pose.matrix())
        return mesh


def segment(kind: Literal["capsule", "cylinder"], p0: Vec3, p1: Vec3, radius: float) -> Primitive:
    """A capsule or cylinder whose axis runs from `p0` to `p1` (link frame)."""
    a, b = np.asarray(p0, float), np.asarray(p1, float)
    d = b - a
    length = float(np.linalg.norm(d))
    if length <= 0:
        raise ValueError("segment endpoints coincide")
    z = d / length
    # rotation taking +z to d: pitch about y, then yaw about z (extrinsic rpy = (0, pitch, yaw))
    pitch = float(np.arccos(np.clip(z[2], -1.0, 1.0)))
    yaw = float(np.arctan2(z[1], z[0]))
    mid = tuple(float(v) for v in (a + b) / 2)
    return Primitive(kind=kind, size=(radius, length), pose=Pose(xyz=mid, rpy=(0.0, pitch, yaw)))


def pose_matrix(xyz: Vec3, rpy: Vec3) -> np.ndarray:
    """4x4 transform from translation and extrinsic roll-pitch-yaw (R = Rz(y) Ry(p) Rx(r))."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    R = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = xyz
    return T


def transform_points(X_AB: RigidTransform, points_B: np.ndarray) -> np.ndarray:
    """(N, 3) points given in frame B, expressed in frame A (``X_AB`` applied to each row)."""
    return points_B @ X_AB.rotation().matrix().T + X_AB.translation()


def rounded_box(extents: tuple[float, ...], radius: float) -> trimesh.Trimesh:
    """A box with rounded edges: the Minkowski sum of a shrunk box and a sphere, as a hull."""
    ext = np.asarray(extents, float)
    radius = float(min(radius, 0.49 * ext.min()))
    inner = ext / 2 - radius
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    points = np.concatenate([sphere.vertices + c * inner for c in corners])
    return trimesh.convex.convex_hull(points)


def mesh_cache_dir() -> Path:
    """Where generated OBJ files live: $BICOORD_CACHE or ~/.cache/bicoord_drake/meshes."""
    root = os.environ.get("BICOORD_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "bicoord_drake"
    )
    path = Path(root) / "meshes"
    path.mkdir(parents=True, exist_ok=True)
    return path


def export_obj(mesh: trimesh.Trimesh, name: str) -> Path:
    """Write `mesh` as an OBJ with vertex normals, named by content hash; atomic and cached."""
    text = trimesh.exchange.obj.export_obj(mesh, include_normals=True, include_texture=False)
    digest = hashlib.sha1(text.encode()).hexdigest()[:16]
    path = mesh_cache_dir() / f"{name}_{digest}.obj"
    if not path.exists():
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".obj.tmp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    return path


def sdf_inertial(mass: float, com: Vec3, inertia_diag: Vec3) -> str:
    ixx, iyy, izz = inertia_diag
    return (
        f"<inertial>{Pose(xyz=com).sdf()}<mass>{mass:.6g}</mass><inertia>"
        f"<ixx>{ixx:.6g}</ixx><iyy>{iyy:.6g}</iyy><izz>{izz:.6g}</izz>"
        "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>"
    )


def sdf_material(rgba: Rgba) -> str:
    c = " ".join(_fmt(rgba))
    return f"<material><diffuse>{c}</diffuse><ambient>{c}</ambient></material>"


def sdf_mesh_visual(name: str, path: Path, rgba: Rgba) -> str:
    return (
        f'<visual name="{name}"><geometry><mesh><uri>file://{path}</uri></mesh></geometry>'
        f"{sdf_material(rgba)}</visual>"
    )


class ContactProps(BaseModel):
    """Contact properties of a collision geometry (Drake's proximity properties)."""

    model_config = ConfigDict(frozen=True)

    friction: float = Field(1.0, gt=0)
    hydroelastic: Literal["none", "compliant", "rigid"] = "none"
    hydroelastic_modulus: float = Field(5e6, gt=0)
    resolution_hint: float = Field(0.01, gt=0)
    dissipation: float = Field(1.0, ge=0)

    def sdf(self) -> str:
        mu = f"{self.friction:.4g}"
        parts = [
            "<drake:proximity_properties>",
            f"<drake:mu_dynamic>{mu}</drake:mu_dynamic><drake:mu_static>{mu}</drake:mu_static>",
            f"<drake:hunt_crossley_dissipation>{self.dissipation:.4g}</drake:hunt_crossley_dissipation>",
        ]
        if self.hydroelastic == "compliant":
            parts.append(
                "<drake:compliant_hydroelastic/>"
                f"<drake:hydroelastic_modulus>{self.hydroelastic_modulus:.6g}</drake:hydroelastic_modulus>"
                f"<drake:mesh_resolution_hint>{self.resolution_hint:.4g}</drake:mesh_resolution_hint>"
            )
        elif self.hydroelastic == "rigid":
            parts.append(
                "<drake:rigid_hydroelastic/>"
                f"<drake:mesh_resolution_hint>{self.resolution_hint:.4g}</drake:mesh_resolution_hint>"
            )
        parts.append("</drake:proximity_properties>")
        return "".join(parts)


def sdf_collision(name: str, prim: Primitive, props: ContactProps) -> str:
    return (
        f'<collision name="{name}">{prim.pose.sdf()}<geometry>{prim.sdf_geometry()}</geometry>'
        f"{props.sdf()}</collision>"
    )


def _fmt(values) -> list[str]:
    return [f"{float(v):.6g}" for v in values]

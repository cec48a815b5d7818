"""Pens, markers and a pen holder (collect_pens).

A :class:`PenShape` is a writing instrument along its own z axis, its frame at the middle of
its full length: a round body and a writing tip at the -z end (:meth:`PenShape.tip_point`),
so the tip is known from the shape itself. It collides as two cylinders - the body and a
narrow cylinder for the tip (the cone's bounding cylinder at half the body's radius) - and
looks like a body, a conical tip and a back cap, the tip and cap in an accent colour
(:meth:`PenShape.accent_visuals`). Lying on the table its frame is turned by roll pi/2.

The holder is a straight open cup (:func:`pen_holder`: a :class:`BowlShape` with vertical
walls standing on its base), so ``cavity_of`` knows its real inside. :func:`max_lean` is the
largest tilt a pen standing on the holder's floor can have: tip at the foot of one wall,
body leaning on the opposite rim.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.models.geometry import Pose, Primitive, Rgba
from bicoord_drake.models.shapes import BowlShape


class PenShape(BaseModel):
    """A pen or marker along z, frame at the middle of its full length, tip at -z."""

    model_config = ConfigDict(frozen=True)

    kind: Literal["pen"] = "pen"
    radius: float = Field(gt=0, description="body radius, m")
    length: float = Field(gt=0, description="full length, tip apex to back end, m")
    tip_length: float = Field(gt=0, description="length of the conical tip, m")
    cap_length: float = Field(0.0, ge=0, description="accent band at the back end, m")
    accent: Rgba = Field((0.1, 0.1, 0.1, 1.0), description="colour of the tip and cap")

    @model_validator(mode="after")
    def _fits(self) -> PenShape:
        if self.tip_length + self.cap_length >= self.length:
            raise ValueError(f"tip {self.tip_length} and cap {self.cap_length} exceed the pen")
        return self

    @property
    def tip_radius(self) -> float:
        """Radius of the tip's collision cylinder, m."""
        return 0.5 * self.radius

    def tip_point(self) -> np.ndarray:
        """The tip's apex in the object frame."""
        return np.array([0.0, 0.0, -self.length / 2])

    def primitives(self) -> list[Primitive]:
        half, t = self.length / 2, self.tip_length
        body = self.length - t
        return [
            Primitive(kind="cylinder", size=(self.radius, body), pose=Pose(xyz=(0.0, 0.0, t / 2))),
            Primitive(
                kind="cylinder",
                size=(self.tip_radius, t),
                pose=Pose(xyz=(0.0, 0.0, -half + t / 2)),
            ),
        ]

    def visual_mesh(self) -> trimesh.Trimesh:
        """The body (without tip and cap)."""
        half, t, c = self.length / 2, self.tip_length, self.cap_length
        z0, z1 = -half + t, half - c
        mesh = trimesh.creation.cylinder(radius=self.radius, height=z1 - z0, sections=32)
        mesh.apply_translation((0.0, 0.0, (z0 + z1) / 2))
        return mesh

    def accent_visuals(self) -> list[tuple[trimesh.Trimesh, Rgba]]:
        """The conical tip and the back cap, in the accent colour."""
        half, t, c, r = self.length / 2, self.tip_length, self.cap_length, self.radius
        profile = np.array(
            [[0.0, -half], [0.18 * r, -half], [r, -half + t], [0.0, -half + t]], dtype=float
        )
        parts = [trimesh.creation.revolve(profile, sections=32)]
        if c > 0:
            cap = trimesh.creation.cylinder(radius=r * 1.06, height=c, sections=32)
            cap.apply_translation((0.0, 0.0, half - c / 2))
            parts.append(cap)
        return [(trimesh.util.concatenate(parts), self.accent)]


def pen_holder(radius: float = 0.04, height: float = 0.10, wall: float = 0.004) -> BowlShape:
    """The pen holder: a straight open cup, `radius` outside, walls standing on its base."""
    return BowlShape(
        radius=radius, base_radius=radius, height=height, wall=wall, segments=24, walls_on_base=True
    )


def max_lean(inner_radius: float, depth: float, pen_radius: float, tip_radius: float) -> float:
    """Largest tilt (rad) of a pen whose tip stands on the floor of a round cavity
    (`inner_radius`, `depth` from floor to rim), leaning on the opposite rim: the tip's
    collision cylinder against one wall, the body (`pen_radius`) touching the rim's inner edge
    on the other side. Solves D cos(a) - H sin(a) = r for the tilt a."""
    d = 2 * inner_radius - tip_radius
    hyp = math.hypot(d, depth)
    if pen_radius >= hyp:
        raise ValueError("the pen is too thick for the holder")
    return math.acos(pen_radius / hyp) - math.atan2(depth, d)


#: The kinds: (radius range, length range, tip length, cap length, mass range kg).
PEN_KINDS: dict[str, tuple[tuple[float, float], tuple[float, float], float, float, tuple]] = {
    "pen": ((0.007, 0.0075), (0.13, 0.145), 0.018, 0.02, (0.012, 0.016)),
    "marker": ((0.009, 0.0095), (0.12, 0.135), 0.014, 0.03, (0.018, 0.024)),
}
#: Body colours and accent colours drawn from.
BODY_COLORS: tuple[Rgba, ...] = (
    (0.12, 0.3, 0.8, 1.0),
    (0.85, 0.15, 0.15, 1.0),
    (0.15, 0.6, 0.25, 1.0),
    (0.95, 0.95, 0.93, 1.0),
    (0.95, 0.75, 0.1, 1.0),
    (0.55, 0.25, 0.7, 1.0),
)
ACCENT_COLORS: tuple[Rgba, ...] = (
    (0.08, 0.08, 0.08, 1.0),
    (0.9, 0.9, 0.9, 1.0),
    (0.2, 0.2, 0.75, 1.0),
    (0.75, 0.1, 0.1, 1.0),
)


def random_pen(rng: np.random.Generator, kind: str) -> tuple[PenShape, float, Rgba]:
    """A `kind` ('pen' or 'marker') of random size and colours from `rng`: shape, mass, body
    colour."""
    (r0, r1), (l0, l1), tip, cap, (m0, m1) = PEN_KINDS[kind]
    shape = PenShape(
        radius=round(float(rng.uniform(r0, r1)), 5),
        length=round(float(rng.uniform(l0, l1)), 4),
        tip_length=tip,
        cap_length=cap,
        accent=ACCENT_COLORS[int(rng.integers(len(ACCENT_COLORS)))],
    )
    mass = round(float(rng.uniform(m0, m1)), 4)
    return shape, mass, BODY_COLORS[int(rng.integers(len(BODY_COLORS)))]

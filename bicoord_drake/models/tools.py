"""Hand tools made of boxes: a dustpan and a hand brush (sweep_block).

A :class:`ToolShape` is a rigid union of box parts, like a ``CompoundShape``, with some parts
drawn in an accent colour (a brush's dark bristles under its wooden back). It collides through
exactly its parts.

:func:`dustpan` is a flat pan with low side walls and a taller back wall, open at its front
(+x), and a straight handle sticking out of the back wall's top toward -x. Its frame is at the
centre of the floor's underside; :func:`dustpan_cavity` is its inside for ``inside``: the box
between the side walls, from the back wall's inner face to the open front edge, above the
floor, up to the side walls' top.

:func:`hand_brush` is a block of bristles (frame at the centre of their bottom face) under a
wooden back, and a straight handle along +x at the back's top. Both handles lie level, raised
off the support by the walls or the head, so a top grasp closes the pads across the handle's
width with the fingertips above the table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bicoord_drake.models.geometry import Pose, Primitive, Rgba


class ToolShape(BaseModel):
    """A union of box parts; the parts listed in `accent_parts` are drawn in `accent`."""

    model_config = ConfigDict(frozen=True)

    kind: Literal["tool"] = "tool"
    parts: tuple[Primitive, ...] = Field(min_length=1)
    accent_parts: tuple[int, ...] = ()
    accent: Rgba = (0.12, 0.12, 0.12, 1.0)

    @model_validator(mode="after")
    def _accents_exist(self) -> ToolShape:
        if any(not 0 <= i < len(self.parts) for i in self.accent_parts):
            raise ValueError(f"accent parts {self.accent_parts} out of range")
        return self

    def primitives(self) -> list[Primitive]:
        return list(self.parts)

    def _mesh(self, indices) -> trimesh.Trimesh:
        return trimesh.util.concatenate(
            [self.parts[i].trimesh(smooth=0.25 * min(self.parts[i].size)) for i in indices]
        )

    def visual_mesh(self) -> trimesh.Trimesh:
        """The parts in the object's own colour."""
        return self._mesh([i for i in range(len(self.parts)) if i not in self.accent_parts])

    def accent_visuals(self) -> list[tuple[trimesh.Trimesh, Rgba]]:
        """The accent parts, in the accent colour."""
        if not self.accent_parts:
            return []
        return [(self._mesh(self.accent_parts), self.accent)]


@dataclass(frozen=True)
class DustpanDims:
    """Dustpan sizes (m): the pan's outer length (x) and width (y), floor and wall thickness,
    side and back wall heights above the floor, the handle's length, width (across the grip)
    and height."""

    length: float = 0.13
    width: float = 0.15
    floor: float = 0.005
    wall: float = 0.005
    side_height: float = 0.03
    back_height: float = 0.045
    handle_length: float = 0.09
    handle_width: float = 0.022
    handle_height: float = 0.024

    @property
    def handle_centre(self) -> tuple[float, float, float]:
        """The handle's centre in the pan frame: out of the back wall, flush with its top."""
        top = self.floor + self.back_height
        return (-self.length / 2 - self.handle_length / 2, 0.0, top - self.handle_height / 2)


def dustpan(d: DustpanDims = DustpanDims()) -> ToolShape:
    """The dustpan (see the module doc), its mouth toward +x."""
    L, W, t, w = d.length, d.width, d.floor, d.wall
    hs, hb = d.side_height, d.back_height
    side_x = L - w  # the side walls run from the back wall to the front edge
    parts = (
        Primitive(kind="box", size=(L, W, t), pose=Pose(xyz=(0.0, 0.0, t / 2))),
        Primitive(kind="box", size=(w, W, hb), pose=Pose(xyz=(-L / 2 + w / 2, 0.0, t + hb / 2))),
        Primitive(
            kind="box", size=(side_x, w, hs), pose=Pose(xyz=(w / 2, W / 2 - w / 2, t + hs / 2))
        ),
        Primitive(
            kind="box", size=(side_x, w, hs), pose=Pose(xyz=(w / 2, -W / 2 + w / 2, t + hs / 2))
        ),
        Primitive(
            kind="box",
            size=(d.handle_length, d.handle_width, d.handle_height),
            pose=Pose(xyz=d.handle_centre),
        ),
    )
    return ToolShape(parts=parts)


@dataclass(frozen=True)
class DustpanCavity:
    """The inside of a dustpan in its frame: x from the back wall's inner face to the front
    edge, |y| within the side walls, from the floor's top to the side walls' top."""

    x_range: tuple[float, float]
    half_y: float
    floor: float
    rim: float


def dustpan_cavity(d: DustpanDims = DustpanDims()) -> DustpanCavity:
    """The dustpan's inside (see :class:`DustpanCavity`)."""
    return DustpanCavity(
        x_range=(-d.length / 2 + d.wall, d.length / 2),
        half_y=d.width / 2 - d.wall,
        floor=d.floor,
        rim=d.floor + d.side_height,
    )


@dataclass(frozen=True)
class BrushDims:
    """Hand brush sizes (m): the bristle block's depth (x), width (y) and height; the wooden
    back's depth, width and height on top of it; the handle's length (from the back's +x
    face), width (across the grip) and height."""

    bristle_depth: float = 0.03
    width: float = 0.10
    bristle_height: float = 0.022
    back_depth: float = 0.04
    back_width: float = 0.108
    back_height: float = 0.012
    handle_length: float = 0.12
    handle_width: float = 0.02
    handle_height: float = 0.016

    @property
    def top(self) -> float:
        """Height of the back's (and handle's) top above the bristles' tips."""
        return self.bristle_height + self.back_height

    @property
    def handle_centre(self) -> tuple[float, float, float]:
        """The handle's centre in the brush frame (toward +x, flush with the back's top)."""
        return (
            self.back_depth / 2 + self.handle_length / 2,
            0.0,
            self.top - self.handle_height / 2,
        )


def hand_brush(d: BrushDims = BrushDims()) -> ToolShape:
    """The brush (see the module doc): bristles (accent) first, its handle toward +x."""
    parts = (
        Primitive(
            kind="box",
            size=(d.bristle_depth, d.width, d.bristle_height),
            pose=Pose(xyz=(0.0, 0.0, d.bristle_height / 2)),
        ),
        Primitive(
            kind="box",
            size=(d.back_depth, d.back_width, d.back_height),
            pose=Pose(xyz=(0.0, 0.0, d.bristle_height + d.back_height / 2)),
        ),
        Primitive(
            kind="box",
            size=(d.handle_length, d.handle_width, d.handle_height),
            pose=Pose(xyz=d.handle_centre),
        ),
    )
    return ToolShape(parts=parts, accent_parts=(0,))

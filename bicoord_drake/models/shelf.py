"""A low shelf: two side walls under a flat top plate, forming a tunnel along x.

The shelf is one fixed compound body (``CompoundShape``: three boxes), framed at the centre of
its footprint on the table, so its box's centre in xy is the top plate's centre and its box's
top is the plate's top face (what ``rests_on`` and ``top_z`` read).
"""

from __future__ import annotations

from dataclasses import dataclass

from bicoord_drake.models.geometry import Pose, Primitive, Rgba
from bicoord_drake.models.objects import CompoundShape, SceneObject

#: Light grey painted wood (it stands out from the brown table).
SHELF_COLOR: Rgba = (0.78, 0.78, 0.8, 1.0)


@dataclass(frozen=True)
class ShelfDims:
    """Sizes of a shelf (m): `length` along the tunnel (x), `width` of the top plate across
    it (y), the tunnel's inner `gap` (between the walls) and `clearance` (table to the plate's
    underside, the walls' height), the walls' and the plate's thickness."""

    length: float = 0.15
    width: float = 0.20
    gap: float = 0.09
    clearance: float = 0.065
    wall: float = 0.02
    plate: float = 0.02

    def __post_init__(self) -> None:
        if self.gap + 2 * self.wall > self.width:
            raise ValueError(f"walls {self.gap} m apart do not fit under a {self.width} m plate")

    @property
    def top(self) -> float:
        """Height of the top plate's upper face above the table."""
        return self.clearance + self.plate

    @property
    def wall_y(self) -> float:
        """|y| of each wall's centre from the shelf's axis."""
        return self.gap / 2 + self.wall / 2


def shelf_shape(dims: ShelfDims = ShelfDims()) -> CompoundShape:
    """The shelf's three boxes: walls at y = +-``wall_y``, the plate on top of them."""
    walls = [
        Primitive(
            kind="box",
            size=(dims.length, dims.wall, dims.clearance),
            pose=Pose(xyz=(0.0, s * dims.wall_y, dims.clearance / 2)),
        )
        for s in (1.0, -1.0)
    ]
    plate = Primitive(
        kind="box",
        size=(dims.length, dims.width, dims.plate),
        pose=Pose(xyz=(0.0, 0.0, dims.clearance + dims.plate / 2)),
    )
    return CompoundShape(parts=(*walls, plate))


def shelf(
    name: str,
    xy: tuple[float, float],
    table_top: float,
    dims: ShelfDims = ShelfDims(),
    color: Rgba = SHELF_COLOR,
) -> SceneObject:
    """A shelf fixed to the table with its footprint centred at `xy`, tunnel along x."""
    return SceneObject(
        name=name,
        shape=shelf_shape(dims),
        color=color,
        mass=1.0,
        fixed=True,
        pose=Pose(xyz=(xy[0], xy[1], table_top)),
    )

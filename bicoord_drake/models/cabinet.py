"""A low cabinet with one drawer: an articulated scene object.

The cabinet is a fixed compound body (two side walls, a back wall and a top plate over an
opening toward -y); the drawer is an open box with a bar handle on its front, mounted on a
prismatic joint (``Slide``) to the cabinet: it slides out along -y (toward the robot) from
closed (joint position 0) to ``travel``, with viscous damping. Contact between the two is
filtered (jointed bodies); the drawer floats ``lift`` above the table on its joint.

Frames: the cabinet's at the centre of its footprint on the table; the drawer's at the centre
of its underside. The handle bar runs along x, ``standoff`` in front of the drawer's front face.
"""

from __future__ import annotations

from dataclasses import dataclass

from bicoord_drake.models.geometry import Pose, Primitive, Rgba
from bicoord_drake.models.objects import CompoundShape, SceneObject, Slide

CABINET_COLOR: Rgba = (0.55, 0.38, 0.25, 1.0)
DRAWER_COLOR: Rgba = (0.86, 0.72, 0.52, 1.0)


@dataclass(frozen=True)
class CabinetDims:
    """Sizes (m): the drawer's outer box (`width` x, `depth` y, `height` z, `wall`), its
    `lift` above the table, the `gap` between it and the cabinet's walls and top, the
    cabinet's `panel` thickness, the handle bar (`bar_length` x, `bar_thickness` y,
    `bar_height` z, its centre `standoff` in front of the drawer's face, `handle_z` above
    the drawer's underside and `handle_x` right of its middle), the slide's `travel` and
    `damping` (N s/m)."""

    width: float = 0.23
    depth: float = 0.20
    height: float = 0.075
    wall: float = 0.008
    lift: float = 0.003
    gap: float = 0.004
    panel: float = 0.012
    bar_length: float = 0.10
    bar_thickness: float = 0.012
    bar_height: float = 0.016
    standoff: float = 0.045
    handle_z: float = 0.05
    handle_x: float = 0.0
    travel: float = 0.19
    damping: float = 4.0

    @property
    def outer(self) -> tuple[float, float, float]:
        """The cabinet's outer x, y, z."""
        x = self.width + 2 * (self.gap + self.panel)
        y = self.depth + self.gap + self.panel
        z = self.lift + self.height + self.gap + self.panel
        return x, y, z

    @property
    def inner_half(self) -> tuple[float, float]:
        """Half the drawer's inner x and y."""
        return self.width / 2 - self.wall, self.depth / 2 - self.wall

    @property
    def drawer_offset(self) -> tuple[float, float, float]:
        """The closed drawer's frame in the cabinet's frame (its front flush with the
        cabinet's front)."""
        return 0.0, -self.outer[1] / 2 + self.depth / 2, self.lift

    def handle_center(self) -> tuple[float, float, float]:
        """The handle bar's centre in the drawer's frame."""
        return self.handle_x, -self.depth / 2 - self.standoff, self.handle_z


def cabinet_shape(dims: CabinetDims = CabinetDims()) -> CompoundShape:
    """Side walls, back wall and top plate; open at -y and at the bottom."""
    sx, sy, sz = dims.outer
    p = dims.panel
    wall_h = sz - p
    parts = [
        Primitive(
            kind="box",
            size=(p, sy, wall_h),
            pose=Pose(xyz=(s * (sx / 2 - p / 2), 0.0, wall_h / 2)),
        )
        for s in (-1.0, 1.0)
    ]
    parts.append(
        Primitive(
            kind="box",
            size=(sx - 2 * p, p, wall_h),
            pose=Pose(xyz=(0.0, sy / 2 - p / 2, wall_h / 2)),
        )
    )
    parts.append(Primitive(kind="box", size=(sx, sy, p), pose=Pose(xyz=(0.0, 0.0, sz - p / 2))))
    return CompoundShape(parts=tuple(parts))


def drawer_shape(dims: CabinetDims = CabinetDims()) -> CompoundShape:
    """The drawer: floor, front, back and side walls, and the handle (a bar on two posts)
    in front. The bar is part :data:`HANDLE_PART`."""
    w, d, h, t = dims.width, dims.depth, dims.height, dims.wall
    zc = t + (h - t) / 2
    box = [
        Primitive(kind="box", size=(w, d, t), pose=Pose(xyz=(0.0, 0.0, t / 2))),
        Primitive(kind="box", size=(w, t, h - t), pose=Pose(xyz=(0.0, -d / 2 + t / 2, zc))),
        Primitive(kind="box", size=(w, t, h - t), pose=Pose(xyz=(0.0, d / 2 - t / 2, zc))),
        Primitive(kind="box", size=(t, d - 2 * t, h - t), pose=Pose(xyz=(-w / 2 + t / 2, 0, zc))),
        Primitive(kind="box", size=(t, d - 2 * t, h - t), pose=Pose(xyz=(w / 2 - t / 2, 0, zc))),
    ]
    hx, hy, hz = dims.handle_center()
    bar = Primitive(
        kind="box",
        size=(dims.bar_length, dims.bar_thickness, dims.bar_height),
        pose=Pose(xyz=(hx, hy, hz)),
    )
    post_len = dims.standoff - dims.bar_thickness / 2
    posts = [
        Primitive(
            kind="box",
            size=(dims.bar_thickness, post_len, dims.bar_height),
            pose=Pose(
                xyz=(
                    hx + s * (dims.bar_length / 2 - dims.bar_thickness / 2),
                    -d / 2 - post_len / 2,
                    hz,
                )
            ),
        )
        for s in (-1.0, 1.0)
    ]
    return CompoundShape(parts=(*box, bar, *posts))


#: Index of the handle bar in :func:`drawer_shape`'s parts.
HANDLE_PART = 5


def cabinet(
    name: str,
    drawer_name: str,
    xy: tuple[float, float],
    table_top: float,
    dims: CabinetDims = CabinetDims(),
    drawer_mass: float = 0.4,
) -> tuple[SceneObject, SceneObject]:
    """The cabinet fixed on the table, its footprint centred at `xy`, and its closed drawer
    on a slide along -y (list the cabinet first in the scene)."""
    body = SceneObject(
        name=name,
        shape=cabinet_shape(dims),
        color=CABINET_COLOR,
        color_fixed=True,
        mass=2.0,
        fixed=True,
        pose=Pose(xyz=(xy[0], xy[1], table_top)),
    )
    ox, oy, oz = dims.drawer_offset
    drawer = SceneObject(
        name=drawer_name,
        shape=drawer_shape(dims),
        color=DRAWER_COLOR,
        color_fixed=True,
        mass=drawer_mass,
        pose=Pose(xyz=(xy[0] + ox, xy[1] + oy, table_top + oz)),
        slide=Slide(parent=name, axis=(0.0, -1.0, 0.0), upper=dims.travel, damping=dims.damping),
    )
    return body, drawer

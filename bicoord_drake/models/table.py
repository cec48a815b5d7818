"""The table (rigid-hydroelastic top, 1.2 m x 0.7 m, top at z = 0.75) and the floor."""

from __future__ import annotations

from pathlib import Path

from bicoord_drake.models.appearance import Appearance
from bicoord_drake.models.geometry import ContactProps, Pose, Primitive, sdf_collision, sdf_material
from bicoord_drake.models.scene import TABLE_TOP

TABLE_SIZE = (1.2, 0.7)
TABLE_THICKNESS = 0.04
#: Thickness of the floor's collision slab (m), below its visible surface.
FLOOR_SLAB = 1.0


def _box_visual(name: str, prim: Primitive, rgba, texture: Path | None = None) -> str:
    material = sdf_material(rgba)
    if texture is not None:  # the texture's colours as they are (white diffuse)
        material = f"<material><drake:diffuse_map>file://{texture}</drake:diffuse_map></material>"
    return (
        f'<visual name="{name}">{prim.pose.sdf()}<geometry>{prim.sdf_geometry()}</geometry>'
        f"{material}</visual>"
    )


def table_sdf(appearance: Appearance | None = None) -> str:
    """SDFormat of a static model `table` (top + legs) and a floor slab, plain or with the
    appearance's table and floor textures and table height (the floor `table_raise` lower)."""
    table_png = appearance.table.png() if appearance else None
    floor_png = appearance.floor.png() if appearance else None
    floor_z = -appearance.table_raise if appearance else 0.0  # a higher table: a lower floor
    sx, sy = TABLE_SIZE
    top = Primitive(
        kind="box",
        size=(sx, sy, TABLE_THICKNESS),
        pose=Pose(xyz=(0, 0, TABLE_TOP - TABLE_THICKNESS / 2)),
    )
    floor = Primitive(kind="box", size=(4.0, 4.0, 0.02), pose=Pose(xyz=(0, 0, floor_z - 0.01)))
    # The floor collides as a thick slab: an object knocked off the table at speed (a flailing
    # policy throws cubes at 15+ m/s, 13 cm per plant step) lands on it instead of passing
    # through a thin one and falling for ever until its state overflows.
    floor_slab = Primitive(
        kind="box",
        size=(4.0, 4.0, FLOOR_SLAB),
        pose=Pose(xyz=(0, 0, floor_z - FLOOR_SLAB / 2)),
    )
    rigid = ContactProps(friction=0.8, hydroelastic="rigid", resolution_hint=0.05)
    parts = [
        '<link name="table_top">',
        sdf_collision("top", top, rigid),
        _box_visual("top", top, (0.62, 0.5, 0.38, 1), table_png),
    ]
    leg_h = TABLE_TOP - TABLE_THICKNESS - floor_z
    for i, (x, y) in enumerate(
        [
            (sx / 2 - 0.05, sy / 2 - 0.05),
            (-sx / 2 + 0.05, sy / 2 - 0.05),
            (sx / 2 - 0.05, -sy / 2 + 0.05),
            (-sx / 2 + 0.05, -sy / 2 + 0.05),
        ]
    ):
        leg = Primitive(
            kind="box", size=(0.05, 0.05, leg_h), pose=Pose(xyz=(x, y, floor_z + leg_h / 2))
        )
        parts.append(_box_visual(f"leg_{i}", leg, (0.4, 0.32, 0.24, 1)))
    parts += [
        sdf_collision("floor", floor_slab, rigid),
        _box_visual("floor", floor, (0.5, 0.5, 0.52, 1), floor_png),
        "</link>",
    ]
    return (
        '<?xml version="1.0"?><sdf version="1.9" xmlns:drake="http://drake.mit.edu">'
        f'<model name="table"><static>true</static>{"".join(parts)}</model></sdf>'
    )

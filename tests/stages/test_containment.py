"""inside() against the container's real shape: round bowls, compound bowls, box bins."""

import math

import numpy as np
import pytest

from bicoord_drake.models.geometry import Pose, Primitive
from bicoord_drake.models.objects import BinShape, BowlShape, CompoundShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.stages import predicates as P
from bicoord_drake.stages.stage import WorldState, quat_to_matrix
from tests.stages.helpers import IDENTITY, pose, quat_about

CUBE = 0.02
#: The catching bowl of handover_block_with_bowls: 7.5 cm radius, straight 12 mm wall.
BOWL = BowlShape(radius=0.075, base_radius=0.075, height=0.05, wall=0.012)
#: A bin: 16 x 12 cm base 1 cm thick, 1 cm walls 6 cm high.
BIN_PARTS = (
    Primitive(kind="box", size=(0.16, 0.12, 0.01), pose=Pose(xyz=(0, 0, 0.005))),
    Primitive(kind="box", size=(0.01, 0.12, 0.06), pose=Pose(xyz=(0.075, 0, 0.03))),
    Primitive(kind="box", size=(0.01, 0.12, 0.06), pose=Pose(xyz=(-0.075, 0, 0.03))),
    Primitive(kind="box", size=(0.16, 0.01, 0.06), pose=Pose(xyz=(0, 0.055, 0.03))),
    Primitive(kind="box", size=(0.16, 0.01, 0.06), pose=Pose(xyz=(0, -0.055, 0.03))),
)
BIN_CAVITY = P.Cavity(kind="box", floor=0.01, rim=0.06, half_xy=(0.07, 0.05))
#: The same bowl described as a compound with an explicit round cavity.
COMPOUND_CAVITY = P.Cavity(
    kind="round", floor=0.012, rim=0.05, floor_radius=0.063, rim_radius=0.063
)

KINDS = {
    "bowl": (BOWL, None, 0.063, 0.075),
    "compound": (CompoundShape(parts=tuple(BOWL.primitives())), COMPOUND_CAVITY, 0.063, 0.075),
    "bin": (CompoundShape(parts=BIN_PARTS), BIN_CAVITY, 0.05, 0.06),
    # the same bin as a BinShape: its cavity comes from cavity_of
    "bin_shape": (BinShape(size=(0.16, 0.12, 0.06), wall=0.01), None, 0.05, 0.06),
}
BINS = ("bin", "bin_shape")


def world(kind: str, container_pose, cube_pose) -> tuple[WorldState, P.Predicate]:
    shape, cavity, _, _ = KINDS[kind]
    scene = Scene(
        name="containment",
        seed=0,
        objects=(
            SceneObject(name="box", shape=shape, pose=Pose(xyz=(0.0, 0.0, TABLE_TOP))),
            cube("cube", 0.3, 0.0, size=CUBE),
        ),
    )
    s = WorldState.initial(scene, object_poses={"box": container_pose, "cube": cube_pose})
    return s, P.inside("cube", "box", cavity=cavity)


ON_TABLE = pose(0.0, 0.0, TABLE_TOP)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_just_inside(kind):
    inner = KINDS[kind][2]
    floor = (BIN_CAVITY if kind in BINS else COMPOUND_CAVITY).floor
    s, inside = world(kind, ON_TABLE, pose(0.0, inner - CUBE / 2 - 0.002, TABLE_TOP + floor + 0.01))
    assert inside(s)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_on_the_rim_is_not_inside(kind):
    outer = KINDS[kind][3]
    wall = 0.012 if kind not in BINS else 0.01
    s, inside = world(kind, ON_TABLE, pose(0.0, outer - wall / 2, TABLE_TOP + 0.06 + 0.01))
    assert not inside(s)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_on_the_table_beside_it_in_the_box_corner_is_not_inside(kind):
    if kind in BINS:  # a box's corner is inside the bin's inner box: beside it is past the wall
        xy = (0.0, 0.058)
    else:  # 9.2 cm from the axis, inside the 7.5 cm bounding square's corner
        xy = (0.065, 0.065)
    s, inside = world(kind, ON_TABLE, pose(*xy, TABLE_TOP + CUBE / 2))
    assert not inside(s)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_under_the_lifted_container_is_not_inside(kind):
    lifted = pose(0.0, 0.0, TABLE_TOP + 0.04)
    s, inside = world(kind, lifted, pose(0.0, 0.0, TABLE_TOP + CUBE / 2))
    assert not inside(s)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_upside_down_container_holds_nothing(kind):
    flipped = pose(0.0, 0.0, TABLE_TOP + 0.06, quat_about("x", math.pi))
    under = pose(0.0, 0.0, TABLE_TOP + CUBE / 2)  # trapped under the upturned container
    on_top = pose(0.0, 0.0, TABLE_TOP + 0.06 + CUBE / 2)  # lying on its upturned base
    for cube_pose in (under, on_top):
        s, inside = world(kind, flipped, cube_pose)
        assert not inside(s)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_tilted_container_judged_in_its_frame_up_to_max_tilt(kind):
    floor = (BIN_CAVITY if kind in BINS else COMPOUND_CAVITY).floor
    origin = np.array([0.0, 0.0, TABLE_TOP + 0.1])
    for angle, expected in ((math.radians(25), True), (math.radians(60), False)):
        q = quat_about("x", angle)
        on_floor = origin + quat_to_matrix(q) @ [0.0, 0.0, floor + CUBE / 2]
        s, inside = world(kind, pose(*origin, q), pose(*on_floor, q))
        assert inside(s) is expected


def test_cavity_of_needs_a_bowl_a_bin_or_an_explicit_cavity():
    assert P.cavity_of(BOWL) == COMPOUND_CAVITY
    cav = P.cavity_of(KINDS["bin_shape"][0])
    assert (cav.kind, cav.floor, cav.rim) == ("box", BIN_CAVITY.floor, BIN_CAVITY.rim)
    assert cav.half_xy == pytest.approx(BIN_CAVITY.half_xy)
    s, _ = world("bin", ON_TABLE, pose(0.0, 0.0, TABLE_TOP + 0.02, IDENTITY))
    with pytest.raises(ValueError, match="cavity="):
        P.inside("cube", "box")(s)
    with pytest.raises(ValueError, match="rim"):
        P.Cavity(kind="box", floor=0.05, rim=0.01, half_xy=(0.1, 0.1))

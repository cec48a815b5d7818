"""tip_in: a pen stands tip first in a holder (synthetic states, no Drake)."""

import math

import numpy as np
import pytest

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import SceneObject
from bicoord_drake.models.pens import PenShape, max_lean, pen_holder
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.stages.predicates import tip_in
from tests.stages.helpers import pose, quat_about, state

HOLDER = pen_holder(radius=0.04, height=0.1, wall=0.004)
PEN = PenShape(radius=0.007, length=0.14, tip_length=0.018)
LIMIT = max_lean(0.036, 0.096, PEN.radius, PEN.tip_radius) + math.radians(3)
FLOOR = TABLE_TOP + HOLDER.wall


def _scene() -> Scene:
    return Scene(
        name="pens",
        seed=0,
        objects=(
            SceneObject(name="holder", shape=HOLDER, fixed=True, pose=Pose(xyz=(0, 0, TABLE_TOP))),
            SceneObject(name="pen", shape=PEN, pose=Pose(xyz=(0.2, 0, TABLE_TOP + 0.007))),
            cube("block", -0.2, 0.0),
        ),
    )


SC = _scene()
PRED = tip_in("pen", "holder", LIMIT)


def _pen_at(tip_xy, tip_z, lean=0.0, toward="y"):
    """Pen pose with its tip at (tip_xy, tip_z), its axis leaning by `lean` about `toward`."""
    q = quat_about("x", -lean) if toward == "y" else quat_about("y", lean)
    axis = (
        (0, math.sin(lean), math.cos(lean))
        if toward == "y"
        else (math.sin(lean), 0, math.cos(lean))
    )
    c = np.array([*tip_xy, tip_z]) + 0.07 * np.array(axis)
    return pose(*c, quat=q)


def test_upright_on_the_floor_counts():
    assert PRED(state(SC, poses={"pen": _pen_at((0, 0), FLOOR)}))


def test_leaning_on_the_rim_counts_up_to_the_holders_limit():
    assert math.radians(28) < LIMIT < math.radians(40)
    lean = LIMIT - math.radians(4)
    tip_y = -0.036 + PEN.tip_radius
    assert PRED(state(SC, poses={"pen": _pen_at((0, tip_y), FLOOR, lean)}))
    assert not PRED(state(SC, poses={"pen": _pen_at((0, tip_y), FLOOR, LIMIT + 0.02)}))


def test_lying_across_the_opening_does_not_count():
    # tip just inside below the rim, the pen nearly flat over the cup
    st = state(SC, poses={"pen": _pen_at((0.02, 0), TABLE_TOP + 0.095, math.radians(80), "x")})
    assert not PRED(st)


def test_upside_down_back_end_in_the_cup_does_not_count():
    c = pose(0, 0, FLOOR + 0.07, quat=quat_about("x", math.pi))
    assert not PRED(state(SC, poses={"pen": c}))


def test_beside_the_holder_or_above_its_rim_does_not_count():
    assert not PRED(state(SC))  # lying on the table
    standing_beside = _pen_at((0.1, 0), TABLE_TOP)
    assert not PRED(state(SC, poses={"pen": standing_beside}))
    held_above = _pen_at((0, 0), TABLE_TOP + HOLDER.height + 0.01)
    assert not PRED(state(SC, poses={"pen": held_above}))
    in_the_wall = _pen_at((0.039, 0), FLOOR)
    assert not PRED(state(SC, poses={"pen": in_the_wall}))


def test_under_the_floor_or_in_a_tipped_holder_does_not_count():
    assert not PRED(state(SC, poses={"pen": _pen_at((0, 0), TABLE_TOP - 0.01)}))
    tipped = pose(0, 0, TABLE_TOP, quat=quat_about("x", math.radians(90)))
    st = state(SC, poses={"pen": _pen_at((0, 0), FLOOR), "holder": tipped})
    assert not PRED(st)


def test_an_object_without_a_tip_is_an_error():
    with pytest.raises(ValueError, match="no tip"):
        tip_in("block", "holder", LIMIT)(state(SC))

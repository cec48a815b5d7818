"""in_pan: an object lying in a dustpan, judged against the pan's real inside."""

import math

import numpy as np
import pytest
from pydrake.all import RollPitchYaw, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.models.tools import DustpanDims, dustpan, dustpan_cavity
from bicoord_drake.stages.predicates import in_pan
from tests.stages.helpers import pose, quat_about, state

D = DustpanDims()
CAV = dustpan_cavity(D)
EDGE = 0.04
PAN_Z = TABLE_TOP + 0.1  # the pan held 10 cm up


def _scene() -> Scene:
    return Scene(
        name="pan",
        seed=0,
        objects=(
            SceneObject(name="pan", shape=dustpan(D), pose=Pose(xyz=(0.0, 0.0, TABLE_TOP))),
            cube("cube", 0.3, 0.0, size=EDGE),
        ),
    )


def _quat(R: RotationMatrix) -> tuple:
    q = R.ToQuaternion()
    return (q.w(), q.x(), q.y(), q.z())


def _pan_state(cube_in_pan, pan_rpy=(0.0, 0.0, 0.0), cube_rpy=(0.0, 0.0, 0.0)):
    """The pan at (0, 0, PAN_Z) turned by `pan_rpy`; the cube at `cube_in_pan` (its centre, in
    the pan's frame) turned by `cube_rpy` relative to the pan."""
    R_WP = RotationMatrix(RollPitchYaw(*pan_rpy))
    p_WP = np.array([0.0, 0.0, PAN_Z])
    R_WC = R_WP @ RotationMatrix(RollPitchYaw(*cube_rpy))
    p_WC = p_WP + R_WP @ np.asarray(cube_in_pan, dtype=float)
    return state(
        _scene(),
        poses={"pan": pose(*p_WP, _quat(R_WP)), "cube": pose(*p_WC, _quat(R_WC))},
    )


ON_FLOOR = CAV.floor + EDGE / 2


@pytest.fixture
def pred():
    return in_pan("cube", "pan", CAV)


def test_a_cube_lying_on_the_floor_is_in(pred):
    assert pred(_pan_state((0.0, 0.0, ON_FLOOR)))
    assert pred(_pan_state((-0.03, 0.04, ON_FLOOR), cube_rpy=(0, 0, 0.6)))  # turned, aside
    assert pred(_pan_state((0.04, 0.0, ON_FLOOR)))  # near the open front, wholly on the floor
    # the pan turned about the vertical, or tilted 20 degrees, the cube lying in it
    assert pred(_pan_state((0.0, 0.0, ON_FLOOR), pan_rpy=(0, 0, math.pi)))
    assert pred(_pan_state((0.0, 0.0, ON_FLOOR), pan_rpy=(0, math.radians(20), 0)))


def test_not_fooled_by_an_object_outside_the_walls(pred):
    # hanging over the open front edge, or through a side wall, or behind the back wall
    assert not pred(_pan_state((D.length / 2 - 0.01, 0.0, ON_FLOOR)))
    assert not pred(_pan_state((0.0, D.width / 2 - 0.015, ON_FLOOR)))
    assert not pred(_pan_state((-D.length / 2 + 0.015, 0.0, ON_FLOOR)))
    # beside the pan on whatever holds it up (a pedestal in front of the mouth)
    assert not pred(_pan_state((D.length / 2 + 0.03, 0.0, ON_FLOOR + 0.006)))


def test_not_fooled_by_an_object_above_or_below_the_floor(pred):
    assert not pred(_pan_state((0.0, 0.0, ON_FLOOR + 0.02)))  # carried over the pan
    assert not pred(_pan_state((0.0, 0.0, ON_FLOOR + 0.05)))  # above the walls
    assert not pred(_pan_state((0.0, 0.0, ON_FLOOR - 0.03)))  # under it


def test_not_fooled_by_a_tipped_pan(pred):
    assert not pred(_pan_state((0.0, 0.0, ON_FLOOR), pan_rpy=(0, math.radians(40), 0)))
    assert not pred(_pan_state((0.0, 0.0, ON_FLOOR), pan_rpy=(math.pi, 0, 0)))


def test_a_cube_on_an_edge_in_the_pan_counts_while_on_the_floor(pred):
    """Leaning on an edge (45 degrees) its lowest point is on the floor: in; its centre is
    then higher, still below the side walls' top."""
    lean = EDGE / 2 * math.sqrt(2) + CAV.floor
    assert pred(_pan_state((0.0, 0.0, lean), cube_rpy=(0, math.pi / 4, 0)))
    assert not pred(_pan_state((0.0, 0.0, lean + 0.015), cube_rpy=(0, math.pi / 4, 0)))


def test_quat_helper_matches_the_stage_helpers():
    assert _quat(RotationMatrix.MakeZRotation(0.5)) == pytest.approx(quat_about("z", 0.5))

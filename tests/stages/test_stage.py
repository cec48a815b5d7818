"""WorldState snapshots and rotation helpers."""

import math

import numpy as np
import pytest

from bicoord_drake.models.geometry import pose_matrix
from bicoord_drake.stages.stage import WorldState, matrix_to_quat, quat_to_matrix
from tests.stages.helpers import scene


@pytest.mark.parametrize("rpy", [(0, 0, 0), (0.3, -0.2, 1.0), (math.pi, 0, 0), (0, math.pi, 0.5)])
def test_quaternion_round_trip(rpy):
    R = pose_matrix((0, 0, 0), rpy)[:3, :3]
    q = matrix_to_quat(R)
    assert q[0] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-12)


def test_world_state_is_immutable_and_validated():
    s = WorldState.initial(scene(), contacts={"small": {"left"}})
    with pytest.raises(ValueError):
        s.object_poses["small"][0] = 1.0
    with pytest.raises(TypeError):
        s.object_poses["new"] = np.zeros(7)
    with pytest.raises(AttributeError):
        s.step = 3
    assert s.touching("small") == frozenset({"left"}) and s.touching("large") == frozenset()
    assert s.opening("left") == 1.0 and s.opening("right") == 1.0
    with pytest.raises(ValueError, match="shape"):
        WorldState(scene=scene(), object_poses={"small": np.zeros(3)})
    with pytest.raises(ValueError, match="no velocity"):
        WorldState(scene=scene(), object_poses={}).velocity("small")


def test_initial_state_matches_scene_poses():
    sc = scene()
    s = WorldState.initial(sc)
    for obj in sc.objects:
        np.testing.assert_allclose(s.position(obj.name), obj.pose.xyz)
        np.testing.assert_allclose(s.rotation(obj.name), obj.pose.matrix()[:3, :3], atol=1e-12)
        np.testing.assert_allclose(s.initial_pose(obj.name), s.pose(obj.name))

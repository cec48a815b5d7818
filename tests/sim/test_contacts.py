"""Which robot bodies touch an object: any arm body counts as touching, only fingers hold."""

from dataclasses import replace

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.stages import predicates as P
from bicoord_drake.stages.stage import WorldState


@pytest.fixture(scope="module")
def cube_on_the_left_hand():
    """A 3 cm cube set on the back of the left gripper's body (no finger near it; placed where
    it rests, not overlapping: SAP pushes an initial overlap out hard), and a cube on the table
    that nothing touches; the arms hold their home pose, in the default physics (the gripper
    body is rigid-hydroelastic: the cube rests on it, where with point contact under "lagged"
    it bounced off within a control step).
    """
    # 0.155 m in front of the left base along the arm's plane, which home_spread turns
    embodiment = get_embodiment("aloha_viperx")
    base, spread = np.array(embodiment.left_base.xyz), embodiment.home_spread
    xy = base[:2] + 0.155 * np.array([-np.sin(spread), np.cos(spread)])
    on_hand = SceneObject(
        name="on_hand",
        shape=BoxShape(size=(0.03, 0.03, 0.03)),
        pose=Pose(xyz=(float(xy[0]), float(xy[1]), 1.030), rpy=(0.0, 0.0, spread)),
    )
    scene = Scene(name="on_hand", objects=(on_hand, cube("free", 0.1, 0.0)))
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    home = sim.station.embodiment.home_action()
    for _ in range(30):
        sim.step(home)
    return sim, home


def test_a_body_other_than_the_fingers_is_a_robot_contact(cube_on_the_left_hand):
    sim, _ = cube_on_the_left_hand
    assert sim.robot_contacts() == {"on_hand": {"left"}, "free": set()}
    assert sim.finger_contacts() == {"on_hand": set(), "free": set()}


def test_an_object_on_the_palm_is_neither_released_nor_held(cube_on_the_left_hand):
    sim, home = cube_on_the_left_hand
    state = WorldState.capture(sim, home)
    assert state.touching("on_hand") == {"left"}
    assert state.fingers_touching("on_hand") == frozenset()
    assert not P.released("on_hand")(state)
    assert not P.untouched("on_hand")(state)
    closed = home.copy()
    closed[6] = 0.0  # the left gripper commanded shut: still no finger on the cube
    assert not P.held_by("on_hand", "left")(replace(state, action=closed))
    assert P.released("free")(state)

"""Skills executed in physics: plans run through the station's action path, objects move only
because the fingers move them."""

import numpy as np
import pytest
from pydrake.all import RigidTransform

from bicoord_drake.config import StationConfig
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills import ArmPlan, Skills
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station


@pytest.fixture(scope="module")
def world():
    scene = Scene(
        name="two_cubes",
        objects=(cube("a", -0.15, -0.1), cube("b", 0.12, 0.0, color=(0.2, 0.6, 0.2, 1))),
    )
    return (
        scene,
        Skills(PlanningModel(scene)),
        Simulation(build_station(scene, StationConfig(render=False))),
    )


def test_bimanual_pick_then_place_in_physics(world):
    scene, skills, sim = world
    pick = skills.merge(skills.pick("left", "a"), skills.pick("right", "b"))
    both_act = np.mean(
        np.any(np.diff(pick.q[:, :6], axis=0) != 0, axis=1)
        & np.any(np.diff(pick.q[:, 6:], axis=0) != 0, axis=1)
    )
    assert both_act > 0.5, "the two picks should run at the same time"
    for action in pick.actions():
        sim.step(action)
    poses = sim.object_poses()
    assert poses["a"][2] > 0.85 and poses["b"][2] > 0.85
    assert sim.finger_contacts() == {"a": {"left"}, "b": {"right"}}

    goals = {"a": (-0.05, -0.15), "b": (0.1, -0.15)}
    place = skills.merge(
        skills.place("left", RigidTransform([*goals["a"], 0.77])),
        skills.place("right", RigidTransform([*goals["b"], 0.77])),
    )
    for action in place.actions():
        sim.step(action)
    for _ in range(8):
        sim.step(place.actions()[-1])
    for name, xy in goals.items():
        pose = sim.object_poses()[name]
        assert np.linalg.norm(pose[:2] - xy) < 0.01, f"{name} placed at {pose[:2]}"
        assert pose[2] == pytest.approx(0.77, abs=0.003)
    assert sim.finger_contacts() == {"a": set(), "b": set()}
    # every commanded sample respects the joint limits
    q = np.vstack([pick.q, place.q])
    lower, upper = skills.model.lower, skills.model.upper
    assert np.all(q >= lower - 1e-9) and np.all(q <= upper + 1e-9)


def test_unreachable_pick_raises_planning_error():
    scene = Scene(name="far", objects=(cube("far", -0.5, 0.33),))
    skills = Skills(PlanningModel(scene))
    with pytest.raises(PlanningError) as info:
        skills.pick("right", "far")
    assert info.value.reason == "pick_failed"


def test_arm_plans_chain_only_where_they_meet():
    a = ArmPlan("left", np.zeros((3, 6)), np.ones(3))
    b = ArmPlan("left", np.ones((2, 6)), np.ones(2))
    with pytest.raises(ValueError, match="does not start"):
        a.then(b)
    c = ArmPlan("left", np.zeros((4, 6)), np.zeros(4), events=[(1, "attach", "x")])
    chained = a.then(c)
    assert chained.num_steps == 6 and chained.events == [(3, "attach", "x")]

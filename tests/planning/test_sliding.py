"""pull: a side-grasped block dragged straight along its support, in physics."""

import numpy as np
import pytest

import bicoord_drake.planning.skills as sk
from bicoord_drake.config import StationConfig
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import GraspParams, box_grasps
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station

TOP = TABLE_TOP + 0.06


@pytest.fixture(scope="module")
def scene():
    platform = SceneObject(
        name="platform",
        shape=BoxShape(size=(0.08, 0.08, 0.06)),
        fixed=True,
        pose=Pose(xyz=(0.05, 0.0, TABLE_TOP + 0.03)),
    )
    block = cube("block", 0.05, 0.0, size=0.05, mass=0.075)
    block = block.model_copy(update={"pose": Pose(xyz=(0.05, 0.0, TOP + 0.025))})
    return Scene(name="pull", objects=(platform, block))


def _side_grasps(ctx, scene):
    """Side grasps of the block from +x (the right arm's side), jaws along y."""
    grasps = box_grasps(
        ctx.model.object_pose("block"),
        scene.object("block").shape,
        ctx.model.embodiment.arm.gripper,
        kinds=("side",),
        params=GraspParams(support_z=TOP, side_clearance=0.0),
    )
    return [g for g in grasps if g.approach[0] < -0.99]


def test_pull_drags_the_block_off_its_support_in_a_straight_line(scene):
    ctx = sk.SkillContext(PlanningModel(scene))
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    take = sk.pick(ctx, "right", "block", lift=0.0, grasps=_side_grasps(ctx, scene))
    start = ctx.model.tcp_pose(ctx.q, "right")
    plan = sk.pull(ctx, "right", (1.0, 0.0, 0.0), 0.10, ignore=["platform"])
    # the TCP keeps its height, its y and its orientation, and ends 10 cm further along x
    tcps = [ctx.model.tcp_pose(np.r_[ctx.q[:6], q6], "right") for q6 in plan.q]
    p = np.array([X.translation() for X in tcps])
    assert np.allclose(p[:, 1:], start.translation()[1:], atol=1e-3)
    assert p[-1, 0] - p[0, 0] == pytest.approx(0.10, abs=1e-3)
    assert np.all(np.diff(p[:, 0]) >= -1e-4)  # never back
    R0 = start.rotation().matrix()
    assert all(np.allclose(X.rotation().matrix(), R0, atol=0.01) for X in tcps)
    for action in sk.merge(ctx, None, take.then(plan)).actions():
        sim.step(action)
    block = sim.object_poses()["block"]
    # dragged 10 cm, still held at its height beside the platform (not dropped)
    assert block[0] == pytest.approx(0.15, abs=0.01) and block[1] == pytest.approx(0.0, abs=0.01)
    assert block[2] == pytest.approx(TOP + 0.025, abs=0.005)
    assert sim.finger_contacts()["block"] == {"right"}


def test_pull_needs_something_held_and_a_direction(scene):
    ctx = sk.SkillContext(PlanningModel(scene))
    with pytest.raises(PlanningError, match="gripper_empty"):
        sk.pull(ctx, "right", (1.0, 0.0, 0.0), 0.1)
    sk.pick(ctx, "right", "block", lift=0.0, grasps=_side_grasps(ctx, scene))
    with pytest.raises(ValueError):
        sk.pull(ctx, "right", (0.0, 0.0, 0.0), 0.1)
    with pytest.raises(ValueError):
        sk.pull(ctx, "right", (1.0, 0.0, 0.0), 0.0)

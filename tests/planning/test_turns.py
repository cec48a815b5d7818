"""Turn-taking at a shared spot (arrive_as_leaves) and dropping into a container (drop_into)."""

import numpy as np
import pytest
from pydrake.all import RigidTransform

import bicoord_drake.tasks.clean_table as ct
from bicoord_drake.models.geometry import Pose, Primitive
from bicoord_drake.models.objects import CompoundShape
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import bounding_box_grasps
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills import (
    SkillContext,
    arrival_delay,
    arrive_as_leaves,
    drop_into,
    first_step_in_zone,
    retreat,
    take_turn,
    turns,
)
from bicoord_drake.stages.predicates import Cavity, cavity_of
from tests.planning.bins import to_bin

RADIUS = 0.12
LAG = 0.2


@pytest.fixture()
def scene():
    return ct.CleanTable().sample_scene(0)


def _tcp_dist(ctx, motion, side):
    cols = ctx.model.side_slice(side)
    q12 = np.array(ctx.q, dtype=float)
    out = []
    for q in motion.q:
        q12[cols] = q[cols]
        p = ctx.model.tcp_pose(q12, side).translation()
        out.append(np.hypot(p[0] - ct.BIN_XY[0], p[1] - ct.BIN_XY[1]))
    return np.array(out)


def test_arriving_arm_enters_the_zone_as_the_other_leaves_it_and_waits_no_longer(scene):
    ctx = SkillContext(PlanningModel(scene))
    to_bin(ctx, "right", 0.03)  # the right arm's TCP over the bin; it leaves from there
    to_bin(ctx, "left", -0.14)  # the left one waits just outside the zone
    leave = retreat(ctx, "right")
    arrive = to_bin(ctx, "left", -0.03)
    delay = arrival_delay(ctx, leave, arrive, ct.BIN_XY, RADIUS, LAG)
    assert delay > 0  # the left arm would come in too early at its own pace
    motion = arrive_as_leaves(ctx, leave, arrive, ct.BIN_XY, RADIUS, lag=LAG)
    right, left = _tcp_dist(ctx, motion, "right"), _tcp_dist(ctx, motion, "left")
    assert right[0] <= RADIUS and left[-1] <= RADIUS
    out = int(np.argmax(right > RADIUS))
    into = int(np.argmax(left <= RADIUS))
    assert into == out + ctx.steps(
        LAG
    )  # not earlier: never both in the zone; not later: no idle wait
    assert np.all(right[into:] > RADIUS)
    # both arms move from the first step on (the arrival is timed, not queued after the leave)
    assert np.any(motion.q[1, 6:] != motion.q[0, 6:])
    assert first_step_in_zone(ctx, arrive, ct.BIN_XY, RADIUS) + delay == into
    # a leaver already outside the zone needs no more than the lag
    far = arrival_delay(ctx, leave, arrive, (0.5, 0.5), 0.01, LAG)
    assert far == 0


def test_arrive_as_leaves_needs_two_arms(scene):
    ctx = SkillContext(PlanningModel(scene))
    plan = to_bin(ctx, "right")
    with pytest.raises(ValueError, match="both the right arm"):
        arrive_as_leaves(ctx, plan, plan, ct.BIN_XY, RADIUS)


def _leave_and_arrive(scene):
    ctx = SkillContext(PlanningModel(scene))
    to_bin(ctx, "right", 0.03)
    to_bin(ctx, "left", -0.14)
    leave = retreat(ctx, "right")
    return ctx, leave, to_bin(ctx, "left", -0.03)


def test_take_turn_is_arrive_as_leaves_when_the_arms_keep_apart(scene):
    ctx, leave, arrive = _leave_and_arrive(scene)
    timed = arrive_as_leaves(ctx, leave, arrive, ct.BIN_XY, RADIUS, lag=LAG)
    taken = take_turn(ctx, leave, arrive, ct.BIN_XY, RADIUS, lag=LAG)
    np.testing.assert_array_equal(taken.q, timed.q)


def test_take_turn_falls_back_to_one_after_the_other_when_the_arms_conflict(scene, monkeypatch):
    ctx, leave, arrive = _leave_and_arrive(scene)
    tried = []

    def conflicting(*args, ignore=(), **kwargs):
        tried.append(tuple(ignore))
        raise PlanningError("arm_conflict", "the arms meet")

    monkeypatch.setattr(turns, "arrive_as_leaves", conflicting)
    motion = take_turn(ctx, leave, arrive, ct.BIN_XY, RADIUS, ignore=("object_1",))
    assert tried == [(), ("object_1",)]  # first checked against everything, then without it
    left = motion.q[:, ctx.model.side_slice("left")]
    done = leave.num_steps - 1
    assert np.all(left[:done] == left[0])  # the arriver waits until the leaver is done
    assert np.any(left[done + 1] != left[0])


def test_take_turn_passes_other_planning_errors_on(scene, monkeypatch):
    ctx, leave, arrive = _leave_and_arrive(scene)

    def unreachable(*args, **kwargs):
        raise PlanningError("ik_infeasible", "out of reach")

    monkeypatch.setattr(turns, "arrive_as_leaves", unreachable)
    with pytest.raises(PlanningError, match="ik_infeasible"):
        take_turn(ctx, leave, arrive, ct.BIN_XY, RADIUS, ignore=("object_1",))


def _centred_compound(scene):
    """The scene with its first object made a compound whose frame is at its centre (a
    frame-at-the-bottom compound or a box would hide a wrong sign of the frame offset)."""
    obj = scene.object(ct.OBJECTS[0])
    part = Primitive(kind="box", size=(0.05, 0.04, 0.03))
    xyz = (*obj.pose.xyz[:2], TABLE_TOP + 0.015)
    new = obj.model_copy(
        update={"shape": CompoundShape(parts=(part,)), "pose": Pose(xyz=xyz, rpy=obj.pose.rpy)}
    )
    objects = tuple(new if o.name == obj.name else o for o in scene.objects)
    return scene.model_copy(update={"objects": objects})


@pytest.mark.parametrize("centred", [False, True])
def test_drop_into_lets_go_just_above_the_opening(scene, centred):
    if centred:
        scene = _centred_compound(scene)
    ctx = SkillContext(PlanningModel(scene))
    name = ct.OBJECTS[0]
    side = scene.draws["first_side"]
    ct._pick(ctx, side, name)
    plan = drop_into(ctx, side, "bin", offset_xy=(0.02, 0.01), fall=0.025)
    assert side not in ctx.model.held and plan.opening[-1] == 1.0
    assert [k for _, k, n in plan.events if n == name] == ["detach"]
    X_WO = ctx.model.object_pose(name)
    shape = ctx.model.object(name).shape
    bottom = X_WO.translation()[2] + min(p.trimesh().bounds[0][2] for p in shape.primitives())
    assert bottom == pytest.approx(TABLE_TOP + ct.BIN.size[2] + 0.025, abs=1e-6)  # rim + fall
    cav: Cavity = cavity_of(ct.BIN)
    p = X_WO.translation() - [*ct.BIN_XY, TABLE_TOP]
    assert cav.contains_xy(p) and p[:2] == pytest.approx([0.02, 0.01], abs=1e-9)


def test_drop_into_needs_a_held_object(scene):
    ctx = SkillContext(PlanningModel(scene))
    with pytest.raises(PlanningError, match="holds nothing"):
        drop_into(ctx, "left", "bin")


def test_bounding_box_grasps_close_across_the_whole_compound(scene):
    from bicoord_drake.models.objects import toy_car

    ctx = SkillContext(PlanningModel(scene))
    car = toy_car()
    X_WO = RigidTransform([0.2, 0.0, TABLE_TOP])
    gripper = ctx.model.embodiment.arm.gripper
    grasps = bounding_box_grasps(X_WO, car, gripper)
    assert grasps and {g.kind for g in grasps} == {"top"}
    lo = np.min([p.trimesh().bounds[0] for p in car.primitives()], axis=0)
    hi = np.max([p.trimesh().bounds[1] for p in car.primitives()], axis=0)
    for g in grasps:
        np.testing.assert_allclose((X_WO @ g.X_OG).GetAsMatrix4(), g.X_WG.GetAsMatrix4(), atol=1e-9)
        assert g.width == pytest.approx(hi[0] - lo[0]) or g.width == pytest.approx(hi[1] - lo[1])
        assert g.approach @ [0, 0, 1] == pytest.approx(-1.0)  # straight down

"""Two hands on one object: the two-handed hold in the planning model, the grasps chosen
together, the constrained two-arm carry (relative TCP pose held, one timing) and a lift and
carry of a long box in physics."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.all import Quaternion, RigidTransform, RotationMatrix

import bicoord_drake.planning.skills as sk
from bicoord_drake.config import StationConfig
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station

BAR = BoxShape(size=(0.30, 0.04, 0.04))


def bar_scene() -> Scene:
    bar = SceneObject(
        name="bar",
        shape=BAR,
        mass=0.15,
        color=(0.7, 0.5, 0.3, 1.0),
        pose=Pose(xyz=(0.0, -0.12, TABLE_TOP + 0.02)),
    )
    return Scene(name="two_hands", objects=(bar,))


@pytest.fixture()
def ctx() -> sk.SkillContext:
    return sk.SkillContext(PlanningModel(bar_scene()), speed=0.75)


def _relative(ctx: sk.SkillContext, q: np.ndarray) -> RigidTransform:
    return ctx.model.tcp_pose(q, "left").inverse() @ ctx.model.tcp_pose(q, "right")


def _pose_error(a: RigidTransform, b: RigidTransform) -> tuple[float, float]:
    d = a.inverse() @ b
    return float(np.linalg.norm(d.translation())), float(d.rotation().ToAngleAxis().angle())


def _moving(q: np.ndarray) -> np.ndarray:
    """Per control step, whether the joints change."""
    return np.any(np.abs(np.diff(q, axis=0)) > 1e-9, axis=1)


# --------------------------------------------------------------------------- planning model
def test_a_two_handed_hold_filters_the_object_against_both_hands(ctx):
    m = ctx.model
    pair = sk.two_hand_grasps(ctx, "bar")[0]
    q = ctx.ik.solve(
        {"left": TcpTarget(pair.left.X_WG), "right": TcpTarget(pair.right.X_WG)},
        ignore=["bar"],
        env_clearance=0.0,
    )
    # Raised 15 cm: the bar runs through both grippers' fingers.
    up = {}
    for side in ("left", "right"):
        X = m.tcp_pose(q, side)
        up[side] = TcpTarget(RigidTransform(X.rotation(), X.translation() + [0, 0, 0.15]))
    m.attach_both("bar", q)
    q_up = ctx.ik.solve(up, seed=q)
    assert m.held_together == "bar" and m.holders("bar") == ["left", "right"]
    m.set_padding(0.03, 0.005)
    assert m.collision_free(q_up)
    # still checked against the world: lying on the table it is within the 5 mm margin
    assert any("table" in a + b for a, b, _ in m.colliding_pairs(q))
    with pytest.raises(PlanningError) as err:
        m.attach("bar", "left", q_up)
    assert err.value.reason == "gripper_busy"
    # One hand lets go: the bar, still in the other's hand, now runs through the free fingers.
    m.detach("right")
    assert m.held_together is None and m.holders("bar") == ["left"]
    pairs = m.colliding_pairs(q_up)
    assert any(a.startswith("right_arm/") or b.startswith("right_arm/") for a, b, _ in pairs)
    with pytest.raises(PlanningError) as err:
        m.attach("bar", "right", q_up)
    assert err.value.reason == "object_held"
    m.attach("bar", "right", q_up, together=True)
    assert m.collision_free(q_up)
    # Put down where the hands leave it.
    m.detach_both(q_up)
    assert not m.held
    assert np.allclose(
        m.object_pose("bar").translation(), [0.0, -0.12, TABLE_TOP + 0.17], atol=2e-3
    )


def test_grasps_are_chosen_together_one_per_end(ctx):
    pairs = sk.two_hand_grasps(ctx, "bar", inset=0.04)
    assert pairs and all(a.score >= b.score for a, b in zip(pairs, pairs[1:], strict=False))
    for pair in pairs:
        left, right = pair.left.X_WG.translation(), pair.right.X_WG.translation()
        # 4 cm in from each end, symmetric about the centre, the left hand on the left end
        assert left[0] == pytest.approx(-0.11, abs=1e-9) and right[0] == pytest.approx(0.11)
        assert left[1] == pytest.approx(right[1]) and left[2] == pytest.approx(right[2])
        for g in (pair.left, pair.right):  # fingers across the bar, not along it
            assert abs(g.finger_axis[0]) < 1e-9 and abs(g.approach[0]) < 1e-9


def test_a_failed_pick_together_changes_nothing(ctx):
    far = RigidTransform([0.0, 0.9, TABLE_TOP + 0.3])
    grasps = sk.two_hand_grasps(ctx, "bar", X_WO=far)
    q = ctx.q.copy()
    with pytest.raises(PlanningError) as err:
        sk.pick_together(ctx, "bar", pairs=grasps)
    assert err.value.reason == "pick_failed"
    assert np.array_equal(ctx.q, q) and not ctx.model.held


# --------------------------------------------------------------------------- constrained IK
def test_carry_together_holds_the_relative_tcp_pose_on_one_timing(ctx):
    pick = sk.pick_together(ctx, "bar", lift=0.08)
    i = pick.info["grip_index"]
    # both grippers close on the same steps; both arms arrive at the grasp on the same step
    assert np.array_equal(pick.openings[:, 0], pick.openings[:, 1])
    closed = int(np.flatnonzero(pick.openings[:, 0] == 0.0)[0])
    assert closed <= i and np.all(pick.openings[closed:, 0] == 0.0)
    assert not _moving(pick.q[closed - ctx.gripper_steps : i + 1]).any()  # still while closing
    assert {(k, side) for k, side, kind, _ in pick.events if kind == "attach"} == {
        (i, "left"),
        (i, "right"),
    }
    rel0 = _relative(ctx, ctx.q)
    X = ctx.model.held_pose("left", ctx.q)
    turn = RotationMatrix.MakeZRotation(np.radians(20)) @ X.rotation()
    goal = RigidTransform(turn, X.translation() + [0.06, 0.10, 0.04])
    carry = sk.carry_together(ctx, goal)
    # relative pose of the two TCPs and the object on its path at every control sample
    for q, X_WO in zip(carry.q, carry.info["object_poses"], strict=True):
        dp, dr = _pose_error(rel0, _relative(ctx, q))
        assert dp < 2e-3 and dr < 0.02
        dp, dr = _pose_error(X_WO, ctx.model.held_pose("left", q))
        assert dp < 2e-3 and dr < 0.02
    assert _pose_error(goal, carry.info["object_poses"][-1]) == pytest.approx((0, 0), abs=1e-9)
    # one profile for both arms: they start and stop moving on the same steps
    left, right = _moving(carry.q[:, :6]), _moving(carry.q[:, 6:])
    assert np.array_equal(left, right) and left.all()
    vmax = np.tile(ctx.arm_limits.velocity, 2)
    assert np.max(np.abs(np.diff(carry.q, axis=0)) / ctx.dt / vmax) <= 1
    release = sk.release_together(ctx, gentle=True)
    r = release.info["release_index"]
    n = ctx.steps(sk.gentle_release_time(ctx))
    assert np.array_equal(release.openings[:, 0], release.openings[:, 1])
    assert release.openings[r, 0] == 1.0 and release.openings[n, 0] == 1.0
    assert release.openings[n - 1, 0] < 1.0
    assert not ctx.model.held


def test_one_arm_cannot_move_alone_while_both_hold(ctx):
    sk.pick_together(ctx, "bar", lift=0.05)
    q = ctx.q.copy()
    X = ctx.model.tcp_pose(q, "left")
    with pytest.raises(PlanningError) as err:
        sk.move_tcp(ctx, "left", RigidTransform(X.rotation(), X.translation() + [0, 0, 0.05]))
    assert err.value.reason == "held_together" and np.array_equal(ctx.q, q)


def test_carry_together_needs_a_two_handed_hold(ctx):
    with pytest.raises(PlanningError) as err:
        sk.carry_together(ctx, RigidTransform([0.0, 0.0, 1.0]))
    assert err.value.reason == "not_held_together"


# --------------------------------------------------------------------------- physics
def _X(p: np.ndarray) -> RigidTransform:
    q = np.asarray(p[3:], dtype=float)
    return RigidTransform(Quaternion(q / np.linalg.norm(q)), p[:3])


def test_two_hands_lift_and_carry_a_bar_in_physics():
    """Pick, lift 10 cm and carry 14 cm sideways, up and away in physics: the TCPs keep their
    relative pose within 3 mm and the bar stays within 5 mm of its planned path; then it is set
    down and let go with both hands on the same steps."""
    scene = bar_scene()
    ctx = sk.SkillContext(PlanningModel(scene), speed=0.75)
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    pick = sk.pick_together(ctx, "bar", lift=0.10)
    for action in pick.actions():
        sim.step(action)
    assert sim.finger_contacts()["bar"] == {"left", "right"}
    rel0 = _X(sim.tcp_pose("left")).inverse() @ _X(sim.tcp_pose("right"))
    X = ctx.model.held_pose("left", ctx.q)
    carry = sk.carry_together(
        ctx, RigidTransform(X.rotation(), X.translation() + [0.08, 0.1, 0.05])
    )
    rel_err, path_err = [], []
    for action, planned in zip(carry.actions(), carry.info["object_poses"][1:], strict=True):
        sim.step(action)
        rel = _X(sim.tcp_pose("left")).inverse() @ _X(sim.tcp_pose("right"))
        rel_err.append(_pose_error(rel0, rel)[0])
        path_err.append(_pose_error(planned, _X(sim.object_poses()["bar"]))[0])
    assert max(rel_err) < 3e-3, max(rel_err)
    assert max(path_err) < 5e-3, max(path_err)
    assert sim.finger_contacts()["bar"] == {"left", "right"}
    # set it down on the table and let go with both hands at once
    X = ctx.model.held_pose("left", ctx.q)
    down = RigidTransform(X.rotation(), [*X.translation()[:2], TABLE_TOP + 0.021])
    lower = sk.carry_together(ctx, down, ignore=["bar"])
    release = sk.release_together(ctx, gentle=True)
    for action in np.vstack([lower.actions(), release.actions()]):
        sim.step(action)
    bar = sim.object_poses()["bar"]
    assert sim.finger_contacts()["bar"] == set()
    assert np.linalg.norm(bar[:2] - down.translation()[:2]) < 0.01
    assert abs(bar[2] - (TABLE_TOP + 0.02)) < 0.003


def test_a_pot_is_held_by_its_two_handles_left_hand_on_the_left():
    from pydrake.all import RollPitchYaw

    from bicoord_drake.models.objects import PotShape

    pot = PotShape(radius=0.07, height=0.08)
    # turned half a turn: its +x handle is on the world's left
    obj = SceneObject(
        name="pot", shape=pot, mass=0.3, pose=Pose(xyz=(0.0, -0.1, TABLE_TOP), rpy=(0, 0, 3.0))
    )
    ctx = sk.SkillContext(PlanningModel(Scene(name="pot", objects=(obj,))), speed=0.75)
    pairs = sk.two_hand_grasps(ctx, "pot")
    same = sk.handle_pairs(ctx, "pot")
    assert [p.score for p in pairs] == [p.score for p in same]
    assert all(a.score >= b.score for a, b in zip(pairs, pairs[1:], strict=False))
    for pair in pairs:
        left, right = pair.left.X_WG.translation(), pair.right.X_WG.translation()
        assert left[0] < -pot.radius and right[0] > pot.radius
        assert pair.left.approach[0] > 0.9 and pair.right.approach[0] < -0.9  # from outside
    # both reach their handle at once, the model then holds the pot with both hands
    motion = sk.pick_together(ctx, "pot", lift=0.05)
    assert ctx.model.held_together == "pot"
    X = ctx.model.held_pose("left", ctx.q)
    assert X.translation()[2] == pytest.approx(TABLE_TOP + 0.05, abs=1e-3)
    assert RollPitchYaw(X.rotation()).yaw_angle() == pytest.approx(3.0, abs=1e-3)
    assert motion.num_steps > 0
    with pytest.raises(PlanningError):
        sk.handle_pairs(sk.SkillContext(PlanningModel(bar_scene())), "bar")


def test_release_together_backs_off_on_the_branch_the_arms_are_on():
    """Two hands carry a pot by its handles 40 cm to the right and set it down: the back-off
    after the release is solved toward the arms' current joints when the home-pulled IK answer
    lies on another wrist branch (the TCPs would sweep arcs instead of backing straight off)."""
    from bicoord_drake.models.objects import PotShape

    pot = PotShape(radius=0.06, height=0.08)
    obj = SceneObject(name="pot", shape=pot, mass=0.3, pose=Pose(xyz=(-0.15, -0.17, TABLE_TOP)))
    ctx = sk.SkillContext(PlanningModel(Scene(name="pot", objects=(obj,))), speed=0.8)
    sk.pick_together(ctx, "pot", lift=0.05)
    X = ctx.model.held_pose("left", ctx.q)
    sk.carry_together(ctx, RigidTransform(X.rotation(), [0.25, -0.17, TABLE_TOP + 0.05]))
    down = RigidTransform(X.rotation(), [0.25, -0.17, TABLE_TOP + 0.002])
    sk.carry_together(ctx, down, ignore=["pot"])
    before = {s: ctx.model.tcp_pose(ctx.q, s) for s in ("left", "right")}
    q = ctx.q.copy()
    motion = sk.release_together(ctx)
    assert ctx.model.held_together is None
    for i, side in enumerate(("left", "right")):
        after = ctx.model.tcp_pose(ctx.q, side)
        back = before[side].translation() - 0.06 * before[side].rotation().col(0)
        assert np.linalg.norm(after.translation() - back) < 2e-3
        sl = slice(6 * i, 6 * i + 6)
        assert np.max(np.abs(ctx.q[sl] - q[sl])) < 0.5  # no wrist flip
    assert motion.num_steps > 0


def _pot_ctx(xy) -> sk.SkillContext:
    from bicoord_drake.models.objects import PotShape

    pot = PotShape(radius=0.06, height=0.09)
    obj = SceneObject(name="pot", shape=pot, mass=0.3, pose=Pose(xyz=(*xy, TABLE_TOP)))
    return sk.SkillContext(PlanningModel(Scene(name="pot", objects=(obj,))), speed=0.8)


def test_the_other_wrist_branch_reaches_the_same_tcp_poses():
    from bicoord_drake.planning.skills.bimanual import on_wrist_branch

    ctx = _pot_ctx((0.15, 0.05))
    WRIST_ANGLE = ctx.model.embodiment.wrist_flip.pitch  # noqa: N806
    pair = sk.handle_pairs(ctx, "pot")[0]
    targets = {"left": TcpTarget(pair.left.X_WG), "right": TcpTarget(pair.right.X_WG)}
    q = ctx.ik.solve(targets, env_clearance=0.0, ignore=["pot"])
    for side, i in (("left", WRIST_ANGLE), ("right", 6 + WRIST_ANGLE)):
        sign = -np.sign(q[i])
        flipped = on_wrist_branch(ctx, q, side, sign)
        assert np.sign(flipped[i]) == sign and flipped[i] == pytest.approx(-q[i])
        assert ctx.model.within_limits(flipped)
        for s in ("left", "right"):
            dp, da = _pose_error(ctx.model.tcp_pose(q, s), ctx.model.tcp_pose(flipped, s))
            assert dp < 1e-4 and da < 1e-3
        assert np.array_equal(on_wrist_branch(ctx, q, side, -sign), q)  # already there
    # a wrist angle whose negative is beyond the joint limit (-1.87 rad) has no other branch
    q_bent = q.copy()
    q_bent[WRIST_ANGLE] = 2.1
    with pytest.raises(PlanningError) as err:
        on_wrist_branch(ctx, q_bent, "left", -1.0)
    assert err.value.reason == "wrist_branch"


def test_a_pot_carried_to_the_left_arms_base_needs_the_positive_wrist_branch():
    """Both hands carry a pot raised 20 cm from (0.15, 0.05) to (-0.15, -0.17): the left hand
    ends close in front of its own base, where its wrist angle is about +2 rad. Picked on the
    home-pulled branch (a negative wrist angle) the carry runs the wrist into its -1.87 rad limit
    and the IK jumps branch; picked with ``wrist={"left": 1}`` it is continuous."""
    from pydrake.all import RollPitchYaw

    def carry(wrist):
        ctx = _pot_ctx((0.15, 0.05))
        sk.pick_together(ctx, "pot", lift=0.2, wrist=wrist)
        start = ctx.q.copy()
        R = RotationMatrix(RollPitchYaw(0.0, 0.0, np.radians(30)))
        goal = RigidTransform(R, [-0.15, -0.17, TABLE_TOP + 0.2])
        return start, ctx, sk.carry_together(ctx, goal)

    with pytest.raises(PlanningError) as err:
        carry(None)
    assert err.value.reason == "track_discontinuous"
    start, ctx, motion = carry({"left": 1.0})
    assert start[4] > 0
    assert np.max(np.abs(np.diff(motion.q, axis=0))) < 0.3
    X = ctx.model.held_pose("left", ctx.q)
    assert np.linalg.norm(X.translation()[:2] - [-0.15, -0.17]) < 1e-3

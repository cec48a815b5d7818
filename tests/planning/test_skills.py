"""Skills executed in physics: plans run through the station's action path, objects move only
because the fingers move them."""

import numpy as np
import pytest
from pydrake.all import RigidTransform

import bicoord_drake.planning.skills as sk
from bicoord_drake.config import StationConfig
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BowlShape, BoxShape, SceneObject
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import stack_target
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills import ArmPlan
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
        sk.SkillContext(PlanningModel(scene)),
        Simulation(build_station(scene, StationConfig(render=False))),
    )


def test_bimanual_pick_then_place_in_physics(world):
    scene, ctx, sim = world
    pick = sk.merge(ctx, sk.pick(ctx, "left", "a"), sk.pick(ctx, "right", "b"))
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
    place = sk.merge(
        ctx,
        sk.place(ctx, "left", RigidTransform([*goals["a"], 0.77])),
        sk.place(ctx, "right", RigidTransform([*goals["b"], 0.77])),
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
    lower, upper = ctx.model.lower, ctx.model.upper
    assert np.all(q >= lower - 1e-9) and np.all(q <= upper + 1e-9)


def test_unreachable_pick_raises_planning_error():
    scene = Scene(name="far", objects=(cube("far", -0.5, 0.33),))
    ctx = sk.SkillContext(PlanningModel(scene))
    with pytest.raises(PlanningError) as info:
        sk.pick(ctx, "right", "far")
    assert info.value.reason == "pick_failed"


def test_arm_plans_chain_only_where_they_meet():
    a = ArmPlan("left", np.zeros((3, 6)), np.ones(3))
    b = ArmPlan("left", np.ones((2, 6)), np.ones(2))
    with pytest.raises(ValueError, match="does not start"):
        a.then(b)
    c = ArmPlan("left", np.zeros((4, 6)), np.zeros(4), events=[(1, "attach", "x")])
    chained = a.then(c)
    assert chained.num_steps == 6 and chained.events == [(3, "attach", "x")]


def test_gentle_release_unloads_the_squeeze_at_one_rate_on_every_gripper():
    ctx = sk.SkillContext(PlanningModel(Scene(name="empty")))
    g = ctx.model.embodiment.arm.gripper
    ctx.opening["left"] = 0.0
    fast = sk.grip(ctx, "left", 1.0)
    ctx.opening["left"] = 0.0
    seconds = sk.gentle_release_time(ctx)
    # the command crosses the servo's force band (force_limit / kp of finger travel) at
    # RELEASE_FORCE_RATE N/s, so the ramp lasts the stroke x kp / rate
    stroke = g.finger_max - g.finger_min
    assert seconds == pytest.approx(stroke * g.finger_kp / sk.RELEASE_FORCE_RATE)
    slow = sk.grip(ctx, "left", 1.0, gentle=True)
    n = ctx.steps(seconds)
    assert n == 12  # the ViperX's whole stroke at 15 Hz
    assert fast.num_steps == ctx.gripper_steps + 4 and slow.num_steps == n + 4
    assert np.all(np.diff(slow.opening) >= 0) and slow.opening[n] == 1.0
    assert slow.opening[n // 2] == pytest.approx(0.5)
    assert np.all(slow.q == slow.q[0])  # the arm keeps still
    # a partial opening is spread over the same time: gentler still
    ctx.opening["left"] = 0.0
    narrow = sk.grip(ctx, "left", 0.4, gentle=True)
    assert narrow.num_steps == slow.num_steps and narrow.opening[n] == pytest.approx(0.4)
    assert np.max(np.diff(narrow.opening)) < np.max(np.diff(slow.opening))


def test_gentle_release_together_opens_both_on_the_same_steps():
    ctx = sk.SkillContext(PlanningModel(Scene(name="empty")))
    ctx.opening["left"], ctx.opening["right"] = 0.0, 0.5
    both = sk.grip_together(ctx, 1.0, gentle=True)
    assert both.num_steps == 12 + 4
    assert both.openings[12, 0] == 1.0 and both.openings[12, 1] == 1.0
    assert both.openings[11, 0] < 1.0 and both.openings[11, 1] < 1.0


def test_tcp_deviation_tells_a_descent_from_an_arc():
    scene = Scene(name="one", objects=(cube("a", 0.15, -0.05),))
    ctx = sk.SkillContext(PlanningModel(scene))
    X = ctx.model.tcp_pose(ctx.q, "right")
    above = sk.solve_tcp(ctx, "right", TcpTarget(X))
    lower = RigidTransform(X.rotation(), X.translation() - [0, 0, 0.08])
    below = sk.solve_tcp(ctx, "right", TcpTarget(lower), seed_arm=above)
    assert sk.tcp_deviation(ctx, "right", above, below) < 0.01
    swung = above.copy()
    swung[0] += 1.6  # the waist turns: the TCP sweeps an arc between the same kind of poses
    assert sk.tcp_deviation(ctx, "right", above, swung) > 0.04


def test_place_lets_go_slowly_when_asked():
    scene = Scene(name="one", objects=(cube("a", 0.15, -0.05),))
    plans, gentle_steps = {}, None
    for gentle in (False, True):
        ctx = sk.SkillContext(PlanningModel(scene))
        sk.pick(ctx, "right", "a")
        if gentle:
            gentle_steps = ctx.steps(sk.gentle_release_time(ctx))
        goal = RigidTransform([0.1, -0.1, 0.77])
        plans[gentle] = sk.place(ctx, "right", goal, gentle_release=gentle)
    rising = lambda p: int(np.sum(np.diff(p.opening) > 0))  # noqa: E731
    assert rising(plans[False]) <= 4 and rising(plans[True]) == gentle_steps > 4


# --------------------------------------------------------------------------------------------
# Pour, push, stabilize, release
# --------------------------------------------------------------------------------------------

BOWL = BowlShape(radius=0.075, base_radius=0.075, height=0.05, wall=0.012)


def _bowl(x: float, y: float, shape: BowlShape = BOWL) -> SceneObject:
    return SceneObject(
        name="bowl", shape=shape, color=(0.9, 0.9, 0.85, 1), mass=0.1, pose=Pose(xyz=(x, y, 0.75))
    )


def _bowl_in_left_hand(lift: float):
    """A planning context whose left hand holds the bowl by its rim, lifted `lift` m; the
    bowl's pose and the joint positions then."""
    ctx = sk.SkillContext(
        PlanningModel(Scene(name="pour", objects=(_bowl(-0.15, 0.0),))), speed=0.75
    )
    sk.pick(ctx, "left", "bowl", kinds=["rim"], lift=lift)
    return ctx, ctx.model.held_pose("left", ctx.q), ctx.q.copy()


def test_pour_turns_the_bowl_about_its_rim_and_back():
    ctx, X0, q0 = _bowl_in_left_hand(lift=0.12)
    angle = np.radians(60)
    pour = sk.pour(ctx, "left", angle, hold_time=0.33)
    # the rim point on the pouring side stays put; the tilt reaches the angle; back level
    poses = [ctx.model.held_pose("left", np.r_[q6, q0[6:]]) for q6 in pour.q]
    tilts = [np.arccos(np.clip(X.rotation().col(2)[2], -1, 1)) for X in poses]
    assert max(tilts) == pytest.approx(angle, abs=1e-3)
    assert np.allclose(pour.q[-1], q0[:6], atol=1e-3)
    up = X0.rotation().col(2)
    rims = [
        X0.translation() + 0.05 * up + 0.075 * d
        for d in (np.array(v, float) for v in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)))
    ]
    fixed = [
        p for p in rims if all(np.linalg.norm(X @ (X0.inverse() @ p) - p) < 1e-3 for X in poses)
    ]
    assert len(fixed) == 1
    speed = np.abs(np.diff(pour.q, axis=0)) / ctx.dt
    assert np.all(speed <= ctx.arm_limits.velocity + 1e-9)
    with pytest.raises(PlanningError) as info:
        sk.pour(ctx, "left", np.radians(170))
    assert info.value.reason == "pour_failed"
    assert np.array_equal(ctx.q, np.r_[pour.q[-1], q0[6:]])


def test_pour_about_a_given_pivot_keeps_that_point_still():
    ctx, X0, q0 = _bowl_in_left_hand(lift=0.12)
    d = np.array([1.0, 0.0, 0.0])
    pivot = X0.translation() + 0.06 * X0.rotation().col(2) + 0.03 * d  # inside the rim
    pour = sk.pour(ctx, "left", np.radians(45), direction=d, pivot=pivot, hold_time=0.2)
    poses = [ctx.model.held_pose("left", np.r_[q6, q0[6:]]) for q6 in pour.q]
    p_O = X0.inverse() @ pivot
    assert max(np.linalg.norm(X @ p_O - pivot) for X in poses) < 1e-3
    mouth = [X.rotation().col(2) @ d for X in poses]
    assert max(mouth) == pytest.approx(np.sin(np.radians(45)), abs=1e-3)  # tipped toward d


def test_pour_descending_lowers_the_lip_only_past_90_degrees():
    ctx, X0, q0 = _bowl_in_left_hand(lift=0.15)
    d = np.array([-1.0, 0.0, 0.0])
    lip = X0.translation() + 0.05 * X0.rotation().col(2) + 0.075 * d
    angle, drop = np.radians(110), 0.03
    pour = sk.pour(ctx, "left", angle, direction=d, descend=drop, hold_time=0.2)
    poses = [ctx.model.held_pose("left", np.r_[q6, q0[6:]]) for q6 in pour.q]
    p_O = X0.inverse() @ lip
    tilts = np.array([np.arccos(np.clip(X.rotation().col(2)[2], -1, 1)) for X in poses])
    drops = np.array([lip[2] - (X @ p_O)[2] for X in poses])
    moved = np.array([np.linalg.norm((X @ p_O - lip)[:2]) for X in poses])
    assert max(tilts) == pytest.approx(angle, abs=1e-3)
    assert np.all(np.abs(drops[tilts < np.pi / 2 - 1e-3]) < 1e-3)  # still the fixed pivot
    assert max(drops) == pytest.approx(drop, abs=1e-3)  # lowered at the full tilt
    assert np.all(moved < 1e-3)  # straight down, never sideways
    assert np.allclose(pour.q[-1], q0[:6], atol=1e-3)  # and back up, level


def test_pour_withdrawing_draws_the_tipped_lip_off_what_it_poured_before_it_tilts_back():
    ctx, X0, q0 = _bowl_in_left_hand(lift=0.15)
    d = np.array([-1.0, 0.0, 0.0])
    lip = X0.translation() + 0.05 * X0.rotation().col(2) + 0.075 * d
    angle, drop, back = np.radians(110), 0.03, 0.04
    pour = sk.pour(ctx, "left", angle, direction=d, descend=drop, withdraw=back, hold_time=0.2)
    poses = [ctx.model.held_pose("left", np.r_[q6, q0[6:]]) for q6 in pour.q]
    p_O = X0.inverse() @ lip
    tilts = np.array([np.arccos(np.clip(X.rotation().col(2)[2], -1, 1)) for X in poses])
    lips = np.array([X @ p_O for X in poses])
    full = np.flatnonzero(tilts > angle - 1e-3)
    drawn = (lips[full] - lip) @ -d  # how far back the lip is, tipped
    rise = lips[full, 2] - (lip[2] - drop)  # how far above its lowest
    assert lips[full[0]] == pytest.approx(lip - [0, 0, drop], abs=1e-3)  # poured low
    assert max(drawn) == pytest.approx(back, abs=1e-3) and min(drawn) > -1e-3
    assert np.all(np.abs(lips[full, 1] - lip[1]) < 1e-3)  # straight back, never sideways
    # It rises only drawn all the way back, and comes forward only risen all the way.
    assert np.all((rise < 1e-3) | (drawn > back - 1e-3) | (rise > drop - 1e-3))
    # The tilt back turns about the lip where the tilt started.
    after = np.arange(full[-1] + 1, len(poses))
    assert np.all(np.linalg.norm(lips[after] - lip, axis=1) < 1e-3)
    assert np.allclose(pour.q[-1], q0[:6], atol=1e-3)


def test_rehearsal_puts_the_state_back_whether_the_plan_works_or_not():
    ctx = sk.SkillContext(
        PlanningModel(Scene(name="pour", objects=(_bowl(-0.15, 0.0),))), speed=0.75
    )
    ctx.model.set_padding(0.01, 0.002)
    padding = np.array(ctx.model.checker.GetPaddingMatrix(), copy=True)
    q0, X0 = ctx.q.copy(), ctx.model.object_pose("bowl")
    with ctx.rehearsal():
        sk.pick(ctx, "left", "bowl", kinds=["rim"], lift=0.12)
        assert "left" in ctx.model.held
    assert not ctx.model.held and np.array_equal(ctx.q, q0)
    assert ctx.model.object_pose("bowl").IsExactlyEqualTo(X0)
    np.testing.assert_array_equal(ctx.model.checker.GetPaddingMatrix(), padding)
    sk.pick(ctx, "left", "bowl", kinds=["rim"], lift=0.12)
    q1 = ctx.q.copy()
    with pytest.raises(PlanningError), ctx.rehearsal():
        sk.pour(ctx, "left", np.radians(170))
    assert ctx.model.held["left"].name == "bowl" and np.array_equal(ctx.q, q1)


def test_merge_can_check_the_fingers_as_open_as_commanded():
    """The checker's fingers follow `openings`: open around a cube they are free, closed they
    pass through it; the finger bound keeps the widest opening of the last gripper_steps."""
    from bicoord_drake.planning.grasps import grasp_candidates
    from bicoord_drake.planning.skills.core import _finger_bounds

    scene = Scene(name="one_cube", objects=(cube("a", -0.15, -0.1),))
    ctx = sk.SkillContext(PlanningModel(scene))
    m = ctx.model
    grasp = grasp_candidates(scene.object("a"), m.embodiment.arm.gripper, kinds=["top"])[0]
    q = ctx.ik.solve_single(
        "left", TcpTarget(grasp.X_WG), m.home[6:], clearance=0.0, env_clearance=0.0, ignore=["a"]
    )
    m.set_padding(0.0, 0.0)
    assert m.collision_free(q)
    assert not m.collision_free(q, {"left": 0.0})
    assert m.collision_free(q)  # the fingers as set again
    n, w = 12, ctx.gripper_steps
    openings = np.ones((n, 2))
    openings[2:, 0] = 0.2
    bounds = _finger_bounds(ctx, sk.Motion(np.zeros((n, 12)), openings))
    assert [b["left"] for b in bounds] == [1.0] * (2 + w) + [0.2] * (n - 2 - w)
    assert all(b["right"] == 1.0 for b in bounds)


def test_push_slides_a_cube_with_a_held_stick_in_physics():
    stick = SceneObject(
        name="stick",
        shape=BoxShape(size=(0.16, 0.025, 0.03)),
        color=(0.6, 0.4, 0.2, 1),
        mass=0.05,
        pose=Pose(xyz=(0.22, -0.12, 0.765), rpy=(0, 0, np.pi / 2)),
    )
    scene = Scene(name="push", objects=(stick, cube("box", 0.15, 0.05, size=0.04, mass=0.03)))
    ctx = sk.SkillContext(PlanningModel(scene), speed=0.75)
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    pick = sk.pick(ctx, "right", "stick", kinds=["top"], lift=0.08)
    start, end = np.array([0.15, 0.0, 0.77]), np.array([0.15, 0.10, 0.77])
    push = sk.push(ctx, "right", start, end, ignore=["box"])
    # the stick's leading end follows the straight line while pushing
    held = ctx.model.held["right"]
    tip = np.array([0.08, 0.0, 0.0])
    q_right = [np.r_[ctx.q[:6], q6] for q6 in push.q]
    tips = np.array([(ctx.model.held_pose("right", q) @ tip) for q in q_right])
    on_line = tips[np.abs(tips[:, 2] - 0.77) < 1e-4]
    assert len(on_line) > 5 and np.allclose(on_line[:, [0, 2]], [0.15, 0.77], atol=1e-3)
    assert on_line[:, 1].min() == pytest.approx(0.0, abs=1e-3)
    assert on_line[:, 1].max() == pytest.approx(0.10, abs=1e-3)
    assert held.name == "stick"
    motion = sk.merge(ctx, None, pick.then(push))
    for action in motion.actions():
        sim.step(action)
    box = sim.object_poses()["box"]
    # the box's near face ends at the tip's last position (0.10): centre 2 cm further
    assert box[1] == pytest.approx(0.12, abs=0.01) and box[0] == pytest.approx(0.15, abs=0.01)
    assert sim.finger_contacts()["stick"] == {"right"}


def test_stabilize_then_release_keeps_the_planning_world_consistent():
    scene = Scene(name="steady", objects=(_bowl(-0.08, 0.0), cube("cube", 0.15, -0.05)))
    ctx = sk.SkillContext(PlanningModel(scene), speed=0.75)
    steady = sk.stabilize(ctx, "left", "bowl", kinds=["rim"])
    assert steady.opening[-1] == 0.0 and ctx.model.held["left"].name == "bowl"
    # the other arm can still plan (the steadied bowl does not count as touching the table)
    sk.pick(ctx, "right", "cube", kinds=["top"])
    let_go = sk.release(ctx, "left")
    assert let_go.opening[-1] == 1.0 and "left" not in ctx.model.held
    bowl = ctx.model.object_pose("bowl").translation()
    assert np.allclose(bowl, [-0.08, 0.0, 0.75], atol=1e-6)


@pytest.mark.slow
def test_stabilized_bowl_stays_put_while_the_other_arm_fills_it():
    shape = BowlShape(radius=0.09, base_radius=0.09, height=0.04, wall=0.012)
    bowl = _bowl(-0.08, 0.0, shape)
    scene = Scene(name="fill", objects=(bowl, cube("cube", 0.15, -0.05, size=0.03, mass=0.03)))
    ctx = sk.SkillContext(PlanningModel(scene), speed=0.75, clearance=0.015)
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    hold = sk.merge(ctx, sk.stabilize(ctx, "left", "bowl", kinds=["rim"]), None)
    away = 0.03 if ctx.model.tcp_pose(ctx.q, "left").translation()[0] < -0.08 else -0.03
    goal = stack_target(
        RigidTransform(bowl.pose.matrix()), shape, scene.object("cube").shape, offset_xy=(away, 0.0)
    )
    g = ctx.model.embodiment.arm.gripper
    fill = sk.pick(ctx, "right", "cube", kinds=["top"]).then(
        sk.place(ctx, "right", goal, ignore=["bowl"], opening=float(g.opening(0.025)))
    )
    work = sk.merge(ctx, None, fill, ignore=["bowl"])
    for action in hold.actions():
        sim.step(action)
    before = sim.object_poses()["bowl"][:3]
    for action in work.actions():
        sim.step(action)
    poses = sim.object_poses()
    assert np.linalg.norm(poses["bowl"][:3] - before) < 0.003
    assert np.linalg.norm(poses["cube"][:2] - goal.translation()[:2]) < 0.015
    assert sim.finger_contacts()["bowl"] == {"left"}


def test_carry_above_stops_over_the_goal_still_holding():
    scene = Scene(name="one_cube", objects=(cube("a", -0.15, -0.1),))
    ctx = sk.SkillContext(PlanningModel(scene))
    with pytest.raises(PlanningError) as info:
        sk.carry_above(ctx, "left", RigidTransform([-0.05, -0.15, 0.77]))
    assert info.value.reason == "gripper_empty"
    sk.pick(ctx, "left", "a")
    goal = RigidTransform([-0.05, -0.15, 0.772])
    plan = sk.carry_above(ctx, "left", goal, height=0.08)
    assert plan.num_steps > 1 and np.all(plan.opening == plan.opening[0])
    assert "left" in ctx.model.held  # still held: nothing was released
    p = ctx.model.held_pose("left", ctx.q).translation()
    np.testing.assert_allclose(p, goal.translation() + [0, 0, 0.08], atol=0.003)


def test_a_start_contact_is_as_deep_as_the_deepest_of_its_shapes():
    pairs = [("gripper", "plate", -6e-4), ("gripper", "plate", -4e-4), ("finger", "table", -1e-4)]
    assert sk.tracking.deepest_contacts(pairs) == {
        ("gripper", "plate"): -6e-4,
        ("finger", "table"): -1e-4,
    }


def test_track_may_leave_a_contact_it_starts_in_but_never_press_deeper():
    """A push can leave a finger pressed a fraction of a millimetre into the table (the
    measured state the next move starts from): tracking away from it, or along it, is allowed;
    pressing deeper into the table is not."""
    scene = Scene(name="one", objects=(cube("a", 0.25, 0.1),))
    ctx = sk.SkillContext(PlanningModel(scene))
    home = ctx.model.tcp_pose(ctx.q, "right")

    def lowered(dz: float, env_clearance: float) -> np.ndarray:
        X = RigidTransform(home.rotation(), home.translation() - [0, 0, dz])
        return sk.solve_tcp(ctx, "right", TcpTarget(X), env_clearance=env_clearance)

    def depth(q6: np.ndarray) -> float:
        """How deep (m) the arm at `q6` is in the table (negative: clear of it)."""
        ctx.model.set_padding(ctx.clearance / 2, 0.0)
        pairs = ctx.model.colliding_pairs(ctx.with_arm("right", q6), margin=0.05)
        return -min(d for _, other, d in pairs if other == "table_top")

    # Lower the TCP in joint space (extrapolating two IK solutions 1 cm apart, about 1.5 cm
    # above the table) in 0.01 mm steps until the gripper is a fraction of a millimetre in.
    a, b = lowered(0.14, 0.0), lowered(0.15, 0.0)
    for t in np.arange(1.0, 4.0, 0.001):
        q6 = a + t * (b - a)
        if depth(q6) > 0:
            break
    assert 0 < depth(q6) < sk.tracking.START_CONTACT_DEPTH
    ctx.q = ctx.with_arm("right", q6)
    start = ctx.model.tcp_pose(ctx.q, "right")
    R, p = start.rotation(), start.translation()

    def line(dz: float):
        return lambda s: RigidTransform(R, p + [0.0, 0.0, s * dz])

    saved = ctx.q.copy()
    sk.track(ctx, "right", line(0.05), 0.05, 0.0, label="up")
    assert ctx.model.tcp_pose(ctx.q, "right").translation()[2] == pytest.approx(p[2] + 0.05)
    ctx.q = saved
    with pytest.raises(PlanningError, match="ik_infeasible|ik_collision|path_in_collision"):
        sk.track(ctx, "right", line(-0.005), 0.005, 0.0, label="down")


def test_merge_sees_the_object_an_arm_carries():
    """Between its pick and its release a carried object rides on its hand in the merged
    check: the other arm reaching into where the lifted bar is carried is rejected (it was
    invisible to the check before), reaching above it passes."""
    from pydrake.all import RollPitchYaw, RotationMatrix

    from bicoord_drake.planning.skills.core import carried_spans, combine

    bar = SceneObject(
        name="bar",
        shape=BoxShape(size=(0.30, 0.03, 0.03)),
        color=(0.6, 0.4, 0.2, 1),
        mass=0.05,
        pose=Pose(xyz=(-0.14, -0.05, 0.765)),
    )
    ctx = sk.SkillContext(PlanningModel(Scene(name="bar", objects=(bar,))))
    pick = sk.pick(ctx, "left", "bar", kinds=["top"], lift=0.15)
    X_WB = ctx.model.held_pose("left", ctx.q)
    down = RotationMatrix(RollPitchYaw(0.0, np.pi / 2, 0.0))
    q0 = ctx.arm_q("right")

    def reach(dz: float) -> ArmPlan:
        """The right TCP to `dz` above the carried bar's centre line, 12 cm from its middle."""
        target = RigidTransform(down, X_WB @ np.array([0.12, 0.0, 0.0]) + [0.0, 0.0, dz])
        q = ctx.ik.solve_single(
            "right", TcpTarget(target), q0, seed=ctx.q, clearance=0.03, ignore=["bar"]
        )[6:]
        return ArmPlan("right", np.linspace(q0, q, 40), np.ones(40), label=f"reach {dz}")

    into, above = reach(0.0), reach(0.04)
    (span,) = carried_spans(ctx, combine(pick, into))
    assert span[:2] == (pick.events[0][0], pick.num_steps - 1) and span[2].side == "left"
    q_into = ctx.with_arm("right", into.q[-1])
    ctx.model.set_padding(ctx.clearance, ctx.env_clearance)
    assert not ctx.model.collision_free(q_into)
    with ctx.model.ignoring(["bar"]):  # what the check saw before
        assert ctx.model.collision_free(q_into)
    with pytest.raises(PlanningError) as info:
        sk.merge(ctx, pick, into)
    assert info.value.reason == "arm_conflict"
    motion = sk.merge(ctx, pick, above)
    assert motion.num_steps == pick.num_steps  # together, no delay needed
    assert ctx.model.held["left"].name == "bar"  # the check leaves the model as it was
    assert ctx.model.collision_free(q_into) is False


def test_carried_spans_follow_picks_and_releases():
    """An object picked, released, or picked and released by one arm is carried from its
    pick (or the start) to its release (or the end), at the grasp its release pose gives;
    one passed between the arms is not."""
    from bicoord_drake.planning.skills.core import Motion, carried_spans

    scene = Scene(name="cubes", objects=(cube("a", -0.15, -0.1), cube("b", 0.12, 0.0)))
    ctx = sk.SkillContext(PlanningModel(scene))
    q = np.tile(ctx.q, (10, 1))
    events = [(2, "left", "attach", "a"), (7, "left", "detach", "a"), (5, "right", "detach", "b")]
    (a, b) = carried_spans(ctx, Motion(q, np.ones((10, 2)), events))
    X_WG = ctx.model.gripper_pose(ctx.q, "left")
    assert a[:2] == (2, 7) and a[2].name == "a" and a[2].side == "left"
    assert (X_WG @ a[2].X_GO).IsNearlyEqualTo(ctx.model.object_pose("a"), 1e-12)
    assert b[:2] == (0, 5) and b[2].side == "right"
    passed = [(2, "left", "detach", "a"), (2, "right", "attach", "a")]
    assert carried_spans(ctx, Motion(q, np.ones((10, 2)), passed)) == []
    assert carried_spans(ctx, Motion(q, np.ones((10, 2)), events), ignore=["a", "b"]) == []


def test_tuned_settings_hold_inside_the_block_and_come_back_after_a_failure():
    ctx = sk.SkillContext(PlanningModel(Scene(name="empty")), speed=0.5)
    before = ctx.speed, ctx.clearance, ctx.env_clearance
    with pytest.raises(PlanningError):
        with ctx.tuned(speed=0.3, clearance=0.01, env_clearance=0.001):
            assert (ctx.speed, ctx.clearance, ctx.env_clearance) == (0.3, 0.01, 0.001)
            raise PlanningError("ik_unreachable", "inside the block")
    assert (ctx.speed, ctx.clearance, ctx.env_clearance) == before
    with ctx.tuned(env_clearance=0.002):  # the others kept
        assert (ctx.speed, ctx.clearance, ctx.env_clearance) == (*before[:2], 0.002)

"""Bimanual IK: reachable random targets, clearances per call, held objects, bad input."""

from __future__ import annotations

import time

import numpy as np
import pytest
from pydrake.all import RigidTransform, RollPitchYaw, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.ik import (
    BimanualIK,
    TcpTarget,
    arm_ik_closed_form,
    closed_form_applies,
)
from bicoord_drake.planning.model import PlanningModel
from tests.planning.conftest import reachable_targets, top_down

SIDES = ("left", "right")


def assert_valid(model, q12, targets, clearance, env_clearance):
    """The answer meets every target and both clearances (independent checker query)."""
    assert model.within_limits(q12)
    for side, t in targets.items():
        dp, dr = t.error(model.tcp_pose(q12, side))
        assert dp <= t.pos_tol * 1.001 and dr <= t.rot_tol * 1.001, (side, dp, dr)
    model.set_padding(clearance - 1e-4, env_clearance - 1e-4)
    assert model.collision_free(q12), model.colliding_pairs(q12)


def test_closed_form_recovers_every_branch(cubes_model):
    m = cubes_model
    assert closed_form_applies(m)
    rng = np.random.default_rng(3)
    for _ in range(50):
        q12 = rng.uniform(m.lower, m.upper)
        for side in SIDES:
            q = q12[m.side_slice(side)]
            sols = arm_ik_closed_form(m, side, m.tcp_pose(q12, side), q)
            assert any(np.allclose(s, q, atol=1e-7) for s in sols)


@pytest.mark.parametrize("analytic", [True, False], ids=["closed_form", "snopt_only"])
def test_random_reachable_pairs_with_3cm_clearance(cubes_model, analytic):
    """FK of random valid configurations; IK seeded from home must recover a valid answer."""
    m = cubes_model
    ik = BimanualIK(m, analytic=analytic)
    n = 40 if analytic else 15
    cases = reachable_targets(m, np.random.default_rng(7), n)
    solved = 0
    for targets in cases:
        try:
            q = ik.solve(targets, clearance=0.03, env_clearance=0.01)
        except PlanningError:
            continue
        assert_valid(m, q, targets, 0.03, 0.01)
        solved += 1
    assert solved >= (0.95 * n if analytic else n - 1)


def test_handover_clearance_is_set_per_call(cubes_model, cubes_ik):
    """Grippers facing each other 4 cm apart: fine at 5 mm clearance, impossible at 3 cm."""
    m, ik = cubes_model, cubes_ik
    X_l = RigidTransform(RotationMatrix(), [-0.02, -0.1, 1.0])
    X_r = RigidTransform(RotationMatrix(RollPitchYaw(np.pi / 2, 0, np.pi)), [0.02, -0.1, 1.0])
    targets = {"left": TcpTarget(X_l), "right": TcpTarget(X_r)}
    for side in SIDES:
        m.set_gripper(side, 0.5)
    try:
        q = ik.solve(targets, clearance=0.005)
        assert_valid(m, q, targets, 0.005, 0.01)
        m.set_padding(0.0, 0.0)
        cross = [p for p in m.colliding_pairs(q, 0.03) if p[0][:4] != p[1][:4]]
        assert cross and cross[0][2] < 0.025  # the grippers really are close
        with pytest.raises(PlanningError, match="inter-arm clearance 3.0 cm") as err:
            ik.solve(targets, clearance=0.03, restarts=2)
        assert err.value.reason == "ik_collision"
    finally:
        for side in SIDES:
            m.set_gripper(side, 1.0)


def test_single_arm_keeps_the_other_fixed(cubes_model, cubes_ik):
    m = cubes_model
    q_right = m.home[6:] + np.array([0.3, 0.1, -0.1, 0.2, 0.1, -0.3])
    target = TcpTarget(top_down(-0.2, -0.05, TABLE_TOP + 0.1, yaw=0.4))
    q = cubes_ik.solve_single("left", target, q_right)
    np.testing.assert_array_equal(q[6:], q_right)
    assert_valid(m, q, {"left": target}, 0.03, 0.01)


def test_free_axis_leaves_the_roll_free(cubes_model):
    m = cubes_model
    ik = BimanualIK(m, analytic=False)
    target = TcpTarget(top_down(0.2, -0.1, TABLE_TOP + 0.12, yaw=2.5), free_axis=True)
    q = ik.solve({"right": target}, seed=m.home)
    X = m.tcp_pose(q, "right")
    assert X.rotation().matrix()[:, 0] @ np.array([0, 0, -1.0]) > np.cos(0.0101)
    assert np.max(np.abs(X.translation() - target.X_WT.translation())) <= 1.001e-3


def test_seed_from_previous_solution(cubes_ik):
    ik = cubes_ik
    t0 = TcpTarget(top_down(-0.15, -0.1, TABLE_TOP + 0.15))
    q0 = ik.solve({"left": t0})
    t1 = TcpTarget(top_down(-0.14, -0.1, TABLE_TOP + 0.15))
    q1 = ik.solve({"left": t1}, seed=q0)
    assert np.max(np.abs(q1 - q0)) < 0.2  # a nearby answer on the same branch


def test_environment_clearance_and_ignore(cubes_model, cubes_ik):
    """Fingers half closed around a cube violate the environment clearance unless it is
    ignored (the object being grasped)."""
    m, ik = cubes_model, cubes_ik
    x, y, z = m.object_pose("cube_2").translation()
    target = TcpTarget(top_down(x, y, z + 0.01), free_axis=True)  # fingertips 1.25 cm up
    m.set_gripper("right", 0.3)  # 3.3 cm jaw gap, the cube is 4 cm
    try:
        with pytest.raises(PlanningError, match="environment clearance .* cube_2") as err:
            ik.solve({"right": target}, restarts=2)
        assert err.value.reason == "ik_collision"
        q = ik.solve({"right": target}, ignore=["cube_2"])
        with m.ignoring(["cube_2"]):
            assert_valid(m, q, {"right": target}, 0.03, 0.01)
        m.set_padding(0.0, 0.0)
        assert not m.collision_free(q)
    finally:
        m.set_gripper("right", 1.0)


def test_held_object_counts_as_robot_geometry():
    """A 12 cm bar held in the left gripper hits the table where the bare gripper would not."""
    bar = SceneObject(
        name="bar",
        shape=BoxShape(size=(0.04, 0.04, 0.12)),
        pose=Pose(xyz=(-0.25, -0.1, TABLE_TOP + 0.06)),
    )
    m = PlanningModel(Scene(name="bar", objects=(bar,)))
    ik = BimanualIK(m)
    m.set_gripper("left", 0.39)
    grasp = TcpTarget(top_down(-0.25, -0.1, TABLE_TOP + 0.06))
    q_grasp = ik.solve({"left": grasp}, q_fixed={"right": m.home[6:]}, ignore=["bar"])
    low = {"left": TcpTarget(top_down(-0.05, -0.1, TABLE_TOP + 0.045))}
    q_low = ik.solve(low, q_fixed={"right": m.home[6:]}, env_clearance=0.005)  # free-handed
    m.attach("bar", "left", q_grasp)
    with pytest.raises(PlanningError, match="environment clearance") as err:
        ik.solve(low, q_fixed={"right": m.home[6:]}, env_clearance=0.005, restarts=2)
    assert "gripper_link - table_top" in str(err.value)
    m.set_padding(0.0, 0.0)
    assert not m.collision_free(q_low)
    with m.ignoring(["bar"]):
        assert m.collision_free(q_low)
    m.detach("left", q_grasp)
    assert m.collision_free(q_low)
    assert np.allclose(m.object_pose("bar").translation(), bar.pose.xyz, atol=2e-3)


def test_unreachable_target_says_which_constraint(cubes_model):
    far = TcpTarget(top_down(0.0, 0.8, TABLE_TOP + 0.1))
    for ik in (BimanualIK(cubes_model), BimanualIK(cubes_model, analytic=False)):
        with pytest.raises(PlanningError, match="position") as err:
            ik.solve({"left": far}, restarts=2)
        assert err.value.reason == "ik_unreachable"
    R_up = RotationMatrix(RollPitchYaw(0, -np.pi / 2, 0))  # approach axis pointing up
    up = TcpTarget(RigidTransform(R_up, [-0.25, -0.3, 0.8]))
    with pytest.raises(PlanningError, match="orientation") as err:
        BimanualIK(cubes_model).solve({"left": up})
    assert err.value.reason == "ik_unreachable"


def test_bad_arguments(cubes_ik):
    with pytest.raises(ValueError, match="left"):
        cubes_ik.solve({"middle": TcpTarget(RigidTransform())})
    with pytest.raises(ValueError, match="fixed"):
        cubes_ik.solve({"left": TcpTarget(RigidTransform())}, q_fixed={"left": np.zeros(6)})


@pytest.mark.slow
def test_acceptance_200_pairs_median_under_10ms(cubes_model):
    """Issue acceptance: >= 95 % of 200 reachable pairs at 3 cm clearance, median <= 10 ms."""
    m = cubes_model
    ik = BimanualIK(m)
    cases = reachable_targets(m, np.random.default_rng(2024), 200)
    times, solved = [], 0
    for targets in cases:
        t0 = time.perf_counter()
        try:
            q = ik.solve(targets, clearance=0.03)
            solved += 1
        except PlanningError:
            q = None
        times.append(time.perf_counter() - t0)
        if q is not None:
            assert_valid(m, q, targets, 0.03, 0.01)
    assert solved >= 190
    assert np.median(times) <= 0.010


@pytest.mark.slow
def test_acceptance_snopt_only_200_pairs(cubes_model):
    """The same 200 pairs without the closed form (two-stage SNOPT with restarts)."""
    m = cubes_model
    ik = BimanualIK(m, analytic=False)
    cases = reachable_targets(m, np.random.default_rng(2024), 200)
    solved = 0
    for targets in cases:
        try:
            q = ik.solve(targets, clearance=0.03)
        except PlanningError:
            continue
        assert_valid(m, q, targets, 0.03, 0.01)
        solved += 1
    assert solved >= 190

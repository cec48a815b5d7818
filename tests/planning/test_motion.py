"""Collision-checked joint paths: swaps through each other's space, held objects, bad input."""

from __future__ import annotations

import time

import numpy as np
import pytest

import bicoord_drake.planning.motion as motion
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.ik import BimanualIK, TcpTarget
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.motion import plan_path, verify_path
from tests.planning.conftest import swap_cases, top_down


def independently_collision_free(model, path, resolution=0.01) -> bool:
    """Every straight segment, sampled so no robot point moves more than `resolution`
    between samples, is in contact with nothing (zero padding), one configuration at a time."""
    model.set_padding(0.0, 0.0)
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(1, int(np.ceil(model.path_distance(a, b) / resolution)))
        for s in np.linspace(0.0, 1.0, n + 1):
            if not model.collision_free(a + s * (b - a)):
                return False
    return True


def test_path_distance_bounds_point_motion(cubes_model):
    """The resolution metric bounds how far the TCPs (the farthest points) actually move."""
    m = cubes_model
    rng = np.random.default_rng(0)
    for _ in range(50):
        a, b = rng.uniform(m.lower, m.upper), rng.uniform(m.lower, m.upper)
        d = m.path_distance(a, b)
        for side in ("left", "right"):
            pts = [m.tcp_pose(a + s * (b - a), side).translation() for s in np.linspace(0, 1, 40)]
            assert np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)) <= d + 1e-9


def test_padded_restores_the_padding_it_found(cubes_model):
    """Padding set inside a `padded` block does not leak out of it, also when it raises."""
    m = cubes_model
    m.set_padding(0.03, 0.01)
    before = np.array(m.checker.GetPaddingMatrix(), copy=True)
    with m.padded(0.0, 0.0):
        assert np.max(m.checker.GetPaddingMatrix()) == 0.0
    np.testing.assert_array_equal(m.checker.GetPaddingMatrix(), before)
    with pytest.raises(RuntimeError), m.padded(0.05, 0.02):
        raise RuntimeError("inside the block")
    np.testing.assert_array_equal(m.checker.GetPaddingMatrix(), before)


def test_free_straight_line_is_returned_as_is(cubes_model):
    m = cubes_model
    goal = m.home + np.array([0.2, 0.1, -0.1, 0, 0, 0, -0.2, 0.1, -0.1, 0, 0, 0])
    path = plan_path(m, m.home, goal)
    assert path.shape == (2, 12)
    np.testing.assert_array_equal(path[0], m.home)
    np.testing.assert_array_equal(path[-1], goal)


def test_swaps_through_each_others_space(cubes_model, cubes_ik):
    """Left TCP ends on the right half, right TCP on the left: the arms must cross."""
    m = cubes_model
    cases = swap_cases(m, cubes_ik, np.random.default_rng(11), 20)
    solved = 0
    for start, goal in cases:
        try:
            path = plan_path(m, start, goal)
        except PlanningError:
            continue
        solved += 1
        np.testing.assert_array_equal(path[0], start)
        np.testing.assert_array_equal(path[-1], goal)
        assert independently_collision_free(m, path)
    assert solved >= 19


def test_single_arm_path_keeps_the_other_arm(cubes_model, cubes_ik):
    m = cubes_model
    start = m.home.copy()
    target = TcpTarget(top_down(0.0, -0.12, TABLE_TOP + 0.12, yaw=1.0))
    goal = cubes_ik.solve_single("left", target, m.home[6:])
    path = plan_path(m, start, goal, arms=("left",))
    assert np.all(path[:, 6:] == m.home[6:])
    assert independently_collision_free(m, path)
    goal[6] += 0.1
    with pytest.raises(ValueError, match="right arm"):
        plan_path(m, start, goal, arms=("left",))


@pytest.fixture()
def bar_world():
    """A 12 cm bar held in the left gripper, an 11 cm wall fixed on the table next to it."""
    bar = SceneObject(
        name="bar",
        shape=BoxShape(size=(0.04, 0.04, 0.12)),
        pose=Pose(xyz=(-0.25, -0.1, TABLE_TOP + 0.06)),
    )
    wall = SceneObject(
        name="wall",
        shape=BoxShape(size=(0.02, 0.3, 0.11)),
        pose=Pose(xyz=(-0.12, -0.1, TABLE_TOP + 0.055)),
        fixed=True,
    )
    m = PlanningModel(Scene(name="bar_and_wall", objects=(bar, wall)))
    ik = BimanualIK(m)
    m.set_gripper("left", 0.39)
    right = {"right": m.home[6:]}
    q_grasp = ik.solve(
        {"left": TcpTarget(top_down(-0.25, -0.1, TABLE_TOP + 0.06))}, q_fixed=right, ignore=["bar"]
    )
    m.attach("bar", "left", q_grasp)
    q_a = ik.solve({"left": TcpTarget(top_down(-0.25, -0.1, TABLE_TOP + 0.16))}, q_fixed=right)
    q_b = ik.solve({"left": TcpTarget(top_down(0.0, -0.1, TABLE_TOP + 0.16))}, q_fixed=right)
    return m, q_grasp, q_a, q_b


def test_held_object_is_part_of_the_checked_geometry(bar_world):
    """Over the wall the bare gripper passes straight; the held bar forces a detour."""
    m, _, q_a, q_b = bar_world
    m.set_padding(0.0, 0.0)
    assert not m.edge_free(q_a, q_b, 0.01)
    with m.ignoring(["bar"]):
        assert m.edge_free(q_a, q_b, 0.01)
    path = plan_path(m, q_a, q_b, arms=("left",))
    assert len(path) > 2
    assert independently_collision_free(m, path)


def test_holding_and_arms_only_change_the_check_only_inside(bar_world):
    """Under ``holding({})`` the bar lies where it was grasped (the left gripper passes the
    wall free of it); under ``arms_only()`` the held bar may rest on the table. Afterwards the
    holds, the anchors and the filters are as they were."""
    m, q_grasp, q_a, q_b = bar_world
    m.set_padding(0.0, 0.0)
    filters = np.array(m.checker.GetFilteredCollisionMatrix(), copy=True)
    held = m.held
    assert not m.collision_free(q_grasp)  # the held bar rests on the table
    with m.arms_only():
        assert m.collision_free(q_grasp)
        assert not np.array_equal(m.checker.GetFilteredCollisionMatrix(), filters)
    with m.holding({}):
        assert not m.held and m.edge_free(q_a, q_b, 0.01)
    with m.holding(held):
        assert not m.edge_free(q_a, q_b, 0.01)
    with pytest.raises(ValueError):
        with m.holding({"right": held["left"]}):
            pass
    assert m.held == held and not m.edge_free(q_a, q_b, 0.01)
    np.testing.assert_array_equal(m.checker.GetFilteredCollisionMatrix(), filters)


def test_start_in_collision_names_the_pair(bar_world):
    """Right after the grasp the bar still rests on the table."""
    m, q_grasp, q_a, _ = bar_world
    with pytest.raises(PlanningError, match="left_arm/gripper_link - table_top") as err:
        plan_path(m, q_grasp, q_a, arms=("left",))
    assert err.value.reason == "start_in_collision"
    path = plan_path(m, q_a, q_grasp, arms=("left",), env_clearance=0.0, ignore=["bar"])
    assert path.shape[1] == 12


def test_a_colliding_path_is_never_returned(cubes_model, cubes_ik, monkeypatch):
    """Even if the search were wrong, the dense check refuses its path."""
    m = cubes_model
    rng = np.random.default_rng(5)
    for _ in range(20):
        start, goal = swap_cases(m, cubes_ik, rng, 1)[0]
        m.set_padding(0.0, 0.0)
        if not m.edge_free(start, goal, 0.01):
            break
    else:
        pytest.fail("no swap case with a colliding straight line")

    def straight(self, a, b, *args):
        return np.array([a, b])

    monkeypatch.setattr(motion._Planner, "solve", straight)
    with pytest.raises(PlanningError) as err:
        plan_path(m, start, goal)
    assert err.value.reason == "path_in_collision"


def test_out_of_limits_and_bad_shapes(cubes_model):
    m = cubes_model
    with pytest.raises(PlanningError) as err:
        plan_path(m, m.home, m.upper + 0.1)
    assert err.value.reason == "goal_out_of_limits"
    with pytest.raises(ValueError, match="12-vector"):
        plan_path(m, m.home, m.home[:6])


def test_refined_path_is_verified(cubes_model, cubes_ik):
    m = cubes_model
    start, goal = swap_cases(m, cubes_ik, np.random.default_rng(8), 1)[0]
    coarse = plan_path(m, start, goal)
    path = plan_path(m, start, goal, refine=True)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal)
    assert independently_collision_free(m, path)
    m.set_padding(0.01, 0.005)
    assert verify_path(m, path)
    assert len(path) >= len(coarse)


@pytest.mark.slow
def test_acceptance_100_swaps(cubes_model):
    """Issue acceptance: >= 95 % of 100 random swaps solved; every path collision-free at
    1 cm resolution."""
    m = cubes_model
    cases = swap_cases(m, BimanualIK(m), np.random.default_rng(2024), 100)
    solved, times = 0, []
    for start, goal in cases:
        t0 = time.perf_counter()
        try:
            path = plan_path(m, start, goal)
        except PlanningError:
            continue
        finally:
            times.append(time.perf_counter() - t0)
        solved += 1
        assert independently_collision_free(m, path)
    assert solved >= 95

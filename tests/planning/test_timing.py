"""Ruckig timing: limits at every sample, exact paths, synchronized arrival, throws and catches."""

from __future__ import annotations

import numpy as np
import pytest

from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.throwing import (
    ballistic_landing,
    release_joint_velocity,
    schedule_catch,
    throw_and_catch,
    throw_release,
)
from bicoord_drake.planning.timing import (
    CONTROL_DT,
    JointLimits,
    TimedTrajectory,
    concatenate,
    gripper_schedule,
    opening_rate,
    planning_substeps,
    rendezvous,
    stack_arms,
    synchronize,
    time_path,
)

TOL = 1e-6  # relative slack on velocity / acceleration limits
DT = CONTROL_DT


@pytest.fixture(scope="module")
def embodiment():
    return get_embodiment("aloha_viperx")


@pytest.fixture(scope="module")
def limits(embodiment) -> JointLimits:
    return JointLimits.from_embodiment(embodiment)


@pytest.fixture(scope="module")
def arm_limits(embodiment) -> JointLimits:
    return JointLimits.from_embodiment(embodiment, arms=1)


def random_path(rng, limits: JointLimits, k: int) -> np.ndarray:
    centre = (limits.lower + limits.upper) / 2
    half = (limits.upper - limits.lower) / 2
    return centre + rng.uniform(-0.7, 0.7, size=(k, limits.n)) * half


def assert_within_limits(traj: TimedTrajectory, limits: JointLimits) -> None:
    assert np.all(np.abs(traj.qd) <= limits.velocity * (1 + TOL))
    assert np.all(np.abs(traj.qdd) <= limits.acceleration * (1 + TOL))
    assert np.all(traj.q >= limits.lower - 1e-9)
    assert np.all(traj.q <= limits.upper + 1e-9)


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    best = np.full(len(points), np.inf)
    for a, b in zip(polyline, polyline[1:], strict=False):
        d = b - a
        s = np.clip((points - a) @ d / max(d @ d, 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - a - s[:, None] * d, axis=1))
    return best


def arrival_index(q: np.ndarray, goal: np.ndarray, tol: float = 1e-12) -> int:
    """First sample from which the motion stays at its goal."""
    away = np.any(np.abs(q - goal) > tol, axis=1)
    return int(np.nonzero(away)[0][-1] + 1) if np.any(away) else 0


# --------------------------------------------------------------------------------------------
# Limits
# --------------------------------------------------------------------------------------------


def test_limits_from_embodiment_tile_and_scale(embodiment):
    lim = JointLimits.from_embodiment(embodiment)
    assert lim.n == 12
    assert np.allclose(lim.velocity[:6], [j.velocity_limit for j in embodiment.arm.joints])
    assert np.array_equal(lim.velocity[:6], lim.velocity[6:])
    slow = JointLimits.from_embodiment(embodiment, speed=0.5)
    assert np.allclose(slow.velocity, 0.5 * lim.velocity)
    assert np.allclose(slow.acceleration, 0.25 * lim.acceleration)
    assert np.allclose(slow.jerk, 0.125 * lim.jerk)
    assert np.array_equal(lim.arm("right").lower, lim.lower[6:])
    with pytest.raises(ValueError):
        lim.scaled(0.0)


def test_slower_speed_gives_longer_motion(embodiment):
    path = np.array([embodiment.home * 2, np.array(embodiment.home * 2) + 0.4])
    fast = time_path(path, JointLimits.from_embodiment(embodiment))
    slow = time_path(path, JointLimits.from_embodiment(embodiment, speed=0.5))
    assert slow.num_steps >= 2 * fast.num_steps - 2


# --------------------------------------------------------------------------------------------
# time_path
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(12))
def test_time_path_limits_exact_path_and_goal(seed, limits):
    rng = np.random.default_rng(seed)
    path = random_path(rng, limits, k=int(rng.integers(2, 6)))
    traj = time_path(path, limits)
    assert np.allclose(traj.times, np.arange(len(traj.q)) * DT)
    assert traj.duration == pytest.approx(traj.num_steps * DT)
    assert np.array_equal(traj.q[0], path[0])
    assert np.array_equal(traj.q[-1], path[-1])  # last sample exactly on the goal
    assert np.allclose(traj.qd[[0, -1]], 0.0) and np.allclose(traj.qdd[[0, -1]], 0.0)
    assert_within_limits(traj, limits)
    assert distance_to_polyline(traj.q, path).max() < 1e-9
    # The continuous motion between samples stays on the path and within limits as well.
    dense = np.linspace(0.0, traj.duration, 1500)
    states = [traj.at(t) for t in dense]
    q = np.array([s[0] for s in states])
    qd = np.array([s[1] for s in states])
    assert distance_to_polyline(q, path).max() < 1e-9
    assert np.all(np.abs(qd) <= limits.velocity * (1 + TOL))
    # Some joint actually reaches its velocity or acceleration limit (time-optimal per segment).
    r = traj.limit_ratios(limits)
    assert max(r["velocity"], r["acceleration"]) > 0.9


@pytest.mark.parametrize("seed", range(6))
def test_time_path_both_arms_arrive_together(seed, limits):
    rng = np.random.default_rng(100 + seed)
    path = random_path(rng, limits, k=3)
    # The right arm moves only a little: it still arrives with the left arm.
    path[:, 6:] = path[0, 6:] + 0.05 * (path[:, 6:] - path[0, 6:])
    traj = time_path(path, limits)
    left = arrival_index(traj.q[:, :6], path[-1, :6])
    right = arrival_index(traj.q[:, 6:], path[-1, 6:])
    assert abs(left - right) <= 1
    assert left == traj.num_steps


def test_time_path_stops_at_corners_and_merges_collinear_points(limits):
    a = (limits.lower + limits.upper) / 2
    b = a + 0.5
    line = np.linspace(a, b, 25)  # densified straight line: one rest-to-rest profile
    traj = time_path(line, limits)
    speeds = np.linalg.norm(traj.qd, axis=1)
    assert np.all(speeds[1:-1] > 0)
    single = time_path(np.array([a, b]), limits)
    assert traj.num_steps == single.num_steps
    # A real corner is passed at rest.
    c = b + np.r_[0.3, -0.3, np.zeros(10)]
    corner = time_path(np.array([a, b, c]), limits)
    at_b = np.nonzero(np.all(np.abs(corner.q - b) < 1e-12, axis=1))[0]
    assert len(at_b) >= 1 and np.allclose(corner.qd[at_b], 0.0)


def test_time_path_single_waypoint_and_out_of_limit_waypoint(limits):
    q = (limits.lower + limits.upper) / 2
    still = time_path(q[None], limits)
    assert still.num_steps == 0 and np.array_equal(still.q[0], q)
    bad = q.copy()
    bad[1] = limits.upper[1] + 0.1
    with pytest.raises(PlanningError) as err:
        time_path(np.array([q, bad]), limits)
    assert err.value.reason == "joint_limits"


def test_concatenate_requires_continuity(limits):
    rng = np.random.default_rng(3)
    p = random_path(rng, limits, 3)
    first = time_path(p[:2], limits)
    second = time_path(p[1:], limits)
    joined = first.then(second)
    assert joined.num_steps == first.num_steps + second.num_steps
    assert np.array_equal(joined.q[-1], p[-1])
    with pytest.raises(PlanningError):
        concatenate([first, time_path(p[[0, 2]], limits)])


# --------------------------------------------------------------------------------------------
# synchronize / rendezvous
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(8))
def test_synchronize_stretches_the_faster_arm(seed, limits):
    rng = np.random.default_rng(200 + seed)
    lim = limits.arm("left")
    fast_path = random_path(rng, lim, 2)
    fast_path[1] = fast_path[0] + 0.2 * (fast_path[1] - fast_path[0])
    slow_path = random_path(rng, lim, 4)
    fast, slow = time_path(fast_path, lim), time_path(slow_path, lim)
    a, b = synchronize(fast, slow)
    assert a.num_steps == b.num_steps == max(fast.num_steps, slow.num_steps)
    for traj, path in ((a, fast_path), (b, slow_path)):
        assert np.array_equal(traj.q[-1], path[-1])
        assert_within_limits(traj, lim)
        assert distance_to_polyline(traj.q, path).max() < 1e-9
        assert abs(arrival_index(traj.q, path[-1]) - traj.num_steps) <= 1


@pytest.mark.parametrize("seed", range(8))
def test_rendezvous_arrives_together(seed, limits):
    rng = np.random.default_rng(300 + seed)
    left_path = random_path(rng, limits.arm("left"), int(rng.integers(2, 4)))
    right_path = random_path(rng, limits.arm("right"), int(rng.integers(2, 4)))
    traj = rendezvous(left_path, right_path, limits)
    assert traj.n == 12
    assert_within_limits(traj, limits)
    left = arrival_index(traj.q[:, :6], left_path[-1])
    right = arrival_index(traj.q[:, 6:], right_path[-1])
    assert abs(left - right) <= 1
    assert np.array_equal(traj.q[-1], np.r_[left_path[-1], right_path[-1]])
    # A later meeting time is honoured exactly on the grid.
    later = rendezvous(left_path, right_path, limits, arrive_at=traj.duration + 0.5)
    assert later.num_steps == int(np.ceil((traj.duration + 0.5) / DT - 1e-9))
    assert_within_limits(later, limits)
    assert abs(arrival_index(later.q[:, :6], left_path[-1]) - later.num_steps) <= 1
    assert abs(arrival_index(later.q[:, 6:], right_path[-1]) - later.num_steps) <= 1


def test_rendezvous_too_early_is_a_planning_error(limits):
    rng = np.random.default_rng(7)
    left = random_path(rng, limits.arm("left"), 2)
    right = random_path(rng, limits.arm("right"), 2)
    with pytest.raises(PlanningError) as err:
        rendezvous(left, right, limits, arrive_at=0.1)
    assert err.value.reason == "timing_infeasible"


def test_stack_arms_pads_the_shorter_arm(arm_limits):
    rng = np.random.default_rng(11)
    a = time_path(random_path(rng, arm_limits, 2), arm_limits)
    b = TimedTrajectory.hold(random_path(rng, arm_limits, 1)[0], 3)
    both = stack_arms(a, b)
    assert both.n == 12 and both.num_steps == a.num_steps
    assert np.allclose(both.q[:, 6:], b.q[0])
    assert np.array_equal(both.arm("left").q, a.q)


# --------------------------------------------------------------------------------------------
# Throw and catch
# --------------------------------------------------------------------------------------------


def throw_case(rng, embodiment):
    q0 = np.array(embodiment.home)
    q_rel = q0 + rng.uniform(-0.3, 0.3, 6) * np.array([1, 0.5, 0.3, 1, 0.5, 1])
    v = rng.uniform(-1.2, 1.2, 6) * np.array([1, 1, 0.5, 0.5, 1, 0.5])
    return q0, q_rel, v


@pytest.mark.parametrize("seed", range(10))
def test_throw_release_state_on_grid_and_limits(seed, embodiment, arm_limits):
    rng = np.random.default_rng(400 + seed)
    q0, q_rel, v = throw_case(rng, embodiment)
    plan = throw_release(q0, q_rel, arm_limits, qd_release=v)
    traj = plan.trajectory
    i = plan.release_index
    assert plan.release_time == pytest.approx(i * DT)
    assert np.array_equal(traj.q[i], q_rel) and np.array_equal(traj.qd[i], v)
    assert np.allclose(traj.q[0], q0) and np.allclose(traj.qd[0], 0.0)
    assert np.allclose(traj.qd[-1], 0.0, atol=1e-9)  # braked to rest
    # Constant-velocity coast around the release: first-order hold reproduces qd exactly.
    assert np.allclose((traj.q[i] - traj.q[i - 1]) / DT, v, atol=1e-9)
    assert np.allclose((traj.q[i + 1] - traj.q[i]) / DT, v, atol=1e-9)
    assert_within_limits(traj, arm_limits)
    with pytest.raises(PlanningError):
        traj.stretched(traj.num_steps + 5)


def test_throw_release_at_requested_step(embodiment, arm_limits):
    rng = np.random.default_rng(5)
    q0, q_rel, v = throw_case(rng, embodiment)
    early = throw_release(q0, q_rel, arm_limits, qd_release=v)
    plan = throw_release(q0, q_rel, arm_limits, qd_release=v, release_at=early.release_time + 0.3)
    assert plan.release_index == int(np.ceil((early.release_time + 0.3) / DT - 1e-9))
    assert np.array_equal(plan.trajectory.q[plan.release_index], q_rel)
    assert_within_limits(plan.trajectory, arm_limits)


def test_throw_from_tcp_velocity_uses_the_jacobian(embodiment, arm_limits):
    rng = np.random.default_rng(9)
    J = rng.normal(size=(6, 6))
    q0 = np.array(embodiment.home)
    q_rel = q0 + np.r_[0.1, -0.1, 0.05, 0, 0.1, 0]
    v_tcp = np.array([0.4, 0.0, 0.4])
    plan = throw_release(q0, q_rel, arm_limits, tcp_velocity=v_tcp, jacobian=lambda q: J)
    assert np.allclose(J[3:] @ plan.qd_release, v_tcp)
    qd = release_joint_velocity(J[3:], q_rel, v_tcp)
    assert np.allclose(qd, plan.qd_release)
    twist = np.r_[0.1, 0.0, 0.0, v_tcp]
    assert np.allclose(J @ release_joint_velocity(J, q_rel, twist), twist)


def test_throw_errors(embodiment, arm_limits):
    q0 = np.array(embodiment.home)
    too_fast = arm_limits.velocity * 1.1
    with pytest.raises(PlanningError) as err:
        throw_release(q0, q0, arm_limits, qd_release=too_fast)
    assert err.value.reason == "throw_too_fast"
    # Braking from a fast elbow near its upper limit would leave the joint range.
    q_rel = q0.copy()
    q_rel[2] = arm_limits.upper[2] - 0.05
    v = np.zeros(6)
    v[2] = 2.5
    with pytest.raises(PlanningError) as err:
        throw_release(q0, q_rel, arm_limits, qd_release=v)
    assert err.value.reason in ("throw_joint_limits", "timing_limits")
    singular = np.zeros((3, 6))
    singular[0, 0] = 1.0
    with pytest.raises(PlanningError) as err:
        release_joint_velocity(singular, q0, np.array([0.0, 1.0, 0.0]))
    assert err.value.reason == "throw_unreachable"


def test_ballistic_landing_golden_values():
    g = 9.81
    p, t = ballistic_landing([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 0.0)
    assert t == pytest.approx(np.sqrt(2 / g))
    assert np.allclose(p, [np.sqrt(2 / g), 0.0, 0.0])
    # Thrown up at 45 degrees and caught at the release height: range v^2 sin(2a) / g.
    v = 1.2
    p, t = ballistic_landing([0.1, 0.2, 0.9], [0.0, v / np.sqrt(2), v / np.sqrt(2)], 0.9)
    assert t == pytest.approx(2 * v / np.sqrt(2) / g)
    assert np.allclose(p, [0.1, 0.2 + v**2 / g, 0.9])
    with pytest.raises(PlanningError):
        ballistic_landing([0, 0, 0.8], [0, 0, 1.0], 2.0)


def test_catcher_is_in_place_before_landing(embodiment, limits, arm_limits):
    rng = np.random.default_rng(21)
    q0, q_rel, v = throw_case(rng, embodiment)
    throw = throw_release(q0, q_rel, arm_limits, qd_release=v)
    catcher = time_path(np.array([q0, q0 + np.r_[-0.4, 0.2, -0.2, 0, 0.3, 0]]), arm_limits)
    flight = 0.6
    for start in ("early", "late"):
        plan = throw_and_catch(throw, catcher, flight, "left", margin=0.15, start=start)
        traj = plan.trajectory
        assert traj.n == 12
        assert_within_limits(traj, limits)
        landing = throw.release_time + flight
        arrived = arrival_index(traj.q[:, 6:], catcher.goal)
        assert arrived * DT <= landing - 0.15 + 1e-9
        assert plan.catch.arrival_index == arrived
        assert traj.duration >= landing
        i = throw.release_index
        assert np.array_equal(traj.q[i, :6], q_rel) and np.array_equal(traj.qd[i, :6], v)
    late = throw_and_catch(throw, catcher, flight, "left", margin=0.15, start="late")
    assert late.catch.slack < 0.15 + DT + 1e-9
    with pytest.raises(PlanningError) as err:
        schedule_catch(0.2, 0.1, catcher, margin=0.1)
    assert err.value.reason == "catch_too_late"


# --------------------------------------------------------------------------------------------
# Actions and gripper schedules
# --------------------------------------------------------------------------------------------


def test_to_actions_layout_and_gripper_schedule(embodiment, limits):
    rng = np.random.default_rng(31)
    traj = time_path(random_path(rng, limits, 2), limits)
    n = len(traj.q)
    rate = opening_rate(embodiment.arm.gripper)
    close = gripper_schedule(n, 1.0, [(2, 0.0)], rate=rate)
    assert close[0] == close[1] == 1.0 and close[-1] == 0.0
    assert np.all(np.abs(np.diff(close)) <= rate * DT + 1e-12)
    actions = traj.to_actions(close, lambda t: (t > 0.5).astype(float))
    assert actions.shape == (n, 14)
    assert np.array_equal(actions[:, :6], traj.q[:, :6])
    assert np.array_equal(actions[:, 7:13], traj.q[:, 6:])
    assert np.array_equal(actions[:, 6], close)
    assert np.array_equal(actions[:, 13], (traj.times > 0.5).astype(float))
    still = TimedTrajectory.hold(traj.goal, 4).to_actions(0.5, 0.0)
    assert still.shape == (5, 14) and np.all(still[:, 6] == 0.5)


@pytest.mark.parametrize(
    "rate,k",
    [(15, 1), (30, 1), (50, 1), (1000, 1), (10, 2), (7.5, 2), (12, 2), (14.9, 2), (5, 3), (1, 15)],
)
def test_planning_substeps_plan_no_coarser_than_15_hz(rate, k):
    assert planning_substeps(1.0 / rate) == k
    assert 1.0 / rate / k <= CONTROL_DT * (1 + 1e-9)


def test_planning_substeps_need_a_positive_period():
    with pytest.raises(ValueError):
        planning_substeps(0.0)

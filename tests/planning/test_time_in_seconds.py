"""Plans in seconds: the control period comes from the planning model, every skill duration is
in seconds, so a plan lasts as long at 10, 15, 30 or 50 Hz and only its sampling changes."""

import numpy as np
import pytest
from pydrake.all import RigidTransform

import bicoord_drake.planning.skills as sk
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills.core import merge_substeps
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import step_limit_at

SCENE = Scene(name="one", objects=(cube("a", 0.15, -0.05),))


@pytest.fixture(scope="module")
def models():
    return {hz: PlanningModel(SCENE, control_period=1.0 / hz) for hz in (15, 30, 50)}


def test_periods_round_a_duration_to_the_nearest_whole_period():
    assert sk.periods(0.0, 1 / 15) == 0
    # the 15 Hz step counts the tasks used before, written as seconds to 2 decimals
    for steps in (2, 3, 4, 6, 8, 10, 12, 20, 90):
        assert sk.periods(round(steps / 15, 2), 1 / 15) == steps
    assert sk.periods(0.53, 1 / 50) == 27  # 26.5 periods: half up
    assert sk.periods(0.8, 1 / 30) == 24
    with pytest.raises(ValueError, match=">= 0"):
        sk.periods(-0.1, 1 / 15)


def test_the_context_plans_on_the_models_control_period(models):
    for hz, model in models.items():
        ctx = sk.SkillContext(model)
        assert ctx.dt == pytest.approx(1.0 / hz)
        assert ctx.steps(1.0) == hz
    assert sk.SkillContext(models[15], dt=0.02).dt == 0.02  # an explicit period still wins
    with pytest.raises(ValueError, match="control_period"):
        PlanningModel(SCENE, control_period=0.0)


def test_holds_and_releases_last_the_same_time_at_every_rate(models):
    for hz, model in models.items():
        ctx = sk.SkillContext(model)
        assert sk.hold(ctx, "left", 0.8).num_steps - 1 == round(0.8 * hz)
        ctx.opening["left"] = 0.0
        ramp = sk.gentle_release_time(ctx)
        slow = sk.grip(ctx, "left", 1.0, gentle=True, settle=0.2)
        # the opening ramps for the gentle release's seconds, then holds 0.2 s, at any rate
        first_open = int(np.argmax(slow.opening >= 1.0))
        assert first_open / hz == pytest.approx(ramp, abs=1 / hz)
        assert (slow.num_steps - 1) / hz == pytest.approx(ramp + 0.2, abs=1 / hz)
        both = sk.hold_still(ctx, 0.53)
        assert (both.num_steps - 1) / hz == pytest.approx(0.53, abs=0.5 / hz + 1e-9)


def test_a_planned_move_takes_the_same_time_at_every_rate(models):
    durations = {}
    for hz, model in models.items():
        ctx = sk.SkillContext(model)
        X = ctx.model.tcp_pose(ctx.q, "right")
        goal = RigidTransform(X.rotation(), X.translation() + [0.05, 0.1, -0.1])
        plan = sk.move_tcp(ctx, "right", goal)
        durations[hz] = (plan.num_steps - 1) / hz
        # the samples stay within the joints' velocity limits at every rate
        speed = np.max(np.abs(np.diff(plan.q, axis=0)) * hz / ctx.arm_limits.velocity)
        assert speed <= 1.0 + 1e-6
    assert max(durations.values()) - min(durations.values()) <= 1 / 15 + 1e-9


def _off_polyline(q: np.ndarray, corners: np.ndarray) -> float:
    """How far the station's linear interpolation between samples `q` leaves the polyline."""
    a, d = corners[:-1], np.diff(corners, axis=0)
    worst = 0.0
    for f in np.linspace(0, 1, 9):
        for x in q[:-1] * (1 - f) + q[1:] * f:
            s = np.clip(np.einsum("kj,kj->k", x - a, d) / np.einsum("kj,kj->k", d, d), 0, 1)
            worst = max(worst, float(np.min(np.linalg.norm(x - (a + s[:, None] * d), axis=1))))
    return worst


def test_a_path_of_many_corners_lasts_the_same_time_at_every_rate():
    """Segments last whole 15 Hz periods at every rate (rounded up to each rate's own period,
    30 short segments drifted by 4 % between 10 and 50 Hz); the path's total is rounded up
    once. At 15 and 30 Hz every corner is a sample; at 10 and 50 Hz a corner between two
    samples is cut only by the at-rest motion of half a period."""
    from bicoord_drake.models.viperx import aloha_viperx
    from bicoord_drake.planning.timing import JointLimits, time_path

    limits = JointLimits.from_embodiment(aloha_viperx(), arms=1)
    rng = np.random.default_rng(7)
    mid = (limits.lower + limits.upper) / 2
    corners = mid + np.cumsum(rng.normal(0, 0.04, (31, limits.n)), axis=0)
    timed = {hz: time_path(corners, limits, 1.0 / hz) for hz in (10, 15, 30, 50)}
    for hz, traj in timed.items():
        assert traj.duration == pytest.approx(timed[15].duration, abs=1.0 / hz + 1e-9)
        traj.check_limits(limits)
        assert np.array_equal(traj.q[-1], corners[-1])
    assert timed[30].duration == pytest.approx(timed[15].duration, abs=1e-9)
    assert _off_polyline(timed[15].q, corners) < 1e-12
    assert _off_polyline(timed[30].q, corners) < 1e-12
    assert _off_polyline(timed[50].q, corners) < 1e-4
    assert _off_polyline(timed[10].q, corners) < 2e-3


def test_the_dense_merge_check_keeps_its_spacing_in_seconds():
    assert merge_substeps(1 / 15) == 4  # as before at 15 Hz
    for hz in (10, 15, 30, 50, 100):
        assert 1 / hz / merge_substeps(1 / hz) <= 1 / 60 + 1e-12


def test_step_limits_scale_with_the_rate():
    task = get_task("jigsaw")
    assert step_limit_at(task, 15) == task.step_limit
    assert step_limit_at(task, 30) == 2 * task.step_limit
    assert step_limit_at(task, 50) == int(np.ceil(task.step_limit * 50 / 15))
    assert step_limit_at(task, 10) == int(np.ceil(task.step_limit * 10 / 15))


def test_env_gap_measures_how_close_a_planned_arm_comes_to_the_table(models):
    ctx = sk.SkillContext(models[15])
    home = ctx.arm_q("right")
    assert sk.env_gap(ctx, ctx.q, "right", home[None]) == ctx.env_clearance  # far above
    X = ctx.model.tcp_pose(ctx.q, "right")
    from bicoord_drake.models.scene import TABLE_TOP
    from bicoord_drake.planning.ik import TcpTarget

    low = RigidTransform(X.rotation(), [X.translation()[0], X.translation()[1], TABLE_TOP + 0.02])
    q_low = sk.solve_tcp(ctx, "right", TcpTarget(low), env_clearance=0.0)
    gap = sk.env_gap(ctx, ctx.q, "right", np.vstack([home, q_low]))
    assert gap < ctx.env_clearance  # the hand at the table: closer than the skills' clearance


@pytest.mark.parametrize("seed", range(3))
def test_a_throw_is_the_same_motion_at_every_rate(seed):
    """Timed on the 15 Hz quantum, a throw reaches its release state on a control step at 10,
    30 and 50 Hz, at the 15 Hz release instant or less than one period later (it starts late,
    at rest), and coasts at the release velocity a whole quantum before it (at 10 Hz the coast
    used to be a 0.1 s period, at 50 Hz 0.08 s: a windup farther back than at 15 Hz)."""
    from bicoord_drake.models.viperx import aloha_viperx
    from bicoord_drake.planning.throwing import throw_release
    from bicoord_drake.planning.timing import SEGMENT_QUANTUM, JointLimits

    limits = JointLimits.from_embodiment(aloha_viperx(), arms=1)
    rng = np.random.default_rng(50 + seed)
    mid = (limits.lower + limits.upper) / 2
    q_rel = mid + rng.normal(0, 0.05, limits.n)
    v = rng.normal(0, 0.6, limits.n)
    q_wind = q_rel - 0.4 * v
    plans = {
        hz: throw_release(
            q_wind, q_rel, limits, 1.0 / hz, qd_release=v, coast=(1, 3), grid=SEGMENT_QUANTUM
        )
        for hz in (10, 15, 30, 50)
    }
    reference = plans[15]
    for hz, plan in plans.items():
        dt = 1.0 / hz
        traj, i = plan.trajectory, plan.release_index
        assert np.allclose(traj.q[i], q_rel, atol=1e-9) and np.allclose(traj.qd[i], v, atol=1e-9)
        late = plan.release_time - reference.release_time
        assert -1e-9 <= late < dt - 1e-9
        # the whole quantum before the release is the coast: the hold reproduces v
        t = plan.release_time - SEGMENT_QUANTUM
        q_before, qd_before, _ = traj.at(t)
        assert np.allclose(qd_before, v, atol=1e-9)
        assert np.allclose(q_before, q_rel - SEGMENT_QUANTUM * v, atol=1e-9)
        # late by less than a period, then rounded up to one
        assert 0 <= traj.duration - reference.trajectory.duration < 2 * dt
        assert np.allclose(traj.qd[-1], 0.0, atol=1e-9)
        traj.check_limits(limits)
    assert plans[30].release_time == pytest.approx(reference.release_time, abs=1e-9)


def test_the_release_opens_the_fingers_the_same_way_in_time_at_every_rate():
    """The thrower's opening: light grip up to the release sample, the release clearance one
    quantum later (at 15 Hz the next sample, as before), then fully open at the fingers' rate;
    at 50 Hz the same ramp sampled every 20 ms."""
    from bicoord_drake.planning.skills.toss import release_openings
    from bicoord_drake.planning.timing import SEGMENT_QUANTUM

    soft, gap, rate = 0.2, 0.3, 1.5
    at_15 = release_openings(20, 5, soft, gap, rate, SEGMENT_QUANTUM)
    assert np.all(at_15[:6] == soft) and at_15[6] == gap
    assert np.allclose(np.diff(at_15[6:]), np.minimum(rate * SEGMENT_QUANTUM, 1.0 - at_15[6:-1]))
    for hz in (10, 30, 50):
        dt = 1.0 / hz
        openings = release_openings(int(3 * hz), 7, soft, gap, rate, dt)
        times = (np.arange(len(openings)) - 7) * dt
        expected = np.interp(times, (np.arange(20) - 5) * SEGMENT_QUANTUM, at_15)
        inside = times <= 6 * SEGMENT_QUANTUM  # before the cap at 1 (8 quanta)
        assert np.allclose(openings[inside], expected[inside], atol=1e-12)
        assert openings.max() == 1.0

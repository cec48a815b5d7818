"""Overlapping phases: a leaving arm's way back slowed after the shared zone (slowed_after,
leave_as_arrives)."""

from types import SimpleNamespace

import numpy as np
import pytest

import bicoord_drake.tasks.clean_table as ct
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills import (
    ArmPlan,
    SkillContext,
    arrive_as_leaves,
    first_step_in_zone,
    leave_as_arrives,
    periods,
    retreat,
    slowed_after,
    split_at,
)
from tests.planning.bins import to_bin

RADIUS = 0.12
LAG = 0.2
#: What slowed_after needs of a context: the 15 Hz grid.
CTX15 = SimpleNamespace(steps=lambda seconds: periods(seconds, 1 / 15))


def _plan(n=30):
    t = np.linspace(0.0, 1.0, n)
    s = t * t * (3 - 2 * t)  # rest to rest
    q = np.column_stack([0.8 * s, -0.4 * s])
    opening = np.where(np.arange(n) < 20, 0.0, 1.0)
    return ArmPlan("left", q, opening, [(20, "detach", "cube")], "p")


def test_slowed_after_keeps_the_head_and_the_path_and_only_slows_the_tail():
    plan = _plan()
    slow = slowed_after(CTX15, plan, 10, 61)
    assert slow.num_steps == 61
    np.testing.assert_array_equal(slow.q[:11], plan.q[:11])  # unchanged up to the start
    np.testing.assert_array_equal(slow.q[-1], plan.q[-1])  # the same goal, exactly
    # the same path: every sample lies on the plan's (straight here) joint line, in order
    ratio = slow.q[:, 1] / -0.4
    np.testing.assert_allclose(slow.q[:, 0], ratio * 0.8, atol=1e-12)
    assert np.all(np.diff(slow.q[:, 0]) >= -1e-12)
    # never faster than the plan's own fastest step, and the speed blends down (no jump)
    v_old, v_new = np.diff(plan.q[:, 0]), np.diff(slow.q[:, 0])
    assert v_new.max() <= v_old.max() + 1e-12
    assert np.max(np.abs(np.diff(v_new))) <= np.max(np.abs(np.diff(v_old))) + 1e-12
    # the detach event and the gripper keep their place along the motion
    ((i, kind, name),) = slow.events
    assert (kind, name) == ("detach", "cube") and slow.q[i, 0] >= plan.q[20, 0] - 1e-12
    assert slow.opening[i] == 1.0 and slow.opening[i - 1] < 1.0


def test_slowed_after_leaves_a_long_enough_plan_alone():
    plan = _plan()
    assert slowed_after(CTX15, plan, 10, 30) is plan
    assert slowed_after(CTX15, plan, 29, 50) is plan


def test_leave_as_arrives_times_the_arrival_and_ends_the_leave_with_it():
    ctx = SkillContext(PlanningModel(ct.CleanTable().sample_scene(0)))
    to_bin(ctx, "right", 0.03)
    to_bin(ctx, "left", -0.14)
    leave = retreat(ctx, "right")
    arrive = to_bin(ctx, "left", -0.03)
    timed = arrive_as_leaves(ctx, leave, arrive, ct.BIN_XY, RADIUS, lag=LAG)
    motion = leave_as_arrives(ctx, leave, arrive, ct.BIN_XY, RADIUS, lag=LAG)
    left, right = ctx.model.side_slice("left"), ctx.model.side_slice("right")
    # the arriver's timing is arrive_as_leaves'; the motion is no longer
    np.testing.assert_array_equal(motion.q[:, left], timed.q[:, left])
    assert motion.num_steps == timed.num_steps
    # the leaver is unchanged until it is out of the zone, then still moving at the end
    out = first_step_in_zone(ctx, leave, ct.BIN_XY, RADIUS, inside=False)
    np.testing.assert_array_equal(motion.q[: out + 1, right], leave.q[: out + 1])
    assert np.any(motion.q[-2, right] != motion.q[-1, right])
    np.testing.assert_array_equal(motion.q[-1, right], leave.q[-1])
    with pytest.raises(ValueError, match="both the right arm"):
        leave_as_arrives(ctx, leave, leave, ct.BIN_XY, RADIUS)


def test_split_at_cuts_a_plan_into_two_that_chain_back_to_it():
    plan = _plan()
    head, tail = split_at(plan, 12)
    assert head.num_steps == 13 and tail.num_steps == 18
    np.testing.assert_array_equal(tail.q[0], head.q[-1])  # the tail starts where the head ends
    again = head.then(tail)
    np.testing.assert_array_equal(again.q, plan.q)
    np.testing.assert_array_equal(again.opening, plan.opening)
    assert head.events == [] and tail.events == [(8, "detach", "cube")]
    assert again.events == plan.events
    # a cut before the first step moves to it; one at or past the end leaves the whole plan
    # as the head and its last sample as the tail
    assert split_at(plan, 0)[0].num_steps == 2
    head, tail = split_at(plan, 99)
    assert head.num_steps == 30 and tail.num_steps == 1
    np.testing.assert_array_equal(tail.q[0], plan.q[-1])

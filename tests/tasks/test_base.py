"""How experts are driven below 15 Hz: the planning grid, every k-th sample executed, the anchor."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.models.layout import ActionLayout
from bicoord_drake.planning.skills import Motion
from bicoord_drake.tasks.base import WorldView, anchored, execute_every, expert_actions

LAYOUT = ActionLayout(6)
GRIPPERS = LAYOUT.gripper_indices  # [6, 13]


def samples(n: int, gripper: list[float] | None = None) -> list[np.ndarray]:
    """n actions; joint entries count the sample, the grippers follow `gripper` (default 1)."""
    out = []
    for i in range(n):
        a = np.full(LAYOUT.action_size, float(i))
        a[GRIPPERS] = 1.0 if gripper is None else gripper[i]
        out.append(a)
    return out


def indices(actions) -> list[int]:
    return [int(a[0]) for a in actions]


def view_at(rate: float) -> WorldView:
    station = SimpleNamespace(
        config=StationConfig(control_rate=rate, render=False), layout=LAYOUT, scene=None
    )
    return WorldView(SimpleNamespace(station=station))


class Expert:
    """A task whose expert yields `plan` (a function of the view, for anchored plans)."""

    def __init__(self, plan):
        self.plan = plan

    def expert(self, scene, view):
        yield from self.plan(view)


def test_execute_every_is_the_identity_at_one():
    plan = samples(5, [1.0, 0.2, 1.0, 0.2, 1.0])
    assert all(a is b for a, b in zip(execute_every(iter(plan), 1, GRIPPERS), plan, strict=True))


@pytest.mark.parametrize(
    "n,k,expected",
    [
        (8, 2, [1, 3, 5, 7]),
        (7, 2, [1, 3, 5, 6]),  # the last sample skipped: commanded at the end
        (1, 2, [0]),
        (0, 2, []),
        (9, 3, [2, 5, 8]),
        (8, 3, [2, 5, 7]),
        (10, 3, [2, 5, 8, 9]),
    ],
)
def test_execute_every_takes_every_kth_sample_on_time_and_the_last(n, k, expected):
    plan = samples(n)
    got = list(execute_every(iter(plan), k, GRIPPERS))
    assert indices(got) == expected
    for a in got:  # unchanged samples
        assert np.array_equal(a, plan[int(a[0])])


def test_execute_every_keeps_monotone_gripper_ramps_as_sampled():
    ramp = [1.0, 1.0, 0.8, 0.6, 0.4, 0.2, 0.1, 0.1, 0.1]
    plan = samples(len(ramp), ramp)
    got = list(execute_every(iter(plan), 2, GRIPPERS))
    assert indices(got) == [1, 3, 5, 7, 8]
    assert [a[GRIPPERS[0]] for a in got] == [ramp[i] for i in (1, 3, 5, 7, 8)]


def test_execute_every_does_not_lose_a_gripper_pulse_on_a_skipped_sample():
    # the left gripper opens on sample 2 only (skipped at k = 2); the right stays put
    left = [0.2, 0.2, 0.9, 0.2, 0.2, 0.2, 0.2, 0.2]
    plan = samples(len(left), left)
    for a in plan:
        a[GRIPPERS[1]] = 0.5
    got = list(execute_every(iter(plan), 2, GRIPPERS))
    assert indices(got) == [1, 3, 5, 7]
    assert [a[GRIPPERS[0]] for a in got] == [0.2, 0.9, 0.2, 0.2]
    assert all(a[GRIPPERS[1]] == 0.5 for a in got)
    # the arm joints stay the executed sample's
    assert np.array_equal(np.delete(got[1], GRIPPERS), np.delete(plan[3], GRIPPERS))
    assert not any(np.shares_memory(got[1], p) for p in plan)  # the plan is not modified
    assert plan[3][GRIPPERS[0]] == 0.2


def test_execute_every_ends_on_the_plans_last_action():
    # a pulse in the last, partial window: commanded, then the plan's last action
    for n in (6, 5):  # the last sample executed, skipped
        plan = samples(n, [0.2, 0.2, 0.2, 0.9, 0.2, 0.2][:n])
        got = list(execute_every(iter(plan), 3, GRIPPERS))
        assert indices(got) == [2, n - 1, n - 1]
        assert got[1][GRIPPERS[0]] == 0.9 and got[-1] is plan[-1]


def test_expert_actions_at_15_hz_and_faster_pass_the_experts_actions():
    for rate in (15.0, 30.0, 50.0):
        plan = samples(6)
        view = view_at(rate)
        got = list(expert_actions(Expert(lambda v, plan=plan: iter(plan)), None, view))
        assert view.substeps == 1 and view.plan_samples == 6
        assert all(a is b for a, b in zip(got, plan, strict=True))


def test_expert_actions_at_10_hz_execute_every_second_sample():
    plan = samples(9, [1.0, 1.0, 1.0, 1.0, 0.3, 1.0, 1.0, 1.0, 1.0])
    view = view_at(10.0)
    got = list(expert_actions(Expert(lambda v: iter(plan)), None, view))
    assert view.substeps == 2 and view.plan_samples == 9
    assert indices(got) == [1, 3, 5, 7, 8]
    assert got[2][GRIPPERS[0]] == 0.3  # the close on skipped sample 4 is commanded


def test_the_planning_model_samples_at_the_planning_period():
    assert view_at(10.0).config.control_period / view_at(10.0).substeps == pytest.approx(0.05)
    assert view_at(5.0).substeps == 3
    assert view_at(15.0).substeps == 1


def anchored_motion(anchor: int, steps: int = 8) -> Motion:
    q = np.arange(steps + 1, dtype=float)[:, None] * np.ones(12) + 100.0
    q[:2] = q[0]  # at rest at its start
    openings = np.full((steps + 1, 2), 0.5)
    motion = Motion(q, openings, [(anchor, "left", "detach", "cube")], "throw")
    motion.anchor = anchor
    return motion


@pytest.mark.parametrize("k", [1, 2, 3])
@pytest.mark.parametrize("before", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("anchor", [1, 2, 5])
def test_anchored_puts_the_anchor_on_an_executed_sample(k, before, anchor):
    motion = anchored_motion(anchor)
    held = anchored(motion, before, k)
    delay = held.num_steps - motion.num_steps
    assert 0 <= delay < k
    assert (before + held.anchor - 1) % k == k - 1
    assert held.anchor == anchor + delay and held.events[0][0] == anchor + delay
    assert np.array_equal(held.q[held.anchor], motion.q[anchor])
    assert np.array_equal(held.q[: delay + 1], np.repeat(motion.q[:1], delay + 1, 0))


def test_an_anchored_motion_through_expert_actions_executes_its_anchor():
    motion = anchored_motion(5)

    def plan(view):
        for before in range(3):  # some samples, then the throw (as follow runs it)
            yield from samples(before + 1)
            yield from anchored(motion, view.plan_samples, view.substeps).actions()

    view = view_at(10.0)
    got = list(expert_actions(Expert(plan), None, view))
    throws = [a for a in got if a[0] >= 100.0]
    assert sum(np.array_equal(a, motion.actions()[4]) for a in throws) == 3  # every time


def test_motion_then_and_delayed_keep_the_anchor():
    a, b = anchored_motion(3), anchored_motion(2)
    b.q = b.q + (a.q[-1] - b.q[0])
    a_only = Motion(a.q, a.openings)
    assert a_only.then(b).anchor == a.num_steps - 1 + 2
    assert a.then(b).anchor == 3
    assert a_only.delayed(1).anchor is None and a_only.then(Motion(b.q, b.openings)).anchor is None
    assert a.delayed(2).anchor == 5 and a.delayed(0) is a

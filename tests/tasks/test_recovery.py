"""Drop recovery (issue #54, item 2; bicoord_drake.tasks.recovery): what the expert takes for
fallen, the frame a fallen cube is picked up in, and a dropped jigsaw cube picked up again in
physics (kept, its recovery row, the replay reproducing it).

The detection tests plan on a jigsaw station without stepping it; the episode test runs
jigsaw seed 0 with ``disturb=drop`` (a clean traced run, the disturbed run, the replay)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.all import RigidTransform, RollPitchYaw

from bicoord_drake.config import StationConfig
from bicoord_drake.data.episode import read_episode
from bicoord_drake.episode_setup import EpisodeSetup, assemble
from bicoord_drake.models.layout import ActionLayout
from bicoord_drake.models.shapes import BoxShape, CylinderShape
from bicoord_drake.planning.skills import merge, pick, place
from bicoord_drake.runner import generate as gen
from bicoord_drake.sim import disturbances as dist
from bicoord_drake.tasks.recovery import (
    KNOCKED_DISTANCE,
    MISSED_ON_TABLE,
    MISSED_PLACEMENT,
    carried_by,
    fallen,
    knocked,
    missed_distance,
    reach,
    resting_frame,
)

STATION = StationConfig(render=False)


@pytest.fixture
def planned():
    """jigsaw seed 0: the left hand picks spare_left_1 (held at the motion's end), the right
    hand picks spare_right_1 and places it 10 cm to its left (set down in the motion)."""
    episode = assemble(EpisodeSetup(task="jigsaw", seed=0, split="seen", station=STATION))
    ctx = episode.task.skill_context(episode.view)
    left = pick(ctx, "left", "spare_left_1")
    X = ctx.model.object_pose("spare_right_1")
    goal = RigidTransform(X.rotation(), X.translation() + [-0.10, 0.0, 0.0])
    right = pick(ctx, "right", "spare_right_1").then(place(ctx, "right", goal))
    motion = merge(ctx, left, right)
    return ctx, motion, goal


def as_measured(ctx, **moved: RigidTransform) -> dict[str, RigidTransform]:
    """The poses a measurement at the motion's end gives when everything went to plan, with
    `moved` objects elsewhere."""
    poses = {o.name: ctx.model.object_pose(o.name) for o in ctx.model.scene.objects}
    for side, held in ctx.model.held.items():
        poses[held.name] = ctx.model.held_pose(side, ctx.q)
    return {**poses, **moved}


def test_what_the_motion_carries(planned):
    ctx, motion, goal = planned
    held, placed = carried_by(ctx, motion)
    assert held == {"spare_left_1": "left"}
    assert placed == {"spare_right_1": "right"}
    assert ctx.placements["spare_right_1"].X_WO_goal.IsExactlyEqualTo(goal)


def test_nothing_fell_when_everything_went_to_plan(planned):
    ctx, motion, _ = planned
    held, placed = carried_by(ctx, motion)
    measured = as_measured(ctx)
    assert fallen(ctx, measured, held, placed, dict(ctx.placements)) == ([], [])
    # a placement landing a few mm off its goal, a grasp settled by a few mm: still fine
    X = measured["spare_right_1"]
    near = RigidTransform(X.rotation(), X.translation() + [0.005, -0.004, 0.0])
    H = measured["spare_left_1"]
    settled = RigidTransform(H.rotation(), H.translation() + [0.0, 0.0, -0.004])
    measured = as_measured(ctx, spare_right_1=near, spare_left_1=settled)
    assert fallen(ctx, measured, held, placed, dict(ctx.placements)) == ([], [])


def test_a_cube_out_of_its_hand_and_a_missed_placement_are_fallen(planned):
    ctx, motion, goal = planned
    held, placed = carried_by(ctx, motion)
    on_table = RigidTransform([-0.25, -0.1, 0.77])
    far = missed_distance(ctx.model.object("spare_right_1").shape, goal)
    assert far == MISSED_ON_TABLE  # set down on the table top
    off_goal = RigidTransform(goal.translation() + [far + 0.01, 0.0, 0.0])
    measured = as_measured(ctx, spare_left_1=on_table, spare_right_1=off_goal)
    lost, missed = fallen(ctx, measured, held, placed, dict(ctx.placements))
    assert lost == [("left", "spare_left_1")]
    assert missed == [("right", "spare_right_1")]
    # a few mm short of that: where it was put, not fallen
    tipped = RigidTransform(goal.translation() + [far - 0.005, 0.0, 0.0])
    measured = as_measured(ctx, spare_right_1=tipped)
    assert fallen(ctx, measured, held, placed, dict(ctx.placements)) == ([], [])


def test_a_cube_set_down_earlier_and_moved_since_is_knocked(planned):
    """What a motion sets down on the table top is watched from then on (where it came to
    rest): moved more than KNOCKED_DISTANCE by the next boundary, with no plan handling it,
    it was knocked; a few mm is not; once a plan picks it up it is no longer watched."""
    ctx, motion, goal = planned
    held, placed = carried_by(ctx, motion)
    measured = as_measured(ctx)
    assert knocked(ctx, measured, motion, placed, dict(ctx.placements)) == []
    side, placement, X_rest = ctx.settled["spare_right_1"]
    assert side == "right" and placement.X_WO_goal.IsExactlyEqualTo(goal)
    assert "spare_left_1" not in ctx.settled  # held, not set down
    still = merge(ctx, None, None)  # the next motion handles neither cube

    def moved_by(dx: float) -> dict[str, RigidTransform]:
        X = RigidTransform(X_rest.rotation(), X_rest.translation() + [dx, 0.0, 0.0])
        return as_measured(ctx, spare_right_1=X)

    assert knocked(ctx, moved_by(0.005), still, {}, {}) == []
    assert knocked(ctx, moved_by(KNOCKED_DISTANCE + 0.01), still, {}, {}) == [
        ("right", "spare_right_1")
    ]
    again = pick(ctx, "right", "spare_right_1")  # picked up: no longer watched
    assert knocked(ctx, moved_by(0.1), merge(ctx, None, again), {}, {}) == []
    assert "spare_right_1" not in ctx.settled


def test_off_the_table_a_placement_may_land_farther_from_its_goal():
    pen = CylinderShape(radius=0.005, length=0.12)
    in_holder = RigidTransform([0.0, 0.0, 0.87])  # let go above a holder's bottom
    assert missed_distance(pen, in_holder) == pytest.approx(MISSED_PLACEMENT + reach(pen))
    assert reach(pen) == pytest.approx(np.hypot(0.06, 0.005), abs=1e-3)
    on_table = RigidTransform([0.0, 0.0, 0.75 + 0.06])  # standing on the table top
    assert missed_distance(pen, on_table) == MISSED_ON_TABLE


def test_a_cube_on_its_side_is_picked_up_as_if_upright():
    cube = BoxShape(size=(0.04, 0.04, 0.04))
    for rpy in [(math.pi / 2, 0, 0.3), (0, -math.pi / 2, 1.0), (math.pi, 0, 0), (0.1, 0, 0)]:
        X = RigidTransform(RollPitchYaw(*rpy), [0.1, 0.0, 0.77])
        frame = resting_frame(cube, X)
        R = X.rotation() if frame is None else X.rotation() @ frame.rotation()
        assert R.matrix()[2, 2] > math.cos(0.11), rpy  # the model's z axis up
        if frame is not None:
            assert np.allclose(frame.translation(), 0)
    assert resting_frame(cube, RigidTransform([0.1, 0, 0.77])) is None  # already upright
    # a long box on its side: its square end faces swap, so it lies upright in another frame;
    # on its end it does not (no symmetry turns its long axis down)
    bar = BoxShape(size=(0.08, 0.02, 0.02))
    on_side = RigidTransform(RollPitchYaw(math.pi / 2, 0, 0), [0, 0, 0.77])
    assert (on_side.rotation() @ resting_frame(bar, on_side).rotation()).matrix()[2, 2] > 0.99
    on_end = RigidTransform(RollPitchYaw(0, math.pi / 2, 0), [0, 0, 0.77])
    assert resting_frame(bar, on_end) is None
    pen = CylinderShape(radius=0.005, length=0.12)
    assert resting_frame(pen, on_side) is None  # no box: nothing to re-read


def test_a_dropped_cube_is_picked_up_again_recorded_and_replayed(tmp_path):
    """jigsaw seed 0 with ``disturb=drop``: the right grip loosens as it lifts its first
    spare off the table (drops start at most DROP_HEIGHT up); at the next plan boundary the
    expert finds the cube on the table, picks it up again and fills the grid; the recovery
    row spans the drop to the end of the new pick, and the replay reproduces every stage."""
    root, episode, drop = dropped("jigsaw", tmp_path / "a")
    assert drop.kind == "drop" and drop.side == "right"
    ((start, end, subgoal, *_),) = episode.recovery
    assert start == drop.step < drop.end < end < episode.length
    assert subgoal == f"recover from the drop of {drop.body!r} (right gripper)"
    cube = episode.objects[drop.body]
    assert cube[drop.end + 5, 2] < cube[0, 2] + 0.003  # it fell back onto the table
    assert cube[end - 1, 2] > cube[drop.end + 5, 2] + 0.05  # and is lifted again
    grip = ActionLayout(6).gripper("right")
    executed = episode.executed_action[:, grip]
    assert executed[drop.end - 1] == pytest.approx(1.0)  # the grip opened
    assert np.all(episode.joint_action[drop.step : drop.end, grip] < 0.5)  # the label: closed
    replayed = replay(root, "jigsaw", tmp_path / "replay")
    assert replayed.success and replayed.disturbances


def test_a_dropped_mic_is_picked_up_again_and_handed_over(tmp_path):
    """exchange_mics seed 0 with ``disturb=drop`` (a handover task, where jigsaw is a
    pick-and-place one): a mic slips out of the hand that carries it to the meeting point; the
    expert picks it up again, the handover and the rest of the task follow, and the replay
    reproduces every stage with the drop applied again."""
    root, episode, drop = dropped("exchange_mics", tmp_path / "a")
    ((start, end, subgoal, *_),) = episode.recovery
    assert start == drop.step < drop.end < end < episode.length
    assert subgoal.startswith(f"recover from the drop of {drop.body!r}")
    mic = episode.objects[drop.body]
    assert mic[drop.end + 5, 2] < mic[0, 2] + 0.003  # it fell back onto the table
    assert mic[end - 1, 2] > mic[drop.end + 5, 2] + 0.03  # and is lifted again
    replayed = replay(root, "exchange_mics", tmp_path / "replay")
    assert replayed.success and replayed.disturbances


def replay(root, task: str, out):
    """The replay of the one episode under `root` (``scripts/evaluate.py --policy replay``,
    its recorded disturbances applied again): its rollout record."""
    from bicoord_drake.runner.evaluate import EvaluateConfig, evaluate

    config = EvaluateConfig(
        task=task, policy="replay", episodes=1, data=str(root), render=False, workers=1,
        out=str(out),
    )  # fmt: skip
    return evaluate(config).rollouts[0]


def dropped(task: str, out):
    """Seed 0 of `task` generated with ``disturb=drop`` into `out` (it must be kept): the
    dataset's root, the episode and its one disturbance."""
    config = gen.GenerateConfig(
        task=task, seed=0, episodes=1, max_tries=1, render=False, disturb="drop",
        out=str(out), workers=1,
    )  # fmt: skip
    summary = gen.generate(config)
    assert summary.kept == 1, [f.reason for f in summary.failures]
    episode = read_episode(summary.root / "data" / "episode0.hdf5", images=False)
    (drop,) = dist.from_records(episode.disturbances)
    return summary.root, episode, drop

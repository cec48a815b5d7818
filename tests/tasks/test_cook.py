"""cook: seeded scenes, stage definitions, the shake predicate, and (slow) the expert in physics."""

from dataclasses import replace

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.tasks import get_task


@pytest.fixture(scope="module")
def cook():
    import bicoord_drake.tasks.cook as module

    return module


@pytest.fixture(scope="module")
def task():
    return get_task("cook")


def test_scene_holds_the_task_objects_in_their_ranges(cook, task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == {*cook.ROLLS, "skillet"}
    assert scene.object("plate").fixed and scene.object("stove").fixed
    assert not scene.object("stove").collide
    for seed in range(20):
        s = task.sample_scene(seed)
        rolls = [np.array(s.object(r).pose.xyz) for r in cook.ROLLS]
        for p in rolls:
            assert -0.28 <= p[0] <= -0.20 and -0.20 <= p[1] <= 0.05
        assert abs(rolls[0][1] - rolls[1][1]) >= 0.09
        x, y, _ = s.object("skillet").pose.xyz
        assert 0.15 <= x <= 0.25 and -0.15 <= y <= -0.05
        assert s.draws["skillet_xy"] == [round(x, 6), round(y, 6)]
        plate, skillet = s.object("plate"), s.object("skillet")
        gap = np.linalg.norm(np.subtract(plate.pose.xyz, skillet.pose.xyz)[:2])
        assert gap > plate.shape.radius + skillet.shape.radius  # they never overlap


def test_the_stove_is_the_references_red_square(cook, task):
    stove = task.sample_scene(4).object("stove")
    assert stove.pose.xyz[:2] == pytest.approx((-0.055, -0.055))
    assert cook.STOVE_XY == (-0.055, -0.055)
    assert stove.color[0] > 0.8 and stove.color[1] < 0.2  # red


def test_stages_follow_the_spec_table(task):
    stages = task.stages(task.sample_scene(0))
    assert [s.subgoal for s in stages] == [
        "pick bread and skillet",
        "throw the bread into the skillet",
        "cook",
        "serve",
    ]
    assert "stand off" in stages[2].left and "not home" in stages[2].left
    assert "stand-off" in stages[3].left


def test_initial_state_scores_nothing(task):
    scene = task.sample_scene(3)
    stages = task.stages(scene)
    assert [s.score for s in stages] == [0.0, 0.5, 0.0, 0.5]
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert [s.kind for s in stages] == ["transient", "transient", "transient", "persistent"]
    values = StageMonitor(stages).evaluate(WorldState.initial(scene))
    assert list(values) == [0, 0, 0, 0]


def _moved(scene, state, **poses):
    """`state` with objects moved (xyz only, orientation kept)."""
    new = dict(state.object_poses)
    for name, xyz in poses.items():
        new[name] = np.r_[xyz, new[name][3:]]
    return WorldState.initial(scene, object_poses=new)


def test_rolls_in_the_lifted_skillet_and_the_shake_are_recognized(cook, task):
    scene = task.sample_scene(0)
    stages = task.stages(scene)
    start = WorldState.initial(scene)
    pan = np.array([0.06, -0.05, 0.87])

    def at(x: float, step: int):
        p = pan + [x, 0, 0]
        s = _moved(
            scene, start, skillet=p, roll_0=p + [0.02, 0, 0.035], roll_1=p + [-0.02, 0, 0.035]
        )
        return WorldState.initial(scene, object_poses=s.object_poses, step=step)

    in_pan, shaken = stages[1].predicate, stages[2].predicate
    assert in_pan(at(0.0, 0)) == 1.0
    a = cook.SHAKE_AMPLITUDE
    path = [0, a, -a, a, -a, 0]
    results = [shaken(at(x, k)) for k, x in enumerate(path)]
    assert results[:4] == [False] * 4 and results[-1]  # three full swings: done
    # A new rollout starts the count afresh after the monitor's reset, and only then.
    with pytest.raises(ValueError, match="reset"):
        shaken(at(0.0, 0))
    shaken.reset()
    assert not shaken(at(0.0, 0))
    # One roll on the table (a fresh episode's stages): not in the pan, no shake counted.
    half = _moved(scene, at(0.0, 0), roll_1=[0.3, 0.0, 0.77])
    assert task.stages(scene)[1].predicate(half) == 0.5


def test_each_roll_in_the_skillet_is_latched(task):
    """Stage 2 gives 0.25 a roll, each latched the first time it is in the skillet (TASKS.md):
    the first roll bouncing out while the second lands keeps its credit."""
    scene = task.sample_scene(0)
    pan = np.array([-0.055, -0.055, 0.87])
    inside_pan = pan + [0.0, 0.0, 0.035]
    table = [0.3, 0.0, 0.77]
    throw = task.stages(scene)[1].predicate
    start = WorldState.initial(scene)
    first = _moved(scene, start, skillet=pan, roll_0=inside_pan, roll_1=table)
    second = _moved(scene, start, skillet=pan, roll_0=table, roll_1=inside_pan)
    assert throw(first) == 0.5
    assert throw(second) == 1.0  # roll_0 out again: still latched


def test_rolls_on_the_plate_are_served(task):
    scene = task.sample_scene(0)
    plate = np.array(scene.object("plate").pose.xyz)
    state = _moved(
        scene,
        WorldState.initial(scene),
        roll_0=plate + [0.03, 0, 0.026],
        roll_1=plate + [-0.03, 0, 0.026],
    )
    serve = task.stages(scene)[3].predicate
    at = [replace(state, time=k / 15, step=k) for k in range(6)]
    assert [serve(s) for s in at] == [0.0] * 5 + [1.0]  # at rest for 0.3 s


def test_rolls_on_the_table_beside_the_skillet_are_not_in_it(task):
    scene = task.sample_scene(0)
    pan = np.array(scene.object("skillet").pose.xyz)
    # 12.7 cm from the pan's axis, inside the corner of its 20 cm bounding square
    corner = [0.09, 0.09, 0.02]
    state = _moved(
        scene,
        WorldState.initial(scene),
        roll_0=pan + corner,
        roll_1=pan + np.array(corner) * [-1, 1, 1],
    )
    assert task.stages(scene)[1].predicate(state) == 0.0


# -------------------------------------------------------------------- planning
@pytest.mark.slow  # planning only, but 145 s (the second toss's search)
def test_the_expert_plans_short_throws_over_the_stove_and_a_stand_off(cook, task):
    """Planning only (seed 0): each toss leaves the hand at most 0.15 m above the rim with the
    TCP within 0.06 m of the pan's centre at the catch, over the stove, and the pan arrives
    in the same motion (it moves during the throw and is in place by the release); in the
    shake the left arm goes to a stand-off just clear of it, not home, and stays there
    while the serve plans."""
    from bicoord_drake.planning.model import PlanningModel
    from bicoord_drake.planning.skills import SkillContext, merge, pick

    scene = task.sample_scene(0)
    ctx = SkillContext(PlanningModel(scene))
    merge(
        ctx,
        pick(ctx, "left", cook.ROLLS[0], kinds=["top"]),
        pick(ctx, "right", "skillet", kinds=["rim"], lift=0.10),
    )
    throws = [cook._toss(ctx, list(cook.FIRST_AIMS))]
    cook._park(ctx, [cook.ROLLS[0]])
    cook._pick_making_room(ctx, cook.ROLLS[1])
    throws.append(cook._toss(ctx, [(0.0, -0.02)]))
    for motion in throws:
        info = motion.info
        pan = info["bowl_pose"].translation()
        assert info["release_above_rim"] <= cook.SHORT_THROW_HEIGHT
        assert info["release_tcp_offset"] <= cook.SHORT_THROW_REACH
        assert np.hypot(*(pan[:2] - cook.STOVE_XY)) <= 0.03  # over the 10 cm stove
        i = info["release_index"]
        right = motion.q[:, ctx.model.side_slice("right")]
        assert np.any(np.abs(np.diff(right[: i + 1], axis=0)) > 1e-6)  # moving to catch
        assert info["catch_arrival_index"] <= i + 1
    cook._park(ctx, list(cook.ROLLS))
    cook._shake_standing_off(ctx)
    left = ctx.model.side_slice("left")
    left_q = ctx.q[left].copy()
    assert not np.allclose(left_q, ctx.model.home[left])
    tcp = ctx.model.tcp_pose(ctx.q, "left").translation()
    pan = ctx.model.held_pose("right", ctx.q).translation()
    clear = cook.SKILLET.radius + cook.SHAKE_AMPLITUDE
    assert clear < pan[0] - tcp[0] <= clear + cook.STANDOFF_GAP + 1e-6
    serve = cook._serve_clear(ctx, np.array(scene.object("plate").pose.xyz))
    assert np.allclose(serve.q[:, left], left_q)  # stays at the stand-off


# -------------------------------------------------------------------- physics (slow)
def _kept_episode(task, seed: int, tmp_path):
    """The expert's episode of `seed` in physics (no cameras), kept, saved and read back."""
    from bicoord_drake.data.episode import EpisodeLayout, EpisodeMeta, read_episode, save_episode

    result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
    assert result.success, result.reason
    layout = EpisodeLayout(tmp_path, "cook", "default")
    meta = EpisodeMeta(
        task="cook",
        seed=seed,
        instruction=result.instruction,
        embodiment="aloha_viperx",
        success=True,
        object_count=4,
        scene=result.scene,
    )
    save_episode(layout, 0, result.recorder, result.rows, meta, video=False)
    return read_episode(layout.episode(0), images=False)


@pytest.mark.slow
def test_expert_throws_each_roll_in_free_flight(cook, task, tmp_path):
    episode = _kept_episode(task, 0, tmp_path)
    tcps = np.stack([episode.left_endpose[:, :3], episode.right_endpose[:, :3]], axis=1)
    for roll in cook.ROLLS:  # 1 to 4 frames at 15 Hz in the 28 episodes of the benchmark
        assert len(cook.free_flight_frames(episode.objects, tcps, roll)) >= 1, roll


@pytest.mark.slow
@pytest.mark.skip(
    reason="short throws (2026-12-06): no seed of 0-29 stacks the second roll any more (seed 17 "
    "is kept without a set-down); the set-down branch needs a new seed that reaches it"
)
def test_a_stacked_roll_is_thrown_again_after_the_pan_is_set_down(task, tmp_path):
    """Seed 17: the second roll lands on the first and the thrower's fingers cannot reach it
    past the catcher's hand; the catcher sets the skillet down, lets go, lifts it again, and the
    roll is thrown again (the episode failed at the throw stage before)."""
    from bicoord_drake.models.scene import TABLE_TOP

    z = _kept_episode(task, 17, tmp_path).objects["skillet"][:, 2] - TABLE_TOP
    lifted = np.flatnonzero(z > 0.05)
    down = np.flatnonzero(z[lifted[0] :] < 0.025) + lifted[0]
    assert len(down), "the skillet never went back onto the table"
    assert np.any(z[down[-1] :] > 0.05), "the skillet was not lifted again"


@pytest.mark.slow
def test_expert_succeeds_on_at_least_90_percent_of_30_seeds(task):
    successes = sum(
        run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False))).success
        for seed in range(30)
    )
    assert successes >= 27


def test_a_roll_lying_on_the_other_roll_in_the_pan_is_not_in_it(cook, task):
    """The throw stage (and the expert's re-throw, which asks the same question) does not count
    a roll resting on the other one above the rim (seed 19's second roll)."""
    scene = task.sample_scene(0)
    stages = task.stages(scene)
    pan = np.array([0.06, -0.05, 0.87])
    floor = cook.SKILLET.wall
    low = pan + [-0.02, 0, floor + cook.ROLL_RADIUS]
    state = _moved(scene, WorldState.initial(scene), skillet=pan, roll_0=low, roll_1=low)
    assert stages[1].predicate(state) == 1.0  # both lying on the floor (overlap is no matter)
    piled = _moved(scene, state, roll_1=low + [0, 0, 2 * cook.ROLL_RADIUS])
    assert task.stages(scene)[1].predicate(piled) == 0.5  # a fresh episode: nothing latched
    assert not cook._in_pan("roll_1")(piled)


def test_a_roll_pinned_in_the_tipped_pan_is_found_for_another_tip(cook):
    """The serve tips again while a measured roll lies in the pan, tipped or not."""
    from pydrake.all import RigidTransform, RotationMatrix

    X_WP = RigidTransform(RotationMatrix.MakeYRotation(2.1), [-0.07, 0.05, 0.90])
    in_it = X_WP @ RigidTransform([0.03, 0.0, cook.SKILLET.wall + cook.ROLL_RADIUS])
    assert cook._lies_in_pan({"skillet": X_WP, "roll_0": in_it}, "roll_0")
    # Tipped back beside the plate: a roll on the plate, or on the table beside the pan.
    level = RigidTransform([-0.19, 0.04, 0.785])
    on_plate = RigidTransform([-0.03, 0.04, 0.796])
    beside = level @ RigidTransform([cook.SKILLET.radius + 0.01, 0.0, 0.03])
    for roll in (on_plate, beside):
        assert not cook._lies_in_pan({"skillet": level, "roll_0": roll}, "roll_0")


def test_the_serve_can_carry_the_pan_higher_over_the_plate(cook, task):
    """The serve's fallback (``_serve_toward(raised=)``, POUR_RAISES: a pan hanging 9 deg
    tilted in its grasp reached the plate with its low side, seed 16 randomized) carries the
    pan as it hangs with its bottom that much higher, then tips it and brings it back."""
    from bicoord_drake.planning.model import PlanningModel
    from bicoord_drake.planning.skills import SkillContext, pick

    scene = task.sample_scene(0)
    ctx = SkillContext(PlanningModel(scene))
    pick(ctx, "right", "skillet", kinds=["rim"], lift=0.10)
    q0 = ctx.q.copy()
    plate = np.array(scene.object("plate").pose.xyz)
    for raised in cook.POUR_RAISES:
        plan = None
        for d in cook.FAR_DIRECTIONS:
            ctx.q = q0.copy()
            args = (ctx, "right", plate, np.asarray(d), -0.075, cook.FAR_GRIP_ALIGNMENT)
            plan = plan or cook._serve_toward(*args, cook.FAR_POUR_ANGLES, [], raised)
        assert plan is not None, raised
        poses = [ctx.model.held_pose("right", np.r_[q0[:6], q6]) for q6 in plan.q]
        tilt = np.array([np.arccos(np.clip(X.rotation().col(2)[2], -1, 1)) for X in poses])
        assert max(tilt) > 2.0  # tipped, and back as it was over the plate:
        over = np.flatnonzero(np.abs(tilt[: np.argmax(tilt)] - tilt[-1]) < 1e-4)[-1]
        bottom = plate[2] + cook.PLATE.height + cook.POUR_HEIGHT + raised
        assert poses[over].translation()[2] == pytest.approx(bottom, abs=2e-3)
        assert poses[-1].translation() == pytest.approx(poses[over].translation(), abs=1e-3)

"""balance_roller: seeded scenes, stages on synthetic states, (slow) the expert."""

import math
from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.balance_roller as br
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from tests.stages.helpers import quat_about
from tests.tasks.helpers import after, quat_mul, state_with

SEED = 3
LEVEL = quat_about("y", math.pi / 2)  # the roller's axis along x
STILL = 17  # frames at 15 Hz: a little over br.STILL_FOR (1 s)


@pytest.fixture(scope="module")
def task():
    return br.BalanceRoller()


@pytest.fixture(scope="module")
def scene(task):
    return task.sample_scene(SEED)


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == {br.ROLLER, br.BLOCK}


@pytest.mark.parametrize("seed", range(25))
def test_draws_stay_in_the_reference_ranges(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    roller, block = scene.object(br.ROLLER), scene.object(br.BLOCK)
    assert br.LENGTH[0] <= d["roller_length"] <= br.LENGTH[1]
    assert br.DIAMETER[0] <= d["roller_diameter"] <= br.DIAMETER[1]
    assert roller.shape.length == d["roller_length"]
    assert roller.shape.radius == pytest.approx(d["roller_diameter"] / 2)
    x, y, z = roller.pose.xyz
    assert [x, y] == d["roller_xy"] and z == pytest.approx(TABLE_TOP + roller.shape.radius)
    assert br.ROLLER_X[0] <= x <= br.ROLLER_X[1] and br.ROLLER_Y[0] <= y <= br.ROLLER_Y[1]
    # lying along x
    assert roller.pose.rpy == pytest.approx((0.0, math.pi / 2, 0.0))
    bx, by = block.pose.xyz[:2]
    assert [bx, by] == d["block_xy"] and block.shape.size == (br.BLOCK_EDGE,) * 3
    assert all(br.BLOCK_XY[0] <= v <= br.BLOCK_XY[1] for v in (bx, by))
    assert by - y >= br.MIN_GAP_Y
    assert block.color == br.COLORS[d["color"]]


def test_initial_state_scores_nothing(task, scene):
    stages = task.stages(scene)
    assert [s.kind for s in stages] == ["transient", "persistent"]
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert list(StageMonitor(stages).evaluate(WorldState.initial(scene))) == [0, 0]


# ------------------------------------------------------------------ synthetic states
def _roller_at(scene, x, y, z, quat=LEVEL):
    return np.array([x, y, z, *quat])


def _radius(scene):
    return scene.object(br.ROLLER).shape.radius


def _on_block(scene, dx=0.0, dy=0.0, dz=0.0, quat=LEVEL):
    bx, by = scene.draws["block_xy"]
    z = TABLE_TOP + br.BLOCK_EDGE + _radius(scene) + dz
    return {br.ROLLER: _roller_at(scene, bx + dx, by + dy, z, quat)}


def test_lift_counts_held_by_both_high_enough_and_level(task, scene):
    lift = task.stages(scene)[0].predicate
    x, y = scene.draws["roller_xy"]
    up = {br.ROLLER: _roller_at(scene, x, y, TABLE_TOP + _radius(scene) + 0.07)}
    both = {br.ROLLER: {"left", "right"}}
    assert lift(state_with(scene, up, (0.0, 0.0), both))
    # one hand only (the other gripper open and off it)
    assert not lift(state_with(scene, up, (0.0, 1.0), {br.ROLLER: {"left"}}))
    # both touch it but one gripper is commanded open
    assert not lift(state_with(scene, up, (0.0, 1.0), both))
    # not high enough: bottom 4 cm above the table
    low = {br.ROLLER: _roller_at(scene, x, y, TABLE_TOP + _radius(scene) + 0.04)}
    assert not lift(state_with(scene, low, (0.0, 0.0), both))
    # held up steeply, one end high
    q = quat_about("y", math.pi / 2 - math.radians(25))
    steep = {br.ROLLER: _roller_at(scene, x, y, TABLE_TOP + 0.15, q)}
    assert not lift(state_with(scene, steep, (0.0, 0.0), both))


def test_balance_counts_released_on_the_block_for_one_second(task, scene):
    balanced = task.stages(scene)[1].predicate
    on = _on_block(scene)
    assert after(balanced, state_with(scene, on), frames=STILL)
    assert not after(balanced, state_with(scene, on), frames=12)  # only 0.73 s so far
    # off centre by 2 cm still counts; turned about its own axis still rests on it
    assert after(balanced, state_with(scene, _on_block(scene, dy=0.02)), frames=STILL)
    rolled = quat_about("x", 0.7)
    q = quat_mul(rolled, LEVEL)
    assert after(balanced, state_with(scene, _on_block(scene, quat=q)), frames=STILL)


def test_balance_is_not_fooled(task, scene):
    balanced = task.stages(scene)[1].predicate
    on = _on_block(scene)
    # still held (fingers on it, grippers closed), or one hand still touching it
    assert not after(
        balanced, state_with(scene, on, (0.0, 0.0), {br.ROLLER: {"left", "right"}}), frames=STILL
    )
    assert not after(
        balanced, state_with(scene, on, (1.0, 1.0), {br.ROLLER: {"right"}}), frames=STILL
    )
    # beside the block: 4 cm off in xy (rolled off the top would be on the table anyway)
    assert not after(balanced, state_with(scene, _on_block(scene, dy=0.04)), frames=STILL)
    # dropped on the table next to the block
    bx, by = scene.draws["block_xy"]
    dropped = {br.ROLLER: _roller_at(scene, bx, by - 0.06, TABLE_TOP + _radius(scene))}
    assert not after(balanced, state_with(scene, dropped), frames=STILL)
    # hovering above the block (held up)
    assert not after(balanced, state_with(scene, _on_block(scene, dz=0.02)), frames=STILL)
    # toppled onto one end against the block: steep
    q = quat_about("y", math.pi / 2 - math.radians(30))
    assert not after(balanced, state_with(scene, _on_block(scene, dz=0.05, quat=q)), frames=STILL)
    # still rolling
    moving = {br.ROLLER: np.array([0.0, 0.2, 0.0, 5.0, 0.0, 0.0])}
    assert not after(balanced, state_with(scene, on, velocities=moving), frames=STILL)
    # the block knocked over
    block = np.array([bx, by, TABLE_TOP + br.BLOCK_EDGE / 2, *quat_about("x", 0.6)])
    assert not after(balanced, state_with(scene, {**on, br.BLOCK: block}), frames=STILL)


def test_stages_count_only_in_order(task, scene):
    """The roller balanced on the block without the two-handed lift scores nothing."""
    monitor = StageMonitor(task.stages(scene))
    on = state_with(scene, _on_block(scene))
    for k in range(20):
        monitor.update(replace(on, step=k, time=k / 15))
    monitor.finish(replace(on, step=20, time=20 / 15))
    assert monitor.completed() == [False, False] and monitor.score() == 0.0


# ------------------------------------------------------------------ physics
@pytest.mark.slow
def test_expert_balances_the_roller_on_two_seeds(task):
    for seed in (0, 2):
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, (seed, result.reason)
        assert len(result.recorder) <= task.step_limit

"""build_tower_with_blocks: seeded scenes, stages on synthetic states, (slow) the expert."""

from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.build_tower_with_blocks as btb
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from tests.tasks.helpers import after, state_with

LARGE, MIDDLE, SMALL = btb.BLOCKS
SEED = 3


@pytest.fixture(scope="module")
def task():
    return btb.BuildTowerWithBlocks()


@pytest.fixture(scope="module")
def scene(task):
    return task.sample_scene(SEED)


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == set(btb.BLOCKS)
    assert scene.object("tower_spot").fixed and not scene.object("tower_spot").collide
    assert len({scene.object(n).color for n in btb.BLOCKS}) == 3


@pytest.mark.parametrize("seed", range(25))
def test_draws_stay_in_the_reference_ranges(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    for k, (lo, hi) in btb.SIZES.items():
        edge = scene.object(f"{k}_cube").shape.size
        assert lo <= d[f"{k}_edge"] <= hi and edge == (d[f"{k}_edge"],) * 3
        x, y = scene.object(f"{k}_cube").pose.xyz[:2]
        assert [x, y] == d[f"{k}_xy"]
        # each cube lies on its drawn side, never on the centre line
        assert np.sign(x) == (1 if d[f"{k}_side"] == "right" else -1)
        assert btb.X_RANGE[0] <= abs(x) <= btb.X_RANGE[1]
        assert btb.Y_RANGE[0] <= y <= btb.Y_RANGE[1]
        assert abs(d[f"{k}_yaw"]) <= btb.YAW
        assert np.hypot(x, y - d["spot_xy"][1]) >= btb.SPOT_GAP
    # one of the two smaller cubes on each side: each arm has one to pick
    assert {d["middle_side"], d["small_side"]} == {"left", "right"}
    assert d["spot_xy"][0] == 0.0 and btb.SPOT_Y[0] <= d["spot_xy"][1] <= btb.SPOT_Y[1]
    xy = np.array([d[f"{k}_xy"] for k in btb.SIZES])
    assert min(np.linalg.norm(xy[i] - xy[j]) for i in range(3) for j in range(i)) >= btb.MIN_GAP


def test_both_sides_get_the_large_cube_and_the_middle_cube(task):
    draws = [task.sample_scene(s).draws for s in range(30)]
    assert {d["large_side"] for d in draws} == {"left", "right"}
    assert {d["middle_side"] for d in draws} == {"left", "right"}


def test_initial_state_scores_nothing(task, scene):
    stages = task.stages(scene)
    assert [s.kind for s in stages] == ["transient"] * 3 + ["persistent"] * 2
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert list(StageMonitor(stages).evaluate(WorldState.initial(scene))) == [0] * 5


# ------------------------------------------------------------------ synthetic states
def _edge(scene, name):
    return scene.object(name).shape.size[0]


def _tower(scene, levels=(LARGE, MIDDLE, SMALL), offset=(0.0, 0.0)):
    """Poses of `levels` stacked bottom first at the spot (+ offset), resting."""
    x, y = scene.draws["spot_xy"][0] + offset[0], scene.draws["spot_xy"][1] + offset[1]
    poses, z = {}, TABLE_TOP
    for name in levels:
        e = _edge(scene, name)
        poses[name] = np.array([x, y, z + e / 2, 1.0, 0.0, 0.0, 0.0])
        z += e
    return poses


def test_large_cube_counts_at_the_spot_only_on_the_table_and_let_go(task, scene):
    at_spot = task.stages(scene)[1].predicate
    on_spot = _tower(scene, (LARGE,))
    assert at_spot(state_with(scene, on_spot))
    beside = _tower(scene, (LARGE,), offset=(0.04, 0.0))
    assert not at_spot(state_with(scene, beside))
    held_above = {LARGE: on_spot[LARGE] + [0, 0, 0.03, 0, 0, 0, 0]}
    assert not at_spot(state_with(scene, held_above, (0.0, 1.0), {LARGE: {"left"}}))
    # still gripped on the spot: not placed yet (the other arm's gripper may be closed)
    assert not at_spot(state_with(scene, on_spot, (0.0, 1.0), {LARGE: {"left"}}))


def test_middle_cube_counts_on_the_large_one_let_go_while_the_small_is_held(task, scene):
    middle = task.stages(scene)[3].predicate
    two = _tower(scene, (LARGE, MIDDLE))
    small_held = {SMALL: two[MIDDLE] + [0.15, 0.1, 0.1, 0, 0, 0, 0]}
    holding = {SMALL: {"right"}}
    assert middle(state_with(scene, {**two, **small_held}, (1.0, 0.0), holding))
    # still gripped
    touched = {**holding, MIDDLE: {"left"}}
    assert not middle(state_with(scene, {**two, **small_held}, (0.0, 0.0), touched))
    # beside the large cube, on the table
    beside = {**two, MIDDLE: np.r_[two[LARGE][:2] + [0.07, 0.0], TABLE_TOP + 0.025, 1, 0, 0, 0]}
    assert not middle(state_with(scene, beside))
    # the pair built off the spot
    assert not middle(state_with(scene, _tower(scene, (LARGE, MIDDLE), offset=(0.05, 0.0))))
    # toppled: the middle cube leaning on an edge against the large one
    q = (np.cos(np.pi / 8), 0.0, np.sin(np.pi / 8), 0.0)
    leaning = {**two, MIDDLE: np.r_[two[MIDDLE][:3] + [0.0, 0.0, 0.008], q]}
    assert not middle(state_with(scene, leaning))


def test_tower_counts_only_complete_in_order_released_and_settled(task, scene):
    last = task.stages(scene)[4].predicate
    tower = _tower(scene)
    assert after(last, state_with(scene, tower))
    assert not after(last, state_with(scene, tower), frames=4)  # not yet at rest for 0.3 s
    # the small cube still held on top
    assert not after(last, state_with(scene, tower, (1.0, 0.0), {SMALL: {"right"}}))
    # wrong order: small on the large cube, middle on the small one
    wrong = _tower(scene, (LARGE, SMALL, MIDDLE))
    assert not after(last, state_with(scene, wrong))
    # dropped: the small cube fell beside the tower
    dropped = {**tower, SMALL: np.r_[tower[LARGE][:2] + [0.0, 0.08], TABLE_TOP + 0.017, 1, 0, 0, 0]}
    assert not after(last, state_with(scene, dropped))


def test_stages_count_only_in_order(task, scene):
    """A finished tower seen without the earlier stages scores nothing."""
    monitor = StageMonitor(task.stages(scene))
    tower = state_with(scene, _tower(scene))
    for k in range(10):
        monitor.update(replace(tower, step=k, time=k / 15))
    monitor.finish(replace(tower, step=10, time=10 / 15))
    assert monitor.completed() == [False] * 5 and monitor.score() == 0.0


# ------------------------------------------------------------------ physics
@pytest.mark.slow
def test_expert_builds_the_tower_on_two_seeds(task):
    for seed in (0, 2):
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, (seed, result.reason)
        assert len(result.recorder) <= task.step_limit

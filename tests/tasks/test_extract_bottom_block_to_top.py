"""extract_bottom_block_to_top: seeded scenes, stages on synthetic states, (slow) the expert."""

from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.extract_bottom_block_to_top as ebt
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.predicates import stacked
from tests.tasks.helpers import after, state_with

BOTTOM, MIDDLE, TOP = ebt.BLOCKS
SEED = 3


@pytest.fixture(scope="module")
def task():
    return ebt.ExtractBottomBlockToTop()


@pytest.fixture(scope="module")
def scene(task):
    return task.sample_scene(SEED)


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == set(ebt.BLOCKS)
    assert scene.object(ebt.PLATFORM).fixed and scene.object(ebt.PLATFORM).collide
    assert len({scene.object(n).color for n in ebt.BLOCKS}) == 3


@pytest.mark.parametrize("seed", range(20))
def test_the_cubes_stand_stacked_on_the_platform_in_the_reference_ranges(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    x, y = d["platform_xy"]
    assert ebt.PLATFORM_X[0] <= x <= ebt.PLATFORM_X[1]
    assert ebt.PLATFORM_Y[0] <= y <= ebt.PLATFORM_Y[1]
    assert ebt.EDGE[0] <= d["edge"] <= ebt.EDGE[1]
    assert d["extractor"] in ("left", "right")
    platform = scene.object(ebt.PLATFORM)
    assert platform.shape.size == ebt.PLATFORM_SIZE and platform.pose.xyz[:2] == (x, y)
    state = WorldState.initial(scene)
    assert stacked([ebt.PLATFORM, *ebt.BLOCKS])(state)
    for name in ebt.BLOCKS:
        assert scene.object(name).shape.size == (d["edge"],) * 3


def test_both_arms_get_to_extract(task):
    assert {task.sample_scene(s).draws["extractor"] for s in range(20)} == {"left", "right"}


def test_initial_state_scores_nothing(task, scene):
    stages = task.stages(scene)
    assert [s.kind for s in stages] == ["transient", "persistent", "persistent"]
    assert [s.score for s in stages] == [0.0, 0.5, 0.5]
    assert list(StageMonitor(stages).evaluate(WorldState.initial(scene))) == [0] * 3


# ------------------------------------------------------------------ synthetic states
def _roles(scene):
    ext = scene.draws["extractor"]
    return ext, ("left" if ext == "right" else "right")


def _at(scene, x=0.0, y=0.0, z=0.0):
    """A resting-cube pose (7,) at the platform's centre + (x, y), bottom at the platform
    top + z."""
    px, py = scene.draws["platform_xy"]
    e = scene.draws["edge"]
    return np.array([px + x, py + y, ebt.PLATFORM_TOP + z + e / 2, 1.0, 0.0, 0.0, 0.0])


def _closed(*sides):
    return tuple(0.0 if side in sides else 1.0 for side in ("left", "right"))


def _extracted(scene, pulled=0.10, lift=0.02):
    """The moment of the pull: the middle cube `lift` up with the top one on it, the bottom
    cube pulled `pulled` toward the extractor's side."""
    e = scene.draws["edge"]
    ext, _ = _roles(scene)
    sign = 1.0 if ext == "right" else -1.0
    return {
        BOTTOM: _at(scene, x=sign * pulled),
        MIDDLE: _at(scene, z=e + lift),
        TOP: _at(scene, z=2 * e + lift),
    }


def test_extraction_counts_only_clear_of_the_platform_with_the_rest_held_up(task, scene):
    pulled = task.stages(scene)[0].predicate
    ext, lifter = _roles(scene)
    holding = {BOTTOM: {ext}, MIDDLE: {lifter}}
    both = _closed(ext, lifter)
    assert pulled(state_with(scene, _extracted(scene), both, holding))
    # only half out: still partly over the platform
    assert not pulled(state_with(scene, _extracted(scene, pulled=0.04), both, holding))
    # the rest not held up: the middle cube let go (resting 2 cm up is impossible, but the
    # lifter's fingers are off it)
    assert not pulled(state_with(scene, _extracted(scene), _closed(ext), {BOTTOM: {ext}}))
    # the middle cube held but not raised (the stack only tipped): not held up
    low = {**_extracted(scene), MIDDLE: _at(scene, z=scene.draws["edge"] + 0.003)}
    assert not pulled(state_with(scene, low, both, holding))
    # the top cube fell off the middle one onto the table
    fallen = {**_extracted(scene), TOP: np.r_[_at(scene, y=-0.12)[:2], 0.77, 1, 0, 0, 0]}
    assert not pulled(state_with(scene, fallen, both, holding))
    # the bottom cube knocked out (not held by the extractor), lying on the table
    knocked = {**_extracted(scene), BOTTOM: np.r_[_at(scene, x=0.12)[:2], 0.78, 1, 0, 0, 0]}
    assert not pulled(state_with(scene, knocked, _closed(lifter), {MIDDLE: {lifter}}))


def test_two_cube_stack_counts_on_the_platform_let_go(task, scene):
    lowered = task.stages(scene)[1].predicate
    e = scene.draws["edge"]
    ext, lifter = _roles(scene)
    two = {MIDDLE: _at(scene), TOP: _at(scene, z=e)}
    raised = {BOTTOM: _at(scene, x=0.1, z=0.15)}
    assert lowered(state_with(scene, {**two, **raised}, _closed(ext), {BOTTOM: {ext}}))
    # still held by the lifter
    held = {BOTTOM: {ext}, MIDDLE: {lifter}}
    assert not lowered(state_with(scene, {**two, **raised}, _closed(ext, lifter), held))
    # still hovering 2 cm above the platform
    up = {MIDDLE: _at(scene, z=0.02), TOP: _at(scene, z=e + 0.02)}
    assert not lowered(state_with(scene, {**up, **raised}, _closed(ext), {BOTTOM: {ext}}))
    # set down beside the platform's centre (hanging over its edge)
    beside = {MIDDLE: _at(scene, x=0.03), TOP: _at(scene, x=0.03, z=e)}
    assert not lowered(state_with(scene, {**beside, **raised}))
    # the top cube toppled off onto the table
    fallen = {**two, TOP: np.r_[_at(scene, y=-0.1)[:2], 0.775, 1, 0, 0, 0]}
    assert not lowered(state_with(scene, {**fallen, **raised}))


def test_the_tower_counts_with_the_old_bottom_cube_on_top_released_and_settled(task, scene):
    last = task.stages(scene)[2].predicate
    e = scene.draws["edge"]
    ext, _ = _roles(scene)
    tower = {MIDDLE: _at(scene), TOP: _at(scene, z=e), BOTTOM: _at(scene, z=2 * e)}
    assert after(last, state_with(scene, tower))
    assert not after(last, state_with(scene, tower), frames=4)  # not yet at rest for 0.3 s
    # still held on top
    assert not after(last, state_with(scene, tower, _closed(ext), {BOTTOM: {ext}}))
    # the original order (nothing moved): the bottom cube still at the bottom
    assert not after(last, state_with(scene, {}))
    # dropped beside the stack
    dropped = {**tower, BOTTOM: np.r_[_at(scene, x=0.1)[:2], 0.75 + e / 2, 1, 0, 0, 0]}
    assert not after(last, state_with(scene, dropped))
    # tipped on the top: leaning 30 degrees on an edge
    q = (np.cos(np.pi / 12), 0.0, np.sin(np.pi / 12), 0.0)
    leaning = {**tower, BOTTOM: np.r_[tower[BOTTOM][:3] + [0.0, 0.0, 0.008], q]}
    assert not after(last, state_with(scene, leaning))


def test_stages_count_only_in_order(task, scene):
    """A finished tower seen without the extraction scores nothing."""
    e = scene.draws["edge"]
    monitor = StageMonitor(task.stages(scene))
    tower = {MIDDLE: _at(scene), TOP: _at(scene, z=e), BOTTOM: _at(scene, z=2 * e)}
    state = state_with(scene, tower)
    for k in range(10):
        monitor.update(replace(state, step=k, time=k / 15))
    monitor.finish(replace(state, step=10, time=10 / 15))
    assert monitor.completed() == [False] * 3 and monitor.score() == 0.0


# ------------------------------------------------------------------ physics
@pytest.mark.slow
def test_expert_moves_the_bottom_cube_to_the_top_on_two_seeds(task):
    for seed in (0, 1):
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, (seed, result.reason)
        assert len(result.recorder) <= task.step_limit

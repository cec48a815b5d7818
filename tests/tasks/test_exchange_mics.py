"""exchange_mics: seeded scenes, stage definitions, and (slow) the expert in physics."""

import functools
from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.exchange_mics  # noqa: F401  (registers the task)
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.objects import CompoundShape
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.predicates import reset_predicate, upright
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.exchange_mics import SQUARE_X, SQUARE_Y


@pytest.fixture(scope="module")
def task():
    return get_task("exchange_mics")


def test_scene_holds_two_compound_mics_of_different_colours(task):
    scene = task.sample_scene(7)
    mics = {o.name: o for o in scene.free_objects}
    assert set(mics) == {"mic_left", "mic_right"}
    assert all(isinstance(m.shape, CompoundShape) for m in mics.values())
    kinds = sorted(p.kind for p in mics["mic_left"].shape.parts)
    assert kinds == ["cylinder", "sphere"]
    assert mics["mic_left"].color != mics["mic_right"].color


def test_squares_and_mics_are_drawn_in_their_ranges(task):
    for seed in range(20):
        scene = task.sample_scene(seed)
        objs = {o.name: o for o in scene.objects}
        for side in ("left", "right"):
            x, y = scene.draws[f"square_{side}"]
            assert SQUARE_X[side][0] <= x <= SQUARE_X[side][1]
            assert SQUARE_Y[0] <= y <= SQUARE_Y[1]
            square, mic = objs[f"square_{side}"], objs[f"mic_{side}"]
            assert square.fixed and not square.collide
            np.testing.assert_allclose(mic.pose.xyz[:2], (x, y))
            np.testing.assert_allclose(square.pose.xyz[:2], (x, y))


def test_no_stage_holds_in_the_initial_state(task):
    scene = task.sample_scene(3)
    state = WorldState.initial(scene)
    stages = task.stages(scene)
    values = StageMonitor(stages).evaluate(state)
    assert list(values) == [0, 0, 0, 0, 0]
    assert [s.score for s in stages] == [0.0, 0.0, 0.0, 0.0, 1.0]
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert [s.kind for s in stages] == ["transient"] * 4 + ["persistent"]
    assert upright("mic_left")(state) and upright("mic_right")(state)


def _held(pred, state, seconds=0.34):
    """`pred` after `state` was seen, unchanged, for `seconds` at 15 Hz (from a reset)."""
    reset_predicate(pred)
    values = [pred(replace(state, time=k / 15, step=k)) for k in range(round(seconds * 15) + 1)]
    return values[-1]


def test_crosswise_placement_needs_the_mics_at_rest_for_0_3_s(task):
    scene = task.sample_scene(4)
    place = task.stages(scene)[4].predicate
    poses = {o.name: np.array([*o.pose.xyz, 1.0, 0.0, 0.0, 0.0]) for o in scene.objects}
    poses["mic_right"] = np.array([*scene.draws["square_left"], poses["mic_left"][2], 1, 0, 0, 0])
    poses["mic_left"] = np.array([*scene.draws["square_right"], poses["mic_right"][2], 1, 0, 0, 0])
    state = WorldState.initial(scene, object_poses=poses)
    assert _held(place, state, 0.2) == 0.0
    assert _held(place, state, 0.34) == 1.0


def test_crosswise_placement_scores_half_per_mic(task):
    scene = task.sample_scene(4)
    stages = task.stages(scene)
    stages = [replace(s, predicate=functools.partial(_held, s.predicate)) for s in stages]
    poses = {o.name: np.array([*o.pose.xyz, 1.0, 0.0, 0.0, 0.0]) for o in scene.objects}
    swapped = dict(poses)
    swapped["mic_right"] = np.array([*scene.draws["square_left"], poses["mic_left"][2], 1, 0, 0, 0])
    state = WorldState.initial(scene, object_poses=swapped)
    assert stages[4].predicate(state) == pytest.approx(0.5)
    swapped["mic_left"] = np.array(
        [*scene.draws["square_right"], poses["mic_right"][2], 1, 0, 0, 0]
    )
    state = WorldState.initial(scene, object_poses=swapped)
    assert stages[4].predicate(state) == pytest.approx(1.0)
    tipped = dict(swapped)
    s = np.sqrt(0.5)
    tipped["mic_left"] = np.array([*scene.draws["square_right"], 0.77, s, s, 0, 0])  # lying
    state = WorldState.initial(scene, object_poses=tipped)
    assert stages[4].predicate(state) == pytest.approx(0.5)


@pytest.mark.slow
def test_expert_succeeds_on_at_least_90_percent_of_30_seeds(task):
    successes = sum(
        run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False))).success
        for seed in range(30)
    )
    assert successes >= 27

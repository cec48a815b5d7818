"""handover_block_with_bowls: seeded scenes, stage definitions, and (slow) the expert in physics."""

from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.handover_block_with_bowls as hbb
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.predicates import inside, lifted, released, reset_predicate
from bicoord_drake.tasks.registry import get_task


@pytest.fixture(scope="module")
def task():
    return get_task("handover_block_with_bowls")


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.objects} == {"pour_bowl", "catch_bowl", "cube", "target"}
    assert scene.object("target").fixed and not scene.object("target").collide


@pytest.mark.parametrize("seed", range(20))
def test_draws_stay_in_the_reference_ranges(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    assert -0.2 <= d["left_bowl_xy"][0] <= -0.15 and 0.15 <= d["right_bowl_xy"][0] <= 0.2
    for xy in (d["left_bowl_xy"], d["right_bowl_xy"]):
        assert -0.15 <= xy[1] <= -0.05
    assert 0.15 <= d["target_xy"][0] <= 0.2 and -0.05 <= d["target_xy"][1] <= 0.05
    # the scene is rebuilt from its draws: positions match what was recorded
    assert scene.object("pour_bowl").pose.xyz[:2] == tuple(d["left_bowl_xy"])
    assert scene.object("catch_bowl").pose.xyz[:2] == tuple(d["right_bowl_xy"])
    assert scene.object("target").pose.xyz[:2] == tuple(d["target_xy"])
    cube_z = scene.object("cube").pose.xyz[2]
    assert cube_z == pytest.approx(TABLE_TOP + hbb.POUR_BASE + hbb.CUBE / 2, abs=1e-3)


def test_initial_state_cube_in_the_left_bowl_and_no_stage_done(task):
    scene = task.sample_scene(3)
    state = WorldState.initial(scene)
    assert inside("cube", "pour_bowl", cavity=hbb.POUR_CAVITY)(state)
    assert not inside("cube", "catch_bowl")(state)
    assert not lifted("pour_bowl", 0.05)(state)
    assert released("catch_bowl")(state)
    stages = task.stages(scene)
    assert [s.kind for s in stages] == ["transient", "persistent", "persistent"]
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert list(StageMonitor(stages).evaluate(state)) == [0, 0, 0]


def _moved(state, **xyz):
    poses = dict(state.object_poses)
    for name, p in xyz.items():
        poses[name] = np.r_[p, poses[name][3:]]
    return replace(state, object_poses=poses)


def test_a_cube_on_the_table_beside_the_catching_bowl_is_not_poured(task):
    scene = task.sample_scene(3)
    state = WorldState.initial(scene)
    axis = np.array(scene.object("catch_bowl").pose.xyz)
    # 9 cm from the 7.5 cm bowl's axis, inside its bounding square's corner, on the table
    beside = _moved(state, cube=axis + [0.064, 0.064, hbb.CUBE / 2])
    assert not task.stages(scene)[1].predicate(beside)
    inside_it = _moved(state, cube=axis + [0.02, 0.0, 0.012 + hbb.CUBE / 2])
    assert task.stages(scene)[1].predicate(inside_it)


def test_the_bowl_must_rest_on_the_target_released_and_settled(task):
    scene = task.sample_scene(3)
    target = np.array([*scene.draws["target_xy"], TABLE_TOP])
    state = _moved(
        WorldState.initial(scene), catch_bowl=target, cube=target + [0, 0, 0.012 + hbb.CUBE / 2]
    )
    place = task.stages(scene)[2].predicate

    def after(s, frames):
        reset_predicate(place)
        return [place(replace(s, time=k / 15, step=k)) for k in range(frames)][-1]

    assert after(state, 6) and not after(state, 4)  # at rest for 0.3 s
    hovering = _moved(state, catch_bowl=target + [0, 0, 0.03], cube=target + [0, 0, 0.052])
    assert not after(hovering, 6)  # held (still) above the target, not on the table
    touched = replace(state, contacts={"pour_bowl": frozenset({"left"})})
    assert not after(touched, 6)  # a finger still on the other bowl


def test_pour_bowl_has_a_low_spout_facing_its_x_axis():
    shape = hbb.pour_bowl_shape()
    walls = [p for p in shape.parts if p.kind == "box"]
    tops = [p.pose.xyz[2] + p.size[2] / 2 for p in walls]
    low = [p for p, top in zip(walls, tops, strict=True) if top < hbb.POUR_HEIGHT - 1e-9]
    assert 1 <= len(low) <= 4
    for p in low:
        x, y, z = p.pose.xyz
        assert abs(np.arctan2(y, x)) < hbb.SPOUT_HALF_ANGLE
        # the lip is lower than half the cube: the cube tips over it
        assert z + p.size[2] / 2 - hbb.POUR_BASE < hbb.CUBE / 2


def test_bowl_walls_stand_on_their_bases():
    """Only the base discs touch the table (a bowl at rest is cheap: BOWL_RESOLUTION)."""
    for shape in (hbb.pour_bowl_shape(), hbb.CATCH_BOWL):
        parts = shape.parts if hasattr(shape, "parts") else shape.primitives()
        base, walls = parts[0], parts[1:]
        assert base.kind == "cylinder" and base.pose.xyz[2] - base.size[1] / 2 == 0.0
        for p in walls:
            assert p.pose.xyz[2] - p.size[2] / 2 >= base.size[1] - 1e-9


@pytest.mark.slow
def test_expert_succeeds_on_at_least_90_percent_of_30_seeds(task):
    results = [
        run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        for seed in range(30)
    ]
    failures = [(r.seed, r.reason) for r in results if not r.success]
    assert len(results) - len(failures) >= 27, failures

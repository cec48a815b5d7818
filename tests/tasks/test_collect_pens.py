"""collect_pens: seeded scenes, stages on synthetic states, (slow) the expert."""

import math
from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.collect_pens as cp
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.pens import PenShape
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.predicates import tilt
from tests.stages.helpers import quat_about
from tests.tasks.helpers import after, quat_mul, state_with

P1, P2, P3, P4 = cp.PENS
SEED = 1
FLOOR = TABLE_TOP + cp.HOLDER.wall


@pytest.fixture(scope="module")
def task():
    return cp.CollectPens()


@pytest.fixture(scope="module")
def scene(task):
    return task.sample_scene(SEED)


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == set(cp.PENS)
    assert scene.object("holder").fixed and scene.object("holder").collide
    assert list(scene.object("holder").pose.xyz[:2]) == list(cp.HOLDER_XY)


@pytest.mark.parametrize("seed", range(25))
def test_draws_stay_in_the_ranges(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    first = d["first_side"]
    sides = [first, "right" if first == "left" else "left"] * 2  # drop order
    poses = np.array([d[f"{n}_pose"] for n in cp.PENS])
    for (x, y, yaw), side, name in zip(poses, sides, cp.PENS, strict=True):
        obj = scene.object(name)
        assert isinstance(obj.shape, PenShape)
        assert cp.X_RANGE[side][0] <= x <= cp.X_RANGE[side][1]
        assert any(lo <= y <= hi for lo, hi in cp.Y_RANGE)
        assert yaw / (math.pi / 4) == pytest.approx(round(yaw / (math.pi / 4)))
        # lying flat on the table, its tip pointing along yaw
        assert obj.pose.xyz == pytest.approx((x, y, TABLE_TOP + obj.shape.radius))
        st = WorldState.initial(scene)
        tip = st.rotation(name) @ obj.shape.tip_point() + st.position(name)
        assert tip[:2] - [x, y] == pytest.approx(
            obj.shape.length / 2 * np.array([math.cos(yaw), math.sin(yaw)]), abs=1e-9
        )
    for pair in ((0, 2), (1, 3)):  # one arm's two pens: one per row
        ys = sorted(poses[list(pair), 1])
        assert ys[0] <= -0.05 and ys[1] >= 0.02
    # on each side the pen nearer the holder is picked first
    dist = np.hypot(poses[:, 0] - cp.HOLDER_XY[0], poses[:, 1] - cp.HOLDER_XY[1])
    assert dist[0] <= dist[2] and dist[1] <= dist[3]


def test_seeds_vary_who_goes_first_kinds_and_orientations(task):
    scenes = [task.sample_scene(s) for s in range(30)]
    assert {s.draws["first_side"] for s in scenes} == {"left", "right"}
    assert {k for s in scenes for k in s.draws["kinds"]} == {"pen", "marker"}
    yaws = {round(s.draws[f"{n}_pose"][2] / (math.pi / 4)) for s in scenes for n in cp.PENS}
    assert yaws == set(range(8))


def test_initial_state_scores_nothing(task, scene):
    stages = task.stages(scene)
    assert [s.kind for s in stages] == ["transient"] + ["persistent"] * 4
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert list(StageMonitor(stages).evaluate(WorldState.initial(scene))) == [0] * 5


# ------------------------------------------------------------------ synthetic states
def _standing(k: int, scene, lean: float = math.radians(20)) -> np.ndarray:
    """The k-th pen with its tip on the holder's floor, leaning `lean` towards the k-th
    quarter."""
    shape = scene.object(cp.PENS[k]).shape
    yaw = k * math.pi / 2
    axis = np.array(
        [math.sin(lean) * math.cos(yaw), math.sin(lean) * math.sin(yaw), math.cos(lean)]
    )
    tip = np.array([*cp.HOLDER_XY, FLOOR]) - 0.02 * np.r_[axis[:2], 0.0]
    c = tip + shape.length / 2 * axis
    # rotation taking z to axis: about the horizontal perpendicular
    q = quat_about("z", yaw)
    w, x, y, z = q
    r = (math.cos(lean / 2), 0.0, math.sin(lean / 2), 0.0)  # about y, then yaw about z
    quat = quat_mul((w, x, y, z), r)
    return np.r_[c, quat]


def _limit(scene):
    return cp.lean_limit([scene.object(p).shape for p in cp.PENS])


def test_synthetic_standing_pose_has_its_tip_on_the_floor(scene):
    st = state_with(scene, {P1: _standing(0, scene)})
    shape = scene.object(P1).shape
    tip = st.rotation(P1) @ shape.tip_point() + st.position(P1)
    assert tip[2] == pytest.approx(FLOOR)
    assert tilt(st, P1) == pytest.approx(math.radians(20))


def test_a_pen_standing_in_the_holder_counts_and_one_beside_or_across_it_does_not(scene):
    one = cp.in_holder_count(1, _limit(scene))
    assert one(state_with(scene, {P1: _standing(0, scene)}))
    # beside the holder, lying on the table (where it started)
    assert not one(state_with(scene, {}))
    # lying across the opening (tip just inside, nearly flat)
    assert not one(state_with(scene, {P1: _standing(0, scene, math.radians(75))}))
    # the same pen stood next to the holder on the table
    beside = _standing(0, scene).copy()
    beside[:3] += [0.15, 0.0, -cp.HOLDER.wall]
    assert not one(state_with(scene, {P1: beside}))
    # upside down: back end on the floor
    flipped = _standing(0, scene, 0.0).copy()
    flipped[3:] = quat_about("x", math.pi)
    assert not one(state_with(scene, {P1: flipped}))


def test_a_pen_held_in_the_holder_or_still_moving_does_not_count(scene):
    one = cp.in_holder_count(1, _limit(scene))
    held = state_with(
        scene, {P1: _standing(0, scene)}, openings=(0.0, 1.0), contacts={P1: {"left"}}
    )
    assert not one(held)
    moving = replace(
        state_with(scene, {P1: _standing(0, scene)}),
        object_velocities={
            **WorldState.initial(scene).object_velocities,
            P1: np.r_[0.0, 0.0, -0.3, 0, 0, 0],
        },
    )
    assert not one(moving)
    # let go while the other gripper holds its pen: counts
    other = state_with(
        scene, {P1: _standing(0, scene)}, openings=(1.0, 0.0), contacts={P2: {"right"}}
    )
    assert one(other)


def test_counts_need_that_many_distinct_pens(scene):
    poses = {cp.PENS[k]: _standing(k, scene) for k in range(3)}
    limit = _limit(scene)
    assert cp.in_holder_count(3, limit)(state_with(scene, poses))
    assert not cp.in_holder_count(4, limit)(state_with(scene, poses))


def test_last_stage_needs_all_four_released_and_at_rest(task, scene):
    last = task.stages(scene)[-1].predicate
    four = {cp.PENS[k]: _standing(k, scene) for k in range(4)}
    assert after(last, state_with(scene, four))
    assert not after(last, state_with(scene, four, openings=(0.0, 1.0)))
    assert not after(last, state_with(scene, four, contacts={P4: {"right"}}))
    fallen = {**four, P4: np.r_[0.2, 0.1, TABLE_TOP + 0.008, quat_about("y", math.pi / 2)]}
    assert not after(last, state_with(scene, fallen))


def test_stages_count_only_in_order(task, scene):
    """All four in the holder seen without the pens ever lifted scores nothing."""
    monitor = StageMonitor(task.stages(scene))
    four = state_with(scene, {cp.PENS[k]: _standing(k, scene) for k in range(4)})
    for k in range(10):
        monitor.update(replace(four, step=k, time=k / 15))
    monitor.finish(replace(four, step=10, time=10 / 15))
    assert monitor.completed() == [False] * 5 and monitor.score() == 0.0


def _both_picked(scene):
    """The first two pens 10 cm up, each in its arm's closed gripper."""
    first = scene.draws["first_side"]
    second = "right" if first == "left" else "left"
    up = {
        n: np.r_[scene.object(n).pose.xyz[:2], scene.object(n).pose.xyz[2] + 0.1, 1, 0, 0, 0]
        for n in (P1, P2)
    }
    return state_with(scene, up, openings=(0.0, 0.0), contacts={P1: {first}, P2: {second}})


def test_first_stage_needs_both_pens_up_in_their_arms_grippers(task, scene):
    both = task.stages(scene)[0].predicate
    assert both(_both_picked(scene))
    assert not both(replace(_both_picked(scene), contacts={P1: {"left", "right"}}))
    swapped = {P1: {"left", "right"}, P2: set()}
    assert not both(replace(_both_picked(scene), contacts=swapped))
    low = {P1: np.r_[scene.object(P1).pose.xyz, 1, 0, 0, 0]}
    assert not both(
        replace(_both_picked(scene), object_poses={**_both_picked(scene).object_poses, **low})
    )


def test_a_pen_that_falls_out_stops_counting_at_the_end(task, scene):
    monitor = StageMonitor(task.stages(scene))
    two = {P1: _standing(0, scene), P2: _standing(1, scene)}
    seq = [_both_picked(scene)] * 3 + [state_with(scene, two)] * 3
    out = {**two, P2: np.r_[0.2, 0.1, TABLE_TOP + 0.008, quat_about("y", math.pi / 2)]}
    seq += [state_with(scene, out)] * 3
    for k, s in enumerate(seq):
        monitor.update(replace(s, step=k, time=k / 15))
    monitor.finish(replace(seq[-1], step=len(seq), time=len(seq) / 15))
    assert monitor.completed()[:2] == [True, True]
    assert monitor.completed()[2] is False
    assert monitor.score() == pytest.approx(0.25)


# ------------------------------------------------------------------ physics
@pytest.mark.slow
def test_expert_fills_the_holder_on_two_seeds(task):
    for seed in (0, 1):
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, (seed, result.reason)
        assert len(result.recorder) <= task.step_limit


@pytest.mark.parametrize("embodiment", ["aloha_viperx", "franka_pair"])
def test_pens_are_gripped_up_the_pads_with_the_fingertips_just_over_the_table(task, embodiment):
    """The grasp holds a lying pen's axis 5-7.5 mm up the pads (creeping out past the
    fingertips when held at their lower edge), the fingertips 2 mm over the table."""
    from bicoord_drake.planning.model import PlanningModel
    from bicoord_drake.planning.skills import SkillContext

    scene = task.sample_scene(SEED)
    ctx = SkillContext(PlanningModel(scene, embodiment))
    pad = ctx.model.embodiment.arm.gripper.pad_length
    for name in cp.PENS:
        radius = scene.object(name).shape.radius
        for grasp in cp.pen_grasps(ctx, "left", name):
            tips = grasp.X_WG.translation()[2] - pad / 2
            assert tips == pytest.approx(TABLE_TOP + 0.002)
            assert 0.005 - 1e-9 <= TABLE_TOP + radius - tips <= 0.0075 + 1e-9

"""divide_block_tower: seeded scenes, stages on synthetic states, (slow) the expert."""

from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.divide_block_tower as dbt
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.skills import ArmPlan
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.predicates import reset_predicate
from tests.tasks.helpers import state_with

C0, C1, C2, C3 = dbt.CUBES
TILTED = (np.cos(np.pi / 8), 0.0, np.sin(np.pi / 8), 0.0)  # 45 deg about y


@pytest.fixture(scope="module")
def task():
    return dbt.DivideBlockTower()


def _seed_with(task, pattern):
    return next(s for s in range(200) if "".join(task.sample_scene(s).draws["order"]) == pattern)


@pytest.fixture(scope="module")
def mixed(task):
    """A tower whose top two differ in colour (A B A B, bottom first)."""
    return task.sample_scene(_seed_with(task, "ABAB"))


@pytest.fixture(scope="module")
def same(task):
    """A tower whose top two share colour A (B B A A)."""
    return task.sample_scene(_seed_with(task, "BBAA"))


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert [o.name for o in scene.free_objects] == list(dbt.CUBES)
    assert scene.object("base").fixed and scene.object("base").shape.size == dbt.BASE_SIZE
    for sign in ("sign_a", "sign_b"):
        assert scene.object(sign).fixed and not scene.object(sign).collide


@pytest.mark.parametrize("seed", range(25))
def test_draws_stay_in_the_reference_ranges(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    assert sorted(d["order"]) == ["A", "A", "B", "B"] and len(set(d["colors"])) == 2
    bx, by = d["base_xy"]
    assert dbt.BASE_X[0] <= bx <= dbt.BASE_X[1] and dbt.BASE_Y[0] <= by <= dbt.BASE_Y[1]
    z = TABLE_TOP + dbt.BASE_SIZE[2]
    for name, k, edge in zip(dbt.CUBES, d["order"], d["edges"], strict=True):
        obj = scene.object(name)
        assert dbt.EDGE[0] <= edge <= dbt.EDGE[1] and obj.shape.size == (edge,) * 3
        assert obj.color == dbt.COLORS[d["colors"]["AB".index(k)]]
        x, y, zc = obj.pose.xyz
        assert np.hypot(x - bx, y - by) <= dbt.CUBE_JITTER + 1e-12
        assert zc == pytest.approx(z + edge / 2) and abs(obj.pose.rpy[2]) <= dbt.CUBE_YAW
        z += edge
    for k, side in (("a", "left"), ("b", "right")):
        x, y = d[f"sign_{k}_xy"]
        assert dbt.SIGN_X[side][0] <= x <= dbt.SIGN_X[side][1]
        assert dbt.SIGN_Y[0] <= y <= dbt.SIGN_Y[1]
        assert scene.object(f"sign_{k}").color == dbt.COLORS[d["colors"]["ab".index(k)]]


def test_every_tower_order_is_drawn(task):
    assert {"".join(task.sample_scene(s).draws["order"]) for s in range(30)} == {
        "".join(o) for o in dbt.ORDERS
    }


def test_expert_steps_per_order():
    """Two two-arm steps when the top two differ; one-arm, two-arm, one-arm when they share a
    colour; colour A always by the left arm."""
    steps = dbt._steps(list("ABAB"))
    assert [(s.upper, s.upper_arm, s.lower) for s in steps] == [(3, "right", 2), (1, "right", 0)]
    steps = dbt._steps(list("BBAA"))
    assert [(s.upper, s.upper_arm, s.lower, s.other) for s in steps] == [
        (3, "left", None, "prepare"),
        (2, "left", 1, "hold"),
        (0, "right", None, "hold"),
    ]
    for order in dbt.ORDERS:
        for s in dbt._steps(list(order)):
            assert s.upper_arm == dbt.ARM[order[s.upper]]
            if s.lower is not None:
                assert s.lower_arm == dbt.ARM[order[s.lower]] != s.upper_arm


def test_initial_state_scores_nothing(task, mixed):
    stages = task.stages(mixed)
    assert [s.kind for s in stages] == ["transient", "persistent"] * 2
    assert [s.score for s in stages] == [0.0, 0.25, 0.0, 0.75]
    assert list(StageMonitor(stages).evaluate(WorldState.initial(mixed))) == [0] * 4


# ------------------------------------------------------------------ synthetic states
def _edge(scene, name):
    return scene.object(name).shape.size[0]


def _initial(scene, name):
    return WorldState.initial(scene).pose(name).copy()


def _lifted(scene, name, dz=0.06, dx=0.0):
    p = _initial(scene, name)
    p[0] += dx
    p[2] += dz
    return p


def _sign_tower(scene, names, k, offset=(0.0, 0.0)):
    """Poses of `names` stacked bottom first on colour `k`'s sign (+ offset)."""
    x, y = np.add(scene.draws[f"sign_{k}_xy"], offset)
    poses, z = {}, TABLE_TOP
    for name in names:
        e = _edge(scene, name)
        poses[name] = np.array([x, y, z + e / 2, 1.0, 0.0, 0.0, 0.0])
        z += e
    return poses


def _colour(scene, k):
    return [c for c, kk in zip(dbt.CUBES, scene.draws["order"], strict=True) if kk == k.upper()]


def _after(pred, states, frames=8):
    """`pred` after the `states` in turn, the last repeated for `frames` updates."""
    reset_predicate(pred)
    states = list(states)
    value, k = None, 0
    for s in states[:-1] + [states[-1]] * frames:
        value = pred(replace(s, step=k, time=k / 15))
        k += 1
    return value


def test_top_two_taken_only_off_the_tower_and_the_rest_in_place(task, mixed):
    take = task.stages(mixed)[0].predicate
    both_up = {C3: _lifted(mixed, C3, 0.10), C2: _lifted(mixed, C2, 0.05, dx=0.1)}
    held = {C3: {"right"}, C2: {"left"}}
    assert _after(take, [state_with(mixed, both_up, (0.0, 0.0), held)], 1)
    # only the top one lifted
    assert not _after(take, [state_with(mixed, {C3: both_up[C3]}, (1.0, 0.0), held)], 1)
    # the two lifted together (the second still under the first): 2 cm is not off the tower
    together = {C3: _lifted(mixed, C3, 0.02), C2: _lifted(mixed, C2, 0.02)}
    assert not _after(take, [state_with(mixed, together)], 1)
    # the tower below toppled as they were taken
    knocked = {**both_up, C1: _lifted(mixed, C1, -0.05, dx=0.06)}
    assert not _after(take, [state_with(mixed, knocked)], 1)
    shifted = {**both_up, C0: _lifted(mixed, C0, 0.0, dx=0.012)}
    assert not _after(take, [state_with(mixed, shifted)], 1)
    # lifted one after the other (the first already set on its sign): taken
    first = state_with(mixed, {C3: both_up[C3]})
    on_signs = {**_sign_tower(mixed, [C3], "b"), C2: both_up[C2]}
    assert _after(take, [first, state_with(mixed, on_signs)], 1)
    # knocked off the tower onto the table without ever being lifted: not taken
    fallen = {C3: np.r_[_initial(mixed, C3)[:2] + [0.1, 0], TABLE_TOP + 0.025, 1, 0, 0, 0]}
    assert not _after(take, [state_with(mixed, {**fallen, C2: both_up[C2]})], 1)


def test_sort_counts_each_cube_on_its_own_sign(task, mixed):
    sort = task.stages(mixed)[1].predicate
    top_b, top_a = C3, C2  # mixed is A B A B bottom first
    both = {**_sign_tower(mixed, [top_a], "a"), **_sign_tower(mixed, [top_b], "b")}
    assert _after(sort, [state_with(mixed, both)]) == 1.0
    # one still held above its sign: half the credit
    held = {**both, top_b: both[top_b] + [0, 0, 0.03, 0, 0, 0, 0]}
    assert _after(sort, [state_with(mixed, held, (1.0, 0.0), {top_b: {"right"}})]) == 0.5
    # set down but still gripped
    assert _after(sort, [state_with(mixed, both, (1.0, 0.0), {top_b: {"right"}})]) == 0.5
    # swapped signs: neither counts
    swapped = {**_sign_tower(mixed, [top_a], "b"), **_sign_tower(mixed, [top_b], "a")}
    assert _after(sort, [state_with(mixed, swapped)]) == 0.0
    # beside its sign
    beside = {**both, top_a: both[top_a] + [0.045, 0, 0, 0, 0, 0, 0]}
    assert _after(sort, [state_with(mixed, beside)]) == 0.5
    # toppled on its sign: on an edge
    tipped = {**both, top_a: np.r_[both[top_a][:2], TABLE_TOP + 0.03, TILTED]}
    assert _after(sort, [state_with(mixed, tipped)]) == 0.5
    # still moving
    moving = state_with(mixed, both)
    moving = replace(moving, object_velocities={**moving.object_velocities, top_a: [0.1] + [0] * 5})
    assert _after(sort, [moving]) == 0.5


def test_last_two_taken(task, mixed):
    take = task.stages(mixed)[2].predicate
    placed = {**_sign_tower(mixed, [C2], "a"), **_sign_tower(mixed, [C3], "b")}
    up = {C1: _lifted(mixed, C1, 0.08), C0: _lifted(mixed, C0, 0.05, dx=-0.1)}
    assert _after(take, [state_with(mixed, {**placed, **up})], 1)
    assert not _after(take, [state_with(mixed, {**placed, C1: up[C1]})], 1)
    assert not _after(take, [state_with(mixed, placed)], 1)


def test_stacks_score_per_cube_and_per_tower_released_and_settled(task, same):
    stack = task.stages(same)[3].predicate
    a, b = _colour(same, "a"), _colour(same, "b")  # same is B B A A: a = [C2, C3], b = [C0, C1]
    # the A tower as the expert builds it (top cube first on the sign), the B tower likewise
    done = {**_sign_tower(same, [C3, C2], "a"), **_sign_tower(same, [C1, C0], "b")}
    assert _after(stack, [state_with(same, done)]) == 1.0
    # not yet at rest for 0.3 s: only the two cubes count, not the towers
    assert _after(stack, [state_with(same, done)], frames=3) == pytest.approx(2 / 6)
    # the last cube still held on its tower: only C1 counts (a gripper closed: nothing is
    # released yet, so neither tower counts)
    held = state_with(same, done, (1.0, 0.0), {C0: {"right"}})
    assert _after(stack, [held]) == pytest.approx(1 / 6)
    # a gripper still closed (on nothing): no tower counts as released
    assert _after(stack, [state_with(same, done, (0.0, 1.0))]) == pytest.approx(2 / 6)
    # colours mixed: each sign holds one of each
    mixed_up = {**_sign_tower(same, [a[0], b[0]], "a"), **_sign_tower(same, [b[1], a[1]], "b")}
    assert _after(stack, [state_with(same, mixed_up)]) == pytest.approx(1 / 6)
    # the A cubes side by side, not stacked (C2 also off its sign), the B tower done
    apart = {
        **_sign_tower(same, [C3], "a"),
        **_sign_tower(same, [C2], "a", offset=(0.0, 0.0)),
        **_sign_tower(same, [C1, C0], "b"),
    }
    apart[C2] = apart[C3] + [0.0, 0.0, 0.0, 0, 0, 0, 0]
    apart[C2][0] += 0.05
    apart[C2][2] = TABLE_TOP + _edge(same, C2) / 2
    assert _after(stack, [state_with(same, apart)]) == pytest.approx((1 + 1 + 2) / 6)
    # a tower on the wrong sign
    wrong = {**_sign_tower(same, [C3, C2], "b"), **_sign_tower(same, [C1, C0], "a")}
    assert _after(stack, [state_with(same, wrong)]) == 0.0


def test_stages_count_only_in_order(task, same):
    """The finished towers seen without the earlier stages score nothing."""
    monitor = StageMonitor(task.stages(same))
    done = {**_sign_tower(same, [C3, C2], "a"), **_sign_tower(same, [C1, C0], "b")}
    final = state_with(same, done)
    for k in range(10):
        monitor.update(replace(final, step=k, time=k / 15))
    monitor.finish(replace(final, step=10, time=10 / 15))
    assert monitor.completed() == [False] * 4 and monitor.score() == 0.0


def test_the_same_colour_order_runs_through_every_stage(task, same):
    """B B A A: left takes the top A to its sign, then the next A while right takes the B
    under it, then right takes the last B: every stage counts, in order."""
    monitor = StageMonitor(task.stages(same))
    a_sign = _sign_tower(same, [C3, C2], "a")
    b_sign = _sign_tower(same, [C1, C0], "b")
    frames = [
        {},
        {C3: _lifted(same, C3)},  # left lifts the top cube
        {C3: a_sign[C3]},  # ... and sets it on the A sign
        {C3: a_sign[C3], C2: _lifted(same, C2)},  # stage 1: the next A lifted
        {C3: a_sign[C3], C2: a_sign[C2], C1: _lifted(same, C1)},  # stage 2 (C1 in the air)
        {**a_sign, C1: b_sign[C1]},
        {**a_sign, C1: b_sign[C1], C0: _lifted(same, C0)},  # stage 3
        {**a_sign, **b_sign},  # stage 4
    ]
    k = 0
    for poses in frames:
        for _ in range(6):
            monitor.update(state_with(same, poses, step=k))
            k += 1
    monitor.finish()
    assert monitor.completed() == [True] * 4 and monitor.score() == pytest.approx(1.0)
    assert monitor.completion_frames() == sorted(monitor.completion_frames())


def test_the_expert_refuses_to_go_on_with_a_disturbed_tower(mixed):
    class View:
        def __init__(self, poses):
            self.poses = poses

        def object_pose(self, name):
            return self.poses[name]

    poses = {n: _initial(mixed, n) for n in dbt.CUBES}
    dbt._check_tower(View(poses), mixed, [C0, C1])
    poses[C1] = poses[C1] + [0.011, 0, 0, 0, 0, 0, 0]
    dbt._check_tower(View(poses), mixed, [C0])  # C1 already taken
    with pytest.raises(PlanningError) as err:
        dbt._check_tower(View(poses), mixed, [C0, C1])
    assert err.value.reason == "tower_disturbed"


# ------------------------------------------------------------------ physics
@pytest.mark.slow
def test_expert_divides_the_tower_on_two_seeds(task):
    for seed in (0, 1):  # A B A B (top two differ) and B B A A (top two share a colour)
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, (seed, result.reason)
        assert len(result.recorder) <= task.step_limit


def test_the_lower_cube_is_entered_only_once_the_upper_cube_has_risen(task, monkeypatch):
    """Planning only (seed 0, A B A B): in each two-arm step the lower cube's fingers move in
    (and close) only after the upper cube has risen CLEAR_RISE."""
    scene = task.sample_scene(0)
    seen = []
    take_below = dbt._take_below

    def recording(ctx, upper, come, take, names):
        motion = take_below(ctx, upper, come, take, names)
        seen.append((ctx, upper, come.then(take), names, motion))
        return motion

    class View:
        def planning_model(self):
            return PlanningModel(scene)

        def object_transforms(self):
            return {}

        def object_pose(self, name):
            return np.r_[scene.object(name).pose.xyz, 1.0, 0.0, 0.0, 0.0]

    monkeypatch.setattr(dbt, "_take_below", recording)
    actions = list(task.expert(scene, View()))
    assert 0 < len(actions) <= task.step_limit
    assert [names for _, _, _, names, _ in seen] == [(C3, C2), (C1, C0)]
    for ctx, upper, lower, _, motion in seen:
        # as merged: the lower arm's approach slowed (or held back) by the delay
        col, k = ctx.model.side_slice(lower.side), ("left", "right").index(lower.side)
        done = ArmPlan(lower.side, motion.q[:, col], motion.openings[:, k])
        assert done.num_steps >= lower.num_steps + motion.info["lower_delay"]
        risen = dbt._risen(ctx, upper, dbt.CLEAR_RISE)
        assert dbt._entering(ctx, done) >= risen
        assert dbt._closed_at(done) > risen

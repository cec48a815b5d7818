"""match_blocks_with_signs: seeded scenes, stage definitions, and (slow) the expert in physics."""

from dataclasses import replace

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.predicates import reset_predicate
from bicoord_drake.stages.stage import matrix_to_quat
from bicoord_drake.tasks.match_blocks_with_signs import (
    CUBOID_X,
    CUBOID_Y,
    CUBOIDS,
    ENDS,
    LENGTH,
    SQUARE_X,
    SQUARE_Y,
    SQUARES,
    MatchBlocksWithSigns,
    placement_order,
    upright_part,
)

UP = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def task():
    return MatchBlocksWithSigns()


def test_cuboids_lie_along_y_in_the_slots_and_squares_match_their_sizes(task):
    for seed in range(20):
        scene = task.sample_scene(seed)
        xs = []
        for name, end in zip(CUBOIDS, ENDS, strict=True):
            obj = scene.object(name)
            assert obj.shape.size == (end, end, LENGTH)
            R = obj.pose.matrix()[:3, :3]
            assert abs(R[1, 2]) > 0.99  # the long axis along y: lying
            assert obj.pose.xyz[2] == pytest.approx(TABLE_TOP + end / 2)
            assert abs(obj.pose.xyz[1] - CUBOID_Y) <= 0.01
            xs.append(obj.pose.xyz[0])
        slots = sorted(min(range(3), key=lambda k: abs(x - CUBOID_X[k])) for x in xs)
        assert slots == [0, 1, 2]
        ys = []
        for name, end in zip(SQUARES, ENDS, strict=True):
            sq = scene.object(name)
            assert sq.fixed and not sq.collide
            assert sq.shape.size[:2] == (end, end)
            assert sq.pose.xyz[0] == SQUARE_X
            ys.append(sq.pose.xyz[1])
        assert sorted(ys) == sorted(SQUARE_Y)
        assert len({scene.object(n).color for n in CUBOIDS}) == 3
        # placed from the farthest square
        order = placement_order(scene)
        assert [scene.draws["square_xy"][i][1] for i in order] == sorted(SQUARE_Y, reverse=True)


def test_no_stage_holds_in_the_initial_state(task):
    scene = task.sample_scene(3)
    stages = task.stages(scene)
    assert len(stages) == 10
    values = StageMonitor(stages).evaluate(WorldState.initial(scene))
    assert list(values) == [0] * 10
    third = pytest.approx(1 / 3)
    assert [s.score for s in stages] == [0, 0, third, 0, 0, third, 0, 0, 0, third]
    assert sum(s.score for s in stages) == pytest.approx(1.0)
    assert [s.kind for s in stages].count("persistent") == 3


# -------------------------------------------------------------------- synthetic states
def _standing(scene, name, xy=None, tilt=0.0):
    """Pose of `name` standing on its end at `xy` (default: its own square), tilted about y."""
    i = CUBOIDS.index(name)
    xy = scene.draws["square_xy"][i] if xy is None else xy
    c, s = np.cos(tilt), np.sin(tilt)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    z = TABLE_TOP + LENGTH / 2 * c + ENDS[i] / 2 * abs(s)
    return np.array([xy[0], xy[1], z, *matrix_to_quat(R)])


def _state(scene, poses=None, openings=(1.0, 1.0), contacts=None, tcp=None, step=0):
    base = WorldState.initial(scene)
    action = np.zeros(14)
    action[6], action[13] = openings
    return WorldState(
        scene=scene,
        step=step,
        time=step / 15,
        object_poses={**base.object_poses, **(poses or {})},
        action=action,
        contacts=contacts or {},
        object_velocities=dict(base.object_velocities),
        tcp_poses=tcp or {},
    )


def _held(pred, state, seconds=0.34):
    """`pred` after `state` was seen, unchanged, for `seconds` at 15 Hz (from a reset)."""
    reset_predicate(pred)
    values = [pred(replace(state, time=k / 15, step=k)) for k in range(round(seconds * 15) + 1)]
    return values[-1]


def _lifted(scene, name, dz=0.15):
    p = np.array(WorldState.initial(scene).object_poses[name])
    p[2] += dz
    return p


def test_pick_and_handover_stages(task):
    scene = task.sample_scene(5)
    stages = task.stages(scene)
    first = CUBOIDS[placement_order(scene)[0]]
    pick, hand = stages[0].predicate, stages[1].predicate
    up = {first: _lifted(scene, first)}
    assert pick(_state(scene, up, openings=(0.0, 1.0), contacts={first: {"left"}}))
    assert not pick(_state(scene, openings=(0.0, 1.0), contacts={first: {"left"}}))  # not lifted
    assert not pick(_state(scene, up))  # lifted but nobody holds it (a throw, a bounce)
    assert not pick(_state(scene, up, openings=(1.0, 0.0), contacts={first: {"right"}}))
    # the handover: the right holds it, the left no longer touches it
    assert hand(_state(scene, up, openings=(1.0, 0.0), contacts={first: {"right"}}))
    both = {first: {"left", "right"}}
    assert not hand(_state(scene, up, openings=(0.0, 0.0), contacts=both))
    assert not hand(_state(scene, up, openings=(0.0, 1.0), contacts={first: {"left"}}))
    low = {first: np.array(WorldState.initial(scene).object_poses[first])}
    assert not hand(_state(scene, low, openings=(1.0, 0.0), contacts={first: {"right"}}))


def test_a_cuboid_counts_standing_on_its_own_square_released_and_still(task):
    scene = task.sample_scene(6)
    stages = task.stages(scene)
    order = placement_order(scene)
    first, second = CUBOIDS[order[0]], CUBOIDS[order[1]]
    stand = stages[2].predicate
    assert _held(stand, _state(scene, {first: _standing(scene, first)})) == 1.0
    assert _held(stand, _state(scene, {first: _standing(scene, first)}), 0.2) == 0.0  # too soon
    # the left may hold the next cuboid meanwhile
    busy = _state(
        scene,
        {first: _standing(scene, first), second: _lifted(scene, second)},
        openings=(0.0, 1.0),
        contacts={second: {"left"}},
    )
    assert _held(stand, busy) == 1.0
    # on the wrong square, beside its square, toppled, lying on it, still held
    other = scene.draws["square_xy"][order[1]]
    assert _held(stand, _state(scene, {first: _standing(scene, first, other)})) == 0.0
    xy = scene.draws["square_xy"][order[0]]
    beside = [xy[0] + 0.04, xy[1]]
    assert _held(stand, _state(scene, {first: _standing(scene, first, beside)})) == 0.0
    toppled = _standing(scene, first, tilt=np.radians(25))
    assert _held(stand, _state(scene, {first: toppled})) == 0.0
    lying = np.array([*xy, TABLE_TOP + ENDS[order[0]] / 2, *matrix_to_quat(_lying())])
    assert _held(stand, _state(scene, {first: lying})) == 0.0
    held = _state(
        scene, {first: _standing(scene, first)}, openings=(1.0, 0.0), contacts={first: {"right"}}
    )
    assert _held(stand, held) == 0.0


def _lying() -> np.ndarray:
    return np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


def test_the_last_stage_needs_every_cuboid_up_and_both_hands_free(task):
    scene = task.sample_scene(2)
    stages = task.stages(scene)
    last = stages[-1].predicate
    all_up = {n: _standing(scene, n) for n in CUBOIDS}
    assert _held(last, _state(scene, all_up)) == 1.0
    assert _held(last, _state(scene, all_up, openings=(0.0, 1.0))) == 0.0  # a gripper closed
    name = CUBOIDS[placement_order(scene)[-1]]
    assert _held(last, _state(scene, {**all_up, name: _standing(scene, name, tilt=0.7)})) == 0.0
    # the first cuboid toppled: its own (persistent) stage fails at the end instead
    first = CUBOIDS[placement_order(scene)[0]]
    down = _state(scene, {**all_up, first: _standing(scene, first, tilt=0.7)})
    assert _held(last, down) == 1.0 and _held(stages[2].predicate, down) == 0.0


def test_left_retreats_only_away_from_the_last_cuboid(task):
    scene = task.sample_scene(2)
    stages = task.stages(scene)
    name = CUBOIDS[placement_order(scene)[-1]]
    retreat = stages[8].predicate
    pose = {name: _lifted(scene, name)}
    held = {name: {"right"}}
    p = pose[name][:3]
    near = {"left": np.array([*(p + [0.08, 0, 0]), *UP])}
    far = {"left": np.array([*(p + [-0.2, -0.1, 0]), *UP])}
    assert retreat(_state(scene, pose, openings=(1.0, 0.0), contacts=held, tcp=far))
    assert not retreat(_state(scene, pose, openings=(1.0, 0.0), contacts=held, tcp=near))
    assert not retreat(_state(scene, pose, openings=(1.0, 1.0), tcp=far))  # dropped


def test_stages_count_only_in_order(task):
    """All three cuboids standing at the end, but never picked or handed over: nothing counts."""
    scene = task.sample_scene(4)
    monitor = StageMonitor(task.stages(scene))
    all_up = {n: _standing(scene, n) for n in CUBOIDS}
    for k in range(10):
        monitor.update(_state(scene, all_up, step=k))
    assert monitor.score() == 0.0
    assert not monitor.success


def test_upright_part_removes_a_small_tilt_and_keeps_the_end_and_yaw():
    from pydrake.all import RotationMatrix

    R = RotationMatrix.MakeZRotation(0.7) @ RotationMatrix.MakeXRotation(0.05)
    U = upright_part(R).matrix()
    assert U[2, 2] == pytest.approx(1.0)
    assert np.arctan2(U[1, 0], U[0, 0]) == pytest.approx(0.7, abs=1e-6)
    flipped = upright_part(RotationMatrix.MakeZRotation(-0.4) @ RotationMatrix.MakeXRotation(3.1))
    assert flipped.matrix()[2, 2] == pytest.approx(-1.0)


@pytest.mark.slow
def test_expert_succeeds_on_two_seeds(task):
    for seed in (0, 1):
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, result.reason

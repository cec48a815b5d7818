"""put_objects_cabinet: seeded scenes, stages on synthetic states, (slow) the expert."""

from dataclasses import replace

import numpy as np
import pytest

import bicoord_drake.tasks.put_objects_cabinet as pc
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from tests.tasks.helpers import after, state_with

SEED = 3
UP = (1.0, 0.0, 0.0, 0.0)
B1, B2 = pc.BOXES


@pytest.fixture(scope="module")
def task():
    return pc.PutObjectsCabinet()


@pytest.fixture(scope="module")
def scene(task):
    return task.sample_scene(SEED)


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == {pc.DRAWER, *pc.BOXES}
    assert scene.object(pc.CABINET).fixed and scene.object(pc.DRAWER).slide.parent == pc.CABINET


@pytest.mark.parametrize("seed", range(20))
def test_layout_boxes_on_the_left_clear_of_the_cabinet_and_its_drawer(task, seed):
    scene = task.sample_scene(seed)
    d = scene.draws
    cx, cy, _ = scene.object(pc.CABINET).pose.xyz
    assert [cx, cy] == d["cabinet_xy"]
    assert pc.CABINET_X[0] <= cx <= pc.CABINET_X[1] and pc.CABINET_Y[0] <= cy <= pc.CABINET_Y[1]
    # the cabinet's and the fully open drawer's left edge
    left_edge = cx - pc.DIMS.outer[0] / 2
    xy = np.array([scene.object(b).pose.xyz[:2] for b in pc.BOXES])
    assert xy.tolist() == d["boxes_xy"]
    assert np.linalg.norm(xy[0] - xy[1]) >= 0.10
    for b, yaw in zip(pc.BOXES, d["yaws"], strict=True):
        x, y, z = scene.object(b).pose.xyz
        half_x = pc.BOX_SIZE[0] / 2 * abs(np.cos(yaw)) + pc.BOX_SIZE[1] / 2 * abs(np.sin(yaw))
        assert x + half_x < left_edge - 0.02  # clear of the cabinet and the drawer's path
        assert z == pytest.approx(TABLE_TOP + pc.BOX_SIZE[2] / 2)
    assert d["colors"][0] != d["colors"][1]
    # both slots fit in the part of the drawer that is out, within its walls
    hx, hy = pc.DIMS.inner_half
    for sx, sy in pc.SLOTS:
        assert abs(sx) + pc.BOX_SIZE[0] / 2 < hx
        out_front = -pc.DIMS.depth / 2 + pc.OPEN  # the cabinet's front, drawer frame
        assert -hy < sy - pc.BOX_SIZE[1] / 2 and sy + pc.BOX_SIZE[1] / 2 < out_front


def test_initial_state_scores_nothing(task, scene):
    stages = task.stages(scene)
    assert [s.kind for s in stages] == ["transient"] * 2 + ["persistent"] * 2
    assert [s.score for s in stages] == [0.0, 0.0, 0.5, 0.5]
    assert list(StageMonitor(stages).evaluate(WorldState.initial(scene))) == [0, 0, 0, 0]


# ------------------------------------------------------------------ synthetic states
def _drawer_pose(scene, d: float) -> np.ndarray:
    x, y, z = scene.object(pc.DRAWER).pose.xyz
    return np.array([x, y - d, z, *UP])


def _in_drawer(scene, d: float, slot: int, dx=0.0, dy=0.0, dz=0.0) -> np.ndarray:
    x, y, z = _drawer_pose(scene, d)[:3]
    sx, sy = pc.SLOTS[slot]
    floor = z + pc.DIMS.wall
    return np.array([x + sx + dx, y + sy + dy, floor + pc.BOX_SIZE[2] / 2 + dz, *UP])


def _state(scene, d=0.0, boxes=None, openings=(1.0, 1.0), contacts=None, step=0):
    """The drawer pulled out `d` (m), the `boxes` at their poses."""
    poses = {pc.DRAWER: _drawer_pose(scene, d), **(boxes or {})}
    s = state_with(scene, poses, openings, contacts, step=step)
    return replace(s, joint_positions={pc.DRAWER: d})


def test_stage_1_needs_the_box_in_the_left_hand_and_the_handle_in_the_right(task, scene):
    grab = task.stages(scene)[0].predicate
    both = {B1: {"left"}, pc.DRAWER: {"right"}}
    assert grab(_state(scene, openings=(0.0, 0.0), contacts=both))
    assert not grab(_state(scene, openings=(0.0, 0.0), contacts={B1: {"left"}}))
    assert not grab(_state(scene, openings=(0.0, 0.0), contacts={pc.DRAWER: {"right"}}))
    assert not grab(_state(scene, openings=(1.0, 0.0), contacts=both))  # left open: not held
    assert not grab(
        _state(scene, openings=(0.0, 0.0), contacts={B2: {"left"}, **both} | {B1: set()})
    )


def test_stage_2_counts_the_drawer_open_at_least_12_cm(task, scene):
    opened = task.stages(scene)[1].predicate
    assert opened(_state(scene, 0.16)) and opened(_state(scene, 0.12))
    assert not opened(_state(scene, 0.11)) and not opened(_state(scene, 0.0))


def test_stage_3_gives_a_quarter_per_box_inside_released_at_rest(task, scene):
    put = task.stages(scene)[2].predicate
    one = {B1: _in_drawer(scene, 0.16, 0)}
    both = {**one, B2: _in_drawer(scene, 0.16, 1)}
    hold = {pc.DRAWER: {"right"}}
    assert after(put, _state(scene, 0.16, both, (1.0, 0.0), hold)) == 1.0
    assert after(put, _state(scene, 0.16, one, (1.0, 0.0), hold)) == 0.5
    # anywhere within the walls counts, and once closed too
    shifted = {**one, B2: _in_drawer(scene, 0.16, 1, dx=-0.03, dy=-0.05)}
    assert after(put, _state(scene, 0.16, shifted)) == 1.0
    closed = {B1: _in_drawer(scene, 0.0, 0), B2: _in_drawer(scene, 0.0, 1)}
    assert after(put, _state(scene, 0.0, closed)) == 1.0
    assert after(put, _state(scene, 0.16, both), frames=3) == 0.0  # not 0.3 s at rest yet


def test_stage_3_is_not_fooled(task, scene):
    put = task.stages(scene)[2].predicate
    in_1 = {B1: _in_drawer(scene, 0.16, 0)}
    # still held by the left hand
    assert after(put, _state(scene, 0.16, in_1, (0.0, 0.0), {B1: {"left"}})) == 0.0
    # beside the drawer on the table; in front of it on the table
    x, y, _ = _drawer_pose(scene, 0.16)[:3]
    table_z = TABLE_TOP + pc.BOX_SIZE[2] / 2
    beside = {B1: np.array([x - pc.DIMS.width / 2 - 0.05, y, table_z, *UP])}
    front = {B1: np.array([x, y - pc.DIMS.depth / 2 - 0.06, table_z, *UP])}
    assert after(put, _state(scene, 0.16, beside)) == 0.0
    assert after(put, _state(scene, 0.16, front)) == 0.0
    # hovering above the drawer, or lying on its rim / the cabinet's top
    assert after(put, _state(scene, 0.16, {B1: _in_drawer(scene, 0.16, 0, dz=0.08)})) == 0.0
    on_top = {B1: _in_drawer(scene, 0.16, 0, dy=0.1, dz=pc.DIMS.outer[2] - pc.DIMS.wall)}
    assert after(put, _state(scene, 0.16, on_top)) == 0.0
    # under the drawer is impossible, but a box left where the drawer was (it slid out over
    # it) is not inside it
    assert after(put, _state(scene, 0.16, {B1: _in_drawer(scene, 0.0, 0)})) == 0.0


def test_stage_4_needs_the_drawer_shut_let_go_with_both_boxes_in(task, scene):
    close = task.stages(scene)[3].predicate
    closed = {B1: _in_drawer(scene, 0.0, 0), B2: _in_drawer(scene, 0.0, 1)}

    def at(d, boxes=None, **kw):
        moved = {b: p - [0.0, d, 0, 0, 0, 0, 0] for b, p in (boxes or closed).items()}
        return after(close, _state(scene, d, moved, **kw))

    assert at(0.0) and at(0.015)
    assert not at(0.03)  # 3 cm out
    assert not at(0.0, openings=(1.0, 0.0), contacts={pc.DRAWER: {"right"}})  # still held
    assert not at(0.0, {B1: closed[B1]})  # box 2 left out
    out = {**closed, B2: np.array([-0.3, -0.1, TABLE_TOP + pc.BOX_SIZE[2] / 2, *UP])}
    assert not at(0.0, out)


def _run(task, scene, states) -> StageMonitor:
    mon = StageMonitor(task.stages(scene))
    for k, s in enumerate(states):
        mon.update(replace(s, step=k, time=k / 15))
    mon.finish()
    return mon


def test_the_stages_count_only_in_order(task, scene):
    hold = {B1: {"left"}, pc.DRAWER: {"right"}}
    grabbed = _state(scene, 0.0, openings=(0.0, 0.0), contacts=hold)
    opened = _state(scene, 0.16, openings=(0.0, 0.0), contacts=hold)
    both_in = {B1: _in_drawer(scene, 0.16, 0), B2: _in_drawer(scene, 0.16, 1)}
    filled = _state(scene, 0.16, both_in, (1.0, 0.0), {pc.DRAWER: {"right"}})
    shut_in = {B1: _in_drawer(scene, 0.0, 0), B2: _in_drawer(scene, 0.0, 1)}
    shut = _state(scene, 0.0, shut_in)
    good = _run(task, scene, [grabbed] * 2 + [opened] * 2 + [filled] * 8 + [shut] * 8)
    assert good.success and good.score() == pytest.approx(1.0)
    # the drawer never opened by hand (boxes appear in a shut drawer): nothing counts
    skipped = _run(task, scene, [grabbed] * 2 + [shut] * 16)
    assert not skipped.success and skipped.score() == 0.0
    # filled and then left open: half
    half = _run(task, scene, [grabbed] * 2 + [opened] * 2 + [filled] * 10)
    assert not half.success and half.score() == pytest.approx(0.5)


# ------------------------------------------------------------------ expert (slow)
@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_expert_runs_end_to_end(task, seed):
    result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
    assert result.success, result.reason
    assert len(result.recorder) <= task.step_limit
    assert len(result.rows) == 4

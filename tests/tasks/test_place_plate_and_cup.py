"""place_plate_and_cup: seeded scenes, stage definitions on synthetic states, and (slow) the
expert in physics."""

import math

import pytest

import bicoord_drake.tasks.place_plate_and_cup as ppc
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.stages import StageMonitor, WorldState
from tests.stages.helpers import pose, quat_about, state

PLATE_Z = TABLE_TOP
CUP_ON_PLATE_Z = TABLE_TOP + ppc.PLATE.wall


@pytest.fixture(scope="module")
def task():
    return ppc.PlacePlateAndCup()


@pytest.fixture(scope="module")
def scene(task):
    return task.sample_scene(3)


def test_scene_holds_the_task_objects(task):
    scene = task.sample_scene(7)
    assert {o.name for o in scene.free_objects} == {"plate_0", "plate_1", "cup_0", "cup_1"}
    assert all(scene.object(f"target_{k}").fixed for k in (0, 1))
    assert not scene.object("target_0").collide


@pytest.mark.parametrize("seed", range(20))
def test_draws_stay_in_their_ranges_and_rebuild_the_scene(task, seed):
    sc = task.sample_scene(seed)
    d = sc.draws
    plates, cups, targets = d["plate_xy"], d["cup_xy"], d["target_xy"]
    for x, y in plates:  # plates on the left half
        assert ppc.PLATE_X[0] <= x <= ppc.PLATE_X[1] < 0 and ppc.PLATE_Y[0] <= y <= ppc.PLATE_Y[1]
    for x, y in cups:  # cups on the right half, clear of target 2
        assert 0 < ppc.CUP_X[0] <= x <= ppc.CUP_X[1] and ppc.CUP_Y[0] <= y <= ppc.CUP_Y[1]
        assert math.dist((x, y), targets[1]) >= 0.13
    assert math.dist(*plates) >= ppc.PLATE_GAP and math.dist(*cups) >= ppc.CUP_GAP
    for (x, y), (x0, y0) in zip(targets, ppc.TARGETS, strict=True):
        assert abs(x - x0) <= ppc.TARGET_JITTER and abs(y - y0) <= ppc.TARGET_JITTER
    for name, xy in zip(ppc.PLATES + ppc.CUPS, plates + cups, strict=True):
        assert sc.object(name).pose.xyz[:2] == tuple(xy)


def _set(scene, k, plate, cup, dxy=(0.0, 0.0), cup_dxy=(0.0, 0.0), cup_dz=0.0, cup_quat=None):
    """Poses of `plate` on target k (shifted by dxy) with `cup` standing on it."""
    x, y = scene.draws["target_xy"][k]
    x, y = x + dxy[0], y + dxy[1]
    cup_pose = pose(x + cup_dxy[0], y + cup_dxy[1], CUP_ON_PLATE_Z + cup_dz)
    if cup_quat is not None:
        cup_pose = pose(x + cup_dxy[0], y + cup_dxy[1], CUP_ON_PLATE_Z + cup_dz, cup_quat)
    return {plate: pose(x, y, PLATE_Z), cup: cup_pose}


def _run(task, scene, frames):
    """Stage values counted by a monitor over `frames` (kwargs of _state), 0.1 s apart."""
    monitor = StageMonitor(task.stages(scene))
    for k, kw in enumerate(frames):
        monitor.update(state(scene, step=k * 2, **kw))  # 2 control steps = 0.13 s apart
    monitor.finish()
    return monitor


def test_initial_state_scores_nothing(task, scene):
    values = StageMonitor(task.stages(scene)).evaluate(WorldState.initial(scene))
    assert list(values) == [0, 0, 0, 0]
    assert sum(s.score for s in task.stages(scene)) == pytest.approx(1.0)
    assert [s.kind for s in task.stages(scene)] == [
        "transient",
        "persistent",
        "transient",
        "persistent",
    ]


def test_a_place_is_recognized_and_not_fooled(task, scene):
    place = ppc.place_set(ppc.PLATES, ppc.CUPS, scene.draws["target_xy"][0])

    def ok(poses, contacts=None, steps=4):
        place.reset()
        return [
            place(state(scene, poses=poses, contacts=contacts, step=2 * k)) for k in range(steps)
        ][-1]

    assert ok(_set(scene, 0, "plate_0", "cup_1"))  # any plate with any cup
    assert ok(_set(scene, 0, "plate_1", "cup_0", dxy=(0.02, -0.01), cup_dxy=(0.02, 0.0)))
    # not yet at rest for 0.3 s
    assert not ok(_set(scene, 0, "plate_0", "cup_0"), steps=2)
    # the plate beside the target; the cup beside the plate; the cup toppled on the plate
    assert not ok(_set(scene, 0, "plate_0", "cup_0", dxy=(0.05, 0.0)))
    assert not ok(_set(scene, 0, "plate_0", "cup_0", cup_dxy=(0.09, 0.0), cup_dz=-0.012))
    tipped = quat_about("y", math.radians(80))
    assert not ok(_set(scene, 0, "plate_0", "cup_0", cup_dz=0.03, cup_quat=tipped))
    # still held: a finger on the cup, or on the plate
    assert not ok(_set(scene, 0, "plate_0", "cup_0"), {"cup_0": {"right"}})
    assert not ok(_set(scene, 0, "plate_0", "cup_0"), {"plate_0": {"left"}})
    # the cup held above the plate, not standing on it
    assert not ok(_set(scene, 0, "plate_0", "cup_0", cup_dz=0.03))
    # wrong order: the cup on the table at the target and the plate on top of it
    x, y = scene.draws["target_xy"][0]
    upside = {"cup_0": pose(x, y, TABLE_TOP), "plate_0": pose(x, y, TABLE_TOP + ppc.CUP.height)}
    assert not ok(upside)
    # the plate tipped over (dropped on its side)
    flipped = _set(scene, 0, "plate_0", "cup_0")
    flipped["plate_0"] = pose(x, y, TABLE_TOP + ppc.PLATE.radius, quat_about("x", math.pi / 2))
    assert not ok(flipped)


def _lifted(scene, plate, cup):
    d = scene.draws
    i, j = ppc.PLATES.index(plate), ppc.CUPS.index(cup)
    return {
        plate: pose(*d["plate_xy"][i], TABLE_TOP + 0.1),
        cup: pose(*d["cup_xy"][j], TABLE_TOP + 0.1),
    }


def test_the_stages_count_in_order(task, scene):
    held = {"plate_0": {"left"}, "cup_0": {"right"}}
    first = _set(scene, 0, "plate_0", "cup_0")
    second = {**first, **_set(scene, 1, "plate_1", "cup_1")}
    frames = (
        [dict(poses=_lifted(scene, "plate_0", "cup_0"), contacts=held, openings=(0, 0))]
        + [dict(poses=first)] * 4
        + [dict(poses={**first, **_lifted(scene, "plate_1", "cup_1")}, openings=(0, 0))]
        + [dict(poses=second)] * 4
    )
    monitor = _run(task, scene, frames)
    assert monitor.success and monitor.score() == pytest.approx(1.0)
    # both places set, but never lifted in the order the stages ask: the picks of the second
    # pair happened before the first place was set
    early = (
        [dict(poses={**_lifted(scene, "plate_0", "cup_0")}, openings=(0, 0))]
        + [dict(poses={**first, **_lifted(scene, "plate_1", "cup_1")}, openings=(0, 0))]
        + [dict(poses=second)] * 4
    )
    monitor = _run(task, scene, early)
    assert not monitor.success and monitor.score() == pytest.approx(0.5)
    # the last place still held by the right gripper at the end
    end_held = frames[:-1] + [dict(poses=second, contacts={"cup_1": {"right"}})]
    monitor = _run(task, scene, end_held)
    assert not monitor.success


@pytest.mark.slow
def test_expert_sets_both_places_on_two_seeds(task):
    for seed in (0, 1):
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False)))
        assert result.success, f"seed {seed}: {result.reason}"
        assert len(result.recorder) <= task.step_limit

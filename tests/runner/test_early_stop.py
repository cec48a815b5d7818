"""Early stop: a rollout whose task object has left the table ends at once as a failure with its
reason, the stages done before kept; a policy that holds still keeps its whole step limit; what a
task lets leave the table (``Task.may_leave_table``) does not end it; the report counts the
reasons; ``--no-early-stop`` turns it off."""

import json

import numpy as np
import pytest

import bicoord_drake.runner.evaluate as evaluate_module
from bicoord_drake.env import LOST_SECONDS, LostObjects, make_env, off_table
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.runner.evaluate import EvaluateConfig, evaluate
from bicoord_drake.runner.rollouts import RolloutResult, rollout
from bicoord_drake.sim.simulation import PhysicsDivergedError, Simulation
from bicoord_drake.stages.predicates import lifted
from bicoord_drake.stages.stage import Stage, WorldState
from bicoord_drake.tasks.base import Task
from bicoord_drake.tasks.sweep_block import BIN_XY, BRUSH, CUBE, SweepBlock

LIMIT = 40  # control steps (2.7 s at 15 Hz): a falling cube is lost within 12


class Ledge(Task):
    """Test task: a cube on the table, and one released 10 cm beyond the table's right end,
    15 cm above its top, that falls off the table."""

    name = "ledge"
    step_limit = LIMIT
    instructions_seen = tuple(f"seen {k}" for k in range(5))
    instructions_unseen = tuple(f"unseen {k}" for k in range(5))
    #: Where the second cube starts.
    start = (0.7, 0.0, TABLE_TOP + 0.15)

    def sample_scene(self, seed: int) -> Scene:
        falling = cube("falling", 0.7, 0.0, color=(0.2, 0.6, 0.25, 1))
        falling = falling.model_copy(update={"pose": Pose(xyz=self.start)})
        return Scene(name="ledge", seed=seed, objects=(cube("cube", 0.1, 0.0), falling))

    def stages(self, scene: Scene) -> list[Stage]:
        return [
            Stage("stay", "hold", "hold", 0.5, lambda state: True, "persistent", ()),
            Stage("lift", "lift the cube", "hold", 0.5, lifted("cube", 0.05), "transient", ()),
        ]

    def expert(self, scene, view):
        yield from ()


class LedgeToolDropped(Ledge):
    """The falling cube is a tool the task lets leave the table anywhere."""

    name = "ledge_tool_dropped"

    def may_leave_table(self, scene):
        return {"falling": None}


class LedgeIntoTheBin(Ledge):
    """The second cube lies on the floor beside the table's right end, in the region the task
    lets it be in (a bin on the floor). (It starts there: a cube dropped from the table's height
    does not stay on the floor - at the 1/120 s plant step it goes through the floor slab or
    bounces off far away.)"""

    name = "ledge_into_the_bin"
    start = (0.8, 0.0, 0.02)

    def may_leave_table(self, scene):
        return {"falling": (((0.6, -0.2, -0.1), (0.9, 0.2, TABLE_TOP)),)}


class LedgeOutsideTheBin(LedgeIntoTheBin):
    """The same cube on the floor, the region on the other side of the table."""

    name = "ledge_outside_the_bin"

    def may_leave_table(self, scene):
        return {"falling": (((-0.9, -0.2, -0.1), (-0.6, 0.2, TABLE_TOP)),)}


@pytest.fixture(autouse=True)
def tasks(tmp_path, monkeypatch, temporary_tasks):
    """The test tasks registered for this test only; the expert-check cache kept in tmp."""
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))
    temporary_tasks(Ledge, LedgeToolDropped, LedgeIntoTheBin, LedgeOutsideTheBin)


def config(tmp_path, **kw) -> EvaluateConfig:
    settings = dict(
        task="ledge",
        policy="noop",
        episodes=1,
        render=False,
        expert_check=False,
        workers=1,
        out=str(tmp_path / "eval"),
    )
    settings.update(kw)
    return EvaluateConfig(**settings)


# --------------------------------------------------------------------------- the rule
def test_off_table_is_on_the_floor_or_beyond_the_margin_never_on_the_table():
    assert off_table(np.array([0.0, 0.0, TABLE_TOP + 0.02])) is None
    assert off_table(np.array([0.59, -0.34, TABLE_TOP])) is None  # a table corner
    assert off_table(np.array([0.7, 0.0, TABLE_TOP + 0.2])) is None  # 10 cm out, in the air
    assert "below the table top" in off_table(np.array([0.0, 0.5, 0.02]))
    assert "below the table top" in off_table(np.array([0.0, 0.0, TABLE_TOP - 0.06]))
    assert "outside the table's edge" in off_table(np.array([0.0, -0.55, TABLE_TOP + 0.3]))


def _state(scene: Scene, xyz, fingers=()) -> WorldState:
    sides = frozenset(fingers)
    return WorldState.initial(
        scene,
        object_poses={"cube": [*xyz, 1, 0, 0, 0], "falling": [0.1, 0.1, 0.77, 1, 0, 0, 0]},
        contacts={"cube": sides},
        finger_contacts={"cube": sides},
    )


def test_an_object_is_lost_after_half_a_second_off_the_table_untouched_by_the_fingers():
    task = Ledge()
    scene = task.sample_scene(0)
    watch = LostObjects(task, scene, control_rate=15.0)
    assert watch.hold == int(np.ceil(LOST_SECONDS * 15))
    floor = (0.8, 0.0, 0.02)
    for step in range(1, watch.hold):
        assert watch.update(_state(scene, floor), step) is None
    reason = watch.update(_state(scene, floor), watch.hold)
    assert reason.startswith(f"object_left_table at step {watch.hold}: 'cube' is 0.73 m below")
    assert "(since step 1)" in reason
    # held below the table's edge by a gripper: can be saved, the count starts again
    watch = LostObjects(task, scene, control_rate=15.0)
    for step in range(1, 3 * watch.hold):
        assert watch.update(_state(scene, (0.65, 0.0, 0.6), fingers=("left",)), step) is None
    assert watch.update(_state(scene, floor), 3 * watch.hold) is None  # dropped: counts anew


def test_a_task_naming_an_object_it_does_not_have_is_refused():
    class Wrong(Ledge):
        def may_leave_table(self, scene):
            return {"brush": None}

    with pytest.raises(ValueError, match=r"may_leave_table names \['brush'\]"):
        LostObjects(Wrong(), Wrong().sample_scene(0), 15.0)


def test_sweep_block_lets_its_tools_leave_the_table():
    task = SweepBlock()
    watch = LostObjects(task, task.sample_scene(0), 15.0)
    assert watch.watched == [CUBE]


# --------------------------------------------------------------------------- rollouts
def test_a_dropped_object_ends_the_rollout_early_as_a_failure_with_its_reason(tmp_path):
    report = evaluate(config(tmp_path, episodes=2))
    assert report.n == 2 and report.sr == 0.0
    for r in report.rollouts:
        assert not r.success and r.failure == "object_left_table"
        assert r.steps < LIMIT // 2, r.steps
        assert r.error.startswith(f"object_left_table at step {r.steps}: 'falling' is ")
        assert "below the table top" in r.error and r.traceback is None
        # the stages done before are kept: the persistent one holds when the rollout ends
        assert r.completed == [True, False] and r.score == pytest.approx(0.5)
    assert report.ssr == pytest.approx(0.5)
    assert report.failures == {"object_left_table": 2}
    data = json.loads(report.report_path.read_text())
    assert data["failures"] == {"object_left_table": 2}
    assert data["rollouts"][0]["failure"] == "object_left_table"
    assert data["config"]["early_stop"] is True
    text = report.format_text()
    assert "failures: object_left_table 2" in text
    assert "2 of 2 rollouts ended early when a task object left the table" in text


def test_without_early_stop_the_rollout_runs_to_its_step_limit(tmp_path):
    report = evaluate(config(tmp_path, early_stop=False))
    (r,) = report.rollouts
    assert r.steps == LIMIT and r.failure == "step_limit" and r.error is None
    assert report.failures == {"step_limit": 1}


@pytest.mark.parametrize("task", ["ledge_tool_dropped", "ledge_into_the_bin"])
def test_an_object_the_task_lets_leave_the_table_does_not_end_the_rollout(tmp_path, task):
    (r,) = evaluate(config(tmp_path, task=task, step_limit=20)).rollouts
    assert r.steps == 20 and r.failure == "step_limit"


def test_an_object_outside_the_region_it_may_leave_into_ends_the_rollout(tmp_path):
    (r,) = evaluate(config(tmp_path, task="ledge_outside_the_bin")).rollouts
    assert r.failure == "object_left_table" and r.steps < LIMIT // 2


def test_a_policy_that_holds_still_keeps_its_whole_step_limit():
    """Nothing on a real task's table moves: no early stop, whatever the step limit."""
    env = make_env("jigsaw", 100000, render=False, step_limit=25, early_stop=True)
    r = rollout(env, _HoldStill(), seed=100000)
    assert r.steps == 25 and not r.success and r.failure == "step_limit" and r.error is None
    assert env.info()["failure_reason"] is None and env.info()["truncated"]


class _HoldStill:
    def reset(self, instruction):
        self.target = None

    def act(self, obs):
        if self.target is None:
            self.target = np.asarray(obs["joint_state"], dtype=float)
        return self.target


class SweptIntoTheBin(SweepBlock):
    """sweep_block with the cube already in its bin and the brush dropped on the floor behind
    the table: neither ends a rollout."""

    def sample_scene(self, seed: int) -> Scene:
        scene = super().sample_scene(seed)
        moved = {
            CUBE: Pose(xyz=(*BIN_XY, TABLE_TOP + 0.03)),
            BRUSH: Pose(xyz=(0.0, 0.6, 0.002)),
        }
        objects = tuple(
            o.model_copy(update={"pose": moved[o.name]}) if o.name in moved else o
            for o in scene.objects
        )
        return scene.model_copy(update={"objects": objects})


def test_sweep_block_cube_in_its_bin_and_a_dropped_brush_do_not_end_the_rollout():
    env = make_env(SweptIntoTheBin(), 100000, render=False, step_limit=20, early_stop=True)
    r = rollout(env, _HoldStill(), seed=100000)
    assert r.steps == 20 and r.failure == "step_limit", r.error
    poses = env.sim.object_poses()
    assert poses[BRUSH][2] < TABLE_TOP - 0.3  # on the floor, and allowed there
    assert poses[CUBE][2] > TABLE_TOP  # in the bin on the table


def test_diverged_physics_is_a_failure_with_its_reason(tmp_path, monkeypatch):
    step = Simulation.step

    def diverging(self, action):
        if self.steps == 2:
            raise PhysicsDivergedError("the physics diverged during control step 3 (test)")
        step(self, action)

    monkeypatch.setattr(Simulation, "step", diverging)
    report = evaluate(config(tmp_path, task="ledge_tool_dropped"))
    (r,) = report.rollouts
    assert r.failure == "physics_diverged" and r.error.startswith("physics diverged at step 2")
    assert report.failures == {"physics_diverged": 1}


def test_the_summary_counts_rollouts_per_reason(tmp_path):
    def result(seed, failure):
        ok = failure is None
        return RolloutResult(seed, ok, float(ok), 5, [ok, ok], [float(ok)] * 2, failure=failure)

    reasons = [None, "object_left_table", "step_limit", "object_left_table", "physics_diverged"]
    rollouts = [result(100000 + k, f) for k, f in enumerate(reasons)]
    cfg = config(tmp_path)
    report = evaluate_module._report(Ledge(), cfg, rollouts, [], None)
    assert report.failures == {"object_left_table": 2, "physics_diverged": 1, "step_limit": 1}
    assert list(report.failures) == ["object_left_table", "physics_diverged", "step_limit"]


def test_the_cli_turns_early_stop_off(monkeypatch, capsys):
    import importlib.util
    from pathlib import Path

    script = Path(__file__).resolve().parents[2] / "scripts" / "evaluate.py"
    spec = importlib.util.spec_from_file_location("evaluate_cli_early_stop", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with pytest.raises(SystemExit):
        module.main(["--help"])
    assert "--no-early-stop" in capsys.readouterr().out
    seen = []

    class Report:
        def format_text(self):
            return "ok"

    def fake_evaluate(config, progress=None):
        seen.append(config.early_stop)
        return Report()

    monkeypatch.setattr(evaluate_module, "evaluate", fake_evaluate)
    args = ["--task", "ledge", "--policy", "noop", "--no-render", "--workers", "1"]
    assert module.main(args) == 0 and module.main([*args, "--no-early-stop"]) == 0
    assert seen == [True, False]


def test_the_gymnasium_env_terminates_with_the_failure_reason():
    from bicoord_drake.gym_env import BiCoordEnv

    env = BiCoordEnv("ledge", render=False, early_stop=True)
    obs, info = env.reset(seed=100000)
    assert info["failure_reason"] is None
    for _ in range(LIMIT):
        obs, reward, terminated, truncated, info = env.step(obs["observation.state"])
        if terminated or truncated:
            break
    assert terminated and not truncated and not info["is_success"]
    assert info["failure_reason"].startswith("object_left_table at step ")
    env.close()

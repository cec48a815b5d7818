"""One episode assembly: generation, the policy environment, the Gymnasium environment and the
evaluation's expert check and rollouts all build their episodes from one EpisodeSetup, so every
setting - task, seed, randomize, split, robot, station - reaches the simulation on every path.

The settings used here are all non-default (randomized unseen scenes, another control rate,
another robot: the ViperX pair registered under a second name), so a path that dropped one
would build the default instead and fail."""

import json

import gymnasium
import h5py
import numpy as np
import pytest
from pydantic import ValidationError

from bicoord_drake.config import CameraConfig, StationConfig
from bicoord_drake.data.episode import read_episode, read_manifest
from bicoord_drake.env import make_env
from bicoord_drake.episode_setup import EpisodeSetup, assemble
from bicoord_drake.gym_env import register_envs
from bicoord_drake.models.robots import EMBODIMENTS
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.models.viperx import aloha_viperx
from bicoord_drake.runner import generate as gen
from bicoord_drake.runner import rollouts
from bicoord_drake.runner.evaluate import EvaluateConfig, evaluate
from bicoord_drake.stages import Stage
from bicoord_drake.tasks import registry
from bicoord_drake.tasks.base import Task
from tests.policies.dummy import Spy

ROBOT = "viperx_copy"
SEEN: list[dict] = []


class Probe(Task):
    """A one-cube task whose expert records what it was built with, then holds still."""

    name = "setup_probe"
    step_limit = 10
    supported_robots = ("aloha_viperx", ROBOT)
    instructions_seen = ("Look around.",) * 5
    instructions_unseen = ("Have a look.",) * 5

    def sample_scene(self, seed):
        return Scene(name=self.name, seed=seed, objects=(cube("c", 0.0, 0.0),))

    def stages(self, scene):
        return [Stage("look", "look", "look", 1.0, lambda s: True, "persistent")]

    def expert(self, scene, view):
        SEEN.append({"scene": view.scene, "station": view.config, "robot": view.embodiment.name})
        home = view.embodiment.home_action()
        for _ in range(2):
            yield home


@pytest.fixture
def probe(monkeypatch, tmp_path, temporary_tasks):
    """The probe task and a second robot registered for this test, which the probe and jigsaw
    (for its Gymnasium id) declare; a private check cache."""
    temporary_tasks(Probe)
    monkeypatch.setitem(
        EMBODIMENTS, ROBOT, lambda: aloha_viperx().model_copy(update={"name": ROBOT})
    )
    jigsaw = registry._TASKS["jigsaw"]
    monkeypatch.setattr(jigsaw, "supported_robots", (*jigsaw.supported_robots, ROBOT))
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))
    SEEN.clear()
    Spy.bound.clear()
    yield Probe.name


def randomized_unseen(seed: int) -> Scene:
    return Probe().sample_scene(seed).randomized("unseen")


# --------------------------------------------------------------------------- the value
def test_the_robot_is_given_once_either_way():
    by_field = EpisodeSetup(task="jigsaw", seed=1, embodiment="aloha_viperx")
    assert by_field.station.embodiment == "aloha_viperx"
    with pytest.raises(ValidationError, match="unknown embodiment 'ur5'; choose one of: "):
        EpisodeSetup(task="jigsaw", seed=1, embodiment="ur5")
    with pytest.raises(ValidationError, match="unknown embodiment 'ur5'"):
        EpisodeSetup(task="jigsaw", seed=1, station=StationConfig(embodiment="ur5"))


def test_a_robot_in_the_station_settings_is_the_episodes_robot(probe):
    setup = EpisodeSetup(task=probe, seed=1, station=StationConfig(embodiment=ROBOT))
    assert setup.embodiment == ROBOT == setup.station.embodiment
    setup = EpisodeSetup(task=probe, seed=1, embodiment=ROBOT)
    assert setup.station.embodiment == ROBOT
    with pytest.raises(ValidationError, match="differ: give the robot once"):
        EpisodeSetup(
            task=probe, seed=1, embodiment=ROBOT, station=StationConfig(embodiment="other")
        )


def test_copies_keep_every_other_setting_and_serialize_the_task_by_name(probe):
    setup = EpisodeSetup(
        task=Probe(), seed=3, randomize=True, split="unseen", embodiment=ROBOT
    ).for_seed(4)
    assert (setup.seed, setup.randomize, setup.split, setup.embodiment) == (
        4,
        True,
        "unseen",
        ROBOT,
    )
    assert not setup.without_cameras().station.render and setup.station.render
    assert json.loads(setup.model_dump_json())["task"] == probe
    assert setup.make_scene() == randomized_unseen(4)
    with pytest.raises(ValidationError, match=r"\[0, 2\*\*32\)"):
        setup.for_seed(2**32)


# --------------------------------------------------------------------------- the paths
def test_run_expert_builds_the_setups_scene_robot_and_station(probe):
    station = StationConfig(control_rate=10.0, kp_scale=1.5, render=False)
    setup = EpisodeSetup(
        task=probe, seed=4, randomize=True, split="unseen", embodiment=ROBOT, station=station
    )
    result = gen.run_expert(setup)
    assert result.success, result.reason
    (seen,) = SEEN
    assert seen["scene"] == result.scene == randomized_unseen(4) and seen["scene"].distractors
    assert seen["robot"] == ROBOT and seen["station"] == station.model_copy(
        update={"embodiment": ROBOT}
    )
    assert result.recorder.fps == 10.0 and result.instruction in Probe.instructions_unseen


def test_assemble_reuses_the_simulation_only_for_the_same_scene_and_station(probe):
    setup = EpisodeSetup(task=probe, seed=4, station=StationConfig(render=False))
    first = assemble(setup)
    assert assemble(setup, first).sim is first.sim
    assert assemble(setup.for_seed(5), first).sim is not first.sim
    slower = setup.replace(station=StationConfig(render=False, control_rate=10.0))
    assert assemble(slower, first).sim is not first.sim


def test_make_env_and_the_gymnasium_env_build_what_they_are_given(probe):
    env = make_env(
        probe, 4, randomize=True, split="unseen", fps=10.0, render=False, embodiment=ROBOT
    )
    assert env.scene == randomized_unseen(4) and env.embodiment == ROBOT
    assert env.sim.station.embodiment.name == ROBOT and env.config.control_rate == 10.0
    env.reset(5)  # another seed, the same settings
    assert env.scene == randomized_unseen(5) and env.sim.station.embodiment.name == ROBOT
    gym = gymnasium.make(
        "bicoord_drake/jigsaw-v0",
        render=False,
        randomize=True,
        split="unseen",
        fps=10.0,
        embodiment=ROBOT,
        disable_env_checker=True,
    )
    inner = gym.unwrapped.bicoord_env
    assert inner.embodiment == ROBOT and inner.scene.appearance.split == "unseen"
    assert inner.config.control_rate == 10.0
    assert gym.observation_space["observation.state"].shape == (inner.layout.state_size,)
    with pytest.raises(ValueError, match="unknown embodiment 'ur5'; choose one of"):
        make_env(probe, 4, render=False, embodiment="ur5")


def test_generation_records_the_robot_in_the_file_manifest_and_directory(probe, tmp_path):
    config = gen.GenerateConfig(
        task=probe,
        episodes=1,
        out=str(tmp_path / "data"),
        fps=10.0,
        randomize=True,
        embodiment=ROBOT,
        render=False,
        video=False,
        workers=1,
    )
    assert config.config_name == ROBOT  # robots are kept apart
    assert gen.default_config_name(True, ROBOT) == f"{ROBOT}_randomized"
    assert gen.default_config_name(True) == "randomized"
    summary = gen.generate(config)
    assert summary.kept == 1 and summary.root == tmp_path / "data" / probe / ROBOT
    (seen,) = SEEN  # generation draws from the seen split
    assert seen["robot"] == ROBOT and seen["scene"] == Probe().sample_scene(0).randomized("seen")
    assert seen["station"].control_rate == 10.0
    episode = read_episode(summary.root / "data" / "episode0.hdf5", images=False)
    assert episode.embodiment == ROBOT and episode.config["embodiment"] == ROBOT
    assert episode.layout.action_size == episode.joint_action.shape[1] == 14
    with h5py.File(episode.path) as f:
        assert f["joint_action/left_arm"].shape == (episode.length, 6)
    assert read_manifest(summary.root).config["embodiment"] == ROBOT


def test_an_older_directory_without_a_recorded_robot_resumes(probe, tmp_path):
    config = gen.GenerateConfig(
        task=probe, episodes=1, out=str(tmp_path), render=False, video=False, workers=1
    )
    assert config.config_name == "default"
    gen.generate(config)
    manifest_path = tmp_path / probe / "default" / "manifest.json"
    manifest = json.loads(manifest_path.read_text())
    del manifest["config"]["embodiment"]  # as written before the robot was recorded
    manifest_path.write_text(json.dumps(manifest))
    again = gen.generate(config.model_copy(update={"episodes": 2}))
    assert again.kept == 2
    assert read_manifest(again.root).config["embodiment"] == "aloha_viperx"
    other = config.model_copy(update={"embodiment": ROBOT})  # same directory, other robot
    with pytest.raises(ValueError, match="different settings"):
        gen.generate(other)


def test_the_expert_check_runs_on_the_rollouts_episode(probe, tmp_path):
    config = EvaluateConfig(
        task=probe,
        policy="tests.policies.dummy:Spy",
        episodes=1,
        randomize=True,
        split="unseen",
        fps=10.0,
        embodiment=ROBOT,
        render=False,
        workers=1,
        out=str(tmp_path / "eval"),
    )
    report = evaluate(config)
    assert report.n == 1 and not report.skipped
    (checked,) = SEEN  # the expert check's episode
    (rolled,) = Spy.bound  # the rollout's
    assert checked["scene"] == rolled["scene"] == randomized_unseen(100000)
    assert checked["robot"] == rolled["setup"].embodiment == ROBOT
    physics = {"render", "cameras"}
    assert checked["station"].model_dump(exclude=physics) == rolled["station"].model_dump(
        exclude=physics
    )
    assert rolled["station"].control_rate == 10.0
    # the parallel path's worker checks the same episode
    rollouts_setup = config.episode_setup(Probe(), 100000)
    assert rollouts_setup.model_dump(exclude={"station"}) == rolled["setup"].model_dump(
        exclude={"station"}
    )
    SEEN.clear()
    from bicoord_drake.runner.evaluate_parallel import rollout_job

    outcome = rollout_job(config, 100001, None, check=True, video=False)
    assert outcome.verdict == {"ok": True, "reason": None}
    assert SEEN[0]["scene"] == randomized_unseen(100001) and SEEN[0]["robot"] == ROBOT
    assert Spy.bound[-1]["scene"] == SEEN[0]["scene"]


def test_evaluation_settings_flow_into_one_setup():
    config = EvaluateConfig(
        task="jigsaw", policy="noop", resolution="64x48", depth=True, fps=10.0, split="seen"
    )
    setup = config.episode_setup("jigsaw", 7)
    assert setup.station == StationConfig(
        control_rate=10.0, cameras=CameraConfig(width=64, height=48, depth=True)
    )
    assert (setup.seed, setup.split, setup.randomize) == (7, "seen", False)
    assert rollouts.ExpertCheck.for_config(setup.get_task(), config).setup.station.render is False
    with pytest.raises(ValidationError, match="unknown embodiment 'ur5'"):
        EvaluateConfig(task="jigsaw", policy="noop", embodiment="ur5")
    with pytest.raises(ValidationError, match="unknown embodiment 'ur5'"):
        gen.GenerateConfig(task="jigsaw", embodiment="ur5")


def test_a_demonstration_of_another_robot_is_refused(probe, tmp_path):
    config = gen.GenerateConfig(
        task=probe, episodes=1, out=str(tmp_path), render=False, video=False, workers=1
    )
    root = gen.generate(config).root
    env = make_env(probe, render=False, embodiment=ROBOT)
    with pytest.raises(ValueError, match="recorded with embodiment 'aloha_viperx'.*--embodiment"):
        env.reset(episode=root / "data" / "episode0.hdf5")
    np.testing.assert_array_equal(env.reset()["joint_state"].shape, (14,))


# --------------------------------------------------------------------------- rates and scenarios
class SlowProbe(Probe):
    """The probe, with an expert that needs 15 control steps (its limit is 10 at 15 Hz) and a
    stage named after the scene's seed."""

    name = "setup_probe_slow"

    def stages(self, scene):
        return [Stage(f"look {scene.seed}", "look", "look", 1.0, lambda s: True, "persistent")]

    def expert(self, scene, view):
        home = view.embodiment.home_action()
        for _ in range(15):
            yield home


@pytest.fixture
def slow_probe(probe, temporary_tasks):
    temporary_tasks(SlowProbe)
    return SlowProbe.name


def test_the_step_limit_scales_with_the_rate(probe, slow_probe):
    """TASKS.md gives the limits at 15 Hz: at 30 Hz a rollout and the expert get twice the
    steps, the same time."""
    assert make_env(probe, 4, render=False).step_limit == Probe.step_limit
    assert make_env(probe, 4, render=False, fps=30.0).step_limit == 2 * Probe.step_limit
    assert make_env(probe, 4, render=False, fps=30.0, step_limit=3).step_limit == 3
    register_envs([probe])
    gym = gymnasium.make(
        f"bicoord_drake/{probe}-v0", render=False, fps=30.0, disable_env_checker=True
    )
    assert gym.unwrapped.step_limit == 2 * Probe.step_limit
    station = StationConfig(render=False)
    result = gen.run_expert(EpisodeSetup(task=slow_probe, seed=1, station=station))
    assert not result.success and result.reason == "step_limit: expert exceeded 10 steps"
    faster = station.model_copy(update={"control_rate": 30.0})
    assert gen.run_expert(EpisodeSetup(task=slow_probe, seed=1, station=faster)).success


def test_make_env_and_gymnasium_read_a_scenario_file_the_arguments_override(probe, tmp_path):
    path = tmp_path / "ten.yaml"
    path.write_text(
        "seed: 1\nrandomize: true\nembodiment: viperx_copy\n"
        "station: {control_rate: 10, kp_scale: 1.5, render: false}\n",
        encoding="utf-8",
    )
    env = make_env(probe, scenario=path)
    assert env.seed == 200000  # evaluation seeds of the scenario's seed: 100000 * (1 + 1)
    assert env.scene == randomized_unseen(200000) and env.embodiment == ROBOT
    assert (env.config.control_rate, env.config.kp_scale) == (10.0, 1.5)
    env = make_env(probe, 4, scenario=path, fps=20.0, randomize=False)
    assert (env.config.control_rate, env.config.kp_scale, env.randomize) == (20.0, 1.5, False)
    with pytest.raises(ValueError, match=r"^fps: Input should be less than or equal to 1000"):
        make_env(probe, 4, scenario=path, fps=5000.0)
    register_envs([probe])
    gym = gymnasium.make(
        f"bicoord_drake/{probe}-v0", scenario=str(path), fps=20.0, disable_env_checker=True
    )
    inner = gym.unwrapped.bicoord_env
    assert (inner.config.control_rate, inner.config.kp_scale, inner.seed) == (20.0, 1.5, 200000)
    path.write_text("task: jigsaw\n", encoding="utf-8")
    with pytest.raises(ValueError, match="task 'jigsaw', but this is the id of 'setup_probe'"):
        gymnasium.make(f"bicoord_drake/{probe}-v0", scenario=str(path), render=False)


def test_generation_records_the_scenario_in_files_and_manifests(probe, tmp_path):
    config = gen.GenerateConfig(
        task=probe,
        episodes=1,
        seed=5,
        out=str(tmp_path),
        fps=10.0,
        randomize=True,
        render=False,
        video=False,
        workers=1,
        scenario={"station": {"kp_scale": 1.5, "time_step": 1 / 150}},
    )
    root = gen.generate(config).root
    from bicoord_drake.scenario import Scenario, load_scenario

    episode = load_scenario(root / "data" / "episode0.hdf5")
    assert episode == config.scenario.for_episode(probe, 5)
    assert (episode.seed, episode.episodes, episode.station.time_step) == (5, 1, 1 / 150)
    assert Scenario(**read_manifest(root).scenario) == config.scenario
    dataset = json.loads((tmp_path / "dataset_default.json").read_text())
    assert Scenario(**dataset["scenario"]) == config.scenario
    # other physics are other data: the directory refuses them
    with pytest.raises(ValueError, match="different settings"):
        gen.generate(config.replace(scenario=config.scenario.with_overrides({"fps": 10.0,
                     "station.kp_scale": 2.0})))  # fmt: skip


def test_the_report_names_the_stages_of_the_evaluated_scene(slow_probe, tmp_path):
    """No rollout ran (the expert fails every seed): the stages still come from the scene of
    the evaluated seed, not from seed 0."""
    config = EvaluateConfig(
        task=slow_probe,
        policy="noop",
        episodes=1,
        max_tries=1,
        seed=2,
        randomize=True,
        render=False,
        workers=1,
        out=str(tmp_path / "eval"),
    )
    report = evaluate(config)
    assert report.n == 0 and len(report.skipped) == 1
    assert [s["subgoal"] for s in report.stages] == ["look 300000"]


def test_rollouts_on_demonstrations_get_their_recorded_rate_and_physics(probe, tmp_path):
    generated = gen.GenerateConfig(
        task=probe,
        episodes=1,
        out=str(tmp_path / "data"),
        render=False,
        video=False,
        workers=1,
        scenario={"station": {"control_rate": 10.0, "kp_scale": 1.5, "time_step": 1 / 150}},
    )
    root = gen.generate(generated).root
    config = EvaluateConfig(
        task=probe,
        policy="tests.policies.dummy:Spy",
        data=str(root),
        render=False,
        workers=1,
        out=str(tmp_path / "eval"),
    )
    assert evaluate(config).n == 1
    (rolled,) = Spy.bound
    station = rolled["station"]
    assert (station.control_rate, station.kp_scale, station.time_step) == (10.0, 1.5, 1 / 150)

"""Noisy execution, clean labels (DART, issue #54): the ``action_noise`` setting, the noise
itself, the episode datasets and the replay of a noisy episode.

Two full balance_roller episodes run here (module fixtures, no cameras): one without noise and
one with; everything else needs no physics."""

from __future__ import annotations

from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from bicoord_drake.data.episode import EpisodeRecorder, read_episode
from bicoord_drake.models.layout import layout_of
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.policies.builtin import ReplayPolicy
from bicoord_drake.runner import generate as gen
from bicoord_drake.scenario import (
    ACTION_NOISE_MAX,
    Scenario,
    ScenarioError,
    action_noise_draw,
    load_scenario,
    resolve,
)

TASK, SEED = "balance_roller", 0
RANGE = (0.008, 0.012)
ROBOT = get_embodiment("aloha_viperx")
LAYOUT = layout_of("aloha_viperx")
GRIPPERS = LAYOUT.gripper_indices
ARM = [i for i in range(LAYOUT.action_size) if i not in GRIPPERS]


def noise(setting, seed: int = 0) -> gen.NoisyExecution:
    return gen.NoisyExecution.for_episode(setting, seed, LAYOUT, ROBOT.arm.lower, ROBOT.arm.upper)


# --------------------------------------------------------------------------- the setting
@pytest.mark.parametrize(
    ("given", "expected"),
    [
        (0, 0.0),
        (0.01, 0.01),
        ("0.01", 0.01),
        ("0.005-0.02", (0.005, 0.02)),
        ("1e-3-2e-2", (0.001, 0.02)),
        ([0.005, 0.02], (0.005, 0.02)),
        ([0.01, 0.01], 0.01),  # a range of one level is that level
    ],
)
def test_the_setting_takes_a_level_or_a_range(given, expected):
    assert resolve({}, {"action_noise": given}).action_noise == expected


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ("loud", "write SIGMA or LO-HI"),
        (0.5, f"in \\[0, {ACTION_NOISE_MAX:g}\\] rad"),
        ("-0.1", "write SIGMA or LO-HI"),
        ("0.02-0.01", "a range runs from low to high"),
        ([0.01, 0.02, 0.03], "a range is two levels"),
        (True, "a number of radians"),
    ],
)
def test_a_bad_setting_names_the_flag_and_what_is_wrong(given, message):
    with pytest.raises(ScenarioError, match=f"^--action-noise: .*{message}"):
        resolve({}, {"action_noise": given}, {"action_noise": "--action-noise"})


def test_off_by_default_and_then_absent_from_the_records():
    scenario = Scenario(task=TASK)
    assert scenario.action_noise == 0.0 and not scenario.noisy
    assert "action_noise" not in scenario.to_dict()  # records as before the setting existed
    assert "action_noise" not in gen.GenerateConfig(task=TASK).data_settings()
    assert gen.GenerateConfig(task=TASK).config_name == "default"


def test_a_noisy_run_records_its_setting_and_gets_its_own_directory():
    config = gen.GenerateConfig(task=TASK, action_noise="0.005-0.02")
    assert config.data_settings()["action_noise"] == [0.005, 0.02]
    assert config.config_name == "default_noisy"
    assert (
        gen.default_config_name(True, "franka_pair", noisy=True) == "franka_pair_randomized_noisy"
    )
    assert Scenario.model_validate(config.scenario.to_dict()) == config.scenario


def generate_main():
    """scripts/generate.py's main."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scripts" / "generate.py"
    spec = importlib.util.spec_from_file_location("script_generate_noise", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_the_command_line_flag(capsys):
    main = generate_main()
    assert main(["--task", TASK, "--action-noise", "0.005-0.02", "--print-scenario"]) == 0
    assert capsys.readouterr().out.endswith("action_noise:\n- 0.005\n- 0.02\n")
    assert main(["--task", TASK, "--action-noise", "0.3"]) == 2
    assert "--action-noise: a level must be in [0, 0.2] rad" in capsys.readouterr().err


def test_the_flag_alone_asks_for_the_default_level(capsys):
    """`--action-noise` without a value is DEFAULT_ACTION_NOISE (what the sweep supports); a
    value overrides it; no flag, no noise."""
    from bicoord_drake.scenario import DEFAULT_ACTION_NOISE

    main = generate_main()
    assert main(["--task", TASK, "--action-noise", "--print-scenario"]) == 0
    assert f"action_noise: {DEFAULT_ACTION_NOISE}\n" in capsys.readouterr().out
    assert main(["--task", TASK, "--action-noise", "0.01", "--print-scenario"]) == 0
    assert "action_noise: 0.01\n" in capsys.readouterr().out
    assert main(["--task", TASK, "--print-scenario"]) == 0
    assert "action_noise" not in capsys.readouterr().out


def test_a_range_draws_one_level_per_episode_from_the_seed():
    scenario = Scenario(task=TASK, action_noise=RANGE)
    levels = [scenario.action_noise_level(seed) for seed in range(40)]
    assert all(RANGE[0] <= level <= RANGE[1] for level in levels)
    assert len(set(levels)) == 40 and levels == [scenario.action_noise_level(s) for s in range(40)]
    # the episode's scenario records the level it drew; that level gives the same noise again
    recorded = scenario.for_episode(TASK, 7)
    assert recorded.action_noise == levels[7]
    a, b = noise(RANGE, 7), noise(recorded.action_noise, 7)
    assert a.level == b.level == levels[7]
    action = ROBOT.home_action()
    assert np.array_equal(a.apply(action), b.apply(action))


# --------------------------------------------------------------------------- the noise
def test_the_noise_is_gaussian_on_the_arm_joints_only():
    sigma = 0.01
    noisy = noise(sigma, seed=3)
    label = ROBOT.home_action()
    executed = np.stack([noisy.apply(label) for _ in range(4000)])
    delta = executed - label
    assert np.all(delta[:, GRIPPERS] == 0.0)  # grippers exactly as commanded
    std = delta[:, ARM].std(axis=0)
    assert np.all(np.abs(std / sigma - 1) < 0.06), std  # each joint: sigma within 6 %
    assert np.all(np.abs(delta[:, ARM].mean(axis=0)) < 4 * sigma / np.sqrt(4000))  # zero mean
    assert np.all(label == ROBOT.home_action())  # the label is not touched


def test_the_noise_respects_the_joint_limits():
    lower, upper = ROBOT.arm.lower, ROBOT.arm.upper
    label = LAYOUT.compose({"left": lower, "right": upper}, {"left": 1.0, "right": 0.0})
    noisy = noise(ACTION_NOISE_MAX)
    for _ in range(200):
        q = LAYOUT.split(noisy.apply(label))
        assert np.all(q["left"][0] >= lower) and np.all(q["right"][0] <= upper)
        assert (q["left"][1], q["right"][1]) == (1.0, 0.0)


def test_the_same_seed_gives_the_same_noise():
    label = ROBOT.home_action()
    runs = [[noise(0.01, seed).apply(label) for _ in range(3)] for seed in (5, 5, 6)]
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])
    # its generator is not the scene's: default_rng(seed) draws something else
    _, rng = action_noise_draw(0.01, 5)
    assert rng.random() != np.random.default_rng(5).random()


# --------------------------------------------------------------------------- the file
def recorded(executed: bool) -> EpisodeRecorder:
    recorder = EpisodeRecorder(fps=15.0, initial_action=np.zeros(14))
    for t in range(3):
        recorder.add_frame(
            action=np.full(14, 0.1 * t),
            executed_action=np.full(14, 0.1 * t + 0.01) if executed else None,
            joint_state=np.zeros(14),
            left_endpose=[0, 0, 1, 1, 0, 0, 0],
            right_endpose=[0.5, 0, 1, 1, 0, 0, 0],
            object_poses={},
        )
    return recorder


def test_the_file_holds_the_label_and_the_executed_action(tmp_path):
    meta = dict(
        task=TASK, seed=0, instruction="x", embodiment="aloha_viperx", success=True, object_count=1
    )
    rows = [[0, 1, "a", "l", "r", 0.5], [1, 3, "b", "l", "r", 0.5]]
    path = recorded(True).write(
        tmp_path / "noisy.hdf5", rows, {**meta, "extra": {"action_noise": 0.01}}
    )
    episode = read_episode(path)
    assert np.allclose(episode.joint_action[:, 0], [0.0, 0.1, 0.2])  # the label
    assert np.allclose(episode.executed_action[:, 0], [0.01, 0.11, 0.21])
    assert episode.replay_action is episode.executed_action and episode.action_noise == 0.01
    with h5py.File(path) as f:
        assert np.allclose(f["joint_action/left_arm"][:, 0], [0.0, 0.1, 0.2])
    # the action in effect at a stage's start is the executed one (a stage reset restores it)
    assert np.allclose(episode.initial_action[1], 0.01)
    clean = read_episode(recorded(False).write(tmp_path / "clean.hdf5", rows, meta))
    assert clean.executed_action is None and clean.replay_action is clean.joint_action
    assert clean.action_noise == 0.0 and np.allclose(clean.initial_action[1], 0.0)
    with pytest.raises(ValueError, match="executed_action must be given for every frame"):
        recorder = recorded(True)
        recorder.add_frame(
            action=np.zeros(14),
            joint_state=np.zeros(14),
            left_endpose=[0, 0, 1, 1, 0, 0, 0],
            right_endpose=[0.5, 0, 1, 1, 0, 0, 0],
            object_poses={},
        )


def test_the_replay_policy_replays_the_executed_actions():
    label, executed = np.zeros((4, 14)), np.ones((4, 14))
    episode = SimpleNamespace(
        joint_action=label, executed_action=executed, replay_action=executed, length=4
    )
    env = SimpleNamespace(
        action_mode="qpos", episode=episode, start_frame=1, stage=None, action=np.zeros(14)
    )
    policy = ReplayPolicy()
    policy.bind(env)
    policy.reset("")
    assert np.array_equal([policy.act({}) for _ in range(3)], executed[1:])


# --------------------------------------------------------------------------- episodes
def generated(tmp_path_factory, action_noise):
    """One kept balance_roller episode (no cameras) generated with `action_noise`."""
    out = tmp_path_factory.mktemp("data")
    config = gen.GenerateConfig(
        task=TASK,
        seed=SEED,
        episodes=1,
        max_tries=1,
        render=False,
        action_noise=action_noise,
        out=str(out),
        workers=1,
    )
    summary = gen.generate(config)
    assert summary.kept == 1, [f.reason for f in summary.failures]
    return read_episode(summary.root / "data" / "episode0.hdf5", images=False)


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    from bicoord_drake.sim.simulation import Simulation

    sent: list[np.ndarray] = []
    step = Simulation.step

    def spying(self, action):
        sent.append(np.array(action))
        return step(self, action)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Simulation, "step", spying)
        episode = generated(tmp_path_factory, 0)
    return episode, np.array(sent)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    return generated(tmp_path_factory, f"{RANGE[0]}-{RANGE[1]}")


def test_without_noise_the_station_gets_the_labels_and_nothing_new_is_written(clean):
    episode, sent = clean
    assert np.array_equal(sent, episode.joint_action)  # the expert's actions, bit for bit
    assert episode.executed_action is None and "action_noise" not in episode.attrs
    assert "action_noise" not in episode.scenario_text


def test_with_noise_the_label_stays_and_the_executed_action_is_beside_it(noisy):
    level = Scenario(action_noise=RANGE).action_noise_level(SEED)
    assert noisy.action_noise == level and RANGE[0] <= level <= RANGE[1]
    assert load_scenario(noisy.path).action_noise == level  # regenerating gives this level
    delta = noisy.executed_action - noisy.joint_action
    assert np.all(delta[:, GRIPPERS] == 0.0)
    arm = delta[:, ARM]
    assert abs(arm.std() / level - 1) < 0.1 and abs(arm.mean()) < 0.1 * level, arm.std()
    lower, upper = np.tile(ROBOT.arm.lower, 2), np.tile(ROBOT.arm.upper, 2)
    assert np.all(noisy.executed_action[:, ARM] >= lower)
    assert np.all(noisy.executed_action[:, ARM] <= upper)
    assert noisy.config["action_noise"] == list(RANGE)


def test_the_replay_of_a_noisy_episode_reproduces_it(noisy):
    """From the start bit for bit; from a stage reset within rounding (the interpolator latches
    ``current + (action - current)``, which a restored state cannot give back to the last bit
    for arbitrary actions: 4e-13 rad here)."""
    from bicoord_drake.env import make_env

    env = make_env(TASK, render=False, split="seen")
    policy = ReplayPolicy()
    for stage, atol in ((None, 0.0), (1, 1e-9)):
        obs = env.reset(episode=noisy, stage=stage)
        policy.bind(env)
        policy.reset(env.instruction)
        t = env.start_frame
        assert np.array_equal(obs["joint_state"], noisy.joint_state[t])
        info = {"done": False}
        while not info["done"] and t + 1 < noisy.length:
            obs, info = env.step(policy.act(obs))
            t += 1
            assert np.allclose(obs["joint_state"], noisy.joint_state[t], rtol=0, atol=atol), t
        assert info["done"] and info["success" if stage is None else "stage_success"]
    env.close()


@pytest.mark.slow
def test_the_episode_scenario_makes_the_noisy_episode_again(noisy, tmp_path):
    """``--scenario EPISODE.hdf5``: the recorded level and the seed give the same noise, so the
    same labels and executed actions, bit for bit (one more episode: slow)."""
    config = gen.GenerateConfig(
        scenario=load_scenario(noisy.path),
        out=str(tmp_path),
        max_tries=1,
        workers=1,
    )
    assert config.config_name == "default_noisy"
    root = gen.generate(config).root
    assert "bit for bit" in gen.compare_regenerated(noisy.path, root, SEED)

"""``--env.type=bicoord`` for lerobot-eval and lerobot-train (bicoord_drake/lerobot_env.py):
the observation layout lerobot reads, the config lerobot's CLI finds after package discovery,
its vectorised env factory, the prompt, success and the step limit, early stop, close() releasing
the simulator, and a whole lerobot-eval run of a tiny ACT checkpoint (30-50 s)."""

import gc
import json
import os
import shutil
import subprocess
import sys
import weakref
from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from bicoord_drake.lerobot_env import ENV_ID, LeRobotBiCoordEnv  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TASK = "balance_roller"  # two task objects: a 14-number environment state
SMALL = {"cameras": "head", "resolution": (64, 48), "step_limit": 3}


def test_importing_the_package_imports_neither_lerobot_nor_this_module():
    code = (
        "import sys, bicoord_drake, bicoord_drake.gym_env, bicoord_drake.policies\n"
        "bad = [m for m in ('lerobot', 'torch', 'bicoord_drake.lerobot_env') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]


def test_observations_in_lerobot_s_layout():
    env = gymnasium.make(ENV_ID, task=TASK, environment_state=True, **SMALL)
    assert isinstance(env, LeRobotBiCoordEnv)  # no wrapper hides task_description from lerobot
    obs, info = env.reset(seed=0)
    assert info["seed"] == 100000  # lerobot's seed 0 is the benchmark's first evaluation seed
    assert set(obs) == {"pixels", "agent_pos", "environment_state"}
    assert set(obs["pixels"]) == {"head"}
    assert obs["pixels"]["head"].shape == (48, 64, 3) and obs["pixels"]["head"].dtype == np.uint8
    assert obs["agent_pos"].shape == (14,) and obs["agent_pos"].dtype == np.float32
    assert obs["environment_state"].shape == (14,)
    assert env.observation_space.contains(obs)
    assert env.task_description == env.task == env.unwrapped.task_description != ""
    assert env.get_wrapper_attr("_max_episode_steps") == 3
    assert env.render().shape == (48, 64, 3)
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(obs["agent_pos"])
    assert truncated and not terminated and info["is_success"] is False
    obs, info = env.reset()  # without a seed: the next scene
    assert info["seed"] == 100001
    env.close()


def test_state_observations_and_bad_arguments():
    env = gymnasium.make(ENV_ID, task=TASK, obs_type="state", step_limit=2)
    obs, _ = env.reset(seed=5)
    assert set(obs) == {"agent_pos"} and env.cameras == ()
    closed = []
    env.bicoord_env.close = lambda: closed.append(True)  # the simulator's, where it has one
    env.close()
    assert closed == [True]
    with pytest.raises(ValueError, match="obs_type must be one of"):
        LeRobotBiCoordEnv(TASK, obs_type="rgb")
    with pytest.raises(ValueError, match="unknown camera 'top'; cameras are head, left, right"):
        LeRobotBiCoordEnv(TASK, cameras="head,top")


@pytest.mark.parametrize("level", ["Env", "BiCoordEnv", "LeRobotBiCoordEnv"])
def test_close_releases_the_simulator(level):
    """After close() nothing holds the station or the simulator (they are garbage); a reset
    builds them again."""
    from bicoord_drake.env import make_env

    if level == "Env":
        env = make_env(TASK, 100000, render=False, step_limit=2)
        inner, reset = env, lambda: env.reset(100001)
    elif level == "BiCoordEnv":
        env = gymnasium.make(f"bicoord_drake/{TASK}-v0", render=False, step_limit=2)
        inner, reset = env.unwrapped.bicoord_env, lambda: env.reset(seed=100001)
    else:
        env = gymnasium.make(ENV_ID, task=TASK, obs_type="state", step_limit=2)
        inner, reset = env.bicoord_env, lambda: env.reset(seed=1)
    reset()
    refs = [weakref.ref(x) for x in (inner.sim, inner.sim.station, inner.sim.simulator)]
    env.close()
    env.close()  # twice is fine
    gc.collect()
    assert inner.assembly is None
    assert [r() for r in refs] == [None, None, None]
    reset()  # built again
    assert inner.seed == 100001 and inner.sim is not None
    env.close()


# ------------------------------------------------------------------ with lerobot
@pytest.fixture(scope="module")
def lerobot():
    """lerobot's CLI plug-in loading, as ``--env.discover_packages_path=bicoord_drake`` runs it."""
    from bicoord_drake.policies.lerobot_policy import preload_triton

    preload_triton()  # other tests of the session may have rendered
    pytest.importorskip("torch")
    pytest.importorskip("lerobot.envs.factory")
    from lerobot.configs.parser import load_plugin

    load_plugin("bicoord_drake")  # imports bicoord_drake and every module directly in it
    import lerobot.envs.factory as factory
    import lerobot.envs.utils as utils

    return factory, utils


def _parse(cls, args):
    import draccus

    return draccus.parse(config_class=cls, args=args)


def test_lerobot_finds_the_env_type_and_makes_vectorised_envs(lerobot):
    factory, utils = lerobot
    from lerobot.configs.eval import EvalPipelineConfig
    from lerobot.envs.configs import EnvConfig

    from bicoord_drake.lerobot_env import BiCoordEnvConfig

    assert EnvConfig.get_choice_class("bicoord") is BiCoordEnvConfig
    cfg = _parse(
        EvalPipelineConfig,
        [
            "--env.type=bicoord",
            f"--env.task={TASK}",
            "--env.cameras=head",
            "--env.observation_width=64",
            "--env.observation_height=48",
            "--env.environment_state=true",
            "--env.episode_length=3",
            "--eval.batch_size=2",
            "--eval.n_episodes=2",
        ],
    ).env
    assert isinstance(cfg, BiCoordEnvConfig) and cfg.type == "bicoord"
    # the features lerobot gives a policy are our export's names and shapes
    features = utils.env_to_policy_features(cfg)
    assert {k: tuple(f.shape) for k, f in features.items()} == {
        "action": (14,),
        "observation.images.head": (3, 48, 64),
        "observation.state": (14,),
        "observation.environment_state": (14,),
    }
    envs = factory.make_env(cfg, n_envs=2)
    vec = envs["bicoord"][0]
    assert isinstance(vec, gymnasium.vector.SyncVectorEnv) and vec.num_envs == 2
    utils.check_env_attributes_and_types(vec)
    assert vec.call("_max_episode_steps") == (3, 3)
    obs, info = vec.reset(seed=[0, 1])
    assert list(info["seed"]) == [100000, 100001]
    batch = utils.add_envs_task(vec, utils.preprocess_observation(obs))
    assert batch["observation.images.head"].shape == (2, 3, 48, 64)
    assert batch["observation.state"].shape == (2, 14)
    assert batch["observation.environment_state"].shape == (2, 14)
    assert batch["task"] == [e.task_description for e in vec.envs] and all(batch["task"])
    for _ in range(3):
        obs, reward, terminated, truncated, info = vec.step(np.asarray(obs["agent_pos"]))
    assert truncated.all() and not terminated.any()
    assert info["final_info"]["is_success"].tolist() == [False, False]  # what lerobot reads
    utils.close_envs(envs)


def test_an_early_stop_is_a_terminated_failure_with_its_reason(lerobot, temporary_tasks):
    """``--env.early_stop=true``: lerobot-eval's vector env sees the rollout whose task object
    fell off the table terminated (not truncated), unsuccessful, with the reason in
    ``final_info``; off by default, as in make_env."""
    factory, utils = lerobot
    from lerobot.configs.eval import EvalPipelineConfig

    from bicoord_drake.lerobot_env import BiCoordEnvConfig
    from tests.runner.test_early_stop import LIMIT, Ledge

    temporary_tasks(Ledge)  # a cube falls off the table
    assert BiCoordEnvConfig(task=Ledge.name).gym_kwargs["early_stop"] is False
    args = ["--env.type=bicoord", f"--env.task={Ledge.name}", "--env.obs_type=state"]
    cfg = _parse(EvalPipelineConfig, [*args, "--env.early_stop=true"]).env
    assert cfg.early_stop is True and cfg.gym_kwargs["early_stop"] is True
    envs = factory.make_env(cfg, n_envs=2)
    vec = envs["bicoord"][0]
    obs, _ = vec.reset(seed=[0, 1])
    terminated = truncated = np.zeros(2, dtype=bool)
    step = 0
    while not (terminated.any() or truncated.any()) and step < LIMIT:
        obs, reward, terminated, truncated, info = vec.step(np.asarray(obs["agent_pos"]))
        step += 1
    assert step < LIMIT // 2 and terminated.all() and not truncated.any()
    final = info["final_info"]  # what lerobot-eval reads
    assert final["is_success"].tolist() == [False, False]
    for reason in final["failure_reason"]:
        assert reason.startswith(f"object_left_table at step {step}: 'falling' is "), reason
    utils.close_envs(envs)


def test_the_config_names_bad_values(lerobot):
    from bicoord_drake.lerobot_env import BiCoordEnvConfig

    with pytest.raises(ValueError, match="unknown task 'nope'; tasks: .*jigsaw"):
        BiCoordEnvConfig(task="nope")
    with pytest.raises(ValueError, match="obs_type must be one of"):
        BiCoordEnvConfig(task=TASK, obs_type="rgb")
    with pytest.raises(ValueError, match="disable_env_checker must stay true"):
        BiCoordEnvConfig(task=TASK, disable_env_checker=False)
    with pytest.raises(ValueError, match="franka"):
        BiCoordEnvConfig(task=TASK, embodiment="nope")
    endpose = BiCoordEnvConfig(task=TASK, obs_type="state", action_mode="endpose")
    assert endpose.features["action"].shape == (16,) and "pixels/head" not in endpose.features
    franka = BiCoordEnvConfig(task=TASK, obs_type="pixels", embodiment="franka_pair")
    assert franka.features["action"].shape == (16,) and "agent_pos" not in franka.features


def test_lerobot_train_accepts_the_env(lerobot):
    from lerobot.configs.train import TrainPipelineConfig

    from bicoord_drake.lerobot_env import BiCoordEnvConfig

    cfg = _parse(
        TrainPipelineConfig,
        [
            "--dataset.repo_id=bicoord_drake/jigsaw",
            "--policy.type=act",
            "--policy.push_to_hub=false",
            "--env.type=bicoord",
            "--env.task=jigsaw",
            "--eval_freq=1000",
        ],
    )
    assert isinstance(cfg.env, BiCoordEnvConfig) and cfg.env.task == "jigsaw"
    assert cfg.eval_freq == 1000


# ------------------------------------------------------------------ the whole lerobot-eval
def test_lerobot_eval_runs_a_checkpoint(tmp_path):
    """lerobot-eval, as a user runs it, on a tiny random ACT (state + head image) saved with
    lerobot's own save_pretrained: one episode of 3 steps, its eval_info.json and video
    (30-50 s on a shared 2-core machine, most of it imports: under the 60 s of a slow test)."""
    pytest.importorskip("lerobot.policies.act.modeling_act")
    command = shutil.which("lerobot-eval")
    if command is None:
        pytest.skip("lerobot-eval is not on PATH (pip install --no-deps lerobot==0.4.4)")
    import torch
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.factory import make_pre_post_processors

    from tests.policies.test_lerobot_policy import _act_config

    head = "observation.images.head"
    config = _act_config([("observation.state", ("STATE", (14,))), (head, ("VISUAL", (3, 48, 64)))])
    torch.manual_seed(0)
    stats = {
        "observation.state": {"mean": torch.zeros(14), "std": torch.ones(14)},
        head: {"mean": torch.full((3, 1, 1), 0.5), "std": torch.full((3, 1, 1), 0.25)},
        "action": {"mean": torch.zeros(14), "std": torch.full((14,), 0.01)},
    }
    pre, post = make_pre_post_processors(config, dataset_stats=stats)
    model = tmp_path / "pretrained_model"
    for saved in (ACTPolicy(config), pre, post):
        saved.save_pretrained(model)
    out = tmp_path / "eval"
    env = {**os.environ, "HF_HUB_OFFLINE": "1"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    args = [
        command,
        "--env.discover_packages_path=bicoord_drake",
        "--env.type=bicoord",
        f"--env.task={TASK}",
        "--env.cameras=head",
        "--env.observation_width=64",
        "--env.observation_height=48",
        "--env.episode_length=3",
        f"--policy.path={model}",
        "--policy.device=cpu",
        "--eval.n_episodes=1",
        "--eval.batch_size=1",
        "--seed=0",
        f"--output_dir={out}",
    ]
    run = subprocess.run(args, capture_output=True, text=True, env=env, timeout=900, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    info = json.loads((out / "eval_info.json").read_text())
    assert info["overall"]["n_episodes"] == 1 and info["overall"]["pc_success"] == 0.0
    (video,) = info["overall"]["video_paths"]
    assert Path(video).is_file()

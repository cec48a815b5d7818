"""The Gymnasium interface: registration, check_env, spaces keyed like the LeRobot export,
reset/step signatures, reward, truncation at the step limit, render()."""

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import bicoord_drake  # noqa: E402,F401  (registers the ids)
from bicoord_drake.gym_env import IMAGE_KEYS, builtin_task_names, env_id  # noqa: E402

# check_env's advice about unbounded (joint state, positions) and unnormalized (joint limits)
# Box spaces: the spaces are what the robot has, on purpose.
pytestmark = [
    pytest.mark.filterwarnings("ignore:.*infinity:UserWarning"),
    pytest.mark.filterwarnings("ignore:.*symmetric and normalized:UserWarning"),
]

TASK = "jigsaw"


def test_every_task_has_a_gymnasium_id():
    from bicoord_drake.tasks import list_tasks

    assert sorted(builtin_task_names()) == list_tasks()
    for task in list_tasks():
        assert env_id(task) in gymnasium.registry
    ours = {k for k in gymnasium.registry if k.startswith("bicoord_drake/")}
    assert ours == {env_id(t) for t in list_tasks()}


def test_import_registers_without_drake():
    code = (
        "import sys, gymnasium, bicoord_drake\n"
        "assert 'bicoord_drake/jigsaw-v0' in gymnasium.registry\n"
        "assert 'pydrake' not in sys.modules, 'registration imported Drake'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_keys_are_the_lerobot_export_features():
    from bicoord_drake.data.export import CAMERAS, lerobot_features
    from bicoord_drake.models.layout import layout_of
    from bicoord_drake.policies.lerobot_policy import IMAGE_FEATURES

    assert IMAGE_KEYS == CAMERAS == IMAGE_FEATURES
    episode = SimpleNamespace(
        attrs={"embodiment": "aloha_viperx"},
        rgb=dict.fromkeys(CAMERAS),
        image=lambda cam, t: np.zeros((24, 32, 3), np.uint8),
        path="stub",
    )
    features = lerobot_features(episode)
    from bicoord_drake.gym_env import BiCoordEnv

    # the spaces of a camera environment, without building one
    env = object.__new__(BiCoordEnv)
    env.cameras = tuple(CAMERAS)
    env.bicoord_env = SimpleNamespace(
        task=SimpleNamespace(instructions=lambda split: ("Fill the grid.",)),
        layout=layout_of("aloha_viperx"),
    )
    space = env._observation_space(32, 24)
    observed = set(space.spaces) - {"task"}
    assert observed == set(features) - {"action", "stage_index"}
    for key in observed:
        want = tuple(features[key]["shape"])
        assert space[key].shape == want, key


def _check_env(env):
    from gymnasium.utils.env_checker import check_env

    check_env(env.unwrapped)


def test_check_env_state_only():
    """Cameras off; check_env also makes it with render_mode='rgb_array' (head camera only)."""
    from bicoord_drake.tasks import get_task

    env = gymnasium.make(env_id(TASK), render=False, resolution="32x24")
    _check_env(env)
    assert not any(k.startswith("observation.images") for k in env.observation_space.spaces)
    assert env.unwrapped.step_limit == get_task(TASK).step_limit
    assert env.action_space.shape == (14,)
    assert env.unwrapped.render() is None  # no render mode
    env.close()


def test_check_env_with_cameras_and_render():
    env = gymnasium.make(env_id(TASK), render_mode="rgb_array", resolution="32x24")
    _check_env(env)
    obs, info = env.reset(seed=100000)
    assert set(obs) == {
        "observation.state",
        "observation.endpose",
        "observation.images.head",
        "observation.images.left",
        "observation.images.right",
        "task",
    }
    assert obs["observation.images.head"].shape == (24, 32, 3)
    assert obs["task"] == env.unwrapped.task_description
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (24, 32, 3)
    assert np.array_equal(frame, obs["observation.images.head"])
    env.close()
    env.close()


def test_step_limit_truncates_reward_is_score_progress():
    env = gymnasium.make(env_id(TASK), render=False, step_limit=2, seed=7)
    obs, info = env.reset()
    assert info["seed"] == 7 and info["score"] == 0.0 and info["step"] == 0
    hold = obs["observation.state"]
    result = env.step(hold)
    assert len(result) == 5
    obs, reward, terminated, truncated, info = result
    assert isinstance(reward, float) and isinstance(terminated, bool)
    assert (terminated, truncated) == (False, False)
    assert reward == info["score"] == 0.0
    assert info["is_success"] is False and info["step"] == 1
    obs, reward, terminated, truncated, info = env.step(hold)
    assert (terminated, truncated) == (False, True)
    assert info["truncated"] and info["done"]
    _, info = env.reset()  # no seed: the next one
    assert info["seed"] == 8 and info["step"] == 0
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"bogus": 1})
    env.close()


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="needs render=True"):
        gymnasium.make(env_id(TASK), render=False, cameras=["head_camera"])
    with pytest.raises(ValueError, match="unknown cameras"):
        gymnasium.make(env_id(TASK), cameras=["top_camera"])


def test_environment_state_has_the_exports_layout(tmp_path):
    """At reset, the observation's object poses are the export's feature for the same scene:
    one frame recorded from the environment's own simulation, exported, read back."""
    from bicoord_drake.policies.lerobot_policy import preload_triton

    preload_triton()  # earlier tests rendered (see its docstring)
    pytest.importorskip("lerobot.datasets.lerobot_dataset")
    from bicoord_drake.data import export
    from bicoord_drake.data.environment_state import ENVIRONMENT_STATE, feature_names
    from bicoord_drake.data.episode import (
        EpisodeLayout,
        EpisodeMeta,
        EpisodeRecorder,
        save_episode,
    )

    env = gymnasium.make(env_id(TASK), render=False, environment_state=True)
    _check_env(env)
    obs, _ = env.reset(seed=100003)
    inner = env.unwrapped.bicoord_env
    objects = inner.state_objects
    assert objects == tuple(o.name for o in inner.scene.objects if not o.distractor)
    assert env.unwrapped.environment_state_names == feature_names(objects)
    space = env.observation_space[ENVIRONMENT_STATE]
    assert space.shape == obs[ENVIRONMENT_STATE].shape == (7 * len(objects),)
    assert space.contains(obs[ENVIRONMENT_STATE])
    assert np.array_equal(obs[ENVIRONMENT_STATE], inner.environment_state().astype(np.float32))

    recorder = EpisodeRecorder(fps=15, layout=inner.layout)
    recorder.capture(inner.sim, inner.action)
    meta = EpisodeMeta(
        task=TASK,
        seed=inner.seed,
        instruction=inner.instruction,
        embodiment=inner.embodiment,
        success=False,
        object_count=len(objects),
        scene=inner.scene,
    )
    rows = [[0, 1, s.subgoal, s.left, s.right, s.score] for s in inner.stages[:1]]
    rows[0][-1] = 1.0
    save_episode(EpisodeLayout(tmp_path / "data", TASK, "t"), 0, recorder, rows, meta, video=False)
    result = export.export_lerobot(
        [tmp_path / "data"], tmp_path / "lr", images=False, environment_state=True
    )
    dataset = export.load_lerobot(result.root, result.repo_id)
    assert dataset.meta.features[ENVIRONMENT_STATE]["names"] == feature_names(objects)
    assert np.array_equal(dataset[0][ENVIRONMENT_STATE].numpy(), obs[ENVIRONMENT_STATE])
    assert ENVIRONMENT_STATE not in gymnasium.make(env_id(TASK), render=False).observation_space
    env.close()

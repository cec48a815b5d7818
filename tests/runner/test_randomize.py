"""--randomize: the appearance changes the pictures and clutter stands on the table; the task's
own objects, the expert's actions and the robot's motion stay those of the plain scene."""

import numpy as np

from bicoord_drake.env import make_env
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner import generate as gen
from tests.runner.test_generate_timings import Wave


def test_randomized_episode_has_the_same_actions_and_motion_but_other_pictures():
    plain = gen.run_expert(EpisodeSetup(task=Wave(passes=True), seed=5))
    randomized = gen.run_expert(EpisodeSetup(task=Wave(passes=True), seed=5, randomize=True))
    assert plain.scene.appearance is None and not plain.scene.distractors
    assert randomized.scene.appearance.split == "seen" and randomized.scene.distractors
    np.testing.assert_array_equal(plain.recorder.actions, randomized.recorder.actions)
    # The distractors' resting contacts join the one contact problem the solver solves per
    # step, so the arms' motion agrees to the solver's tolerance (a few microradians), not bits.
    np.testing.assert_allclose(
        plain.recorder.joint_states, randomized.recorder.joint_states, atol=1e-4
    )
    a = next(plain.recorder.frames("head_camera")).astype(int)
    b = next(randomized.recorder.frames("head_camera")).astype(int)
    assert np.abs(a - b).mean() > 10


def test_randomize_is_a_data_setting_only_when_on():
    assert "randomize" not in gen.GenerateConfig(task="jigsaw").data_settings()
    assert gen.GenerateConfig(task="jigsaw", randomize=True).data_settings()["randomize"]


def test_evaluation_env_draws_textures_of_its_split():
    env = make_env("jigsaw", 100_000, render=False, randomize=True, split="unseen")
    assert env.scene.appearance.split == "unseen"
    env.reset(100_001)
    assert env.scene.appearance.split == "unseen" and env.scene.seed == 100_001
    assert make_env("jigsaw", 100_000, render=False).scene.appearance is None

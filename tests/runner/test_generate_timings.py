"""Where generation time goes: every seed's phases are timed, only kept episodes are rendered,
and the run reports simulated seconds per wall second."""

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.runner import generate as gen
from bicoord_drake.stages import Stage
from bicoord_drake.tasks.base import Task


class Wave(Task):
    """A one-cube task: the left waist turns for four steps; its stage holds when `passes`."""

    name = "wave"
    step_limit = 10
    instructions_seen = ("Wave.",) * 5
    instructions_unseen = ("Say hello.",) * 5

    def __init__(self, passes: bool) -> None:
        self.passes = passes

    def sample_scene(self, seed):
        return Scene(name=self.name, seed=seed, objects=(cube("c", 0.0, 0.0),))

    def stages(self, scene):
        return [Stage("wave", "wave", "hold", 1.0, lambda s: self.passes, "persistent")]

    def expert(self, scene, view):
        home = view.embodiment.home_action()
        for k in range(4):
            action = home.copy()
            action[0] += 0.1 * k
            yield action


def test_a_kept_episode_is_rendered_after_verification_with_every_phase_timed():
    result = gen.run_expert(EpisodeSetup(task=Wave(passes=True), seed=0))
    assert result.success
    assert {"build", "planning", "physics", "monitor", "render", "jpeg"} <= set(result.timings)
    assert sorted(result.recorder.cameras) == ["head_camera", "left_camera", "right_camera"]
    head = list(result.recorder.frames("head_camera"))
    assert len(head) == 4 and head[0].shape == (240, 320, 3)
    assert not np.array_equal(head[0], head[-1])  # the frames follow the arm


def test_a_failed_seed_costs_no_rendering():
    result = gen.run_expert(EpisodeSetup(task=Wave(passes=False), seed=0))
    assert not result.success and result.reason.startswith("stage_not_verified")
    assert "render" not in result.timings and "physics" in result.timings


def test_without_cameras_nothing_is_rendered():
    result = gen.run_expert(
        EpisodeSetup(task=Wave(passes=True), seed=0, station=StationConfig(render=False))
    )
    assert result.success and result.recorder.cameras == []
    assert "render" not in result.timings


def test_throughput_counts_kept_simulated_seconds_and_every_seeds_phases():
    tp = gen.Throughput()
    tp.add(gen.SeedOutcome("t", 0, True, frames=30, timings={"physics": 3.0, "render": 1.0}), 15)
    tp.add(gen.SeedOutcome("t", 1, False, "planning: x", timings={"physics": 1.0}), 15)
    assert tp.kept == 1 and tp.simulated_seconds == pytest.approx(2.0)
    assert tp.phases == {"physics": 4.0, "render": 1.0}
    text = tp.describe(wall_seconds=4.0)
    assert "0.50 simulated s per wall s" in text
    assert "physics 80 %" in text and "render 20 %" in text

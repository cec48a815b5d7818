"""One full expert episode of every registered task, in physics without rendering.

Part of the default suite (so of CI): a task whose expert no longer produces a kept episode on
its ``ci_seed`` fails here. New tasks are covered by registering them.
"""

import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.tasks import get_task, list_tasks


@pytest.mark.parametrize("name", list_tasks())
def test_expert_episode_is_kept(name):
    task = get_task(name)
    result = run_expert(
        EpisodeSetup(task=task, seed=task.ci_seed, station=StationConfig(render=False))
    )
    assert result.success, f"{name}, seed {task.ci_seed}: {result.reason}"
    assert 0 < len(result.recorder) <= task.step_limit

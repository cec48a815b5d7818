"""Full expert episodes on the second robot, ``franka_pair`` (two 7-joint Pandas), in physics
without rendering: the same task code as on the ViperX, the robot only in the episode setup.

Three tasks of different families run in the default suite (a two-handed carry, stacking by
pick and place, tool use); the other tasks whose franka expert keeps seed 0 run with
``-m slow``."""

import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.tasks import get_task

#: Run by default: one task per family.
CI_TASKS = ("balance_roller", "build_tower_with_blocks", "sweep_block")
#: The other tasks whose expert keeps seed 0 on franka_pair.
SLOW_TASKS = (
    "jigsaw",
    "stack_bowls",
    "clean_table",
    "fetch_block_with_roller",
    "match_blocks_with_signs",
    "exchange_mics",
    "place_plate_and_cup",
    "build_bridge",
    "divide_block_tower",
    "put_objects_cabinet",
    "exchange_pots",
    "collect_pens",
)


def _run(name: str, seed: int = 0) -> None:
    task = get_task(name)
    result = run_expert(
        EpisodeSetup(
            task=task, seed=seed, embodiment="franka_pair", station=StationConfig(render=False)
        )
    )
    assert result.success, f"{name}, seed {seed} on franka_pair: {result.reason}"
    assert 0 < len(result.recorder) <= task.step_limit
    assert result.recorder.actions.shape[1] == 16  # [left 7, left opening, right 7, right opening]


@pytest.mark.parametrize("name", CI_TASKS)
def test_franka_expert_episode_is_kept(name):
    _run(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW_TASKS)
def test_franka_expert_episode_is_kept_slow(name):
    _run(name)

"""benchmarks/lerobot_eval_parity.py: the pieces that decide which seeds lerobot-eval runs."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "lerobot_eval_parity.py"


@pytest.fixture(scope="module")
def lp():
    sys.path.insert(0, str(SCRIPT.parent))
    spec = importlib.util.spec_from_file_location("lerobot_eval_parity", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_seeds_become_contiguous_lerobot_eval_runs(lp):
    assert lp.seed_blocks([0, 1, 2]) == [(0, 3)]
    assert lp.seed_blocks([0, 2, 3, 7]) == [(0, 1), (2, 2), (7, 1)]


def test_the_checkpoint_directory_and_its_inputs(lp, tmp_path):
    model = tmp_path / "run" / "checkpoints" / "last" / "pretrained_model"
    model.mkdir(parents=True)
    features = {"observation.state": {}, "observation.environment_state": {}}
    (model / "config.json").write_text(json.dumps({"input_features": features}))
    assert lp.pretrained_dir(tmp_path / "run") == model
    assert lp.reads_environment_state(model)
    with pytest.raises(ValueError, match="no pretrained_model"):
        lp.pretrained_dir(tmp_path)


def test_lerobot_eval_seeds_and_observation(lp, tmp_path):
    model = tmp_path / "m"
    model.mkdir()
    (model / "config.json").write_text(json.dumps({"input_features": {"observation.state": {}}}))
    args = type("A", (), {"task": "jigsaw", "batch_size": 4, "work": tmp_path})()
    command = lp.lerobot_eval_command(args, model, 2, 3)
    assert "--env.seed_offset=0" in command and "--seed=2" in command
    assert "--eval.n_episodes=3" in command and "--eval.batch_size=3" in command
    assert "--env.environment_state=false" in command and "--env.obs_type=state" in command


def test_success_per_episode_from_eval_info(lp):
    info = {"per_task": [{"task_group": "bicoord", "metrics": {"successes": [True, False]}}]}
    assert lp.lerobot_successes(info) == [True, False]
    with pytest.raises(ValueError, match="one task"):
        lp.lerobot_successes({"per_task": []})

"""scripts/generate.py --scenario EPISODE.hdf5 makes the episode again from its own record: the
same seed and settings, the same actions bit for bit."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from bicoord_drake.data.episode import read_episode, read_manifest
from bicoord_drake.scenario import load_scenario
from bicoord_drake.tasks import get_task
from tests.test_episode_setup import Probe

ROOT = Path(__file__).resolve().parents[2]


def generate(*args: str) -> int:
    spec = importlib.util.spec_from_file_location("generate_script", ROOT / "scripts/generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main([*args, "--workers", "1", "--no-render"])


def only_episode(root: Path) -> Path:
    (path,) = sorted(root.rglob("episode*.hdf5"))
    return path


def test_an_episode_names_its_own_settings_and_seed(tmp_path, capsys, temporary_tasks):
    temporary_tasks(Probe)
    settings = ("--fps", "10", "--randomize", "--split", "unseen", "--set", "station.kp_scale=2")
    assert generate("--task", Probe.name, "--seed", "7", "--episodes", "1", "--out",
                    str(tmp_path / "a"), *settings) == 0  # fmt: skip
    first = only_episode(tmp_path / "a")
    recorded = load_scenario(first)
    assert (recorded.seed, recorded.split, recorded.station.kp_scale) == (7, "unseen", 2.0)
    capsys.readouterr()
    assert generate("--scenario", str(first), "--out", str(tmp_path / "b")) == 0
    assert "bit for bit" in capsys.readouterr().out
    again = only_episode(tmp_path / "b")
    assert load_scenario(again) == recorded
    assert read_manifest(again.parents[1]).episodes[0].seed == 7  # only its seed was tried
    # the directory is named as the original run would have named it
    assert again.parents[1].name == first.parents[1].name == "randomized"


@pytest.mark.slow  # two expert episodes in physics: about 30 s
def test_a_task_episode_is_made_again_bit_for_bit(tmp_path, capsys):
    """balance_roller (the cheapest expert), randomized at 30 Hz: a regeneration that dropped
    either setting would plan another scene or another timing."""
    seed = get_task("balance_roller").ci_seed
    settings = ["--seed", str(seed), "--episodes", "1", "--randomize", "--fps", "30"]
    assert generate("--task", "balance_roller", *settings, "--out", str(tmp_path / "a")) == 0
    first = only_episode(tmp_path / "a")
    capsys.readouterr()
    assert generate("--scenario", str(first), "--out", str(tmp_path / "b")) == 0
    assert "bit for bit" in capsys.readouterr().out
    recorded = read_episode(first, images=False)
    made = read_episode(only_episode(tmp_path / "b"), images=False)
    assert made.fps == recorded.fps == 30.0 and made.seed == recorded.seed == seed
    assert made.joint_action.dtype == np.float64
    assert np.array_equal(made.joint_action, recorded.joint_action)
    assert np.array_equal(made.joint_state, recorded.joint_state)
    assert made.scene == recorded.scene and made.scene.distractors


@pytest.fixture(autouse=True)
def _private_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))

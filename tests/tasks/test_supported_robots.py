"""Each task declares the robots it supports (``Task.supported_robots``): the declaration is
checked; every entry point refuses an unsupported (task, robot) pair at once, before a station
is built, with one line naming the task, the robot and the robots the task supports;
``--task all`` is every task that supports the robot; ``scripts/generate.py --list-tasks``
prints each task's step limit and robots. No simulation here (the declared pairs' expert
episodes: test_franka_experts.py; the evidence behind each declaration:
test_task_checklist.py)."""

import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path

import gymnasium
import pytest
from pydantic import ValidationError

from bicoord_drake import episode_setup
from bicoord_drake.config import StationConfig
from bicoord_drake.env import make_env
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.layout import default_embodiment
from bicoord_drake.runner import generate as gen
from bicoord_drake.runner.evaluate import EvaluateConfig
from bicoord_drake.scenario import Scenario, ScenarioError
from bicoord_drake.tasks import get_task, list_tasks
from bicoord_drake.tasks.registry import (
    ALLOW_UNDECLARED_ENV,
    check_supported,
    task_table,
    tasks_for_robot,
)

ROOT = Path(__file__).resolve().parents[2]
ROBOT = "franka_pair"
#: Tasks whose franka expert keeps < 85 % of seeds 0-29 (benchmarks/franka_experts.md).
UNDECLARED = ("cook",)
REFUSED = "task 'cook' does not support the robot 'franka_pair': it supports aloha_viperx"


@pytest.fixture(autouse=True)
def nothing_is_built(monkeypatch):
    """The check is on: nothing may build a station."""
    monkeypatch.delenv(ALLOW_UNDECLARED_ENV, raising=False)

    def build_station(*args, **kwargs):
        raise AssertionError("a station was built for an unsupported pair")

    monkeypatch.setattr(episode_setup, "build_station", build_station)


def script(name: str):
    """scripts/<name>.py as a module (its main() runs in this process)."""
    spec = importlib.util.spec_from_file_location(f"script_{name}", ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_script(name: str, *args: str) -> tuple[subprocess.CompletedProcess, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))  # this checkout's package
    env.pop(ALLOW_UNDECLARED_ENV, None)
    t0 = time.perf_counter()
    result = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / f"{name}.py"), *args],
        capture_output=True,
        text=True,
        env=env,
    )
    return result, time.perf_counter() - t0


# --------------------------------------------------------------------------- the declarations
def test_every_task_supports_the_default_robot_and_the_franka_lists_are_the_measured_ones():
    assert tasks_for_robot(default_embodiment()) == list_tasks()
    declared = tasks_for_robot(ROBOT)
    assert declared and not set(declared) & set(UNDECLARED)
    assert set(declared) | set(UNDECLARED) == set(list_tasks())


def test_the_check_names_the_task_the_robot_and_its_robots(monkeypatch):
    # two tasks without the robot: cook, and collect_pens with its declaration taken away
    monkeypatch.setattr(type(get_task("collect_pens")), "supported_robots", ("aloha_viperx",))
    with pytest.raises(ValueError, match=f"^{REFUSED} "):
        check_supported("cook", ROBOT)
    with pytest.raises(ValueError, match=REFUSED):
        check_supported(get_task("cook"), ROBOT)  # a Task object: its class's declaration
    with pytest.raises(ValueError) as err:
        check_supported("jigsaw, cook,collect_pens", ROBOT)
    message = str(err.value)
    assert "'cook', 'collect_pens' do not support the robot 'franka_pair'" in message
    assert "jigsaw" not in message and len(message.splitlines()) == 1
    check_supported("jigsaw", ROBOT)
    check_supported("all", ROBOT)  # the tasks that support it
    check_supported("origami", ROBOT)  # unknown names: get_task's error
    for name in list_tasks():
        check_supported(name, default_embodiment())


def test_the_environment_variable_lets_a_pair_be_measured(monkeypatch):
    monkeypatch.setenv(ALLOW_UNDECLARED_ENV, "1")
    check_supported("cook", ROBOT)
    assert EpisodeSetup(task="cook", seed=0, embodiment=ROBOT).embodiment == ROBOT


# --------------------------------------------------------------------------- the entry points
def test_the_settings_values_refuse_the_pair():
    for make in (
        lambda: Scenario(task="cook", embodiment=ROBOT),
        lambda: Scenario(task="jigsaw,cook", station=StationConfig(embodiment=ROBOT)),
        lambda: EpisodeSetup(task="cook", seed=0, embodiment=ROBOT),
        lambda: EpisodeSetup(task=get_task("cook"), seed=0, embodiment=ROBOT),
        lambda: EpisodeSetup(task="cook", seed=0, station=StationConfig(embodiment=ROBOT)),
        lambda: gen.GenerateConfig(task="cook", embodiment=ROBOT, episodes=1),
        lambda: EvaluateConfig(task="cook", policy="noop", embodiment=ROBOT),
    ):
        with pytest.raises(ValidationError, match=REFUSED):
            make()
    assert Scenario(task="all", embodiment=ROBOT).task == "all"
    assert EpisodeSetup(task="jigsaw", seed=0, embodiment=ROBOT).embodiment == ROBOT


def test_make_env_and_gymnasium_refuse_the_pair_in_one_line():
    for make in (
        lambda: make_env("cook", embodiment=ROBOT, render=False),
        lambda: make_env(get_task("cook"), embodiment=ROBOT, render=False),
        lambda: make_env("cook", scenario=Scenario(embodiment=ROBOT), render=False),
        lambda: gymnasium.make("bicoord_drake/cook-v0", embodiment=ROBOT, render=False),
    ):
        with pytest.raises(ScenarioError) as err:
            make()
        assert str(err.value).startswith(REFUSED) and len(str(err.value).splitlines()) == 1


def test_all_is_every_task_that_supports_the_robot():
    assert gen.resolve_tasks("all", ROBOT) == tasks_for_robot(ROBOT)
    assert gen.resolve_tasks("all") == gen.resolve_tasks("all", default_embodiment())
    assert gen.resolve_tasks("all") == list_tasks()
    assert gen.skipped_tasks("all", ROBOT) == list(UNDECLARED)
    assert gen.skipped_tasks("jigsaw", ROBOT) == gen.skipped_tasks("all", "aloha_viperx") == []


def test_generate_all_runs_the_supported_tasks_and_names_the_skipped(monkeypatch, capsys, tmp_path):
    ran = []

    def fake_dataset(config, progress=None):
        ran.extend(gen.resolve_tasks(config.task, config.embodiment))
        return gen.DatasetSummary({}, tmp_path / "dataset.json", "fake", 0.0)

    monkeypatch.setattr(gen, "generate_dataset", fake_dataset)
    argv = ["--task", "all", "--embodiment", ROBOT, "--episodes", "1", "--out", str(tmp_path)]
    assert script("generate").main(argv) == 0
    assert ran == tasks_for_robot(ROBOT)
    err = capsys.readouterr().err
    assert f"skipped (they do not support {ROBOT}; --list-tasks): " + ", ".join(UNDECLARED) in err


@pytest.mark.parametrize("name", ["generate", "evaluate"])
def test_the_cli_refuses_the_pair_at_once(name, tmp_path):
    args = [
        "--task",
        "cook",
        "--embodiment",
        ROBOT,
        "--episodes",
        "1",
        "--out",
        str(tmp_path / "o"),
    ]
    if name == "evaluate":
        args += ["--policy", "noop"]
    result, seconds = run_script(name, *args)
    assert result.returncode == 2, result.stderr
    hint = "(scripts/generate.py --list-tasks lists each task's robots)"
    assert result.stderr.strip() == f"error: {REFUSED} {hint}"
    assert not (tmp_path / "o").exists()  # nothing made
    assert seconds < 60  # argument checks only (the package's import is most of it)


def test_list_tasks_prints_every_task_its_step_limit_and_robots():
    result, _ = run_script("generate", "--list-tasks")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == task_table()
    rows = {line.split()[0]: line.split(None, 2) for line in result.stdout.splitlines()[1:]}
    assert sorted(rows) == list_tasks()
    for name, (_, limit, robots) in rows.items():
        task = get_task(name)
        assert int(limit) == task.step_limit
        assert robots.split(", ") == list(task.supported_robots)
    assert "franka_pair" in rows["jigsaw"][2] and "franka_pair" not in rows["cook"][2]

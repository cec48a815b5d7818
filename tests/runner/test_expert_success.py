"""benchmarks/expert_success.py: argument checks and the markdown it writes (no physics)."""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "expert_success.py"


@pytest.fixture(scope="module")
def es():
    spec = importlib.util.spec_from_file_location("expert_success", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["expert_success"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def summary(kept: int, tried: int, mean_length: float, seconds_per_episode: float | None = None):
    """What a fake generate() returns: the real summary type, so the fakes keep its fields."""
    from bicoord_drake.runner.generate import GenerateSummary

    return GenerateSummary(Path("unused"), kept, tried, [], mean_length, seconds_per_episode, None)


def test_seed_ranges(es):
    assert es.parse_seeds("0-29") == range(0, 30)
    assert es.parse_seeds("7") == range(7, 8)
    assert es.parse_seeds(" 3 - 5 ") == range(3, 6)


@pytest.mark.parametrize(
    "text,words",
    [("9-3", "empty"), ("a-b", "FIRST-LAST"), ("-4", "FIRST-LAST"), ("0-4294967296", "2**32")],
)
def test_bad_seed_ranges_are_refused(es, text, words):
    with pytest.raises(ValueError, match=words.replace("*", r"\*")):
        es.parse_seeds(text)


def test_tasks_all_and_unknown_names(es):
    valid = ["cook", "jigsaw"]
    assert es.parse_tasks("all", valid) == valid
    assert es.parse_tasks("jigsaw, cook,jigsaw", valid) == ["jigsaw", "cook"]
    with pytest.raises(ValueError, match="'origami'.*cook, jigsaw"):
        es.parse_tasks("cook,origami", valid)


def result(es, task, kept, failures=()):
    return es.TaskResult(
        task=task,
        seeds=range(0, 10),
        kept=kept,
        tried=10,
        failures=list(failures),
        mean_length=512.4,
        wall_seconds=125.0,
        commit="abc123",
        dirty=True,
        date="2026-11-23 10:00",
        machine="x86_64",
    )


def test_section_has_counts_reasons_length_time_and_commit(es):
    text = es.format_section(
        result(es, "cook", 8, [(4, "planning: no IK | x"), (1, "stage_not_verified: serve")])
    )
    assert text.startswith("## cook\n")
    assert "**8/10 kept** (80 %), seeds 0–9" in text
    assert "`abc123` (dirty)" in text and "512 control steps" in text and "2.1 min" in text
    assert "`planning` 1, `stage_not_verified` 1" in text
    # failed seeds in order, table pipes escaped
    assert text.index("| 1 | stage_not_verified") < text.index("| 4 | planning: no IK \\| x |")


def test_updating_one_task_keeps_the_others(es):
    first = es.update_markdown("", {"cook": es.format_section(result(es, "cook", 8))})
    assert first.startswith(es.TITLE)
    both = es.update_markdown(first, {"jigsaw": es.format_section(result(es, "jigsaw", 10))})
    again = es.update_markdown(both, {"cook": es.format_section(result(es, "cook", 9))})
    assert again.count("## cook") == 1 and again.count("## jigsaw") == 1
    assert "**9/10 kept**" in again and "**8/10 kept**" not in again
    assert "**10/10 kept**" in again
    assert again.index("## cook") < again.index("## jigsaw")  # order kept
    assert again.startswith(es.TITLE)


def test_cli_refuses_bad_input_before_running_anything(tmp_path):
    out = tmp_path / "success.md"
    for args, words in [
        (("--tasks", "origami"), "jigsaw"),
        (("--seeds", "5-2"), "empty"),
        (("--workers", "0"), "--workers"),
        (("--action-noise", "0.5"), "[0, 0.2] rad"),
    ]:
        done = subprocess.run(
            [sys.executable, str(SCRIPT), *args, "--out", str(out)],
            capture_output=True,
            text=True,
        )
        assert done.returncode == 2
        assert words in done.stderr and "Traceback" not in done.stderr
    assert not out.exists()


def test_only_package_changes_make_a_measurement_dirty(es, tmp_path):
    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    git("config", "user.email", "t@t")
    git("config", "user.name", "t")
    (tmp_path / "bicoord_drake").mkdir()
    (tmp_path / "bicoord_drake" / "a.py").write_text("x = 1\n")
    (tmp_path / "report.md").write_text("old\n")
    git("add", "-A")
    git("commit", "-qm", "one")
    first, dirty = es.git_state(tmp_path)
    assert not dirty
    (tmp_path / "report.md").write_text("the script's own output\n")  # e.g. expert_success.md
    assert es.git_state(tmp_path) == (first, False)
    git("commit", "-qam", "report only")
    second, _ = es.git_state(tmp_path)
    assert second != first and not es.code_changed(first, second, tmp_path)
    (tmp_path / "bicoord_drake" / "a.py").write_text("x = 2\n")
    assert es.git_state(tmp_path)[1]
    git("commit", "-qam", "code")
    third, _ = es.git_state(tmp_path)
    assert es.code_changed(first, third, tmp_path)


@pytest.mark.parametrize(
    ("option", "section", "applied"),
    [
        (["--randomize"], "jigsaw (randomized)", lambda config: config.randomize),
        (
            ["--embodiment", "franka_pair"],
            "jigsaw (franka_pair)",
            lambda config: config.embodiment == "franka_pair",
        ),
        (
            ["--action-noise", "0.01"],
            "jigsaw (action noise 0.01 rad)",
            lambda config: config.action_noise == 0.01,
        ),
    ],
)
def test_a_variant_is_measured_in_its_own_section(
    es, tmp_path, monkeypatch, option, section, applied
):
    """--randomize and --embodiment reach the generator and get a section beside the plain
    one; the plain run does not inherit them."""
    from bicoord_drake.runner import generate as gen

    seen = {}

    def fake_generate(config):
        seen["config"] = config
        return summary(kept=2, tried=3, mean_length=100.0)

    monkeypatch.setattr(gen, "generate", fake_generate)
    monkeypatch.setattr(es, "git_state", lambda root=es.ROOT: ("abc", False))
    out = tmp_path / "success.md"
    argv = ["--tasks", "jigsaw", "--seeds", "0-2", "--out", str(out)]
    assert es.main([*argv, *option]) == 0
    assert applied(seen["config"]) and not seen["config"].render
    assert es.main(argv) == 0
    assert not applied(seen["config"])
    text = out.read_text()
    assert text.count(f"## {section}") == 1 and text.count("## jigsaw\n") == 1


def test_section_reports_the_replay_check_and_what_did_not_reproduce(es):
    r = result(es, "cook", 10)
    assert "replay check" not in es.format_section(r)
    r.replay, r.replay_failures = (9, 10), [(7, "2, 3")]
    text = es.format_section(r)
    assert "| replay check of the kept episodes | **9/10** reproduce every stage |" in text
    assert "| replay check wall time |" in text
    assert "| 7 | 2, 3 |" in text


def test_replay_option_replays_the_kept_episodes_of_the_run(es, tmp_path, monkeypatch):
    from bicoord_drake.runner import generate as gen

    monkeypatch.setattr(gen, "generate", lambda config: summary(kept=2, tried=3, mean_length=9))
    monkeypatch.setattr(es, "git_state", lambda root=es.ROOT: ("abc", False))
    replayed = {}

    def fake_replay(task, data, workers, embodiment=None):
        replayed.update(task=task, data=data, workers=workers, embodiment=embodiment)
        return 1, 2, [(5, "1")]

    monkeypatch.setattr(es, "replay_check", fake_replay)
    out = tmp_path / "success.md"
    assert es.main(["--tasks", "jigsaw", "--seeds", "0-2", "--out", str(out)]) == 0
    assert not replayed  # only when asked
    argv = ["--tasks", "jigsaw", "--seeds", "0-2", "--replay", "--workers", "2", "--out", str(out)]
    assert es.main(argv) == 0
    assert replayed["task"] == "jigsaw" and replayed["workers"] == 2
    assert replayed["data"].name == "jigsaw"
    assert "**1/2** reproduce every stage" in out.read_text()
    # the episodes of another robot are replayed on that robot (the environment refuses others)
    assert es.main([*argv, "--embodiment", "franka_pair"]) == 0
    assert replayed["embodiment"] == "franka_pair"


def test_data_option_keeps_the_episodes_and_marks_a_resumed_run(es, tmp_path, monkeypatch):
    from bicoord_drake.data.episode import EpisodeLayout
    from bicoord_drake.runner import generate as gen

    seen = []

    def fake_generate(config):
        seen.append(config.out)
        manifest = EpisodeLayout(Path(config.out), config.task, config.config_name).manifest
        manifest.parent.mkdir(parents=True, exist_ok=True)
        manifest.write_text("{}")
        return summary(kept=3, tried=3, mean_length=9, seconds_per_episode=40.0)

    monkeypatch.setattr(gen, "generate", fake_generate)
    monkeypatch.setattr(es, "git_state", lambda root=es.ROOT: ("abc", False))
    data, out = tmp_path / "data", tmp_path / "success.md"
    argv = ["--tasks", "jigsaw", "--seeds", "0-2", "--data", str(data), "--out", str(out)]
    assert es.main(argv) == 0
    assert seen == [str(data)] and (data / "jigsaw" / "default" / "manifest.json").exists()
    assert "resumed" not in out.read_text()
    assert es.main(argv) == 0  # the second run continues the first one's directory
    text = out.read_text()
    assert "(this run only: it resumed an earlier run's data, whose generation workers " in text
    assert "spent 2.0 min on all its seeds)" in text


def test_an_undeclared_pair_is_measured_and_the_check_is_back_afterwards(es, tmp_path, monkeypatch):
    """The evidence for a declaration: the script measures a task on a robot the task does not
    declare (cook on franka_pair), the variable on for the run (worker processes inherit it)
    and off again after it."""
    from bicoord_drake.runner import generate as gen
    from bicoord_drake.tasks.registry import ALLOW_UNDECLARED_ENV

    monkeypatch.delenv(ALLOW_UNDECLARED_ENV, raising=False)
    seen = {}

    def fake_generate(config):
        seen.update(config=config, allowed=os.environ.get(ALLOW_UNDECLARED_ENV))
        return summary(kept=0, tried=1, mean_length=None)

    monkeypatch.setattr(gen, "generate", fake_generate)
    monkeypatch.setattr(es, "git_state", lambda root=es.ROOT: ("abc", False))
    argv = ["--tasks", "cook", "--seeds", "0-0", "--embodiment", "franka_pair"]
    assert es.main([*argv, "--out", str(tmp_path / "success.md")]) == 0
    assert seen["config"].task == "cook" and seen["config"].embodiment == "franka_pair"
    assert seen["allowed"] == "1" and ALLOW_UNDECLARED_ENV not in os.environ
    with pytest.raises(ValueError, match="does not support the robot 'franka_pair'"):
        gen.GenerateConfig(task="cook", embodiment="franka_pair")

"""The generation progress bar stays one short line with every task; the per-task counts are
the end-of-run table."""

import importlib.util
from pathlib import Path

import pytest

import bicoord_drake.runner.generate as gen
from bicoord_drake.runner.generate import (
    POSTFIX_WIDTH,
    DatasetSummary,
    GenerateSummary,
    RunProgress,
    Throughput,
    format_counts,
)
from bicoord_drake.tasks import list_tasks

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "generate.py"
TASKS = list_tasks()


def status(running: tuple[str, ...] = (), kept: int = 3, tried: int = 5) -> RunProgress:
    """Every task with `kept` of 50 kept after `tried` seeds; the first three are done."""
    counts = {t: (50 if i < 3 else kept, 60 if i < 3 else tried, 50) for i, t in enumerate(TASKS)}
    return RunProgress(counts, "jigsaw seed 4: planning: no grasp", running)


def test_all_tasks_fit_in_a_short_postfix():
    assert len(TASKS) == 18
    longest = max(TASKS, key=len)
    for running in [(), ("jigsaw",), (longest,), tuple(TASKS) * 6, (longest, *TASKS)]:
        text = status(running).postfix()
        assert len(text) <= POSTFIX_WIDTH < 80, text
        assert text.startswith("3/18 tasks done, 195/255 kept/tried")
    assert status(("cook", "jigsaw", "cook")).postfix().endswith(", cook +1")
    assert status(tuple(TASKS)).postfix().endswith(" +17")
    # huge counts and the longest name: still one short line, the name cut
    big = status((longest, "cook"), kept=10**6, tried=10**7).postfix()
    assert len(big) <= POSTFIX_WIDTH and "…" in big


def test_the_counts_table_lists_every_task_and_the_totals():
    table = format_counts(status().counts).splitlines()
    assert table[0].split() == ["task", "kept", "target", "tried", "failed"]
    assert [line.split()[0] for line in table[1:]] == [*TASKS, "all"]
    assert table[1].split()[1:] == ["50", "50", "60", "10"]
    assert table[-1].split()[1:] == [str(3 * 50 + 15 * 3), "900", str(3 * 60 + 15 * 5), "60"]
    assert len(format_counts({"jigsaw": (1, 2, 3)}).splitlines()) == 2  # no totals for one


def test_cli_bar_shows_the_short_postfix_and_prints_the_table_at_the_end(
    tmp_path, monkeypatch, capsys
):
    def fake_dataset(config, progress):
        for k in range(3):
            progress(status(("jigsaw", "cook"), kept=k, tried=k))
        summaries = {
            t: GenerateSummary(tmp_path / t, 1, 2, [], None, None, None, target=1) for t in TASKS
        }
        return DatasetSummary(summaries, tmp_path / "dataset.json", "local", 1.0, Throughput())

    monkeypatch.setattr(gen, "generate_dataset", fake_dataset)
    spec = importlib.util.spec_from_file_location("generate_cli", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    code = module.main(["--task", "all", "--episodes", "50", "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0
    updates = [u for u in err.replace("\r", "\n").splitlines() if "tasks done" in u]
    assert updates and all(len(u.split("episode/s, ")[-1]) < 80 for u in updates)
    assert not any(f"{t} " in u for t in TASKS if t != "jigsaw" for u in updates)
    table = out[out.index("task ") :].splitlines()
    assert [line.split()[0] for line in table[1:20]] == [*TASKS, "all"]


@pytest.mark.parametrize("running", [(), ("jigsaw",)])
def test_one_task_postfix(running):
    text = RunProgress({"jigsaw": (2, 3, 10)}, "x", running).postfix()
    assert text == "0/1 tasks done, 2/3 kept/tried" + (", jigsaw" if running else "")


def test_the_driver_reports_the_seeds_in_flight(tmp_path, monkeypatch):
    from tests.runner.test_generate_driver import fake_episode, summary

    monkeypatch.setattr(gen, "produce_episode", fake_episode)
    monkeypatch.setattr(gen, "_summary", summary)
    seen: list[RunProgress] = []
    config = gen.GenerateConfig(task="jigsaw,cook", episodes=1, out=str(tmp_path), workers=1)
    gen.generate_dataset(config, seen.append)
    # one seed in flight at a time, the tasks in turn; nothing once the run is over
    assert [s.running for s in seen] == [("jigsaw",), ("cook",), ()]
    assert seen[0].message.startswith("started") and seen[-1].postfix().startswith("2/2 tasks")

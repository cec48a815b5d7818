"""benchmarks/policy_reproduces.py: its settings, commands, resume logic and Markdown section
(the steps faked: no physics, no training; the real run is the slow test at the end)."""

import json
import shutil
import sys
from pathlib import Path

import pytest

from tests.runner.benchmark_scripts import BENCHMARKS, load_benchmark


@pytest.fixture(scope="module")
def pr():
    return load_benchmark("policy_reproduces")


def test_defaults(pr):
    args = pr.parse_args([])
    assert args.tasks == ["balance_roller", "place_plate_and_cup"]
    assert (args.demos, args.steps, args.batch_size, args.train_seed) == (3, 20000, 8, 1000)
    assert args.out == pr.ROOT / "benchmarks" / "policy_reproduces.md"
    assert args.work.is_absolute() and not args.force
    args = pr.parse_args(["--tasks", " jigsaw,cook,jigsaw ", "--demos", "1", "--force"])
    assert args.tasks == ["jigsaw", "cook"] and args.demos == 1 and args.force


@pytest.mark.parametrize("argv", [["--demos", "0"], ["--steps", "0"], ["--tasks", ","]])
def test_bad_arguments_are_refused(pr, argv):
    with pytest.raises(SystemExit):
        pr.parse_args(argv)


def test_the_act_arguments_are_those_of_the_baselines_notes(pr):
    notes = (BENCHMARKS / "baselines_notes.md").read_text()
    assert f"act={pr.ACT_CPU_ARGS}" in notes
    # the proof's own: the baselines' model at learning rate 1e-4, with temporal ensembling
    extra = set(pr.REPRODUCE_ARGS.split()) - set(pr.ACT_CPU_ARGS.split())
    assert extra == {
        "--policy.n_action_steps=1",
        "--policy.temporal_ensemble_coeff=0.01",
        "--policy.optimizer_lr=1e-4",
    }
    assert "--policy.n_action_steps=20" not in pr.REPRODUCE_ARGS


def demos(tmp_path: Path, task: str, n: int) -> list[Path]:
    """`n` synthetic episode files of `task` (seeds 0..n-1) where generation puts them."""
    from tests.data.synthetic import make_dataset

    make_dataset(tmp_path / "work" / "data", lengths=(3,) * n, task=task)
    root = tmp_path / "work" / "data" / task / "default" / "data"
    return sorted(root.glob("*.hdf5"), key=lambda p: int(p.stem[7:]))


def test_commands_train_on_the_n_demos_and_evaluate_on_their_seeds(pr, tmp_path):
    args = pr.parse_args(["--tasks", "balance_roller", "--work", str(tmp_path / "work")])
    paths = pr.task_paths("balance_roller", args)
    assert paths.demos == tmp_path / "work" / "data" / "balance_roller" / "default"
    generate = pr.generate_command("balance_roller", args, paths)
    assert generate[1] == "scripts/generate.py"
    for option in (["--episodes", "3"], ["--seed", "0"], ["--workers", "1"]):
        assert generate[generate.index(option[0]) : generate.index(option[0]) + 2] == option
    assert "--no-render" in generate and generate[-2:] == ["--out", str(paths.data)]

    files = demos(tmp_path, "balance_roller", 5)[:3]
    export = pr.export_command(files, paths)
    assert export[2:5] == [str(files[0].parent), "--max-episodes", "3"]  # the first 3 exactly
    assert export[-2:] == ["--environment-state", "--no-images"]
    assert export[export.index("--out") + 1] == str(paths.dataset)

    train = pr.train_command("balance_roller", args, paths)
    assert f"--dataset.root={paths.dataset}" in train and "--policy.type=act" in train
    assert set(pr.baselines.COMMON_TRAIN_ARGS) <= set(train)
    assert set(pr.REPRODUCE_ARGS.split()) <= set(train)
    assert {"--steps=20000", "--batch_size=8", "--seed=1000"} <= set(train)
    assert train[-1] == f"--output_dir={paths.checkpoint}"

    evaluate = pr.evaluate_command("balance_roller", args, paths)
    assert evaluate[1] == "scripts/evaluate.py"
    assert evaluate[evaluate.index("--data") + 1] == str(paths.demos)  # the demos' seeds, scenes
    assert evaluate[evaluate.index("--episodes") + 1] == "3"
    assert evaluate[evaluate.index("--policy") + 1] == f"lerobot:{paths.checkpoint}"
    assert "--seed" not in evaluate and "--split" not in evaluate
    assert {"--no-render", "--json"} <= set(evaluate)
    assert evaluate[evaluate.index("--workers") + 1] == "1"
    # another training setting, another checkpoint (and result)
    other = pr.task_paths(
        "balance_roller", pr.parse_args(["--work", str(args.work), "--demos", "2"])
    )
    assert other.checkpoint != paths.checkpoint and other.result != paths.result


def report(files, successes, stages=("lift", "balance")):
    """A fake ``scripts/evaluate.py --json`` report on the episode `files`."""
    return {
        "n": len(files),
        "SR": sum(successes) / len(files),
        "SSR": 0.5,
        "stages": [{"subgoal": s, "completed": 0.5} for s in stages],
        "skipped": [],
        "rollouts": [
            {
                "seed": k,
                "episode": str(f),
                "success": ok,
                "completed": [True, ok],
                "failure": None if ok else "step_limit",
                "error": None,
            }
            for k, (f, ok) in enumerate(zip(files, successes, strict=True))
        ],
    }


def test_rollouts_are_scored_on_the_training_seeds(pr, tmp_path):
    files = [tmp_path / f"episode{k}.hdf5" for k in range(3)]
    scores = pr.score_rollouts(report(files, [True, False, True]), [0, 1, 2], files)
    assert scores["seeds_match"] and scores["eval_seeds"] == [0, 1, 2]
    assert scores["reproduced"] == 2 and scores["n"] == 3
    assert scores["stages"] == ["lift", "balance"]
    assert scores["rollouts"][1] == {
        "seed": 1,
        "success": False,
        "completed": [True, False],
        "failure": "step_limit",
        "error": None,
    }
    assert not pr.score_rollouts(report(files, [True] * 3), [0, 1, 5], files)["seeds_match"]
    others = [tmp_path / "elsewhere" / f.name for f in files]
    assert not pr.score_rollouts(report(others, [True] * 3), [0, 1, 2], files)["seeds_match"]


def fake_result(pr, **changes):
    files = [Path(f"/w/episode{k}.hdf5") for k in range(3)]
    result = {
        "task": "balance_roller",
        "policy": "act",
        "demos": 3,
        "steps": 5000,
        "batch_size": 8,
        "train_seed": 1000,
        **pr.score_rollouts(report(files, [True, False, True]), [0, 1, 2], files),
        "final_loss": 0.04321,
        "train_seconds": 1500.0,
        "generate_seconds": 120.0,
        "export_seconds": None,
        "evaluate_seconds": 300.0,
        "reused": ["export"],
        "commands": {
            "generate": "python scripts/generate.py --task balance_roller --episodes 3",
            "export": "python scripts/export.py D --max-episodes 3",
            "train": "lerobot-train --policy.type=act --steps=5000",
            "evaluate": "python scripts/evaluate.py --data D --episodes 3",
        },
        "run_command": "python benchmarks/policy_reproduces.py --tasks balance_roller",
        "commit": "abc1234",
        "dirty": True,
        "machine": "AMD EPYC, 2 cores",
        "date": "2026-12-01 10:00",
    }
    return {**result, **changes}


def test_section_has_verdict_settings_seeds_and_commands(pr):
    text = pr.format_section(fake_result(pr))
    assert text.startswith("## balance_roller\n")
    assert "**reproduces 2 of 3 training seeds (goal: >= 2 of 3)**: goal met." in text
    assert "| training seeds (the exported demonstrations) | 0, 1, 2 |" in text
    assert "| seeds evaluated (from the report) | 0, 1, 2 |" in text
    assert "| training time | 25.0 min |" in text and "| final loss | 0.0432 |" in text
    assert "| generation, export, evaluation time | 2.0 min, reused, 5.0 min |" in text
    assert "`abc1234` (dirty)" in text and "AMD EPYC, 2 cores" in text and "2026-12-01" in text
    assert "| 0 | yes | 2/2: lift; balance | - |" in text
    assert "| 1 | no | 1/2: lift | step_limit |" in text
    commands = fake_result(pr)["commands"]
    body = text[text.index("```bash") :]
    assert [body.index(commands[k]) for k in ("generate", "export", "train", "evaluate")] == sorted(
        body.index(commands[k]) for k in commands
    )
    assert "policy_reproduces.py --tasks balance_roller" in text
    assert "not the training seeds" not in text
    assert "open-loop error" not in text  # a result from before the fit was measured

    fit = {"mean": 0.0123, "max": 0.5, "episodes": [{"episode": 0, "frames": 9, "mean": 0.0123}]}
    fitted = pr.format_section({**fake_result(pr), "open_loop": fit})
    row = "| open-loop error on the training frames, mean (largest) | 0.0123 (0.500); per episode"
    assert row in fitted

    low = pr.format_section(fake_result(pr, reproduced=1))
    assert "**reproduces 1 of 3 training seeds (goal: >= 2 of 3)**: goal not met." in low
    wrong = pr.format_section(fake_result(pr, seeds_match=False, eval_seeds=[100000]))
    assert "goal not met" in wrong and "(100000) are not the training seeds (0, 1, 2)" in wrong


def test_sections_are_merged_and_written_atomically(pr, tmp_path):
    out = tmp_path / "policy_reproduces.md"
    pr.write_section(out, fake_result(pr))
    pr.write_section(out, fake_result(pr, task="place_plate_and_cup"))
    pr.write_section(out, fake_result(pr, reproduced=3))
    text = out.read_text()
    assert text.startswith(pr.TITLE)
    assert text.count("## balance_roller") == 1 and text.count("## place_plate_and_cup") == 1
    assert text.index("## balance_roller") < text.index("## place_plate_and_cup")
    assert "reproduces 3 of 3" in text and "reproduces 2 of 3" in text  # replaced, kept
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary file left


class FakeSteps:
    """Stands in for benchmarks/baselines.py's run(): makes each step's output as the real
    command would (synthetic episodes, the export's episode list, a checkpoint, a report)."""

    def __init__(self, tmp_path: Path, successes: list[bool]) -> None:
        self.tmp_path = tmp_path
        self.successes = successes
        self.calls: list[str] = []

    def __call__(self, command: list[str], log: Path) -> tuple[str, float]:
        log.parent.mkdir(parents=True, exist_ok=True)
        log.write_text("step:10 loss:0.500\nstep:20 loss:0.125\n")

        def value(name: str) -> str:
            return command[command.index(name) + 1]

        if command[1] == "scripts/generate.py":
            self.calls.append("generate")
            demos(self.tmp_path, value("--task"), int(value("--episodes")))
            return "", 60.0
        if command[1] == "scripts/export.py":
            self.calls.append("export")
            from bicoord_drake.data.readers import find_episode_files

            files = find_episode_files([command[2]])[0][: int(value("--max-episodes"))]
            meta = Path(value("--out")) / "meta"
            meta.mkdir(parents=True)
            lines = [json.dumps({"source": str(f), "seed": k}) for k, f in enumerate(files)]
            (meta / "bicoord_episodes.jsonl").write_text("\n".join(lines) + "\n")
            return "", 5.0
        if command[1] == "scripts/evaluate.py":
            self.calls.append("evaluate")
            from bicoord_drake.runner.rollouts import find_episodes

            files = find_episodes(value("--data"), value("--task"))[: int(value("--episodes"))]
            return json.dumps(report(files, self.successes[: len(files)])), 90.0
        self.calls.append("train")
        output = Path(next(t for t in command if t.startswith("--output_dir=")).split("=", 1)[1])
        assert not output.exists()  # lerobot-train refuses an existing directory
        output.mkdir(parents=True)
        return "", 600.0


def test_every_step_resumes_and_force_redoes_them(pr, tmp_path, monkeypatch):
    steps = FakeSteps(tmp_path, [True, True, False])
    monkeypatch.setattr(pr.baselines, "run", steps)
    fits = []
    fit = {"mean": 0.01, "max": 0.1, "episodes": []}
    monkeypatch.setattr(pr, "open_loop_error", lambda ckpt, data: fits.append(ckpt) or fit)
    argv = ["--tasks", "balance_roller", "--work", str(tmp_path / "work"), "--steps", "20"]
    args = pr.parse_args(argv)
    result = pr.run_task("balance_roller", args, "python benchmarks/policy_reproduces.py")
    assert steps.calls == ["generate", "export", "train", "evaluate"]
    assert result["train_seeds"] == result["eval_seeds"] == [0, 1, 2] and result["seeds_match"]
    assert result["reproduced"] == 2 and result["final_loss"] == 0.125
    assert result["open_loop"] == fit and fits == [pr.task_paths("balance_roller", args).checkpoint]
    assert result["train_seconds"] == 600.0 and result["reused"] == []
    assert "--episodes 3" in result["commands"]["generate"]
    assert result["commands"]["evaluate"].startswith("python scripts/evaluate.py")
    again = pr.run_task("balance_roller", args, "python benchmarks/policy_reproduces.py")
    assert steps.calls == ["generate", "export", "train", "evaluate"] and again == result
    # an interrupted run: the evaluation missing, the rest reused
    pr.task_paths("balance_roller", args).result.unlink()
    resumed = pr.run_task("balance_roller", args, "python benchmarks/policy_reproduces.py")
    assert steps.calls[4:] == ["evaluate"]
    assert resumed["reused"] == ["generation", "export", "training"]
    assert resumed["final_loss"] == 0.125 and resumed["train_seconds"] == 600.0
    forced = pr.parse_args([*argv, "--force"])
    pr.run_task("balance_roller", forced, "python benchmarks/policy_reproduces.py")
    assert steps.calls[5:] == ["generate", "export", "train", "evaluate"]


def test_missing_lerobot_train_says_how_to_install(pr, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(pr.shutil, "which", lambda name: None)
    assert pr.main(["--tasks", "balance_roller", "--work", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "lerobot-train is not on PATH" in err and "pip install -e '.[train]'" in err


@pytest.mark.slow
def test_one_demo_end_to_end(pr, tmp_path, monkeypatch):
    """The whole loop on one demonstration and a 20-step training (minutes)."""
    pytest.importorskip("lerobot.policies.act.modeling_act")
    if shutil.which("lerobot-train") is None:
        pytest.skip("lerobot-train is not on PATH (pip install --no-deps lerobot==0.4.4)")
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "policy_reproduces.md"
    argv = ["--tasks", "balance_roller", "--demos", "1", "--steps", "20", "--batch-size", "4"]
    argv += ["--work", str(tmp_path / "work"), "--out", str(out)]
    assert pr.main(argv) == 0, "the rollout did not run on the training seed"
    text = out.read_text()
    assert "| training seeds (the exported demonstrations) | 0 |" in text
    assert "| seeds evaluated (from the report) | 0 |" in text
    assert "training seeds (goal: >= 1 of 1)" in text
    assert "| open-loop error on the training frames, mean (largest) |" in text
    assert sys.executable not in text  # commands recorded with `python`

"""benchmarks/recovery_act.py: its settings, commands, report reading, resume logic and Markdown
(the steps faked: no physics, no training; the real run is smoke-tested by hand)."""

import json
import shutil
from pathlib import Path

import pytest

from tests.runner.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def rec():
    return load_benchmark("recovery_act")


def test_defaults_are_the_issue_and_the_baselines_act(rec):
    args = rec.parse_args([])
    assert args.tasks == ["balance_roller", "put_objects_cabinet"]
    assert (args.demos, args.noise, args.disturb) == (50, "0.003", ["push"])
    assert (args.clean_seed, args.recovery_seed, args.eval_seed) == (0, 50000, 0)
    # the baselines' state ACT rows: 10000 steps, batch 16, the CPU-sized ACT
    assert (args.steps, args.batch_size, args.train_seed) == (10000, 16, 1000)
    assert args.train_args == rec.ACT_CPU_ARGS
    assert args.eval_episodes == 50 and args.workers == 1
    assert args.out == rec.ROOT / "benchmarks" / "recovery.md"
    assert args.work.is_absolute() and not (args.force or args.dry_run or args.table_only)
    more = rec.parse_args(["--train-args=--policy.optimizer_lr=1e-4", "--disturb", "drop,push"])
    assert more.train_args == rec.ACT_CPU_ARGS + " --policy.optimizer_lr=1e-4"
    assert more.disturb == ["push", "drop"]  # the package's order of kinds
    assert rec.parse_args(["--noise", "0.005-0.02"]).noise == "0.005-0.02"
    assert rec.parse_args(["--noise", "0"]).noise == "0"


@pytest.mark.parametrize(
    "argv",
    [
        ["--demos", "0"],
        ["--steps", "0"],
        ["--eval-episodes", "0"],
        ["--tasks", ","],
        ["--disturb", "none"],  # nothing to evaluate disturbed
        ["--disturb", "shove"],
        ["--noise", "lots"],
        ["--noise", "0.5"],  # above generate.py's largest level
        ["--recovery-seed", "100"],  # inside CLEAN's 250 tries
        ["--recovery-seed", "99900"],  # runs into the evaluation seeds
        ["--max-tries", "10"],  # fewer than --demos
    ],
)
def test_bad_arguments_are_refused(rec, argv):
    with pytest.raises(SystemExit):
        rec.parse_args(argv)


def test_seed_ranges_are_disjoint(rec):
    args = rec.parse_args(["--demos", "10"])
    assert rec.generation_tries(args) == 50 and rec.seed_conflict(args) is None
    args.recovery_seed = 49
    assert rec.seed_conflict(args) == "clean seeds 0-49 and recovery seeds 49-98 overlap"
    args.recovery_seed, args.max_tries = 50, 60
    assert "overlap" in rec.seed_conflict(args)
    args.clean_seed, args.recovery_seed, args.max_tries = 199990, 0, None
    assert "clean seeds 199990-200039 and evaluation seeds 100000-199999" in rec.seed_conflict(args)


def test_generation_commands_and_directories(rec, tmp_path):
    args = rec.parse_args(["--work", str(tmp_path), "--demos", "3", "--workers", "2"])
    gens = rec.generations("balance_roller", args)
    clean, recovery = gens["clean"], gens["recovery"]
    assert clean.demos == tmp_path / "data" / "clean_seed0" / "balance_roller" / "default"
    assert (
        recovery.demos
        == (tmp_path / "data" / "recovery_seed50000_noise0.003_push" / "balance_roller")
        / "default_noisy_disturbed"
    )
    command = rec.generate_command("balance_roller", clean, args)
    assert command[1] == "scripts/generate.py" and "--no-render" in command
    for option in (["--episodes", "3"], ["--seed", "0"], ["--max-tries", "15"]):
        assert command[command.index(option[0]) : command.index(option[0]) + 2] == option
    assert command[command.index("--workers") + 1] == "2"
    assert "--action-noise" not in command and "--disturb" not in command
    command = rec.generate_command("balance_roller", recovery, args)
    assert command[command.index("--seed") + 1] == "50000"
    assert command[command.index("--action-noise") + 1] == "0.003"
    assert command[command.index("--disturb") + 1] == "push"
    assert command[command.index("--out") + 1] == str(recovery.data)
    # disturbances without noise: generate.py's default_disturbed, its own generation root
    quiet = rec.generations(
        "balance_roller", rec.parse_args(["--work", str(tmp_path)] + ["--noise", "0"])
    )
    assert quiet["recovery"].demos.name == "default_disturbed"
    assert quiet["recovery"].data != recovery.data
    assert "--action-noise" not in rec.generate_command("balance_roller", quiet["recovery"], args)


def test_training_and_evaluation_are_identical_but_for_the_dataset(rec, tmp_path):
    args = rec.parse_args(["--work", str(tmp_path), "--steps", "100", "--eval-episodes", "7"])
    clean = rec.train_command("jigsaw", rec.CLEAN, args)
    mixed = rec.train_command("jigsaw", rec.MIXED, args)
    differ = [(a, b) for a, b in zip(clean, mixed, strict=True) if a != b]
    assert [a.split("=")[0] for a, _ in differ] == ["--dataset.root", "--output_dir"]
    assert {"--policy.type=act", "--steps=100", "--batch_size=16", "--seed=1000"} <= set(clean)
    assert set(rec.baselines.COMMON_TRAIN_ARGS) <= set(clean)
    assert set(rec.ACT_CPU_ARGS.split()) <= set(clean)
    paths = {d: rec.dataset_paths("jigsaw", d, args) for d in rec.DATASETS}
    assert clean[-1] == f"--output_dir={paths[rec.CLEAN].checkpoint}"
    assert paths[rec.CLEAN].checkpoint != paths[rec.MIXED].checkpoint
    assert paths[rec.CLEAN].dataset != paths[rec.MIXED].dataset

    evaluations = {d: rec.evaluate_command("jigsaw", d, args) for d in rec.DATASETS}
    for dataset, command in evaluations.items():
        assert command[1] == "scripts/evaluate.py"
        assert command[command.index("--policy") + 1] == f"lerobot:{paths[dataset].checkpoint}"
        for option in (["--split", "unseen"], ["--episodes", "7"], ["--seed", "0"]):
            assert command[command.index(option[0]) : command.index(option[0]) + 2] == option
        assert command[command.index("--disturb") + 1] == "push"
        assert {"--no-render", "--json"} <= set(command)
    differ = [
        (a, b)
        for a, b in zip(evaluations[rec.CLEAN], evaluations[rec.MIXED], strict=True)
        if a != b
    ]
    assert len(differ) == 2  # the checkpoint and the report directory: the same seeds


def demos(root: Path, task: str, n: int, config: str = "default") -> list[Path]:
    """`n` synthetic episode files of `task` in `root/<task>/<config>` (seeds 0..n-1)."""
    from tests.data.synthetic import make_dataset

    scratch = root / ".scratch"
    make_dataset(scratch, lengths=(3,) * n, task=task)
    target = root / task / config
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(str(scratch / task / "default"), str(target))
    shutil.rmtree(scratch)
    return sorted((target / "data").glob("*.hdf5"), key=lambda p: int(p.stem[7:]))


def test_export_names_each_directory_that_holds_exactly_its_demos(rec, tmp_path):
    args = rec.parse_args(["--work", str(tmp_path), "--demos", "2"])
    gens = rec.generations("balance_roller", args)
    clean = demos(gens["clean"].data, "balance_roller", 2)
    recovery = demos(gens["recovery"].data, "balance_roller", 3, gens["recovery"].demos.name)
    out = tmp_path / "ds"
    files = {"clean": clean, "recovery": recovery[:2]}
    command = rec.export_command(rec.CLEAN, gens, out, files)
    assert command[2:4] == [str(gens["clean"].demos), "--to"]
    assert command[-2:] == ["--environment-state", "--no-images"]
    command = rec.export_command(rec.MIXED, gens, out, files)
    # CLEAN's directory holds exactly its 2; RECOVERY's holds 3, so its first 2 are listed
    assert command[2:6] == [str(gens["clean"].demos), *map(str, recovery[:2]), "--to"]
    assert command[command.index("--out") + 1] == str(out)
    planned = rec.export_command(rec.MIXED, gens, out, {"clean": None, "recovery": None})
    assert planned[2:5] == [str(gens["clean"].demos), str(gens["recovery"].demos), "--to"]


def fake_report(seeds=(100000, 100001, 100002), skipped=(100003,), no_window=(100002,)):
    """A ``scripts/evaluate.py --disturb push --json`` report (clean and disturbed sides)."""

    def side(rollout_seeds, sr, ssr):
        return {
            "n": len(rollout_seeds),
            "SR": sr,
            "SSR": ssr,
            "TL": 120.0 if sr else None,
            "stages": [
                {"subgoal": "lift", "completed": 0.5},
                {"subgoal": "balance", "completed": sr},
            ],
            "failures": {"step_limit": 1},
            "rollouts": [
                {
                    "seed": s,
                    "success": k == 0 and sr > 0,
                    "error": "physics diverged at step 9: boom" if k == 1 else None,
                }
                for k, s in enumerate(rollout_seeds)
            ],
        }

    disturbed = [s for s in seeds if s not in no_window]
    return {
        **side(list(seeds), 1 / 3, 0.5),
        "disturb": ["push"],
        "side_by_side": {
            "paired": {
                "n": 2,
                "SR": {"clean": 0.5, "disturbed": 0.0},
                "SSR": {"clean": 0.75, "disturbed": 0.25},
            }
        },
        "skipped": [{"seed": s, "reason": "expert failed: planning"} for s in skipped],
        "disturbed": {
            **side(disturbed, 0.0, 0.25),
            "skipped": [{"seed": s, "reason": "no_disturbance_window: push"} for s in no_window],
        },
    }


def test_scores_are_read_from_both_sides_of_the_report(rec):
    scores = rec.scores_from_report(fake_report())
    clean, disturbed = scores["clean"], scores["disturbed"]
    assert (clean["n"], clean["SR"], clean["SSR"], clean["TL"]) == (3, 1 / 3, 0.5, 120.0)
    assert clean["seeds"] == [100000, 100001, 100002] and clean["skipped"] == [100003]
    assert clean["stages"] == [["lift", 0.5], ["balance", 1 / 3]] and clean["diverged"] == 1
    assert (disturbed["n"], disturbed["SR"], disturbed["SSR"]) == (2, 0.0, 0.25)
    assert disturbed["no_disturbed_rollout"] == [[100002, "no_disturbance_window: push"]]
    assert scores["paired"] == {
        "n": 2,
        "SR": {"clean": 0.5, "disturbed": 0.0},
        "SSR": {"clean": 0.75, "disturbed": 0.25},
    }


def test_report_json_is_read_from_the_path_the_evaluation_printed(rec, tmp_path):
    on_disk = {**fake_report(), "n": 99}
    path = tmp_path / "report.json"
    path.write_text(json.dumps(on_disk))
    assert rec.read_report(json.dumps({**fake_report(), "report": str(path)}))["n"] == 99
    assert rec.read_report(json.dumps({**fake_report(), "report": None}))["n"] == 3


def test_generation_summary_counts_kept_tried_and_failures(rec):
    manifest = {
        "episodes": [
            {"seed": 50000, "success": True},
            {"seed": 50001, "success": False, "reason": "no_disturbance_window: push: none"},
            {"seed": 50002, "success": False, "reason": "planning: pick_failed: x"},
            {"seed": 50003, "success": False, "reason": "planning: ik"},
            {"seed": 50004, "success": True},
        ]
    }
    assert rec.generation_summary(manifest) == {
        "kept": 2,
        "tried": 5,
        "first": 50000,
        "last": 50004,
        "failures": {"planning": 2, "no_disturbance_window": 1},
    }
    assert rec.generation_summary({})["tried"] == 0


def test_marked_frames_come_from_the_exports_recovery_rows(rec, tmp_path):
    meta = tmp_path / "meta"
    meta.mkdir()
    (meta / "info.json").write_text(json.dumps({"total_frames": 200}))
    rows = [
        {"source": "a", "seed": 0},
        {"source": "b", "seed": 1, "recovery": [[10, 25, "recover"], [40, 45, "recover"]]},
    ]
    (meta / "bicoord_episodes.jsonl").write_text("\n".join(map(json.dumps, rows)) + "\n")
    assert rec.marked_frames(tmp_path) == (20, 200)
    assert rec.marked_frames(tmp_path / "missing") is None


def test_the_clean_result_does_not_depend_on_the_recovery_settings(rec):
    a = rec.parse_args([])
    b = rec.parse_args(["--noise", "0.01", "--recovery-seed", "60000"])
    key = lambda args, d: rec.settings_key("t", d, rec.settings(d, args))  # noqa: E731
    assert key(a, rec.CLEAN) == key(b, rec.CLEAN)
    assert key(a, rec.MIXED) != key(b, rec.MIXED)
    c = rec.parse_args(["--disturb", "drop"])  # the evaluation's kinds: both redone
    assert key(a, rec.CLEAN) != key(c, rec.CLEAN)
    d = rec.parse_args(["--steps", "20"])
    assert key(a, rec.CLEAN) != key(d, rec.CLEAN) and key(a, rec.MIXED) != key(d, rec.MIXED)


def fake_result(rec, dataset="clean", **changes):
    args = rec.parse_args([])
    mixed = dataset == rec.MIXED
    result = {
        "task": "balance_roller",
        "dataset": dataset,
        "settings": rec.settings(dataset, args),
        "demos": {"clean": 50, **({"recovery": 50} if mixed else {})},
        "marked_frames": [300, 12000] if mixed else [0, 6000],
        "generation": {
            "clean": {"kept": 50, "tried": 50, "first": 0, "last": 49, "failures": {}},
            **(
                {
                    "recovery": {
                        "kept": 50,
                        "tried": 53,
                        "first": 50000,
                        "last": 50052,
                        "failures": {"no_disturbance_window": 3},
                    }
                }
                if mixed
                else {}
            ),
        },
        "train_seconds": 900.0,
        "final_loss": 0.30412,
        "eval_seconds": 1500.0,
        **rec.scores_from_report(fake_report()),
        "commands": {
            "generate_clean": "python scripts/generate.py --task balance_roller --seed 0",
            **({"generate_recovery": "python scripts/generate.py --seed 50000"} if mixed else {}),
            "export": "python scripts/export.py D --to lerobot",
            "train": f"lerobot-train --dataset.root={dataset}",
            "evaluate": "python scripts/evaluate.py --disturb push",
        },
        "run_command": "python benchmarks/recovery_act.py --demos 50",
        "commit": "abc1234",
        "dirty": False,
        "machine": "AMD EPYC, 2 cores",
        "date": "2026-12-08 10:00 UTC",
    }
    return {**result, **changes}


def cells(text: str, first: str) -> list[str]:
    row = next(line for line in text.splitlines() if line.startswith(f"| {first} |"))
    return [c.strip() for c in row.strip().strip("|").split("|")]


def test_report_has_a_table_per_task_the_commands_and_an_empty_reading(rec):
    results = [fake_result(rec), fake_result(rec, rec.MIXED)]
    text = rec.markdown(results, "python benchmarks/recovery_act.py", "w/results.jsonl", "")
    assert text.startswith(rec.TITLE) and text.count("\n## balance_roller\n") == 1
    header = next(line for line in text.splitlines() if line.startswith("| dataset |"))
    clean = cells(text, "clean")
    assert len(header.strip().strip("|").split("|")) == len(clean)
    assert clean[:12] == [
        "clean", "50", "0 of 6000 (0.0 %)", "10000", "16", "15.0 min", "0.304", "3 / 2",
        "33.3", "50.0", "0.0", "25.0",
    ]  # fmt: skip
    assert clean[12] == "2: SR 50.0 / 0.0, SSR 75.0 / 25.0"
    assert clean[13] == "lift 50.0 / 50.0; balance 33.3 / 0.0"
    assert clean[14:18] == ["100000-100003", "1: 100003", "1: 100002", "1 / 1"]
    mixed = cells(text, "clean+recovery (noise 0.003 rad, push)")
    assert mixed[1:3] == ["50 + 50", "300 of 12000 (2.5 %)"]
    assert "- demonstrations, CLEAN: 50 kept of 50 seeds tried (0-49)" in text
    assert (
        "- demonstrations, RECOVERY (noise 0.003 rad, push): 50 kept of 53 seeds tried "
        "(50000-50052); failures: no_disturbance_window 3"
    ) in text
    assert "- AMD EPYC, 2 cores (2 results)" in text
    reading = text.index("## Reading")
    assert rec.READING_PLACEHOLDER in text[reading:] and reading < text.index("## Commands")
    body = text[text.index("## Commands") :]
    assert body.index("--seed 50000") > body.index("lerobot-train --dataset.root=clean")
    assert "lerobot-train --dataset.root=clean+recovery" in body
    assert "Run by `python benchmarks/recovery_act.py --demos 50`:" in body
    assert "Rollout errors" in body and "physics diverged" in body


def test_rewrites_are_atomic_and_keep_what_the_reader_wrote(rec, tmp_path):
    out = tmp_path / "recovery.md"
    rec.write_report(out, [fake_result(rec)], "cmd", tmp_path)
    assert rec.READING_PLACEHOLDER in out.read_text()
    text = out.read_text().replace(rec.READING_PLACEHOLDER, "Recovery data helped here.")
    out.write_text(text)
    assert rec.existing_reading(text) == "Recovery data helped here."
    rec.write_report(out, [fake_result(rec), fake_result(rec, rec.MIXED)], "cmd", tmp_path)
    text = out.read_text()
    assert "Recovery data helped here." in text and rec.READING_PLACEHOLDER not in text
    assert "| clean+recovery (noise 0.003 rad, push) |" in text
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary file left
    # the latest result of a key replaces the earlier one
    rec.write_report(out, [fake_result(rec), fake_result(rec, final_loss=0.1)], "cmd", tmp_path)
    assert out.read_text().count("| clean |") == 1 and "| 0.100 |" in out.read_text()


class FakeSteps:
    """Stands in for benchmarks/baselines.py's run(): makes each step's output as the real
    command would (synthetic episodes, an export's episode list, a checkpoint, a report)."""

    def __init__(self) -> None:
        self.calls: list[str] = []

    def __call__(self, command: list[str], log: Path) -> tuple[str, float]:
        log.parent.mkdir(parents=True, exist_ok=True)
        log.write_text("step:10 loss:0.500\nstep:20 loss:0.125\n")

        def value(name: str) -> str:
            return command[command.index(name) + 1]

        if command[1] == "scripts/generate.py":
            disturbed = "--disturb" in command
            self.calls.append("generate_recovery" if disturbed else "generate_clean")
            config = "default_noisy_disturbed" if disturbed else "default"
            demos(Path(value("--out")), value("--task"), int(value("--episodes")), config)
            return "", 60.0
        if command[1] == "scripts/export.py":
            self.calls.append("export")
            from bicoord_drake.data.readers import find_episode_files

            files = find_episode_files(command[2 : command.index("--to")])[0]
            meta = Path(value("--out")) / "meta"
            meta.mkdir(parents=True)
            lines = [
                json.dumps(
                    {"source": str(f), "seed": k}
                    | ({"recovery": [[0, 2, "r"]]} if "disturbed" in str(f) else {})
                )
                for k, f in enumerate(files)
            ]
            (meta / "bicoord_episodes.jsonl").write_text("\n".join(lines) + "\n")
            (meta / "info.json").write_text(json.dumps({"total_frames": 3 * len(files)}))
            return "", 5.0
        if command[1] == "scripts/evaluate.py":
            self.calls.append("evaluate")
            root = Path(value("--out")) / value("--task") / "policy"
            root.mkdir(parents=True, exist_ok=True)
            report = {**fake_report(), "report": str(root / "report.json")}
            (root / "report.json").write_text(json.dumps(report))
            return json.dumps(report), 90.0
        self.calls.append("train")
        output = Path(next(t for t in command if t.startswith("--output_dir=")).split("=", 1)[1])
        assert not output.exists()  # lerobot-train refuses an existing directory
        output.mkdir(parents=True)
        return "", 600.0


def test_every_step_resumes_and_force_redoes_them(rec, tmp_path, monkeypatch, capsys):
    steps = FakeSteps()
    monkeypatch.setattr(rec.baselines, "run", steps)
    monkeypatch.setattr(rec.shutil, "which", lambda name: "/usr/bin/" + name)
    out = tmp_path / "recovery.md"
    argv = ["--tasks", "balance_roller", "--demos", "2", "--steps", "20", "--eval-episodes", "3"]
    argv += ["--work", str(tmp_path / "work"), "--out", str(out)]
    assert rec.main(argv) == 0
    assert steps.calls == [
        "generate_clean",
        "generate_recovery",
        *["export", "train", "evaluate"] * 2,
    ]
    results = rec.baselines.read_results(tmp_path / "work" / "results.jsonl")
    assert [r["dataset"] for r in results] == [rec.CLEAN, rec.MIXED]
    clean, mixed = results
    assert clean["demos"] == {"clean": 2} and mixed["demos"] == {"clean": 2, "recovery": 2}
    assert mixed["dataset_seeds"] == [0, 1, 2, 3] and mixed["marked_frames"] == [4, 12]
    assert clean["final_loss"] == 0.125 and clean["train_seconds"] == 600.0
    assert clean["generation"]["clean"]["kept"] == 2
    assert clean["clean"]["SR"] == 1 / 3 and clean["disturbed"]["SSR"] == 0.25
    assert list(mixed["commands"]) == [
        "generate_clean",
        "generate_recovery",
        "export",
        "train",
        "evaluate",
    ]
    assert "generate_recovery" not in clean["commands"]
    text = out.read_text()
    assert "| clean |" in text and "| clean+recovery (noise 0.003 rad, push) |" in text
    printed = capsys.readouterr().out
    assert "[balance_roller] 1/8 CLEAN demonstrations" in printed
    assert "[balance_roller] 8/8 clean+recovery: evaluate" in printed

    # a rerun skips the finished keys
    assert rec.main(argv) == 0
    assert len(steps.calls) == 8
    # an evaluation setting changed: the demonstrations, exports and trainings are reused
    assert rec.main([*argv, "--eval-seed", "1"]) == 0
    assert steps.calls[8:] == ["evaluate", "evaluate"]
    # the recovery settings changed: only clean+recovery is redone, on new demonstrations
    assert rec.main([*argv, "--noise", "0.01"]) == 0
    assert steps.calls[10:] == ["generate_recovery", "export", "train", "evaluate"]
    # --force redoes the results (finished generations stay)
    assert rec.main([*argv, "--force"]) == 0
    assert steps.calls[14:] == ["evaluate", "evaluate"]
    results = rec.baselines.read_results(tmp_path / "work" / "results.jsonl")
    assert len(results) == 7 and len(rec.latest_results(results)) == 5


def test_dry_run_prints_the_commands_and_runs_nothing(rec, tmp_path, monkeypatch, capsys):
    def refuse(command, log):
        raise AssertionError("a dry run ran a step")

    monkeypatch.setattr(rec.baselines, "run", refuse)
    work, out = tmp_path / "work", tmp_path / "recovery.md"
    argv = ["--tasks", "balance_roller", "--work", str(work), "--out", str(out), "--dry-run"]
    assert rec.main(argv) == 0
    printed = capsys.readouterr().out.splitlines()
    commands = [line.strip() for line in printed if line.startswith("  ")]
    assert [c.split()[1] if c.startswith("python") else c.split()[0] for c in commands] == [
        "scripts/generate.py",
        "scripts/generate.py",
        *["scripts/export.py", "lerobot-train", "scripts/evaluate.py"] * 2,
    ]
    assert "--disturb push" in commands[1] and "--disturb push" in commands[-1]
    assert not work.exists() and not out.exists()


def test_missing_lerobot_train_says_how_to_install(rec, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(rec.shutil, "which", lambda name: None)
    argv = ["--tasks", "balance_roller", "--work", str(tmp_path), "--out", str(tmp_path / "o.md")]
    assert rec.main(argv) == 1
    err = capsys.readouterr().err
    assert "lerobot-train is not on PATH" in err and "pip install -e '.[train]'" in err

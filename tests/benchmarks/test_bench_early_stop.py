"""benchmarks/bench_early_stop.py: its settings, commands, resume logic, split and Markdown
section (the steps faked: no physics, no training; the real run is the slow test at the end)."""

import argparse
import contextlib
import json
import shutil
import subprocess
import time

import pytest

from tests.benchmarks.test_policy_reproduces import FakeSteps
from tests.runner.benchmark_scripts import load_benchmark

TASK = "handover_block_with_bowls"


@pytest.fixture(scope="module")
def bes():
    return load_benchmark("bench_early_stop")


def test_defaults(bes):
    args = bes.parse_args([])
    assert args.task == TASK and args.checkpoint is None
    assert (args.demos, args.train_steps, args.batch_size, args.train_seed) == (3, 300, 8, 1000)
    assert (args.episodes, args.seed, args.workers) == (50, 0, 1)
    assert args.order == ("before", "after") and not args.split and not args.force
    assert args.out == bes.ROOT / "benchmarks" / "bench_early_stop.md"
    assert args.work.is_absolute() and args.out.is_absolute()
    args = bes.parse_args(["--order", "after,before", "--split", "--episodes", "5"])
    assert args.order == ("after", "before") and args.split and args.episodes == 5


def test_a_checkpoint_directory_is_taken_resolved(bes, tmp_path, monkeypatch):
    (tmp_path / "ckpt").mkdir()
    monkeypatch.chdir(tmp_path)
    assert bes.parse_args(["--checkpoint", "ckpt"]).checkpoint == tmp_path / "ckpt"


@pytest.mark.parametrize(
    "argv",
    [
        ["--demos", "0"],
        ["--train-steps", "0"],
        ["--batch-size", "0"],
        ["--episodes", "0"],
        ["--workers", "0"],
        ["--seed", "-1"],
        ["--order", "after"],
        ["--order", "before,before"],
        ["--checkpoint", "/no/such/checkpoint"],
    ],
)
def test_bad_arguments_are_refused(bes, argv):
    with pytest.raises(SystemExit):
        bes.parse_args(argv)


def test_bad_task_and_seed_are_refused_before_anything_runs(bes, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(bes.baselines, "run", lambda *a: pytest.fail("a step ran"))
    work = ["--work", str(tmp_path / "work"), "--out", str(tmp_path / "out.md")]
    assert bes.main(["--task", "no_such_task", *work]) == 2
    assert "unknown task 'no_such_task'" in capsys.readouterr().err
    assert bes.main(["--seed", "50000", *work]) == 2  # seeds past 2**32
    assert "seed 50000" in capsys.readouterr().err
    assert not (tmp_path / "out.md").exists()


def test_missing_lerobot_train_says_how_to_install(bes, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(bes.shutil, "which", lambda name: None)
    assert bes.main(["--work", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "lerobot-train is not on PATH" in err and "pip install -e '.[train]'" in err


def test_the_evaluations_differ_only_in_the_early_stop(bes, tmp_path):
    args = bes.parse_args(["--work", str(tmp_path), "--episodes", "7", "--seed", "3"])
    paths = bes.paths_of(TASK, args)
    ckpt = tmp_path / "ckpt"
    before = bes.evaluate_command(TASK, ckpt, "before", args, paths)
    after = bes.evaluate_command(TASK, ckpt, "after", args, paths)
    assert before[1] == after[1] == "scripts/evaluate.py"
    assert "--no-early-stop" in before and "--no-early-stop" not in after
    for command in (before, after):
        assert command[command.index("--policy") + 1] == f"lerobot:{ckpt}"
        assert command[command.index("--episodes") + 1] == "7"
        assert command[command.index("--seed") + 1] == "3"
        assert command[command.index("--workers") + 1] == "1"
        assert command[command.index("--task") + 1] == TASK
        assert {"--no-render", "--json"} <= set(command)
        assert "--split" not in command and "--data" not in command  # default split, seeds
    assert before[-2:] == ["--out", str(tmp_path / "eval_before")]
    assert after[-2:] == ["--out", str(tmp_path / "eval_after")]
    assert [t for t in before if t != "--no-early-stop"][:-1] == after[:-1]
    with pytest.raises(ValueError):
        bes.evaluate_command(TASK, ckpt, "during", args, paths)


def test_the_in_process_config_is_the_commands_scenario(bes, tmp_path):
    """The expert check and the split see the seeds and scenes scripts/evaluate.py makes."""
    from bicoord_drake.scenario import (
        EVALUATION_DEFAULTS,
        add_scenario_arguments,
        scenario_from_args,
    )

    args = bes.parse_args(["--work", str(tmp_path), "--episodes", "4", "--seed", "2"])
    ckpt = tmp_path / "ckpt"
    for mode, early_stop in (("before", False), ("after", True)):
        command = bes.evaluate_command(TASK, ckpt, mode, args, bes.paths_of(TASK, args))
        parser = argparse.ArgumentParser(allow_abbrev=False)
        add_scenario_arguments(parser)
        parsed, _ = parser.parse_known_args(command[2:])
        scenario, _ = scenario_from_args(parsed, EVALUATION_DEFAULTS)
        config = bes.evaluation_config(TASK, ckpt, args, early_stop=early_stop)
        assert config.scenario == scenario
        assert config.policy == command[command.index("--policy") + 1]
        assert config.early_stop is early_stop and config.max_tries == 0


def test_the_policy_is_trained_as_policy_reproduces_trains(bes, tmp_path):
    args = bes.parse_args(["--work", str(tmp_path / "work")])
    paths = bes.paths_of(TASK, args)
    pr = bes.policy_reproduces
    assert paths.train.data == tmp_path / "work" / "data"
    assert paths.train.demos == tmp_path / "work" / "data" / TASK / "default"
    train = pr.train_command(TASK, bes.training_args(args), paths.train)
    assert set(pr.REPRODUCE_ARGS.split()) <= set(train)
    assert {"--steps=300", "--batch_size=8", "--seed=1000", "--policy.type=act"} <= set(train)
    assert train[-1] == f"--output_dir={paths.train.checkpoint}"
    generate = pr.generate_command(TASK, bes.training_args(args), paths.train)
    assert generate[generate.index("--episodes") + 1] == "3"
    assert {"--no-render", "--workers"} <= set(generate)


def test_expert_seeds_are_tried_as_an_evaluation_tries_them(bes):
    tried = []

    def check(seed):
        tried.append(seed)
        return seed != 100001, "expert failed"

    assert bes.expert_seeds(check, 100000, 3, 9) == ([100000, 100002, 100003], [100001])
    assert tried == [100000, 100001, 100002, 100003]
    assert bes.expert_seeds(lambda s: (False, "no"), 5, 2, 4) == ([], [5, 6, 7, 8])


def test_report_is_read_from_stdout_or_its_file(bes, tmp_path):
    assert bes.report_of('{"n": 1}', tmp_path) == {"n": 1}
    target = tmp_path / TASK / "lerobot-x" / "report.json"
    target.parent.mkdir(parents=True)
    target.write_text('{"n": 2}')
    assert bes.report_of("warning: something\n{", tmp_path) == {"n": 2}
    with pytest.raises(RuntimeError):
        bes.report_of("", tmp_path / TASK / "elsewhere")


# --------------------------------------------------------------------------- the split
class ToySim:
    def AdvanceTo(self, t):  # noqa: N802 - Drake's name, which the split looks for
        time.sleep(0.02)


class ToyEnv:
    def __init__(self):
        self.sim = ToySim()

    def reset(self):
        time.sleep(0.01)

    def step(self, action):
        self.sim.AdvanceTo(0.0)
        time.sleep(0.005)


class ToyPolicy:
    def act(self, obs):
        time.sleep(0.01)
        return obs


def test_the_split_names_physics_act_and_the_rest(bes):
    env, policy = ToyEnv(), ToyPolicy()

    def rollout():
        env.reset()
        for _ in range(3):
            env.step(policy.act(0))
        time.sleep(0.01)  # the loop's own time
        return "done"

    split, result = bes.profile_split(rollout, ToyPolicy.act, ToyEnv.step, ToyEnv.reset)
    assert result == "done"
    parts = {p["part"]: p for p in split["parts"]}
    seconds = {name: p["seconds"] for name, p in parts.items()}
    # Each part holds at least the sleeps made in it (a sleep never ends early; on a loaded
    # machine it may end late, so no upper bounds).
    assert seconds[bes.PHYSICS] >= 0.055
    assert seconds[bes.ACT] >= 0.027
    assert seconds[bes.ENV_RESET] >= 0.009
    assert seconds[bes.ENV_STEP] >= 0.013
    shares = [parts[name]["share"] for name in (bes.PHYSICS, bes.ACT, bes.REST)]
    assert sum(shares) == pytest.approx(1.0, abs=1e-3)  # the three parts are the whole
    rest = seconds[bes.ENV_STEP] + seconds[bes.ENV_RESET] + seconds[bes.OTHER]
    assert rest == pytest.approx(seconds[bes.REST], abs=2e-3)
    assert split["wall"] >= 0.1
    assert any("AdvanceTo" in f["function"] for f in split["top"]) or any(
        "sleep" in f["function"] for f in split["top"]
    )


@pytest.mark.parametrize(
    "name, physics",
    [
        ("<built-in method pydrake.systems.analysis.AdvanceTo>", True),  # cProfile's, drake 1.51
        ("<method 'AdvanceTo' of 'pydrake.systems.analysis.Simulator_[float]' objects>", True),
        ("AdvanceTo", True),
        ("<built-in method pydrake.systems.analysis.AdvancePendingEvents>", False),
        ("step", False),
    ],
)
def test_the_physics_is_found_by_its_name_in_the_profile(bes, name, physics):
    assert bes._is_advance(("~", 0, name)) is physics


def test_the_split_is_reused_for_the_same_checkpoint_and_seed(bes, tmp_path, monkeypatch):
    args = bes.parse_args(["--work", str(tmp_path / "work")])
    paths = bes.paths_of(TASK, args)
    ckpt = tmp_path / "ckpt"
    ckpt.mkdir()
    (ckpt / "model.safetensors").write_text("weights")
    runs = []

    def fake_split(task, checkpoint, seed, args):
        runs.append(seed)
        stamp = bes.checkpoint_stamp(checkpoint)
        return {"task": task, "checkpoint": str(checkpoint), "stamp": stamp, "seed": seed}

    monkeypatch.setattr(bes, "run_split", fake_split)
    first = bes.split_step(TASK, ckpt, 100000, args, paths)
    assert bes.split_step(TASK, ckpt, 100000, args, paths) == first and runs == [100000]
    bes.split_step(TASK, ckpt, 100001, args, paths)  # another seed
    time.sleep(0.01)
    (ckpt / "model.safetensors").write_text("other weights")  # another training
    bes.split_step(TASK, ckpt, 100001, args, paths)
    assert runs == [100000, 100001, 100001]


# --------------------------------------------------------------------------- the run, faked
#: Per seed of the fake evaluations: (steps, seconds, failure) without and with the early stop.
BEFORE = {"steps": 350, "seconds": 7.0, "failure": "step_limit"}
AFTER = {"steps": 50, "seconds": 1.0, "failure": "object_left_table"}
SEEDS = [100000, 100002, 100003]


def fake_report(seeds, early_stop):
    """A fake ``scripts/evaluate.py --json`` report: every rollout fails; with the early stop
    all but the last end early."""
    rollouts = []
    for k, seed in enumerate(seeds):
        r = AFTER if early_stop and k < len(seeds) - 1 else BEFORE
        rollouts.append({"seed": seed, "success": False, "error": None, **r})
    failures = {}
    for r in rollouts:
        failures[r["failure"]] = failures.get(r["failure"], 0) + 1
    return {"n": len(seeds), "SR": 0.0, "failures": failures, "skipped": [], "seconds": 50.0,
            "rollouts": rollouts}  # fmt: skip


class FakeRun(FakeSteps):
    """policy_reproduces' fake steps (generation, export, training), the fake expert check in a
    worktree of --before and fake evaluations on the seeds the expert check kept: 400 s without
    the early stop, 100 s with it. `where`: per step its working directory and PYTHONPATH (None:
    baselines.run's own environment); a step in `fail` fails."""

    def __init__(self, tmp_path, successes):
        super().__init__(tmp_path, successes)
        self.where = {}
        self.fail = set()

    def __call__(self, command, log, *, cwd=None, env=None):
        if command[1] == "-c":
            step = "check_before"
        elif command[1] == "scripts/evaluate.py":
            step = "before" if "--no-early-stop" in command else "after"
        else:
            return super().__call__(command, log)
        log.parent.mkdir(parents=True, exist_ok=True)
        self.calls.append(step)
        present = cwd is not None and (cwd / "benchmarks" / "bench_early_stop.py").exists()
        self.where[step] = (cwd, None if env is None else env["PYTHONPATH"], present)
        if step in self.fail:
            raise RuntimeError(f"{step} failed")
        if step == "check_before":
            episodes = int(command[-3])
            return "a warning\n" + json.dumps(fake_check(argparse.Namespace(episodes=episodes))), 9
        report = fake_report(
            SEEDS[: int(command[command.index("--episodes") + 1])], step == "after"
        )
        return json.dumps(report), 100.0 if step == "after" else 400.0


def fake_check(config):
    return {"kept": SEEDS[: config.episodes], "skipped": [100001], "cached": 1, "seconds": 30.0}


@pytest.fixture
def faked(bes, tmp_path, monkeypatch):
    steps = FakeRun(tmp_path, [])
    monkeypatch.setattr(bes.baselines, "run", steps)
    monkeypatch.setattr(bes, "warm_expert_check", fake_check)
    return steps


def run_argv(tmp_path, *more):
    return ["--work", str(tmp_path / "work"), "--episodes", "3", "--demos", "2", *more]


def test_every_step_runs_then_resumes_and_force_redoes_them(bes, tmp_path, faked):
    args = bes.parse_args(run_argv(tmp_path))
    result = bes.run(TASK, args, "python benchmarks/bench_early_stop.py")
    assert faked.calls == ["generate", "export", "train", "before", "after"]
    assert result["seeds_match"] and result["reused"] == []
    assert result["ratio"] == pytest.approx(0.25)
    assert result["ratio_rollouts"] == pytest.approx((2 * 1.0 + 7.0) / 21.0)
    before, after = result["stats"]["before"], result["stats"]["after"]
    assert (before["wall"], before["sum"], before["steps"]) == (400.0, 21.0, 1050)
    assert (after["wall"], after["sum"], after["median"], after["max"]) == (100.0, 9.0, 1.0, 7.0)
    assert after["failures"] == {"object_left_table": 2, "step_limit": 1}
    assert [row["seed"] for row in result["per_seed"]] == SEEDS
    assert result["policy"]["trained_here"] and result["policy"]["final_loss"] == 0.125
    assert list(result["commands"]) == [
        "generate",
        "export",
        "train",
        "evaluate_before",
        "evaluate_after",
    ]
    assert "--no-early-stop" in result["commands"]["evaluate_before"]
    assert result["commands"]["evaluate_after"].startswith("python scripts/evaluate.py")

    again = bes.run(TASK, args, "python benchmarks/bench_early_stop.py")
    assert faked.calls == ["generate", "export", "train", "before", "after"]  # all reused
    assert again["reused"] == ["before", "after"] and again["stats"] == result["stats"]
    assert again["policy"]["reused"] == ["generation", "export", "training"]

    # an interrupted run: the second evaluation missing, the rest reused
    paths = bes.paths_of(TASK, args)
    paths.runs["after"].unlink()
    resumed = bes.run(TASK, args, "python benchmarks/bench_early_stop.py")
    assert faked.calls[5:] == ["after"] and resumed["reused"] == ["before"]

    # another number of rollouts: other commands, both evaluated again, the policy kept
    fewer = bes.parse_args(run_argv(tmp_path, "--episodes", "2"))
    bes.run(TASK, fewer, "python benchmarks/bench_early_stop.py")
    assert faked.calls[6:] == ["before", "after"]

    forced = bes.parse_args(run_argv(tmp_path, "--force", "--order", "after,before"))
    result = bes.run(TASK, forced, "python benchmarks/bench_early_stop.py")
    assert faked.calls[8:] == ["generate", "export", "train", "after", "before"]
    assert list(result["commands"])[-2:] == ["evaluate_after", "evaluate_before"]


def test_a_given_checkpoint_is_evaluated_without_training(bes, tmp_path, faked):
    ckpt = tmp_path / "ckpt"
    ckpt.mkdir()
    args = bes.parse_args(run_argv(tmp_path, "--checkpoint", str(ckpt)))
    result = bes.run(TASK, args, "python benchmarks/bench_early_stop.py")
    assert faked.calls == ["before", "after"]
    assert result["policy"] == {"checkpoint": str(ckpt), "trained_here": False, "commands": {}}
    assert f"lerobot:{ckpt}" in result["commands"]["evaluate_before"]
    text = bes.format_section(result)
    assert f"| policy | the checkpoint `{ckpt}` |" in text
    assert "lerobot-train" not in text


def test_section_has_both_modes_ratio_verdict_and_seeds(bes, tmp_path, faked):
    args = bes.parse_args(run_argv(tmp_path))
    result = bes.run(TASK, args, "python benchmarks/bench_early_stop.py --episodes 3")
    text = bes.format_section(result)
    assert text.startswith(f"## {TASK}\n")
    assert "**after/before wall time 0.25 (goal: <= 1/3): goal met.**" in text
    assert "| wall time of the evaluate process | 6.7 min | 100.0 s |" in text
    assert "| sum of the rollouts' seconds | 21.0 s | 9.0 s |" in text
    assert "| median (largest) rollout | 7.0 s (7.0 s) | 1.0 s (7.0 s) |" in text
    assert "| simulated steps | 1050 | 450 |" in text
    assert "| SR | 0.0 % (0/3) | 0.0 % (0/3) |" in text
    assert "| failures by reason | `step_limit` 3 | `object_left_table` 2, `step_limit` 1 |" in text
    assert "| after/before, wall time | 0.250 |" in text
    assert "| rollouts the early stop shortened | 2 of 3 |" in text
    assert "| rollouts whose outcome it changed | 0 |" in text
    assert "| evaluation seeds | 3, from 100000 to 100003, unseen split, `--seed 0` |" in text
    assert "| expert check before both | 3 kept, 1 skipped (1 found in the cache), 30.0 s |" in text
    assert "| workers, order | 1, before then after |" in text
    assert "ACT (state) trained here: 2 demonstrations, 300 steps" in text
    header = (
        "| seed | steps before | seconds before | steps after | seconds after | failure after |"
    )
    assert header in text
    assert "| 100000 | 350 | 7.0 | 50 | 1.0 | object_left_table |" in text
    assert "| 100003 | 350 | 7.0 | 350 | 7.0 | step_limit |" in text
    assert "machine" in text and "| date (UTC) |" in text and "| commit | `" in text
    body = text[text.index("```bash") :]
    commands = result["commands"]
    assert all(c in body for c in commands.values())
    assert body.index(commands["evaluate_before"]) < body.index(commands["evaluate_after"])
    assert "bench_early_stop.py --episodes 3" in text
    assert "Where the time goes" not in text  # no --split

    slow = bes.format_section({**result, "ratio": 0.5})
    assert "**after/before wall time 0.50 (goal: <= 1/3): goal not met.**" in slow
    wrong = bes.format_section({**result, "seeds_match": False})
    assert "did not roll out the same seeds" in wrong


def test_section_shows_the_split(bes, tmp_path, faked, monkeypatch):
    def fake_split(task, checkpoint, seed, args):
        parts = [
            (bes.PHYSICS, 6.0),
            (bes.ACT, 1.0),
            (bes.REST, 3.0),
            (bes.ENV_STEP, 2.0),
            (bes.ENV_RESET, 0.5),
            (bes.OTHER, 0.5),
        ]
        return {
            "task": task,
            "checkpoint": str(checkpoint),
            "stamp": bes.checkpoint_stamp(checkpoint),
            "seed": seed,
            "steps": 350,
            "failure": "step_limit",
            "policy": "LeRobotPolicy",
            "load_seconds": 2.0,
            "build_seconds": 3.0,
            "wall": 10.0,
            "parts": [{"part": n, "seconds": s, "share": s / 10} for n, s in parts],
            "top": [{"function": "AdvanceTo", "calls": 350, "own_seconds": 6.0}],
        }

    monkeypatch.setattr(bes, "run_split", fake_split)
    args = bes.parse_args(run_argv(tmp_path, "--split"))
    result = bes.run(TASK, args, "python benchmarks/bench_early_stop.py --split")
    assert result["split"]["seed"] == SEEDS[0]  # the first evaluated seed
    text = bes.format_section(result)
    assert "### Where the time goes: one rollout, seed 100000, without the early stop" in text
    assert "10.0 s (in the evaluation without the early stop: 7.0 s)" in text
    assert f"| {bes.PHYSICS} | 6.00 | 60.0 % |" in text
    assert f"| {bes.ACT} | 1.00 | 10.0 % |" in text
    assert f"| {bes.REST} | 3.00 | 30.0 % |" in text
    assert f"| &nbsp;&nbsp;of which {bes.ENV_STEP} | 2.00 | 20.0 % |" in text
    assert "| `AdvanceTo` | 350 | 6.00 |" in text
    assert text.index("Where the time goes") < text.index("### Per seed")


def test_sections_are_merged_and_written_atomically(bes, tmp_path, faked):
    args = bes.parse_args(run_argv(tmp_path))
    result = bes.run(TASK, args, "python benchmarks/bench_early_stop.py")
    out = tmp_path / "md" / "bench_early_stop.md"
    bes.write_section(out, result)
    bes.write_section(out, {**result, "task": "balance_roller"})
    bes.write_section(out, {**result, "ratio": 0.5})
    text = out.read_text()
    assert text.startswith(bes.TITLE)
    assert text.count(f"## {TASK}") == 1 and text.count("## balance_roller") == 1
    assert text.index(f"## {TASK}") < text.index("## balance_roller")
    assert "0.50 (goal: <= 1/3): goal not met" in text  # replaced
    assert "0.25 (goal: <= 1/3): goal met" in text  # kept
    assert text.count("### Per seed") == 2  # subsections stay in their section
    assert [p.name for p in out.parent.iterdir()] == [out.name]  # no temporary file left


def test_main_writes_the_section(bes, tmp_path, faked, monkeypatch, capsys):
    monkeypatch.setattr(bes.shutil, "which", lambda name: f"/usr/bin/{name}")
    out = tmp_path / "out.md"
    assert bes.main(run_argv(tmp_path, "--out", str(out))) == 0
    assert "goal met" in out.read_text()
    assert "after/before wall time 0.25" in capsys.readouterr().out


# --------------------------------------------------------------------------- --before
#: A tree's benchmarks/bench_early_stop.py as --before needs it (b96629b or later): its own
#: expert check; it reports which bicoord_drake it imported.
TREE_SCRIPT = """\
import bicoord_drake


def evaluation_config(task, checkpoint, args, early_stop):
    return (task, str(checkpoint), args.episodes, args.seed, args.workers, early_stop)


def warm_expert_check(config):
    print("the check's own output")
    return {"kept": [bicoord_drake.__file__], "skipped": list(config), "cached": 0, "seconds": 1}
"""


def make_tree(tree, script=TREE_SCRIPT):
    """A stand-in for a checked-out revision: its benchmark script and package."""
    (tree / "benchmarks").mkdir(parents=True)
    (tree / "benchmarks" / "bench_early_stop.py").write_text(script)
    (tree / "bicoord_drake").mkdir()
    (tree / "bicoord_drake" / "__init__.py").write_text("")
    return tree


@pytest.fixture
def fake_worktree(bes, tmp_path, monkeypatch):
    """expert_success.worktree without git: a stand-in tree; the commits checked out, then
    'removed'."""
    events = []

    @contextlib.contextmanager
    def worktree(commit, prefix, root):
        assert (prefix, root) == ("bench-early-stop-", bes.ROOT)
        if commit is None:
            yield None
            return
        tree = make_tree(tmp_path / "trees" / commit / "tree")
        events.append(commit)
        try:
            yield tree
        finally:
            shutil.rmtree(tree)
            events.append("removed")

    monkeypatch.setattr(bes.expert_success, "worktree", worktree)
    return events


def git(repo, *args):
    return subprocess.run(
        ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
        cwd=repo,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()


def test_before_is_resolved_to_a_commit(bes, capsys):
    head = bes.revision("HEAD")
    assert head and head == git(bes.ROOT, "rev-parse", "--short", "HEAD")
    assert bes.parse_args([]).before is None and bes.parse_args([]).before_commit is None
    args = bes.parse_args(["--before", "HEAD"])
    assert (args.before, args.before_commit) == ("HEAD", head)
    assert bes.revision("no-such-revision") is None
    assert bes.revision("HEAD:README.md") is None  # a file, not a commit
    with pytest.raises(SystemExit):
        bes.parse_args(["--help"])
    shown = " ".join(capsys.readouterr().out.split())
    example = "bench_early_stop.py --checkpoint DIR --before 512374c --episodes 50 --workers 2"
    assert f"{example} --split" in shown
    assert example in " ".join(bes.__doc__.replace("\\\n", " ").split())


def test_an_unknown_before_exits_2_naming_it(bes, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(bes.baselines, "run", lambda *a, **k: pytest.fail("a step ran"))
    monkeypatch.setattr(bes.expert_success, "worktree", lambda *a: pytest.fail("a worktree"))
    out = tmp_path / "out.md"
    argv = ["--before", "no-such-rev", "--work", str(tmp_path / "work"), "--out", str(out)]
    assert bes.main(argv) == 2
    err = capsys.readouterr().err
    assert "--before no-such-rev" in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "work").exists()


def test_before_runs_in_a_worktree_of_the_revision(
    bes, tmp_path, faked, fake_worktree, monkeypatch
):
    monkeypatch.delenv("PYTHONPATH", raising=False)  # what this test's own caller set
    ckpt = tmp_path / "ckpt"
    ckpt.mkdir()
    args = bes.parse_args(run_argv(tmp_path, "--checkpoint", str(ckpt), "--before", "HEAD~1"))
    result = bes.run(TASK, args, "python benchmarks/bench_early_stop.py --before HEAD~1")
    old = bes.revision("HEAD~1")
    tree = tmp_path / "trees" / old / "tree"
    assert faked.calls == ["check_before", "before", "after"]
    assert fake_worktree == [old, "removed"]
    for step in ("check_before", "before"):
        cwd, pythonpath, present = faked.where[step]
        assert cwd == tree and present  # the tree, checked out while it runs
        assert pythonpath.split(bes.os.pathsep)[0] == str(tree)
        assert str(bes.ROOT) not in pythonpath.split(bes.os.pathsep)
    assert faked.where["after"] == (bes.ROOT, None, True)  # this checkout, as baselines.run
    assert result["expert_check"] == fake_check(args)
    assert result["expert_check_before"] == fake_check(args)
    assert result["before"] == "HEAD~1"
    assert result["packages"]["before"] == {"commit": old, "dirty": False}
    assert result["packages"]["after"]["commit"] == result["commit"] != old
    shown = result["commands"]["evaluate_before"]
    assert (
        "run from a worktree of HEAD~1" in shown
        and "git worktree add --detach TREE HEAD~1" in shown
    )
    assert "cd TREE && PYTHONPATH=TREE python scripts/evaluate.py" in shown
    assert result["commands"]["evaluate_after"].startswith("python scripts/evaluate.py")
    record = json.loads(bes.paths_of(TASK, args).runs["before"].read_text())
    assert (record["package"], record["package_dirty"], record["worktree"]) == (old, False, True)


def test_the_tree_check_runs_that_trees_code_and_package(bes, tmp_path):
    """TREE_CHECK for real (a subprocess, no physics): the tree's script and bicoord_drake."""
    tree = make_tree(tmp_path / "tree")
    package = bes.Package("abc1234", tree=tree, rev="abc1234")
    args = bes.parse_args(["--episodes", "4", "--seed", "2", "--workers", "3"])
    check = bes.warm_tree_check(TASK, tmp_path / "ckpt", args, package, tmp_path / "check.log")
    assert check["kept"] == [str(tree / "bicoord_drake" / "__init__.py")]
    assert check["skipped"] == [TASK, str(tmp_path / "ckpt"), 4, 2, 3, False]
    assert (check["cached"], check["seconds"]) == (0, 1)
    assert (tmp_path / "check.log").read_text().startswith(f"$ cd {tree} && PYTHONPATH={tree}")


@pytest.mark.parametrize(
    "script", ["", "def evaluation_config():\n    pass\n", TREE_SCRIPT.replace("1}", "1")]
)
def test_a_revision_without_the_tree_check_is_named(bes, tmp_path, script):
    tree = make_tree(tmp_path / "tree", script)
    package = bes.Package("abc1234", tree=tree, rev="old")
    args = bes.parse_args([])
    with pytest.raises(RuntimeError) as err:
        bes.warm_tree_check(TASK, tmp_path / "ckpt", args, package, tmp_path / "check.log")
    assert "--before old" in str(err.value) and "b96629b or later" in str(err.value)


def test_a_record_of_another_package_is_not_reused(bes, tmp_path, faked, fake_worktree):
    ckpt = tmp_path / "ckpt"
    ckpt.mkdir()
    plain = bes.parse_args(run_argv(tmp_path, "--checkpoint", str(ckpt)))
    before = bes.parse_args(run_argv(tmp_path, "--checkpoint", str(ckpt), "--before", "HEAD~1"))
    bes.run(TASK, plain, "x")
    assert faked.calls == ["before", "after"]
    assert bes.run(TASK, before, "x")["reused"] == ["after"]  # before: another package
    assert faked.calls[2:] == ["check_before", "before"]
    assert bes.run(TASK, before, "x")["reused"] == ["before", "after"]
    assert bes.run(TASK, plain, "x")["reused"] == ["after"]  # and back
    assert faked.calls[5:] == ["before"]

    runs = bes.paths_of(TASK, plain).runs
    record = json.loads(runs["after"].read_text())
    runs["after"].write_text(json.dumps({**record, "package": "0000000"}))  # another commit
    bes.run(TASK, plain, "x")
    runs["after"].write_text(json.dumps({**record, "package_dirty": not record["package_dirty"]}))
    bes.run(TASK, plain, "x")
    assert faked.calls[6:] == ["after", "after"]


def test_section_names_both_revisions(bes, tmp_path, faked, fake_worktree):
    args = bes.parse_args(run_argv(tmp_path, "--before", "HEAD~1"))
    text = bes.format_section(bes.run(TASK, args, "python benchmarks/bench_early_stop.py"))
    old = bes.revision("HEAD~1")
    head = bes.revision("HEAD")
    dirty = ", dirty" if bes.expert_success.git_state(bes.ROOT)[1] else ""
    assert (
        f"| | before (`{old}`, `--no-early-stop`) | after (`{head}`{dirty}, early stop) |" in text
    )
    assert "**after/before wall time 0.25 (goal: <= 1/3): goal met.**" in text
    assert f"| package of before | `--before HEAD~1`: `{old}`, run from a worktree of it" in text
    check = "3 kept, 1 skipped (1 found in the cache), 30.0 s"
    assert f"| expert check before both, after's package `{head}`{dirty} | {check} |" in text
    assert f"| expert check before both, before's package `{old}` | {check} |" in text
    assert "run from a worktree of HEAD~1" in text[text.index("```bash") :]

    plain = bes.format_section(bes.run(TASK, bes.parse_args(run_argv(tmp_path)), "x"))
    assert f"| | before (`{head}`{dirty}, `--no-early-stop`) |" in plain
    assert "package of before" not in plain and "worktree" not in plain


def test_the_worktree_is_removed_even_when_the_evaluation_fails(bes, tmp_path, faked, monkeypatch):
    """expert_success.worktree for real, in a repository of its own."""
    repo = tmp_path / "repo"
    repo.mkdir()
    git(repo, "init", "-q")
    make_tree(repo)
    git(repo, "add", ".")
    git(repo, "commit", "-q", "-m", "a revision")
    monkeypatch.setattr(bes, "ROOT", repo)  # where git resolves --before and adds the tree
    ckpt = tmp_path / "ckpt"
    ckpt.mkdir()
    args = bes.parse_args(run_argv(tmp_path, "--checkpoint", str(ckpt), "--before", "HEAD"))
    assert args.before_commit == git(repo, "rev-parse", "--short", "HEAD")

    faked.fail = {"before"}
    with pytest.raises(RuntimeError, match="before failed"):
        bes.run(TASK, args, "x")
    tree, pythonpath, present = faked.where["before"]
    assert present and tree.name == "tree" and pythonpath.startswith(str(tree))
    assert not tree.exists() and not tree.parent.exists()
    assert git(repo, "worktree", "list").count("\n") == 0  # only the repository itself

    faked.fail = set()
    bes.run(TASK, args, "x")
    assert not faked.where["before"][0].exists()
    assert git(repo, "worktree", "list").count("\n") == 0


def test_a_worktree_of_an_old_revision_stops_before_anything_runs(
    bes, tmp_path, faked, monkeypatch
):
    @contextlib.contextmanager
    def worktree(commit, prefix, root):
        tree = tmp_path / "old" / "tree"
        (tree / "benchmarks").mkdir(parents=True)  # no bench_early_stop.py
        yield tree

    monkeypatch.setattr(bes.expert_success, "worktree", worktree)
    args = bes.parse_args(run_argv(tmp_path, "--before", "HEAD~1"))
    with pytest.raises(RuntimeError, match=r"--before HEAD~1: the revision needs .*\(b96629b"):
        bes.run(TASK, args, "x")
    assert faked.calls == []  # no training, no check, no evaluation


@pytest.mark.slow
def test_one_demo_one_rollout_end_to_end(bes, tmp_path, monkeypatch):
    """The whole benchmark on one demonstration, a 20-step training and one rollout per mode,
    with the split (minutes)."""
    pytest.importorskip("lerobot.policies.act.modeling_act")
    if shutil.which("lerobot-train") is None:
        pytest.skip("lerobot-train is not on PATH (pip install --no-deps lerobot==0.4.4)")
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "out.md"
    argv = ["--demos", "1", "--train-steps", "20", "--episodes", "1", "--split"]
    assert bes.main([*argv, "--work", str(tmp_path / "work"), "--out", str(out)]) == 0
    text = out.read_text()
    assert "after/before wall time" in text and "### Where the time goes" in text
    assert text.count("\n| 1000") == 1  # one per-seed row

#!/usr/bin/env python
"""Evaluations that stop when nothing can be saved: time with and without the early stop.

    python benchmarks/bench_early_stop.py                      # train a failing ACT, 50 rollouts
    python benchmarks/bench_early_stop.py --checkpoint out/act_run --episodes 50 --split
    python benchmarks/bench_early_stop.py --checkpoint DIR --before 512374c --episodes 50 \\
        --workers 2 --split                                    # "before": commit 512374c
    python benchmarks/bench_early_stop.py --demos 1 --train-steps 20 --episodes 1 \\
        --work /tmp/bes --out /tmp/bes/out.md                  # a smoke run (minutes)

Issue #53 item 4: a rollout ends early, as a failure with its reason, once a task object has
left the table (``scripts/evaluate.py`` does so by default; ``--no-early-stop`` turns it off;
a diverged physics ends a rollout in both). Goal: ``--episodes`` (50) rollouts of the same
failing policy on ``--task`` (handover_block_with_bowls) in at most 1/3 of the time they take
without the early stop, both measured in one run. By default both evaluations run this
checkout's package; with ``--before REV`` the one without the early stop runs the package of
git revision REV instead (the issue's "current commit", against this one): REV is checked out
with ``git worktree add --detach TMP/tree REV`` and ``scripts/evaluate.py`` runs there (working
directory the tree, the tree first on ``PYTHONPATH``), still with ``--no-early-stop``; the
worktree is removed at the end, also on an error (``expert_success.worktree``). REV needs
``benchmarks/bench_early_stop.py`` with ``warm_expert_check`` (b96629b or later). The steps:

1. the failing policy: ``--checkpoint DIR`` (a lerobot-train output directory), or one trained
   here as ``benchmarks/policy_reproduces.py`` trains (its commands, paths and
   ``REPRODUCE_ARGS``): ``--demos`` plain expert demonstrations from seed 0
   (``scripts/generate.py --no-render --workers 1`` into ``WORK/data``), exported state-based,
   and ACT trained for ``--train-steps`` steps (few: it fails);
2. the expert check of the evaluation seeds, in this process (:func:`warm_expert_check`), so
   that neither evaluation pays for it (the first one would, the second read its cache); with
   ``--before`` also in the worktree (its cache key holds a fingerprint of the package's code):
   its own ``warm_expert_check`` in a subprocess there (:func:`warm_tree_check`);
3. ``scripts/evaluate.py --policy lerobot:CKPT --episodes N --seed S --no-render --workers W
   --json`` twice on the same evaluation seeds (the default, unseen split), one after the other:
   "before" with ``--no-early-stop`` and "after" with the early stop (``--order``: which
   first), each timed from outside (the wall time of the process);
4. with ``--split``: one rollout of the checkpoint on the first evaluated seed, without the
   early stop, in this process under cProfile (:func:`run_split`): the share of its wall time
   in the physics (``Simulator.AdvanceTo``, in ``Simulation.step``), in the policy's ``act``,
   and the rest (the environment's step outside the physics, its reset, the loop); always
   this checkout's package, also with ``--before``.

The task's section of ``--out`` (other sections kept; written to a temporary file, then
renamed) gives the machine, date (UTC), commit (dirty: the package had uncommitted changes),
the exact commands, per mode the package it ran (its commit) and the wall time of the
evaluation process, the sum, median and largest of the rollouts' own seconds, the simulated
steps, SR and the failures by reason, the ratio after/before of the wall times and the verdict
(goal: <= 1/3), the split, and per seed the steps and seconds before and after and why the
rollout failed after.

Every step is skipped when its output is already in ``--work`` (an interrupted run resumes):
demonstrations, dataset and checkpoint as in policy_reproduces.py, an evaluation when its record
(``WORK/eval_<mode>/run.json``) has the same command, checkpoint files and package (its commit
and, for this checkout, whether it was dirty: a ``--before`` run never reuses an evaluation of
this checkout, nor the other way round), the split when ``WORK/split.json`` is of the same
checkpoint and seed; ``--force`` redoes them all. Exit status: 0 when both evaluations ran on
the same seeds, 1 on an error or when their seeds differ, 2 for bad arguments (among them a
``--before`` that git cannot resolve to a commit). Training needs lerobot:
``pip install -e '.[train]' && pip install --no-deps lerobot==0.4.4``.
"""

from __future__ import annotations

import argparse
import cProfile
import hashlib
import importlib
import inspect
import json
import os
import pstats
import re
import shlex
import shutil
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
# Measure the code of this checkout (the commit the report names), whatever is pip-installed.
sys.path.insert(0, str(ROOT))
sys.path.append(str(Path(__file__).resolve().parent))  # the other benchmark scripts, last

policy_reproduces = importlib.import_module("policy_reproduces")
baselines = policy_reproduces._benchmark("baselines")
expert_success = policy_reproduces._benchmark("expert_success")

DEFAULT_TASK = "handover_block_with_bowls"
DEFAULT_WORK = ROOT / "out" / "bench_early_stop"
DEFAULT_OUT = ROOT / "benchmarks" / "bench_early_stop.md"
#: The two evaluations: without the early stop ("before") and with it ("after").
MODES = ("before", "after")
ORDERS = ("before,after", "after,before")
#: The goal: the evaluation with the early stop takes at most this share of the time without.
GOAL = 1 / 3
TITLE = "# Evaluations that stop when nothing can be saved"
PREAMBLE = (
    f"{TITLE}\n\n"
    "Written by `python benchmarks/bench_early_stop.py` (issue #53 item 4): the same failing "
    "policy rolled out on the same evaluation seeds by `scripts/evaluate.py`, once with "
    "`--no-early-stop` (before) and once with the early stop (after: a rollout ends, as a "
    "failure with its reason, once a task object has left the table), one after the other. "
    "Goal: the evaluation with the early stop takes at most 1/3 of the wall time of the one "
    "without. The seeds' expert check runs before both (neither pays for it). `(dirty)` after "
    "the commit: the package (`bicoord_drake/`, `pyproject.toml`) had uncommitted changes or "
    "changed during the run.\n"
)


# --------------------------------------------------------------------------- settings, paths
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (`--order` becomes a tuple of modes; counts must be >= 1)."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--task", default=DEFAULT_TASK, help=f"one task (default {DEFAULT_TASK})")
    parser.add_argument(
        "--checkpoint",
        type=Path,
        help="a lerobot-train output directory to evaluate (default: train a failing ACT here)",
    )
    parser.add_argument("--demos", type=int, default=3, help="demonstrations to train on")
    parser.add_argument("--train-steps", type=int, default=300, help="lerobot-train --steps")
    parser.add_argument("--batch-size", type=int, default=8, help="lerobot-train --batch_size")
    parser.add_argument("--train-seed", type=int, default=1000, help="lerobot-train --seed")
    parser.add_argument("--episodes", type=int, default=50, help="rollouts per evaluation")
    parser.add_argument(
        "--seed", type=int, default=0, help="evaluate.py --seed: seeds from 100000 * (1 + SEED)"
    )
    parser.add_argument("--workers", type=int, default=1, help="evaluate.py --workers")
    parser.add_argument(
        "--order",
        default=ORDERS[0],
        choices=ORDERS,
        metavar="FIRST,SECOND",
        help="the evaluations' order: before,after (default) or after,before",
    )
    parser.add_argument(
        "--before",
        metavar="REV",
        help="run the evaluation without the early stop on the package of git revision REV, "
        "checked out in a temporary git worktree (REV: b96629b or later; default: this "
        "checkout), e.g. python benchmarks/bench_early_stop.py --checkpoint DIR --before "
        "512374c --episodes 50 --workers 2 --split",
    )
    parser.add_argument(
        "--split",
        action="store_true",
        help="also profile one rollout without the early stop: physics, act and the rest "
        "(this checkout's package, also with --before)",
    )
    parser.add_argument(
        "--work",
        type=Path,
        default=DEFAULT_WORK,
        help="demonstrations, dataset, checkpoint, evaluations, logs (default: "
        "out/bench_early_stop)",
    )
    parser.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help="the Markdown file whose section to update"
    )
    parser.add_argument("--force", action="store_true", help="redo every step")
    args = parser.parse_args(argv)
    for name in ("demos", "train_steps", "batch_size", "episodes", "workers"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1")
    if args.seed < 0:
        parser.error("--seed must be at least 0")
    if args.checkpoint is not None:
        if not args.checkpoint.is_dir():
            parser.error(f"--checkpoint {args.checkpoint}: no such directory")
        args.checkpoint = args.checkpoint.resolve()
    args.order = tuple(args.order.split(","))
    args.before_commit = revision(args.before) if args.before is not None else None
    args.work = args.work.resolve()  # the steps run with the checkout as working directory
    args.out = args.out.resolve()
    return args


def training_args(args: argparse.Namespace) -> argparse.Namespace:
    """The settings in the form benchmarks/policy_reproduces.py's paths and commands take."""
    return argparse.Namespace(
        work=args.work,
        demos=args.demos,
        steps=args.train_steps,
        batch_size=args.batch_size,
        train_seed=args.train_seed,
    )


@dataclass(frozen=True)
class Paths:
    """Where the steps write, under ``--work``."""

    train: Any  # policy_reproduces.TaskPaths: data, demos, dataset, checkpoint, logs
    evals: dict[str, Path]  # mode -> scripts/evaluate.py --out
    runs: dict[str, Path]  # mode -> the evaluation's record (command, wall time, report)
    logs: Path
    split: Path


def paths_of(task: str, args: argparse.Namespace) -> Paths:
    """The paths of the steps with `args` (training ones as policy_reproduces.py names them)."""
    evals = {mode: args.work / f"eval_{mode}" for mode in MODES}
    return Paths(
        train=policy_reproduces.task_paths(task, training_args(args)),
        evals=evals,
        runs={mode: path / "run.json" for mode, path in evals.items()},
        logs=args.work / "logs",
        split=args.work / "split.json",
    )


# --------------------------------------------------------------------------- the packages
#: What an older revision needs for ``--before``: its own expert check, run in its worktree.
TREE_NEEDS = "benchmarks/bench_early_stop.py with warm_expert_check (b96629b or later)"
#: ``python -c TREE_CHECK TASK CHECKPOINT EPISODES SEED WORKERS``, in a worktree: that tree's
#: :func:`warm_expert_check` of the evaluation seeds, its result as JSON on the last line.
TREE_CHECK = """\
import argparse, json, sys
from pathlib import Path
sys.path.insert(0, "benchmarks")
import bench_early_stop as bes
task, checkpoint, episodes, seed, workers = sys.argv[1:]
args = argparse.Namespace(episodes=int(episodes), seed=int(seed), workers=int(workers))
config = bes.evaluation_config(task, Path(checkpoint), args, early_stop=False)
print(json.dumps(bes.warm_expert_check(config)))
"""


@dataclass(frozen=True)
class Package:
    """The package an evaluation runs: this checkout's, or that of a worktree of ``--before``."""

    commit: str  # short hash
    dirty: bool = False  # this checkout, with uncommitted changes to the package
    tree: Path | None = None  # the worktree of --before (None: this checkout)
    rev: str | None = None  # --before as given

    @property
    def cwd(self) -> Path:
        """Where its commands run."""
        return ROOT if self.tree is None else self.tree

    def env(self) -> dict[str, str] | None:
        """Its commands' environment: the tree first on PYTHONPATH (None: baselines.run's)."""
        if self.tree is None:
            return None
        path = os.pathsep.join(filter(None, [str(self.tree), os.environ.get("PYTHONPATH")]))
        return {**baselines.subprocess_env(), "PYTHONPATH": path}

    def key(self) -> dict[str, Any]:
        """What an evaluation record keeps of it (a record of another package is not reused)."""
        return {
            "package": self.commit,
            "package_dirty": self.dirty,
            "worktree": self.tree is not None,
        }

    def shown(self, command: str) -> str:
        """`command` as the section shows it: from the worktree, for ``--before``."""
        if self.tree is None:
            return command
        return (
            f"git worktree add --detach TREE {self.rev}  # run from a worktree of {self.rev}\n"
            f"cd TREE && PYTHONPATH=TREE {command}"
        )


def revision(rev: str) -> str | None:
    """The short hash of the commit `rev` names; None when git cannot resolve it."""
    return expert_success.short_commit_of(rev, ROOT)


def packages_of(args: argparse.Namespace, tree: Path | None, here: Package) -> dict[str, Package]:
    """Mode -> the package it runs: "before" the worktree's (with ``--before``), else `here`."""
    if tree is None:
        return dict.fromkeys(MODES, here)
    return {"before": Package(args.before_commit, tree=tree, rev=args.before), "after": here}


# --------------------------------------------------------------------------- the commands
def evaluate_command(
    task: str, checkpoint: Path, mode: str, args: argparse.Namespace, paths: Paths
) -> list[str]:
    """scripts/evaluate.py of `mode`: the same seeds, rollouts and workers in both; before:
    ``--no-early-stop``."""
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: one of {', '.join(MODES)}")
    return [
        sys.executable,
        "scripts/evaluate.py",
        "--task",
        task,
        "--policy",
        f"lerobot:{checkpoint}",
        "--episodes",
        str(args.episodes),
        "--seed",
        str(args.seed),
        "--no-render",
        "--workers",
        str(args.workers),
        *(["--no-early-stop"] if mode == "before" else []),
        "--json",
        "--out",
        str(paths.evals[mode]),
    ]


def evaluation_config(task: str, checkpoint: Path, args: argparse.Namespace, early_stop: bool):
    """The :class:`~bicoord_drake.runner.rollouts.EvaluateConfig` the evaluation commands make
    (their scenario, so the expert check and the split see their seeds and scenes)."""
    from bicoord_drake.runner.rollouts import EvaluateConfig

    return EvaluateConfig(
        task=task,
        policy=f"lerobot:{checkpoint}",
        episodes=args.episodes,
        seed=args.seed,
        render=False,
        early_stop=early_stop,
        workers=args.workers,
    )


# --------------------------------------------------------------------------- 1. the policy
def _say(number: int, text: str) -> None:
    print(f"[bench_early_stop] {number}/4 {text}", flush=True)


def train_policy(task: str, args: argparse.Namespace, paths: Paths) -> dict[str, Any]:
    """Generate, export and train as policy_reproduces.py does (each step skipped when its
    output is in ``--work``); the checkpoint, the commands, times and final loss."""
    train_args = training_args(args)
    p = paths.train
    reused: list[str] = []
    seconds: dict[str, float | None] = {"generate": None, "export": None}

    generate = policy_reproduces.generate_command(task, train_args, p)
    if len(policy_reproduces.existing_demos(p.demos, task)) >= args.demos:
        _say(1, f"{args.demos} demonstrations already in {p.demos}")
        reused.append("generation")
    else:
        _say(1, f"generate {args.demos} demonstrations (seeds from 0, no cameras)")
        _, seconds["generate"] = baselines.run(generate, p.logs / "generate.log")
    files = baselines.demonstrations(p.demos, task, args.demos)

    export = policy_reproduces.export_command(files, p)
    episodes = policy_reproduces.exported(p.dataset)
    if episodes and policy_reproduces.same_files([e["source"] for e in episodes], files):
        _say(1, f"dataset already exported: {p.dataset}")
        reused.append("export")
    else:
        _say(1, f"export {len(files)} demonstrations (state, no images)")
        policy_reproduces._remove(p.dataset)
        _, seconds["export"] = baselines.run(export, p.logs / "export.log")

    train = policy_reproduces.train_command(task, train_args, p)
    train_log = p.logs / f"train_{p.checkpoint.name}.log"
    train_seconds = baselines.trained(p.checkpoint, train)
    if train_seconds is None:
        policy_reproduces._remove(p.checkpoint)  # lerobot-train refuses an existing directory
        _say(1, f"train ACT: {args.train_steps} steps, batch {args.batch_size} (log {train_log})")
        _, train_seconds = baselines.run(train, train_log)
        loss = baselines.final_loss(train_log)
        record = {"command": baselines.shown(train), "seconds": train_seconds, "final_loss": loss}
        baselines.write_json_atomic(p.checkpoint / baselines.TRAINED, record)
    else:
        _say(1, f"trained before: {p.checkpoint}")
        reused.append("training")
        loss = json.loads((p.checkpoint / baselines.TRAINED).read_text()).get("final_loss")
    return {
        "checkpoint": str(p.checkpoint),
        "trained_here": True,
        "demos": args.demos,
        "train_steps": args.train_steps,
        "batch_size": args.batch_size,
        "train_seed": args.train_seed,
        "train_args": policy_reproduces.REPRODUCE_ARGS,
        "final_loss": loss,
        "train_seconds": round(train_seconds, 1),
        **{f"{k}_seconds": None if v is None else round(v, 1) for k, v in seconds.items()},
        "reused": reused,
        "commands": {
            "generate": baselines.shown(generate),
            "export": baselines.shown(export),
            "train": baselines.shown(train),
        },
    }


def checkpoint_stamp(checkpoint: Path) -> str:
    """A short hash of the checkpoint's files (names, sizes, modification times): another
    training into the same directory is another checkpoint."""
    digest = hashlib.sha256()
    for path in sorted(p for p in Path(checkpoint).rglob("*") if p.is_file()):
        if path.name == baselines.TRAINED:
            continue  # written after the training, not part of the model
        stat = path.stat()
        digest.update(f"{path.relative_to(checkpoint)}:{stat.st_size}:{stat.st_mtime_ns}".encode())
    return digest.hexdigest()[:12]


# --------------------------------------------------------------------------- 2. expert check
def _quiet_drake() -> None:
    """Drake's INFO and WARNING logs off in this process, as scripts/evaluate.py turns them off
    (after pydrake is imported: its import configures the "drake" logger)."""
    import logging

    import pydrake  # noqa: F401

    logging.getLogger("drake").setLevel(logging.ERROR)


def expert_seeds(
    check: Callable[[int], tuple[bool, str | None]], first: int, episodes: int, max_tries: int
) -> tuple[list[int], list[int]]:
    """(seeds kept, seeds skipped) as an evaluation tries them: from `first` up, until
    `episodes` seeds pass `check` or `max_tries` seeds were tried."""
    kept: list[int] = []
    skipped: list[int] = []
    seed = first
    while len(kept) < episodes and len(kept) + len(skipped) < max_tries:
        ok, _ = check(seed)
        (kept if ok else skipped).append(seed)
        seed += 1
    return kept, skipped


def warm_expert_check(config) -> dict[str, Any]:
    """Run (or find cached) the expert check of the seeds an evaluation with `config` tries,
    into the cache the evaluations read (``$BICOORD_CACHE``, inherited by them)."""
    from bicoord_drake.runner.rollouts import ExpertCheck, evaluation_seed
    from bicoord_drake.tasks import get_task

    _quiet_drake()
    check = ExpertCheck.for_config(get_task(config.task), config)
    cached = 0

    def counted(seed: int) -> tuple[bool, str | None]:
        nonlocal cached
        cached += check.lookup(seed) is not None
        return check(seed)

    start = time.perf_counter()
    kept, skipped = expert_seeds(
        counted,
        evaluation_seed(config.seed),
        config.episodes,
        config.max_tries or 3 * config.episodes,
    )
    return {
        "kept": kept,
        "skipped": skipped,
        "cached": cached,
        "seconds": round(time.perf_counter() - start, 1),
    }


def tree_check_command(task: str, checkpoint: Path, args: argparse.Namespace) -> list[str]:
    """``python -c TREE_CHECK ...``: the expert check of the evaluation seeds, run in a tree."""
    settings = (args.episodes, args.seed, args.workers)
    return [sys.executable, "-c", TREE_CHECK, task, str(checkpoint), *map(str, settings)]


def warm_tree_check(
    task: str, checkpoint: Path, args: argparse.Namespace, package: Package, log: Path
) -> dict[str, Any]:
    """:func:`warm_expert_check` of the worktree of ``--before``, by its own code and package (the
    cache key holds a fingerprint of the package's code), in a subprocess there."""
    require_tree_check(package)
    command = tree_check_command(task, checkpoint, args)
    try:
        stdout, _ = baselines.run(command, log, cwd=package.cwd, env=package.env())
        check = json.loads(stdout.strip().splitlines()[-1])
        return {k: check[k] for k in ("kept", "skipped", "cached", "seconds")}
    except (RuntimeError, ValueError, IndexError, KeyError, TypeError) as err:
        needs = f"the revision needs {TREE_NEEDS}"
        raise RuntimeError(
            f"--before {package.rev}: the expert check in its worktree failed ({needs}); "
            f"see {log}: {err}"
        ) from err


def require_tree_check(package: Package) -> None:
    """RuntimeError, naming ``--before``, when its tree has no :func:`warm_expert_check`."""
    try:
        code = (package.cwd / "benchmarks" / "bench_early_stop.py").read_text()
    except OSError:
        code = ""
    if "def warm_expert_check" not in code or "def evaluation_config" not in code:
        raise RuntimeError(f"--before {package.rev}: the revision needs {TREE_NEEDS}")


# --------------------------------------------------------------------------- 3. evaluations
def report_of(stdout: str, out: Path) -> dict[str, Any]:
    """The report scripts/evaluate.py printed (``--json``), else the report.json it wrote."""
    try:
        return json.loads(stdout)
    except ValueError:
        found = sorted(Path(out).rglob("report.json"))
        if len(found) != 1:
            raise RuntimeError(f"no report in the evaluation's output nor under {out}") from None
        return json.loads(found[0].read_text())


def summary(report: dict[str, Any]) -> dict[str, Any]:
    """What this benchmark keeps of an evaluation report: scores, failures, skipped seeds, the
    evaluation's own time and per rollout its seed, steps, seconds, outcome and failure."""
    return {
        "n": report["n"],
        "SR": report.get("SR"),
        "failures": report.get("failures") or {},
        "skipped": [s.get("seed") for s in report.get("skipped") or []],
        "seconds": report.get("seconds"),
        "rollouts": [
            {
                "seed": int(r["seed"]),
                "steps": int(r["steps"]),
                "seconds": float(r["seconds"]),
                "success": bool(r["success"]),
                "failure": r.get("failure"),
                "error": (r.get("error") or "")[:200] or None,
            }
            for r in report["rollouts"]
        ],
    }


def evaluate_mode(
    task: str,
    checkpoint: Path,
    mode: str,
    args: argparse.Namespace,
    paths: Paths,
    package: Package,
) -> dict[str, Any]:
    """The evaluation of `mode` on `package`: its record in ``--work`` if it has this command,
    checkpoint and package, else run (in the package's tree), timed (wall time of the process)
    and recorded."""
    command = evaluate_command(task, checkpoint, mode, args, paths)
    stamp = checkpoint_stamp(checkpoint)
    key = {"command": baselines.shown(command), "stamp": stamp, **package.key()}
    try:
        record = json.loads(paths.runs[mode].read_text())
    except (OSError, ValueError):
        record = None
    if record and all(record.get(k) == v for k, v in key.items()):
        _say(3, f"{mode}: evaluated before ({record['date']}): {paths.runs[mode]}")
        return {**record, "reused": True}
    policy_reproduces._remove(paths.evals[mode])
    what = "without the early stop" if mode == "before" else "with the early stop"
    where = f"a worktree of {package.rev}" if package.tree else "this checkout"
    _say(
        3,
        f"{mode}: {args.episodes} rollouts {what}, package {package.commit} ({where}; log "
        f"{paths.logs}/evaluate_{mode}.log)",
    )
    stdout, wall = baselines.run(
        command, paths.logs / f"evaluate_{mode}.log", cwd=package.cwd, env=package.env()
    )
    record = {
        "mode": mode,
        **key,
        "wall_seconds": round(wall, 2),
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M"),
        **summary(report_of(stdout, paths.evals[mode])),
    }
    paths.evals[mode].mkdir(parents=True, exist_ok=True)
    baselines.write_json_atomic(paths.runs[mode], record)
    return {**record, "reused": False}


def mode_stats(record: dict[str, Any]) -> dict[str, Any]:
    """Per evaluation: rollouts, wall time, the rollouts' own seconds (sum, median, max),
    simulated steps, successes and failures by reason."""
    rollouts = record["rollouts"]
    seconds = [r["seconds"] for r in rollouts]
    return {
        "n": len(rollouts),
        "wall": record["wall_seconds"],
        "evaluation": record.get("seconds"),
        "sum": round(sum(seconds), 2),
        "median": round(statistics.median(seconds), 2) if seconds else None,
        "max": round(max(seconds), 2) if seconds else None,
        "steps": sum(r["steps"] for r in rollouts),
        "successes": sum(r["success"] for r in rollouts),
        "SR": record.get("SR"),
        "failures": dict(record.get("failures") or {}),
        "skipped": len(record.get("skipped") or []),
    }


def ratio(after: float, before: float) -> float | None:
    """after / before (None when before is not positive)."""
    return after / before if before > 0 else None


def verdict(value: float | None) -> str:
    """'after/before wall time 0.21 (goal: <= 1/3): goal met'."""
    if value is None:
        return "after/before wall time: not measured (goal: <= 1/3)"
    met = "goal met" if value <= GOAL else "goal not met"
    return f"after/before wall time {value:.2f} (goal: <= 1/3): {met}"


def per_seed(before: dict[str, Any], after: dict[str, Any]) -> list[dict[str, Any]]:
    """Per seed of either evaluation (in evaluation order): steps, seconds and outcome of
    both (None where a mode has no rollout of the seed)."""
    rows: dict[int, dict[str, Any]] = {}
    for mode, record in (("before", before), ("after", after)):
        for r in record["rollouts"]:
            rows.setdefault(r["seed"], {"seed": r["seed"], "before": None, "after": None})[mode] = r
    return list(rows.values())


# --------------------------------------------------------------------------- 4. the split
#: The parts of a rollout's time the split names (besides the physics and the policy).
PHYSICS = "physics advance (Simulator.AdvanceTo)"
ACT = "policy act"
REST = "the rest"
ENV_STEP = "environment step outside the physics (state, stage monitor, early-stop check, obs)"
ENV_RESET = "environment reset"
OTHER = "other (the rollout loop, limit counting, bookkeeping)"


def _code_key(func: Any) -> tuple[str, int, str] | None:
    """cProfile's key of a Python function or method (None for anything else)."""
    code = getattr(inspect.unwrap(func), "__code__", None) if func is not None else None
    return None if code is None else (code.co_filename, code.co_firstlineno, code.co_name)


def _is_advance(key: tuple[str, int, str]) -> bool:
    """Whether a profile entry is a simulator's AdvanceTo: Drake's binding (cProfile names it
    ``<built-in method pydrake.systems.analysis.AdvanceTo>``) or a Python stand-in."""
    return re.search(r"\bAdvanceTo\b", key[2]) is not None


def _label(key: tuple[str, int, str]) -> str:
    file, line, name = key
    return name if file == "~" else f"{Path(file).name}:{line}({name})"


def split_of(
    stats: pstats.Stats, wall: float, act: Any, step: Any, reset: Any, top: int = 8
) -> dict[str, Any]:
    """Where `wall` seconds of a profiled rollout went: the physics (every AdvanceTo), the
    policy's `act`, the rest; the rest split into the environment's `step` outside the
    physics, its `reset` and the other; and the `top` functions by their own time."""
    table = stats.stats  # key -> (primitive calls, calls, own time, cumulative time, callers)

    def cumulative(func: Any) -> float:
        key = _code_key(func)
        return float(table[key][3]) if key in table else 0.0

    physics = sum(float(v[3]) for k, v in table.items() if _is_advance(k))
    acting = cumulative(act)
    env_step = max(0.0, cumulative(step) - physics)
    env_reset = cumulative(reset)
    rest = max(0.0, wall - physics - acting)
    seconds = {
        PHYSICS: physics,
        ACT: acting,
        REST: rest,
        ENV_STEP: env_step,
        ENV_RESET: env_reset,
        OTHER: max(0.0, rest - env_step - env_reset),
    }
    own = sorted(table.items(), key=lambda kv: -kv[1][2])[:top]
    return {
        "wall": round(wall, 3),
        "parts": [
            {"part": name, "seconds": round(s, 3), "share": round(s / wall, 4) if wall else None}
            for name, s in seconds.items()
        ],
        "top": [
            {"function": _label(k), "calls": int(v[1]), "own_seconds": round(float(v[2]), 3)}
            for k, v in own
        ],
    }


def profile_split(call: Callable[[], Any], act: Any, step: Any, reset: Any) -> tuple[dict, Any]:
    """Run `call` under cProfile: (:func:`split_of` its wall time, what it returned)."""
    profiler = cProfile.Profile()
    start = time.perf_counter()
    profiler.enable()
    try:
        result = call()
    finally:
        profiler.disable()
    wall = time.perf_counter() - start
    return split_of(pstats.Stats(profiler), wall, act, step, reset), result


def run_split(task: str, checkpoint: Path, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    """One rollout of `checkpoint` on `seed` without the early stop, in this process and under
    cProfile (the policy loaded and the environment built before, timed apart)."""
    from bicoord_drake.env import Env
    from bicoord_drake.policies import action_size_of, close_policy, load_policy_for
    from bicoord_drake.runner.rollouts import make_evaluation_env, rollout
    from bicoord_drake.tasks import get_task

    _quiet_drake()
    config = evaluation_config(task, checkpoint, args, early_stop=False)
    start = time.perf_counter()
    size = action_size_of(config.embodiment, config.action_mode)
    policy = load_policy_for(config.policy, action_size=size)
    load = time.perf_counter() - start
    try:
        start = time.perf_counter()
        env = make_evaluation_env(get_task(task), config, seed, config.fps)
        build = time.perf_counter() - start
        try:
            act = getattr(type(policy), "act", None) or policy
            split, result = profile_split(
                lambda: rollout(env, policy, seed=seed), act, Env.step, Env.reset
            )
        finally:
            env.close()
    finally:
        close_policy(policy)
    return {
        "task": task,
        "checkpoint": str(checkpoint),
        "stamp": checkpoint_stamp(checkpoint),
        "seed": int(seed),
        "steps": result.steps,
        "failure": result.failure,
        "policy": type(policy).__name__,
        "load_seconds": round(load, 2),
        "build_seconds": round(build, 2),
        **split,
    }


def split_step(
    task: str, checkpoint: Path, seed: int, args: argparse.Namespace, paths: Paths
) -> dict[str, Any]:
    """The split of `seed`: ``WORK/split.json`` if it is of this checkpoint and seed."""
    stamp = checkpoint_stamp(checkpoint)
    try:
        previous = json.loads(paths.split.read_text())
    except (OSError, ValueError):
        previous = None
    key = {"task": task, "checkpoint": str(checkpoint), "stamp": stamp, "seed": int(seed)}
    if previous and all(previous.get(k) == v for k, v in key.items()):
        _say(4, f"profiled before: {paths.split}")
        return previous
    _say(4, f"profile one rollout of seed {seed} without the early stop (cProfile)")
    split = run_split(task, checkpoint, seed, args)
    paths.split.parent.mkdir(parents=True, exist_ok=True)
    baselines.write_json_atomic(paths.split, split)
    return split


# --------------------------------------------------------------------------- the run
def _say_check(package: Package, check: dict[str, Any]) -> None:
    print(
        f"[bench_early_stop] package {package.commit}: {len(check['kept'])} seeds pass, "
        f"{len(check['skipped'])} skipped ({check['cached']} cached, {check['seconds']:.0f} s)",
        flush=True,
    )


def run(task: str, args: argparse.Namespace, run_command: str) -> dict[str, Any]:
    """Every step (each skipped when its output is in ``--work``, unless ``--force``); the
    result the Markdown section is written from. RuntimeError (with the log to read) when a
    step fails."""
    if args.before is not None and args.before_commit is None:
        raise ValueError(f"--before {args.before}: git cannot resolve it to a commit")
    paths = paths_of(task, args)
    if args.force:
        p = paths.train
        for path in (paths.split, *paths.evals.values()):
            policy_reproduces._remove(path)
        if args.checkpoint is None:
            for path in (p.checkpoint, p.dataset, p.demos):
                policy_reproduces._remove(path)
    start_commit, dirty = expert_success.git_state(ROOT)
    here = Package(policy_reproduces.short_commit(start_commit), dirty)

    # removed at the end, also on an error
    with expert_success.worktree(args.before_commit, "bench-early-stop-", ROOT) as tree:
        packages = packages_of(args, tree, here)
        if tree is not None:
            _say(1, f"before: the package of {args.before_commit}, a worktree in {tree}")
            require_tree_check(packages["before"])  # before a training
        if args.checkpoint is not None:
            _say(1, f"the policy: {args.checkpoint}")
            policy = {"checkpoint": str(args.checkpoint), "trained_here": False, "commands": {}}
        else:
            policy = train_policy(task, args, paths)
        checkpoint = Path(policy["checkpoint"])

        _say(2, f"expert check of the evaluation seeds (from 100000 * (1 + {args.seed}))")
        check = warm_expert_check(evaluation_config(task, checkpoint, args, early_stop=True))
        _say_check(here, check)
        before_check = None
        if tree is not None:
            _say(2, f"expert check of the evaluation seeds in the worktree of {args.before}")
            log = paths.logs / "expert_check_before.log"
            before_check = warm_tree_check(task, checkpoint, args, packages["before"], log)
            _say_check(packages["before"], before_check)

        records = {
            mode: evaluate_mode(task, checkpoint, mode, args, paths, packages[mode])
            for mode in args.order
        }
    before, after = records["before"], records["after"]
    seeds = {mode: [r["seed"] for r in records[mode]["rollouts"]] for mode in MODES}

    split = None
    if args.split and seeds["before"]:
        split = split_step(task, checkpoint, seeds["before"][0], args, paths)
    elif args.split:
        _say(4, "no rollout to profile: every seed was skipped")

    end_commit, end_dirty = expert_success.git_state(ROOT)
    stats = {mode: mode_stats(records[mode]) for mode in MODES}
    return {
        "task": task,
        "episodes": args.episodes,
        "seed": args.seed,
        "workers": args.workers,
        "order": list(args.order),
        "policy": policy,
        "expert_check": check,
        "expert_check_before": before_check,
        "before": args.before,
        "packages": {
            mode: {"commit": packages[mode].commit, "dirty": packages[mode].dirty} for mode in MODES
        },
        "seeds_match": seeds["before"] == seeds["after"],
        "stats": stats,
        "ratio": ratio(stats["after"]["wall"], stats["before"]["wall"]),
        "ratio_rollouts": ratio(stats["after"]["sum"], stats["before"]["sum"]),
        "per_seed": per_seed(before, after),
        "measured": {mode: records[mode]["date"] for mode in MODES},
        "reused": [mode for mode in args.order if records[mode]["reused"]],
        "split": split,
        "commands": {
            **policy["commands"],
            **{
                f"evaluate_{mode}": packages[mode].shown(records[mode]["command"])
                for mode in args.order
            },
        },
        "run_command": run_command,
        "commit": policy_reproduces.short_commit(start_commit),
        "dirty": dirty or end_dirty or expert_success.code_changed(start_commit, end_commit),
        "machine": baselines.machine(),
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M"),
    }


# --------------------------------------------------------------------------- Markdown
def _time(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    return f"{seconds / 60:.1f} min" if seconds >= 120 else f"{seconds:.1f} s"


def _failures(failures: dict[str, int]) -> str:
    return ", ".join(f"`{why}` {n}" for why, n in failures.items()) if failures else "none"


def _cell(text: Any) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _policy_rows(policy: dict[str, Any]) -> list[str]:
    if not policy["trained_here"]:
        return [f"| policy | the checkpoint `{policy['checkpoint']}` |"]
    loss = "-" if policy.get("final_loss") is None else f"{policy['final_loss']:.4f}"
    reused = f"; reused: {', '.join(policy['reused'])}" if policy.get("reused") else ""
    return [
        f"| policy | ACT (state) trained here: {policy['demos']} demonstrations, "
        f"{policy['train_steps']} steps, batch {policy['batch_size']}, training seed "
        f"{policy['train_seed']}, final loss {loss}, `{policy['train_args']}` |",
        f"| generation, export, training time | {_time(policy.get('generate_seconds'))}, "
        f"{_time(policy.get('export_seconds'))}, {_time(policy.get('train_seconds'))}"
        f"{reused} |",
    ]


def _package(package: dict[str, Any]) -> str:
    return f"`{package['commit']}`{', dirty' if package['dirty'] else ''}"


def _check(check: dict[str, Any]) -> str:
    return (
        f"{len(check['kept'])} kept, {len(check['skipped'])} skipped ({check['cached']} found "
        f"in the cache), {_time(check['seconds'])}"
    )


def _split_lines(
    split: dict[str, Any] | None, before_seconds: float | None, packages: dict[str, Any]
) -> list[str]:
    if not split:
        return []
    here, before = packages["after"], packages["before"]
    of = "" if before == here else f", package {_package(before)}"
    same = (
        ""
        if before_seconds is None
        else f" (in the evaluation without the early stop{of}: {before_seconds:.1f} s)"
    )
    which = "" if before == here else f" with this checkout's package ({_package(here)})"
    lines = [
        "",
        f"### Where the time goes: one rollout, seed {split['seed']}, without the early stop",
        "",
        f"In this process{which} under cProfile (which slows Python code more than Drake's and "
        f"torch's compiled code): {split['steps']} steps, {split['wall']:.1f} s{same}, ended by "
        f"`{split['failure'] or 'success'}`"
        f"; before it, loading the policy ({split['policy']}) took {split['load_seconds']:.1f} s "
        f"and building the environment {split['build_seconds']:.1f} s.",
        "",
        "| part | seconds | share of the rollout |",
        "|---|---:|---:|",
    ]
    for part in split["parts"]:
        name = part["part"]
        shown = name if name in (PHYSICS, ACT, REST) else f"&nbsp;&nbsp;of which {name}"
        share = "-" if part["share"] is None else f"{100 * part['share']:.1f} %"
        lines.append(f"| {shown} | {part['seconds']:.2f} | {share} |")
    lines += ["", "| function (most own time) | calls | own seconds |", "|---|---:|---:|"]
    for f in split["top"]:
        lines.append(f"| `{_cell(f['function'])}` | {f['calls']} | {f['own_seconds']:.2f} |")
    return lines


def format_section(r: dict[str, Any]) -> str:
    """The Markdown section of one result (starts with '## <task>')."""
    b, a = r["stats"]["before"], r["stats"]["after"]
    check, before_check = r["expert_check"], r.get("expert_check_before")
    packages = r["packages"]
    lines = [f"## {r['task']}", "", f"**{verdict(r['ratio'])}.**", ""]
    if not r["seeds_match"]:
        lines += [
            "**The two evaluations did not roll out the same seeds: the times are not "
            "comparable.**",
            "",
        ]
    kept = check["kept"]
    seeds = f"{len(kept)}, from {kept[0]} to {kept[-1]}" if kept else "none"
    changed = sum(
        1
        for row in r["per_seed"]
        if row["before"] and row["after"] and row["before"]["success"] != row["after"]["success"]
    )
    shortened = sum(
        1
        for row in r["per_seed"]
        if row["before"] and row["after"] and row["after"]["steps"] < row["before"]["steps"]
    )

    def row(name: str, value: Callable[[dict[str, Any]], str]) -> str:
        return f"| {name} | {value(b)} | {value(a)} |"

    def sr(s: dict[str, Any]) -> str:
        return "-" if s["SR"] is None else f"{100 * s['SR']:.1f} % ({s['successes']}/{s['n']})"

    lines += [
        f"| | before ({_package(packages['before'])}, `--no-early-stop`) "
        f"| after ({_package(packages['after'])}, early stop) |",
        "|---|---:|---:|",
        row("rollouts", lambda s: str(s["n"])),
        row("wall time of the evaluate process", lambda s: _time(s["wall"])),
        row("evaluation time in its report", lambda s: _time(s["evaluation"])),
        row("sum of the rollouts' seconds", lambda s: _time(s["sum"])),
        row(
            "median (largest) rollout",
            lambda s: "-" if s["median"] is None else f"{s['median']:.1f} s ({s['max']:.1f} s)",
        ),
        row("simulated steps", lambda s: str(s["steps"])),
        row("SR", sr),
        row("failures by reason", lambda s: _failures(s["failures"])),
        row("seeds skipped (expert failed)", lambda s: str(s["skipped"])),
        f"| measured (UTC) | {r['measured']['before']} | {r['measured']['after']} |",
        "",
        "| | |",
        "|---|---|",
        f"| after/before, wall time | {_ratio(r['ratio'])} |",
        f"| after/before, sum of the rollouts' seconds | {_ratio(r['ratio_rollouts'])} |",
        f"| rollouts the early stop shortened | {shortened} of {a['n']} |",
        f"| rollouts whose outcome it changed | {changed} |",
        f"| evaluation seeds | {seeds}, unseen split, `--seed {r['seed']}` |",
        *(
            [f"| expert check before both | {_check(check)} |"]
            if before_check is None
            else [
                f"| expert check before both, after's package {_package(packages['after'])} "
                f"| {_check(check)} |",
                f"| expert check before both, before's package {_package(packages['before'])} "
                f"| {_check(before_check)} |",
            ]
        ),
        f"| workers, order | {r['workers']}, {' then '.join(r['order'])} |",
        *_policy_rows(r["policy"]),
        *([f"| reused from an earlier run | {', '.join(r['reused'])} |"] if r["reused"] else []),
        f"| commit | `{r['commit']}`{' (dirty)' if r['dirty'] else ''} |",
        *(
            [
                f"| package of before | `--before {r['before']}`: "
                f"{_package(packages['before'])}, run from a worktree of it (`git worktree add "
                f"--detach TREE {r['before']}`, the commands in TREE, `PYTHONPATH=TREE`) |"
            ]
            if r.get("before")
            else []
        ),
        f"| date (UTC) | {r['date']} |",
        f"| machine | {r['machine']} |",
    ]
    first = r["per_seed"][0]["before"] if r["per_seed"] else None
    split = r.get("split")
    same_seed = first is not None and split is not None and first["seed"] == split["seed"]
    lines += _split_lines(split, first["seconds"] if same_seed else None, packages)
    lines += [
        "",
        "### Per seed",
        "",
        "| seed | steps before | seconds before | steps after | seconds after | failure after |",
        "|---:|---:|---:|---:|---:|---|",
    ]
    for seed_row in r["per_seed"]:
        bb, aa = seed_row["before"], seed_row["after"]
        why = "-" if aa is None else ("success" if aa["success"] else aa["failure"] or "?")
        lines.append(
            f"| {seed_row['seed']} | {_steps(bb)} | {_seconds(bb)} | {_steps(aa)} | "
            f"{_seconds(aa)} | {_cell(why)} |"
        )
    lines += ["", f"Written by `{r['run_command']}`; the commands:", "", "```bash"]
    lines += list(r["commands"].values())
    lines += ["```"]
    return "\n".join(lines) + "\n"


def _ratio(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def _steps(rollout: dict[str, Any] | None) -> str:
    return "-" if rollout is None else str(rollout["steps"])


def _seconds(rollout: dict[str, Any] | None) -> str:
    return "-" if rollout is None else f"{rollout['seconds']:.1f}"


def write_section(out: Path, result: dict[str, Any]) -> None:
    """Replace (or append) the result's task section of `out`, keeping the others."""
    text = out.read_text() if out.exists() else PREAMBLE
    updated = expert_success.update_markdown(text, {result["task"]: format_section(result)})
    out.parent.mkdir(parents=True, exist_ok=True)
    expert_success.write_atomic(out, updated)


# --------------------------------------------------------------------------- CLI
def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; 0 when both evaluations ran on the same seeds."""
    args = parse_args(argv)
    if args.before is not None and args.before_commit is None:
        print(
            f"error: --before {args.before}: not a commit of this repository (git rev-parse "
            f"--verify {shlex.quote(args.before + '^{commit}')} failed)",
            file=sys.stderr,
        )
        return 2
    from bicoord_drake.tasks import list_tasks

    if args.task not in list_tasks():
        tasks = ", ".join(list_tasks())
        print(f"error: unknown task {args.task!r}; tasks: {tasks}", file=sys.stderr)
        return 2
    try:  # the evaluations' settings, checked before anything runs
        evaluation_config(args.task, args.checkpoint or args.work, args, early_stop=True)
    except ValueError as err:  # pydantic's ValidationError among them
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.checkpoint is None and shutil.which("lerobot-train") is None:
        install = policy_reproduces.INSTALL
        print(f"error: lerobot-train is not on PATH; install it with: {install}", file=sys.stderr)
        return 1
    run_command = "python benchmarks/bench_early_stop.py " + shlex.join(
        sys.argv[1:] if argv is None else argv
    )
    start = time.perf_counter()
    try:
        result = run(args.task, args, run_command.strip())
    except (RuntimeError, ValueError) as err:
        print(f"[bench_early_stop] error: {err}", file=sys.stderr)
        return 1
    write_section(args.out, result)
    b, a = result["stats"]["before"], result["stats"]["after"]
    packages = result["packages"]
    print(
        f"[bench_early_stop] before ({packages['before']['commit']}) {_time(b['wall'])} "
        f"({_failures(b['failures'])}), after ({packages['after']['commit']}) "
        f"{_time(a['wall'])} ({_failures(a['failures'])}): {verdict(result['ratio'])} "
        f"({(time.perf_counter() - start) / 60:.1f} min); wrote {args.out}",
        flush=True,
    )
    return 0 if result["seeds_match"] else 1


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Proof of the loop: a policy trained here reproduces the demonstrations it was trained on.

    python benchmarks/policy_reproduces.py                       # both tasks, 3 demos, 20000 steps
    python benchmarks/policy_reproduces.py --tasks balance_roller --demos 3 --steps 20000 \\
        --batch-size 8 --work out/policy_reproduces --out benchmarks/policy_reproduces.md

For each task of ``--tasks`` (default balance_roller,place_plate_and_cup):

1. ``scripts/generate.py --no-render --workers 1`` makes ``--demos`` plain expert
   demonstrations from seed 0 up into ``WORK/data`` (``WORK/data/<task>/default``);
2. ``scripts/export.py --environment-state --no-images`` exports exactly those demonstrations
   to a state-based LeRobot dataset (the export of ``benchmarks/baselines.py``);
3. ``lerobot-train`` trains the CPU-sized ACT of ``benchmarks/baselines_notes.md``
   ("Reproduce": :data:`ACT_CPU_ARGS`) on that dataset, at learning rate 1e-4 and with ACT's
   temporal ensembling (:data:`REPRODUCE_ARGS`: why), the training seed fixed
   (``benchmarks/baselines.py``'s command, its common arguments and checkpoint naming), and
   the checkpoint's open-loop error on its training frames is measured (without physics:
   :func:`open_loop_error`);
4. ``scripts/evaluate.py --policy lerobot:CKPT --data WORK/data/<task>/default --episodes N``
   rolls the checkpoint out on the demonstrations' own seeds and scenes (``--data``: the first N
   episode files, the ones exported), and the seeds evaluated, read from the report, are
   checked against the dataset's seeds (``meta/bicoord_episodes.jsonl``).

The task's section of ``--out`` (other sections kept; written to a temporary file, then
renamed) gives the machine, date (UTC), commit (dirty: the package had uncommitted changes),
the exact commands, training time and final loss, per seed whether the rollout succeeded and
which stages counted, and the verdict "reproduces K of N training seeds (goal: >= 2 of 3)".
Every step is skipped when its output is already in ``--work`` (an interrupted run resumes;
a finished one only rewrites its section); ``--force`` redoes them all. Exit status: 0 when
every task ran on its training seeds, 1 on an error or when the seeds evaluated were not the
training seeds, 2 for bad arguments. Training needs lerobot:
``pip install -e '.[train]' && pip install --no-deps lerobot==0.4.4``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
# Measure the code of this checkout (the commit the report names), whatever is pip-installed.
sys.path.insert(0, str(ROOT))


def _benchmark(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as the module `name` (the one already loaded, if any)."""
    path = Path(__file__).resolve().with_name(f"{name}.py")
    module = sys.modules.get(name)
    if module is not None and Path(getattr(module, "__file__", "")).resolve() == path:
        return module
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


baselines = _benchmark("baselines")
expert_success = _benchmark("expert_success")

DEFAULT_TASKS = ("balance_roller", "place_plate_and_cup")
DEFAULT_WORK = ROOT / "out" / "policy_reproduces"
DEFAULT_OUT = ROOT / "benchmarks" / "policy_reproduces.md"
POLICY = "act"
#: The CPU-sized ACT of benchmarks/baselines_notes.md ("Reproduce").
ACT_CPU_ARGS = (
    "--policy.dim_model=128 --policy.n_heads=4 --policy.dim_feedforward=512 "
    "--policy.n_encoder_layers=2 --policy.n_decoder_layers=1 --policy.chunk_size=20 "
    "--policy.n_action_steps=20"
)
#: What this proof trains with beyond the baselines' CPU-sized ACT (balance_roller, 3
#: demonstrations, batch 8; the runs are in policy_reproduces.md, "Diagnosis"): lerobot's
#: default learning rate (1e-5, set for a pretrained backbone) left the from-scratch model far
#: from its frames (5000 steps: loss 0.95, open-loop error 0.07-0.11 rad; 1e-4: loss 0.10,
#: 0.03-0.04 rad; 20000 steps at 1e-4: 0.066, 0.014-0.025 rad), and a 20-step chunk played
#: open loop drifts off the demonstrated states (0 of 3 at either rate); ACT's temporal
#: ensembling (one action per step from every overlapping chunk, weights exp(-0.01 i), ACT's
#: paper) makes it 1-2 of 3.
REPRODUCE_ARGS = (
    ACT_CPU_ARGS.replace(
        "--policy.n_action_steps=20",
        "--policy.n_action_steps=1 --policy.temporal_ensemble_coeff=0.01",
    )
    + " --policy.optimizer_lr=1e-4"
)
INSTALL = "pip install -e '.[train]' && pip install --no-deps lerobot==0.4.4"
TITLE = "# A trained policy reproduces its training demonstrations"
PREAMBLE = (
    f"{TITLE}\n\n"
    "Written by `python benchmarks/policy_reproduces.py`: per task, N plain expert "
    "demonstrations (seeds from 0 up, no cameras) exported state-based to LeRobot, a CPU-sized "
    "ACT trained on exactly those with `lerobot-train`, and the checkpoint rolled out with "
    "`scripts/evaluate.py --data` on the same seeds and scenes. A seed is reproduced when its "
    "rollout succeeds (every stage counts). `(dirty)` after the commit: the package "
    "(`bicoord_drake/`, `pyproject.toml`) had uncommitted changes or changed during the run.\n"
)


# --------------------------------------------------------------------------- settings, paths
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (`--tasks` becomes a list; counts must be >= 1)."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--tasks", default=",".join(DEFAULT_TASKS), help="comma-separated task names"
    )
    parser.add_argument("--demos", type=int, default=3, help="demonstrations = training seeds")
    parser.add_argument("--steps", type=int, default=20000, help="lerobot-train --steps")
    parser.add_argument("--batch-size", type=int, default=8, help="lerobot-train --batch_size")
    parser.add_argument("--train-seed", type=int, default=1000, help="lerobot-train --seed")
    parser.add_argument(
        "--policy-args",
        default="",
        help="more lerobot-train arguments after REPRODUCE_ARGS (a later one wins), e.g. "
        "'--policy.use_vae=false --policy.dropout=0'; they name the checkpoint",
    )
    parser.add_argument(
        "--work",
        type=Path,
        default=DEFAULT_WORK,
        help="demonstrations, dataset, checkpoint, logs, results (default: out/policy_reproduces)",
    )
    parser.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help="the Markdown file whose sections to update"
    )
    parser.add_argument(
        "--action-noise",
        type=float,
        default=0.0,
        help="generate the demonstrations with this DART noise (rad, generate --action-noise: "
        "executed with noise, the expert's actions recorded as labels); the rollouts are clean",
    )
    parser.add_argument("--force", action="store_true", help="redo every step of every task")
    args = parser.parse_args(argv)
    args.tasks = list(dict.fromkeys(t.strip() for t in args.tasks.split(",") if t.strip()))
    if not args.tasks:
        parser.error("--tasks: no task given")
    for name in ("demos", "steps", "batch_size"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1")
    from bicoord_drake.scenario import parse_action_noise

    try:
        parse_action_noise(args.action_noise)
    except ValueError as err:
        parser.error(f"--action-noise: {err}")
    args.work = args.work.resolve()  # the steps run with the checkout as working directory
    args.out = args.out.resolve()
    return args


def action_noise(args: argparse.Namespace) -> float:
    """``--action-noise`` (0 when the caller's namespace has no such option)."""
    return float(getattr(args, "action_noise", 0.0) or 0.0)


def extra_policy_args(args: argparse.Namespace) -> str:
    """``--policy-args`` (none when the caller's namespace has no such option)."""
    return str(getattr(args, "policy_args", "") or "").strip()


def baselines_args(args: argparse.Namespace) -> argparse.Namespace:
    """The settings in the form benchmarks/baselines.py's command and naming functions take."""
    return argparse.Namespace(
        inputs="state",
        resolution=None,
        demos=args.demos,
        steps=args.steps,
        batch_size=args.batch_size,
        train_seed=args.train_seed,
        train_args={POLICY: " ".join(filter(None, (REPRODUCE_ARGS, extra_policy_args(args))))},
        eval_seed=None,
        eval_episodes=args.demos,
    )


@dataclass(frozen=True)
class TaskPaths:
    """Where one task's steps write, under ``--work``."""

    data: Path  # scripts/generate.py --out
    demos: Path  # the task's generation directory: scripts/evaluate.py --data
    dataset: Path
    checkpoint: Path
    eval: Path
    logs: Path
    result: Path


def task_paths(task: str, args: argparse.Namespace) -> TaskPaths:
    """The paths of `task`'s steps with `args` (the checkpoint named by its training settings)."""
    from bicoord_drake.data.episode import EpisodeLayout
    from bicoord_drake.runner.generate import default_config_name

    here = args.work / task
    noise = action_noise(args)
    # Demonstrations executed with noise are other data: their own generation directory (one
    # per level: generate refuses another level in the same one), dataset and checkpoints.
    tag = f"_noise{noise:g}" if noise else ""
    data = args.work / f"data{tag}"
    checkpoint = here / (baselines.checkpoint_name(POLICY, baselines_args(args)) + tag)
    return TaskPaths(
        data=data,
        demos=EpisodeLayout(data, task, default_config_name(noisy=bool(noise))).root,
        dataset=here / f"dataset_state_{args.demos}{tag}",
        checkpoint=checkpoint,
        eval=here / f"eval_{checkpoint.name}",
        logs=here / "logs",
        result=here / f"result_{checkpoint.name}.json",
    )


# --------------------------------------------------------------------------- the commands
def generation_command(
    task: str,
    out: Path,
    *,
    episodes: int,
    seed: int = 0,
    workers: int = 1,
    max_tries: int | None = None,
    action_noise: str | None = None,
    disturb: tuple[str, ...] = (),
) -> list[str]:
    """scripts/generate.py without cameras: `episodes` kept demonstrations of `task` from
    `seed` into `out`, with the given action noise and disturbances (none by default)."""
    command = [sys.executable, "scripts/generate.py", "--task", task]
    command += ["--episodes", str(episodes), "--seed", str(seed)]
    if max_tries is not None:
        command += ["--max-tries", str(max_tries)]
    command += ["--no-render", "--workers", str(workers), "--out", str(out)]
    if action_noise:
        command += ["--action-noise", action_noise]
    if disturb:
        command += ["--disturb", ",".join(disturb)]
    return command


def generate_command(task: str, args: argparse.Namespace, paths: TaskPaths) -> list[str]:
    """scripts/generate.py: `args.demos` plain demonstrations from seed 0, no cameras."""
    noise = action_noise(args)
    return generation_command(
        task, paths.data, episodes=args.demos, action_noise=f"{noise:g}" if noise else None
    )


def export_command(files: list[Path], paths: TaskPaths) -> list[str]:
    """benchmarks/baselines.py's state-based export of exactly `files`."""
    return baselines.export_command(files, paths.dataset, "state", baselines.common_source(files))


def train_command(task: str, args: argparse.Namespace, paths: TaskPaths) -> list[str]:
    """benchmarks/baselines.py's lerobot-train command with the CPU-sized ACT."""
    return baselines.train_command(
        POLICY, task, paths.dataset, paths.checkpoint, baselines_args(args)
    )


def evaluate_command(task: str, args: argparse.Namespace, paths: TaskPaths) -> list[str]:
    """scripts/evaluate.py on the demonstrations' own seeds and scenes (``--data``: its first
    `args.demos` episode files, the exported ones)."""
    return [
        sys.executable,
        "scripts/evaluate.py",
        "--task",
        task,
        "--policy",
        f"lerobot:{paths.checkpoint}",
        "--data",
        str(paths.demos),
        "--episodes",
        str(args.demos),
        "--no-render",
        "--workers",
        "1",
        "--json",
        "--out",
        str(paths.eval),
    ]


# --------------------------------------------------------------------------- checks
def existing_demos(demos: Path, task: str) -> list[Path]:
    """The episode files of `task` already under `demos` (none if it does not exist)."""
    from bicoord_drake.runner.rollouts import find_episodes

    try:
        return find_episodes(demos, task)
    except ValueError:
        return []


def exported(dataset: Path) -> list[dict[str, Any]]:
    """The episodes a LeRobot export holds (source file, seed, ...), [] if none."""
    from bicoord_drake.data.export import EXTRAS_FILE

    try:
        text = (dataset / EXTRAS_FILE).read_text()
    except OSError:
        return []
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def same_files(a: list[str | Path], b: list[str | Path]) -> bool:
    """Whether two lists name the same files in the same order."""
    return [Path(p).resolve() for p in a] == [Path(p).resolve() for p in b]


def goal(n: int) -> int:
    """Training seeds to reproduce: two thirds, rounded up (2 of 3)."""
    return math.ceil(2 * n / 3)


def verdict(reproduced: int, n: int) -> str:
    """'reproduces K of N training seeds (goal: >= G of N)'."""
    return f"reproduces {reproduced} of {n} training seeds (goal: >= {goal(n)} of {n})"


def score_rollouts(
    report: dict[str, Any], train_seeds: list[int], demo_files: list[Path]
) -> dict[str, Any]:
    """What an evaluation report (``scripts/evaluate.py --json``) says about the training
    seeds: the seeds and episode files evaluated (from the report), whether they are the
    training ones, each rollout's success, stages counted and failure, and K reproduced."""
    rollouts = report["rollouts"]
    eval_seeds = [int(r["seed"]) for r in rollouts]
    episodes = [r.get("episode") for r in rollouts]
    files_match = all(episodes) and same_files(episodes, demo_files)
    return {
        "train_seeds": list(train_seeds),
        "eval_seeds": eval_seeds,
        "seeds_match": eval_seeds == list(train_seeds) and bool(files_match),
        "stages": [s["subgoal"] for s in report["stages"]],
        "rollouts": [
            {
                "seed": int(r["seed"]),
                "success": bool(r["success"]),
                "completed": [bool(c) for c in r["completed"]],
                "failure": r.get("failure"),
                "error": (r.get("error") or "")[:200] or None,
            }
            for r in rollouts
        ],
        "skipped": report.get("skipped", []),
        "reproduced": sum(1 for r in rollouts if r["success"] and r["seed"] in train_seeds),
        "n": len(train_seeds),
        "SR": report.get("SR"),
        "SSR": report.get("SSR"),
    }


def open_loop_error(checkpoint: Path, dataset: Path) -> dict[str, Any]:
    """How well the checkpoint fits its training frames, without physics: each exported
    episode's observations fed to it frame by frame (its action queue run as in a rollout,
    reset per episode), and the mean and largest |action - recorded action| over frames and
    action numbers (rad for joints, the gripper's own unit for grippers), per episode and
    overall. A policy that does not fit its frames cannot reproduce them; one that fits them
    and still fails drifts off the demonstrated states (or the frames and actions are
    misaligned, which the dataset-playback check excludes)."""
    import numpy as np

    from bicoord_drake.policies.dataset_policy import STATE, VECTORS, DatasetPlaybackPolicy
    from bicoord_drake.policies.lerobot_policy import LeRobotPolicy

    # The export's frames as the dataset playback reads them (the same columns it compares
    # with a live observation), per episode in frame order.
    playback = DatasetPlaybackPolicy(dataset)
    policy = LeRobotPolicy(checkpoint, device="cpu")
    episodes = []
    try:
        for record in sorted(playback.records, key=lambda r: r.index):
            columns = playback.frames(record.task, record.seed, record.source)
            inputs = {
                STATE: columns["state"],
                **{key: columns[name] for name, key in VECTORS.items() if name in columns},
            }
            keys = [k for k in policy.inputs if k in inputs]
            policy.reset("")
            errors = np.array(
                [
                    np.abs(policy.act({k: inputs[k][t] for k in keys}) - action)
                    for t, action in enumerate(columns["action"])
                ]
            )
            episodes.append(
                {
                    "episode": int(record.index),
                    "frames": len(errors),
                    "mean": round(float(errors.mean()), 4),
                    "max": round(float(errors.max()), 4),
                }
            )
    finally:
        policy.close()
    total = sum(e["frames"] for e in episodes)
    return {
        "mean": round(sum(e["mean"] * e["frames"] for e in episodes) / total, 4),
        "max": max(e["max"] for e in episodes),
        "episodes": episodes,
    }


def short_commit(commit: str) -> str:
    """`commit` as ``git rev-parse --short`` names it (itself if git cannot)."""
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", commit], cwd=ROOT, capture_output=True, text=True
        )
    except OSError:
        return commit
    return out.stdout.strip() if out.returncode == 0 and out.stdout.strip() else commit


# --------------------------------------------------------------------------- one task
def _step(task: str, number: int, text: str) -> None:
    print(f"[{task}] {number}/4 {text}", flush=True)


def _remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()


def run_task(task: str, args: argparse.Namespace, run_command: str) -> dict[str, Any]:
    """Generate, export, train and evaluate `task` (each step skipped when its output is in
    ``--work``, unless ``--force``); returns the result its Markdown section is written from.
    RuntimeError (with the log to read) when a step fails."""
    paths = task_paths(task, args)
    if args.force:
        for path in (paths.result, paths.eval, paths.checkpoint, paths.dataset, paths.demos):
            _remove(path)
    start_commit, dirty = expert_success.git_state(ROOT)
    reused: list[str] = []
    seconds: dict[str, float | None] = {"generate": None, "export": None, "evaluate": None}

    # 1. demonstrations on seeds from 0 up
    generate = generate_command(task, args, paths)
    if len(existing_demos(paths.demos, task)) >= args.demos:
        _step(task, 1, f"{args.demos} demonstrations already in {paths.demos}")
        reused.append("generation")
    else:
        _step(task, 1, f"generate {args.demos} demonstrations (seeds from 0, no cameras)")
        _, seconds["generate"] = baselines.run(generate, paths.logs / "generate.log")
    files = baselines.demonstrations(paths.demos, task, args.demos)

    # 2. the state-based LeRobot dataset of exactly those
    export = export_command(files, paths)
    episodes = exported(paths.dataset)
    if episodes and same_files([e["source"] for e in episodes], files):
        _step(task, 2, f"dataset already exported: {paths.dataset}")
        reused.append("export")
    else:
        _step(task, 2, f"export {len(files)} demonstrations (state, no images)")
        _remove(paths.dataset)
        _, seconds["export"] = baselines.run(export, paths.logs / "export.log")
        episodes = exported(paths.dataset)
    train_seeds = [int(e["seed"]) for e in episodes]

    # 3. ACT on that dataset
    train = train_command(task, args, paths)
    train_log = paths.logs / f"train_{paths.checkpoint.name}.log"
    train_seconds = baselines.trained(paths.checkpoint, train)
    if train_seconds is None:
        _remove(paths.checkpoint)  # lerobot-train refuses an existing directory
        _step(task, 3, f"train ACT: {args.steps} steps, batch {args.batch_size} (log {train_log})")
        _, train_seconds = baselines.run(train, train_log)
        loss = baselines.final_loss(train_log)
        record = {"command": baselines.shown(train), "seconds": train_seconds, "final_loss": loss}
        baselines.write_json_atomic(paths.checkpoint / baselines.TRAINED, record)
        print(f"[{task}] trained in {train_seconds / 60:.1f} min, final loss {loss}", flush=True)
    else:
        _step(task, 3, f"trained before: {paths.checkpoint}")
        reused.append("training")
        record = json.loads((paths.checkpoint / baselines.TRAINED).read_text())
        loss = record.get("final_loss")

    # 4. rollouts on the training seeds
    evaluate = evaluate_command(task, args, paths)
    commands = {
        "generate": baselines.shown(generate),
        "export": baselines.shown(export),
        "train": baselines.shown(train),
        "evaluate": baselines.shown(evaluate),
    }
    try:
        previous = json.loads(paths.result.read_text())
    except (OSError, ValueError):
        previous = None
    if previous is not None and previous.get("commands") == commands:
        _step(task, 4, f"evaluated before: {paths.result}")
        return previous
    fit = open_loop_error(paths.checkpoint, paths.dataset)
    print(
        f"[{task}] open-loop error on the training frames: mean {fit['mean']}, max {fit['max']}",
        flush=True,
    )
    _step(task, 4, f"evaluate on the {len(files)} training seeds {train_seeds}")
    stdout, seconds["evaluate"] = baselines.run(evaluate, paths.logs / "evaluate.log")
    scores = score_rollouts(json.loads(stdout), train_seeds, files)
    end_commit, end_dirty = expert_success.git_state(ROOT)
    result = {
        "task": task,
        "policy": POLICY,
        "demos": args.demos,
        "action_noise": action_noise(args),
        "steps": args.steps,
        "batch_size": args.batch_size,
        "train_seed": args.train_seed,
        "train_args": baselines_args(args).train_args[POLICY],
        **scores,
        "final_loss": loss,
        "open_loop": fit,
        "train_seconds": round(train_seconds, 1),
        **{f"{k}_seconds": None if v is None else round(v, 1) for k, v in seconds.items()},
        "reused": reused,
        "commands": commands,
        "run_command": run_command,
        "commit": short_commit(start_commit),
        "dirty": dirty or end_dirty or expert_success.code_changed(start_commit, end_commit),
        "machine": baselines.machine(),
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"),
    }
    baselines.write_json_atomic(paths.result, result)
    return result


# --------------------------------------------------------------------------- Markdown
def _minutes(value: float | None) -> str:
    return "reused" if value is None else f"{value / 60:.1f} min"


def _seeds(seeds: list[int]) -> str:
    return ", ".join(map(str, seeds)) if seeds else "none"


def _fit_rows(fit: dict[str, Any] | None) -> list[str]:
    """The open-loop fit's table row (none for results written before it was measured)."""
    if not fit:
        return []
    per = ", ".join(f"{e['mean']:.4f}" for e in fit["episodes"])
    return [
        f"| open-loop error on the training frames, mean (largest) | {fit['mean']:.4f} "
        f"({fit['max']:.3f}); per episode {per} |"
    ]


def format_section(r: dict[str, Any]) -> str:
    """The Markdown section of one task's result (starts with '## <task>')."""
    met = r["reproduced"] >= goal(r["n"]) and r["seeds_match"]
    loss = "-" if r.get("final_loss") is None else f"{r['final_loss']:.4f}"
    lines = [
        f"## {r['task']}",
        "",
        f"**{verdict(r['reproduced'], r['n'])}**: goal {'met' if met else 'not met'}.",
        "",
    ]
    if not r["seeds_match"]:
        lines += [
            f"**The seeds evaluated ({_seeds(r['eval_seeds'])}) are not the training seeds "
            f"({_seeds(r['train_seeds'])}): this is no reproduction check.**",
            "",
        ]
    lines += [
        "| | |",
        "|---|---|",
        f"| training seeds (the exported demonstrations) | {_seeds(r['train_seeds'])} |",
        f"| seeds evaluated (from the report) | {_seeds(r['eval_seeds'])} |",
        *(
            [
                f"| demonstrations executed with action noise (DART) | {r['action_noise']:g} rad "
                "per joint (labels: the expert's actions) |"
            ]
            if r.get("action_noise")
            else []
        ),
        f"| policy | ACT (state), {r['demos']} demonstrations, {r['steps']} steps, "
        f"batch {r['batch_size']}, training seed {r['train_seed']} |",
        *(
            [f"| arguments beyond lerobot's ACT defaults | `{r['train_args']}` |"]
            if r.get("train_args")
            else []
        ),
        f"| training time | {_minutes(r['train_seconds'])} |",
        f"| final loss | {loss} |",
        *_fit_rows(r.get("open_loop")),
        f"| generation, export, evaluation time | {_minutes(r.get('generate_seconds'))}, "
        f"{_minutes(r.get('export_seconds'))}, {_minutes(r.get('evaluate_seconds'))} |",
        *([f"| reused from an earlier run | {', '.join(r['reused'])} |"] if r["reused"] else []),
        f"| commit | `{r['commit']}`{' (dirty)' if r['dirty'] else ''} |",
        f"| date (UTC) | {r['date']} |",
        f"| machine | {r['machine']} |",
        "",
        "| seed | reproduced | stages counted | failure |",
        "|---:|---|---|---|",
    ]
    names = r["stages"]
    for rollout in r["rollouts"]:
        done = [n for n, c in zip(names, rollout["completed"], strict=False) if c]
        counted = f"{len(done)}/{len(names)}" + (f": {'; '.join(done)}" if done else "")
        why = rollout["failure"] or "-"
        if rollout.get("error"):
            why += f" ({rollout['error']})"
        why = " ".join(why.split()).replace("|", "\\|")
        lines.append(
            f"| {rollout['seed']} | {'yes' if rollout['success'] else 'no'} | {counted} | {why} |"
        )
    for skipped in r.get("skipped") or []:
        lines.append(f"| {skipped.get('seed')} | skipped | - | {skipped.get('reason', '')} |")
    lines += ["", f"Written by `{r['run_command']}`; the commands:", "", "```bash"]
    lines += [r["commands"][k] for k in ("generate", "export", "train", "evaluate")]
    lines += ["```"]
    return "\n".join(lines) + "\n"


def write_section(out: Path, result: dict[str, Any]) -> None:
    """Replace (or append) the result's task section of `out`, keeping the others."""
    text = out.read_text() if out.exists() else PREAMBLE
    updated = expert_success.update_markdown(text, {result["task"]: format_section(result)})
    out.parent.mkdir(parents=True, exist_ok=True)
    expert_success.write_atomic(out, updated)


# --------------------------------------------------------------------------- CLI
def main(argv: list[str] | None = None) -> int:
    """Run every task of the command line; 0 when all ran on their training seeds."""
    args = parse_args(argv)
    from bicoord_drake.tasks import list_tasks

    try:
        tasks = expert_success.parse_tasks(",".join(args.tasks), list_tasks())
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if shutil.which("lerobot-train") is None:
        print(f"error: lerobot-train is not on PATH; install it with: {INSTALL}", file=sys.stderr)
        return 1
    run_command = "python benchmarks/policy_reproduces.py " + shlex.join(
        sys.argv[1:] if argv is None else argv
    )
    status = 0
    for task in tasks:
        start = time.perf_counter()
        try:
            result = run_task(task, args, run_command.strip())
        except (RuntimeError, ValueError) as err:
            print(f"[{task}] error: {err}", file=sys.stderr)
            status = 1
            continue
        write_section(args.out, result)
        if not result["seeds_match"]:
            status = 1
        print(
            f"[{task}] {verdict(result['reproduced'], result['n'])} "
            f"({(time.perf_counter() - start) / 60:.1f} min); wrote {args.out}",
            flush=True,
        )
    return status


if __name__ == "__main__":
    sys.exit(main())

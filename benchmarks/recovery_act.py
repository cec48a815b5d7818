#!/usr/bin/env python
"""Recovery demonstrations for state-based ACT: clean against clean + recovery (issue #54, 4).

    python benchmarks/recovery_act.py                 # 2 tasks, 50 + 50 demos: hours of CPU
    python benchmarks/recovery_act.py --dry-run       # print the commands, run nothing
    python benchmarks/recovery_act.py --tasks balance_roller --demos 1 --steps 20 \\
        --eval-episodes 1 --work /tmp/recovery_act_smoke --out /tmp/recovery_act_smoke/r.md

For each task of ``--tasks`` (default balance_roller,put_objects_cabinet: two of the tasks whose
experts recover from a push, README "Recovery demonstrations: disturbances"):

1. generation, ``scripts/generate.py --no-render`` (an interrupted run resumes in place):
   CLEAN, ``--demos`` plain expert demonstrations from seed ``--clean-seed`` up, into
   ``WORK/data/clean_seed<S>``; RECOVERY, ``--demos`` demonstrations from seed
   ``--recovery-seed`` up (a disjoint range) executed with ``--action-noise NOISE`` (DART:
   noisy execution, the expert's actions as labels) and ``--disturb KINDS`` (each disturbance
   once per episode, the expert recovering from it), into ``WORK/data/recovery_seed<R>_...``;
2. two state-based LeRobot datasets, ``benchmarks/baselines.py``'s export
   (``--environment-state --no-images``): *clean*, the CLEAN demonstrations, and
   *clean+recovery*, the CLEAN then the RECOVERY ones. The export's per-frame ``disturbed``
   marker (1 from a disturbance to the end of the expert's recovery) stays in; it is no
   ``observation.*`` feature, so ACT does not take it as an input. Nothing is filtered;
3. ACT trained on each with identical settings: ``benchmarks/baselines.py``'s lerobot-train
   command with the CPU-sized ACT of ``benchmarks/baselines_notes.md`` (the baselines' state
   ACT rows: ``--steps 10000 --batch-size 16``), the same ``--train-seed``;
4. each checkpoint evaluated with ``scripts/evaluate.py --policy lerobot:CKPT --no-render
   --split unseen --disturb KINDS`` on ``--eval-episodes`` evaluation seeds from
   100000 (1 + ``--eval-seed``) up, disjoint from the generation seeds and the same for both
   checkpoints: every seed is rolled out clean and disturbed (a seed whose expert fails is
   skipped; a seed without a window for a disturbance has no disturbed rollout). SR, SSR of
   both rollouts come from the evaluation's report.json.

Each result is appended to ``WORK/results.jsonl``, keyed by its task, dataset and every setting
(:data:`SETTINGS`); a rerun skips the keys already there (``--force`` redoes them) and reuses
finished generations, exports and trainings. ``--out`` (default benchmarks/recovery.md) is
rewritten after every result (a temporary file, then renamed) from the latest result of every
key: one table per task, the machine, dates and commits, the exact commands, and a "Reading"
section left for whoever runs it (its text is kept when the file is rewritten). Everything runs
one process at a time; ``--workers`` sets generate.py's and evaluate.py's processes. Needs
lerobot: ``pip install -e '.[train]' && pip install --no-deps lerobot==0.4.4``. Exit status: 0
when every task ran, 1 when a step failed, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import shutil
import sys
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
# Measure the code of this checkout (the commit the report names), whatever is pip-installed.
sys.path.insert(0, str(ROOT))


# Its sibling benchmarks, imported by name (they load theirs the same way).
sys.path.insert(0, str(ROOT / "benchmarks"))
import policy_reproduces  # noqa: E402

from bicoord_drake.scenario import DEFAULT_ACTION_NOISE  # noqa: E402

baselines = policy_reproduces.baselines
expert_success = policy_reproduces.expert_success

DEFAULT_TASKS = ("balance_roller", "put_objects_cabinet")
DEFAULT_WORK = ROOT / "out" / "recovery_act"
DEFAULT_OUT = ROOT / "benchmarks" / "recovery.md"
POLICY = "act"
CLEAN, MIXED = "clean", "clean+recovery"
DATASETS = (CLEAN, MIXED)
#: The baselines' state-based ACT rows (benchmarks/baselines.md): steps, batch size, model.
BASELINE_STEPS = 10000
BASELINE_BATCH = 16
ACT_CPU_ARGS = policy_reproduces.ACT_CPU_ARGS
#: Evaluation seeds of ``--eval-seed`` E are 100000 (1 + E) upward (scripts/evaluate.py).
EVAL_SEED_BLOCK = 100000
INSTALL = policy_reproduces.INSTALL
#: The settings a result is keyed by, besides its task and dataset (see :func:`settings`).
SETTINGS = (
    "demos",
    "clean_seed",
    "recovery_seed",
    "noise",
    "disturb",
    "steps",
    "batch_size",
    "train_seed",
    "train_args",
    "eval_seed",
    "eval_episodes",
)
TITLE = "# Recovery demonstrations and state-based ACT (issue #54, item 4)"
READING_PLACEHOLDER = (
    "_To be written by whoever ran this measurement: what the numbers above show and what "
    "they do not (training budget, number of seeds, seeds without a disturbed rollout)._"
)


# --------------------------------------------------------------------------- settings
def noise_label(text: str | float) -> str:
    """An action-noise setting as written in names and commands: ``0.005``, ``0.005-0.02``, or
    ``0`` (off). ValueError if scripts/generate.py would refuse it."""
    from bicoord_drake.scenario import parse_action_noise

    value = parse_action_noise(text)
    if isinstance(value, tuple):
        return f"{value[0]:g}-{value[1]:g}"
    return f"{float(value):g}"


def generation_tries(args: argparse.Namespace) -> int:
    """Seeds a generation tries at most: ``--max-tries``, else generate.py's 5 x episodes."""
    return args.max_tries or 5 * args.demos


def seed_conflict(args: argparse.Namespace) -> str | None:
    """Why the seed ranges of `args` may overlap (None when they cannot): CLEAN's and
    RECOVERY's generation ranges (each :func:`generation_tries` seeds long) with each other
    and with the block of evaluation seeds."""
    tries = generation_tries(args)
    ranges = {
        "clean": range(args.clean_seed, args.clean_seed + tries),
        "recovery": range(args.recovery_seed, args.recovery_seed + tries),
        "evaluation": range(
            EVAL_SEED_BLOCK * (1 + args.eval_seed), EVAL_SEED_BLOCK * (2 + args.eval_seed)
        ),
    }
    names = list(ranges)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            ra, rb = ranges[a], ranges[b]
            if max(ra.start, rb.start) < min(ra.stop, rb.stop):
                return (
                    f"{a} seeds {ra.start}-{ra.stop - 1} and {b} seeds {rb.start}-{rb.stop - 1} "
                    "overlap"
                )
    return None


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line: lists for ``--tasks`` and ``--disturb``, ``--noise`` normalized."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add = parser.add_argument
    add("--tasks", default=",".join(DEFAULT_TASKS), help="comma-separated task names")
    add("--demos", type=int, default=50, help="CLEAN demonstrations, and as many RECOVERY ones")
    add(
        "--noise",
        default=f"{DEFAULT_ACTION_NOISE:g}",
        help="RECOVERY's --action-noise, rad (SIGMA or LO-HI; 0: off; default: generate.py's "
        "--action-noise without a value)",
    )
    add(
        "--disturb",
        default="push",
        help="RECOVERY's --disturb kinds (comma list), also the evaluation's --disturb",
    )
    add("--clean-seed", type=int, default=0, help="CLEAN's generation seeds start here")
    add(
        "--recovery-seed",
        type=int,
        default=50000,
        help="RECOVERY's generation seeds start here (must not overlap CLEAN's)",
    )
    add(
        "--max-tries",
        type=int,
        default=None,
        help="generate.py --max-tries for each set (default: 5 x --demos, generate.py's own)",
    )
    add("--steps", type=int, default=BASELINE_STEPS, help="lerobot-train --steps (both)")
    add("--batch-size", type=int, default=BASELINE_BATCH, help="lerobot-train --batch_size")
    add("--train-seed", type=int, default=1000, help="lerobot-train --seed")
    add(
        "--train-args",
        default="",
        help="more lerobot-train arguments after the baselines' CPU-sized ACT ones "
        f"({ACT_CPU_ARGS}); a later one wins; write --train-args='--policy.X=...'",
    )
    add("--eval-episodes", type=int, default=50, help="evaluation seeds per checkpoint")
    add("--eval-seed", type=int, default=0, help="scripts/evaluate.py --seed (0: from 100000)")
    add("--workers", type=int, default=1, help="generate.py and evaluate.py --workers")
    add(
        "--work",
        type=Path,
        default=DEFAULT_WORK,
        help="demonstrations, datasets, checkpoints, logs, results.jsonl (default: "
        "out/recovery_act)",
    )
    add("--out", type=Path, default=DEFAULT_OUT, help="the Markdown report to (re)write")
    add("--force", action="store_true", help="redo the results already in --work")
    add("--dry-run", action="store_true", help="print the commands it would run; run nothing")
    add("--table-only", action="store_true", help="only rewrite --out from WORK/results.jsonl")
    args = parser.parse_args(argv)
    args.tasks = list(dict.fromkeys(t.strip() for t in args.tasks.split(",") if t.strip()))
    if not args.tasks and not args.table_only:
        parser.error("--tasks: no task given")
    for name in ("demos", "steps", "batch_size", "eval_episodes", "workers"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1")
    if args.max_tries is not None and args.max_tries < args.demos:
        parser.error("--max-tries must be at least --demos")
    from bicoord_drake.sim.disturbances import parse_disturb

    try:
        args.noise = noise_label(args.noise)
        args.disturb = list(parse_disturb(args.disturb))
    except ValueError as err:
        parser.error(str(err))
    if not args.disturb:
        parser.error("--disturb: at least one kind (the evaluation compares clean and disturbed)")
    conflict = seed_conflict(args)
    if conflict:
        parser.error(f"seeds: {conflict}; choose --clean-seed / --recovery-seed apart")
    args.train_args = baselines.normalized_args(f"{ACT_CPU_ARGS} {args.train_args}")
    args.work = args.work.resolve()  # the steps run with the checkout as working directory
    args.out = args.out.resolve()
    return args


def settings(dataset: str, args: argparse.Namespace) -> dict[str, Any]:
    """The :data:`SETTINGS` of `dataset`'s result with `args`. The clean dataset has no
    recovery demonstrations: its ``recovery_seed`` and ``noise`` are None, so changing them
    does not redo it; ``disturb`` is the evaluation's for both."""
    mixed = dataset == MIXED
    return {
        "demos": args.demos,
        "clean_seed": args.clean_seed,
        "recovery_seed": args.recovery_seed if mixed else None,
        "noise": args.noise if mixed else None,
        "disturb": ",".join(args.disturb),
        "steps": args.steps,
        "batch_size": args.batch_size,
        "train_seed": args.train_seed,
        "train_args": args.train_args,
        "eval_seed": args.eval_seed,
        "eval_episodes": args.eval_episodes,
    }


def settings_key(task: str, dataset: str, values: dict[str, Any]) -> tuple:
    """What identifies a result: task, dataset and its :data:`SETTINGS` values (hashable)."""
    return (task, dataset, *(values.get(name) for name in SETTINGS))


def result_key(result: dict[str, Any]) -> tuple:
    return settings_key(result["task"], result["dataset"], result["settings"])


def latest_results(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One result per :func:`result_key`, the last one written, in the order first seen."""
    latest: dict[tuple, dict[str, Any]] = {}
    for r in results:
        latest[result_key(r)] = r
    return list(latest.values())


def baselines_args(dataset: str, args: argparse.Namespace) -> argparse.Namespace:
    """The settings of `dataset`'s run in the form benchmarks/baselines.py's command and
    naming functions take (its demonstrations: ``--demos``, twice that with recovery)."""
    return argparse.Namespace(
        inputs="state",
        resolution=None,
        demos=args.demos * (2 if dataset == MIXED else 1),
        steps=args.steps,
        batch_size=args.batch_size,
        train_seed=args.train_seed,
        train_args={POLICY: args.train_args},
        eval_seed=args.eval_seed,
        eval_episodes=args.eval_episodes,
        eval_workers=args.workers,
    )


# --------------------------------------------------------------------------- paths
@dataclass(frozen=True)
class Generation:
    """One set of demonstrations: scripts/generate.py's ``--out`` and its task directory."""

    name: str  # "clean" or "recovery"
    data: Path
    demos: Path
    seed: int
    noise: str  # "0": off
    disturb: tuple[str, ...]


def generations(task: str, args: argparse.Namespace) -> dict[str, Generation]:
    """CLEAN and RECOVERY of `task` under ``WORK/data``: one generation root per seed start
    and (for RECOVERY) noise and kinds, since generate.py refuses other settings in a
    directory it resumes."""
    from bicoord_drake.data.episode import EpisodeLayout
    from bicoord_drake.runner.generate import default_config_name

    kinds = tuple(args.disturb)
    noisy = args.noise != "0"
    clean = args.work / "data" / f"clean_seed{args.clean_seed}"
    name = f"recovery_seed{args.recovery_seed}_noise{args.noise}_{'-'.join(kinds)}"
    recovery = args.work / "data" / name
    return {
        "clean": Generation(
            "clean",
            clean,
            EpisodeLayout(clean, task, default_config_name()).root,
            args.clean_seed,
            "0",
            (),
        ),
        "recovery": Generation(
            "recovery",
            recovery,
            EpisodeLayout(recovery, task, default_config_name(noisy=noisy, disturbed=True)).root,
            args.recovery_seed,
            args.noise,
            kinds,
        ),
    }


@dataclass(frozen=True)
class DatasetPaths:
    """Where one dataset's export, training and evaluation write, under ``WORK/<task>``."""

    dataset: Path
    checkpoint: Path
    eval: Path
    logs: Path


def dataset_id(dataset: str, args: argparse.Namespace) -> str:
    """A directory name for `dataset` with `args`: its demonstrations and their seeds."""
    name = f"clean{args.demos}_seed{args.clean_seed}"
    if dataset == MIXED:
        kinds = "-".join(args.disturb)
        name += f"_recovery{args.demos}_seed{args.recovery_seed}_noise{args.noise}_{kinds}"
    return name


def dataset_paths(task: str, dataset: str, args: argparse.Namespace) -> DatasetPaths:
    """`dataset`'s paths for `task` (the checkpoint named by baselines.py's
    :func:`checkpoint_name` of its training settings; the evaluation by its settings)."""
    here = args.work / task / dataset_id(dataset, args)
    checkpoint = here / baselines.checkpoint_name(POLICY, baselines_args(dataset, args))
    kinds = "-".join(args.disturb)
    evaluation = f"eval_{checkpoint.name}_seed{args.eval_seed}_n{args.eval_episodes}_{kinds}"
    return DatasetPaths(
        dataset=here / "dataset",
        checkpoint=checkpoint,
        eval=here / evaluation,
        logs=args.work / task / "logs",
    )


# --------------------------------------------------------------------------- the commands
def generate_command(task: str, gen: Generation, args: argparse.Namespace) -> list[str]:
    """scripts/generate.py for one set: ``--demos`` episodes from its seed, no cameras (with
    its action noise and disturbances for RECOVERY)."""
    return policy_reproduces.generation_command(
        task,
        gen.data,
        episodes=args.demos,
        seed=gen.seed,
        workers=args.workers,
        max_tries=generation_tries(args),
        action_noise=gen.noise if gen.noise != "0" else None,
        disturb=tuple(gen.disturb),
    )


def export_sources(directory: Path, files: list[Path] | None) -> list[Path]:
    """What to pass scripts/export.py for `files` taken from a generation `directory`: the
    directory when it holds exactly those files (or, `files` None, when they are not known
    yet: a dry run), else the files themselves."""
    if files is None:
        return [directory]
    from bicoord_drake.data.readers import find_episode_files

    found, errors = find_episode_files([directory])
    return [directory] if not errors and found == list(files) else list(files)


def export_command(
    dataset: str,
    gens: dict[str, Generation],
    out: Path,
    demos: dict[str, list[Path] | None],
) -> list[str]:
    """benchmarks/baselines.py's state-based export of `dataset`: CLEAN's demonstrations, then
    for clean+recovery RECOVERY's (`demos`: the files of each, None when not known yet)."""
    sources = export_sources(gens["clean"].demos, demos["clean"])
    if dataset == MIXED:
        sources += export_sources(gens["recovery"].demos, demos["recovery"])
    return baselines.export_command(sources, out, "state")


def train_command(task: str, dataset: str, args: argparse.Namespace) -> list[str]:
    """benchmarks/baselines.py's lerobot-train command: the same for both datasets but for
    the dataset and the output directory."""
    paths = dataset_paths(task, dataset, args)
    return baselines.train_command(
        POLICY, task, paths.dataset, paths.checkpoint, baselines_args(dataset, args)
    )


def evaluate_command(task: str, dataset: str, args: argparse.Namespace) -> list[str]:
    """benchmarks/baselines.py's evaluation (unseen split, no cameras, the same seeds for
    every checkpoint) with ``--disturb``: each seed rolled out clean and disturbed."""
    paths = dataset_paths(task, dataset, args)
    command = baselines.evaluate_command(
        task, paths.checkpoint, paths.eval, baselines_args(dataset, args)
    )
    return [*command, "--disturb", ",".join(args.disturb)]


# --------------------------------------------------------------------------- reading outputs
def generation_summary(manifest: dict[str, Any]) -> dict[str, Any]:
    """What a generation's manifest.json says: seeds kept and tried, the range tried and the
    failures counted by kind (the reason up to its first colon)."""
    episodes = manifest.get("episodes") or []
    seeds = [int(e["seed"]) for e in episodes]
    failures = Counter(
        (e.get("reason") or "unknown").split(":", 1)[0].strip()
        for e in episodes
        if not e.get("success")
    )
    return {
        "kept": sum(1 for e in episodes if e.get("success")),
        "tried": len(episodes),
        "first": min(seeds) if seeds else None,
        "last": max(seeds) if seeds else None,
        "failures": dict(failures.most_common()),
    }


def read_generation(gen: Generation) -> dict[str, Any] | None:
    """:func:`generation_summary` of `gen`'s manifest (None if it has none)."""
    try:
        return generation_summary(json.loads((gen.demos / "manifest.json").read_text()))
    except (OSError, ValueError):
        return None


def marked_frames(dataset: Path) -> tuple[int, int] | None:
    """(frames the export marked ``disturbed``, frames) of a LeRobot export: the recovery rows
    of meta/bicoord_episodes.jsonl (``[start, end, ...]``) against meta/info.json's
    ``total_frames``. None when the export cannot be read."""
    try:
        info = json.loads((dataset / "meta" / "info.json").read_text())
        episodes = policy_reproduces.exported(dataset)
    except (OSError, ValueError):
        return None
    marked = sum(int(row[1]) - int(row[0]) for e in episodes for row in (e.get("recovery") or []))
    return marked, int(info.get("total_frames", 0))


def _scores(part: dict[str, Any]) -> dict[str, Any]:
    """SR, SSR, TL, stages, failures and divergences of one side of a report."""
    from bicoord_drake.runner.rollouts import DIVERGED

    rollouts = part.get("rollouts") or []
    errors = [r["error"] for r in rollouts if r.get("error")]
    return {
        "n": part.get("n", len(rollouts)),
        "SR": part.get("SR"),
        "SSR": part.get("SSR"),
        "TL": part.get("TL"),
        "stages": [[s["subgoal"], s["completed"]] for s in part.get("stages") or []],
        "failures": part.get("failures") or {},
        "diverged": sum(1 for e in errors if e.startswith(DIVERGED)),
        "seeds": [int(r["seed"]) for r in rollouts],
        "errors": [e[:300] for e in errors[:3]],
    }


def scores_from_report(report: dict[str, Any]) -> dict[str, Any]:
    """The scores of an evaluation's report.json (scripts/evaluate.py --disturb): ``clean``
    and ``disturbed`` (:func:`_scores`; ``skipped``: the seeds whose expert failed, and
    ``no_disturbed_rollout``: [seed, reason] of the seeds without a disturbed rollout) and
    ``paired``: n, SR and SSR clean and disturbed on the seeds that have both rollouts."""
    disturbed = report.get("disturbed") or {}
    paired = (report.get("side_by_side") or {}).get("paired") or {}
    return {
        "clean": {**_scores(report), "skipped": [int(s["seed"]) for s in report["skipped"]]},
        "disturbed": {
            **_scores(disturbed),
            "no_disturbed_rollout": [
                [int(s["seed"]), str(s.get("reason", ""))] for s in disturbed.get("skipped") or []
            ],
        },
        "paired": {
            "n": paired.get("n"),
            "SR": paired.get("SR") or {},
            "SSR": paired.get("SSR") or {},
        },
    }


def read_report(stdout: str) -> dict[str, Any]:
    """The evaluation's report.json, found through its ``--json`` output (which is the same
    report, used if the file cannot be read)."""
    printed = json.loads(stdout)
    try:
        return json.loads(Path(printed["report"]).read_text())
    except (KeyError, TypeError, OSError, ValueError):
        return printed


# --------------------------------------------------------------------------- one task
def _remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()


def _say(task: str, text: str) -> None:
    print(f"[{task}] {text}", flush=True)


def todo_datasets(task: str, args: argparse.Namespace, done: set[tuple]) -> list[str]:
    """The datasets of `task` whose result with `args` is not in `done`."""
    return [d for d in DATASETS if settings_key(task, d, settings(d, args)) not in done]


def planned_commands(task: str, args: argparse.Namespace, todo: list[str]) -> list[list[str]]:
    """Every command a run of `todo` on `task` may run, in order (exports as they are when
    each generation directory holds exactly its demonstrations)."""
    gens = generations(task, args)
    commands = [generate_command(task, gens["clean"], args)]
    if MIXED in todo:
        commands.append(generate_command(task, gens["recovery"], args))
    for dataset in todo:
        out = dataset_paths(task, dataset, args).dataset
        commands.append(export_command(dataset, gens, out, {"clean": None, "recovery": None}))
        commands.append(train_command(task, dataset, args))
        commands.append(evaluate_command(task, dataset, args))
    return commands


def ensure_demos(task: str, gen: Generation, args: argparse.Namespace, log: Path) -> dict:
    """Generate `gen` unless its directory holds ``--demos`` episodes (generate.py resumes
    an interrupted run); returns its command, seconds (None: reused) and first files."""
    command = generate_command(task, gen, args)
    seconds = None
    if len(policy_reproduces.existing_demos(gen.demos, task)) >= args.demos:
        _say(task, f"{gen.name}: {args.demos} demonstrations already in {gen.demos}")
    else:
        what = f"noise {gen.noise} rad, disturb {','.join(gen.disturb)}, " if gen.disturb else ""
        _say(
            task,
            f"generate {gen.name}: {args.demos} demonstrations from seed {gen.seed} "
            f"({what}no cameras; log {log})",
        )
        _, seconds = baselines.run(command, log)
    return {
        "command": command,
        "seconds": seconds,
        "files": baselines.demonstrations(gen.demos, task, args.demos),
        "summary": read_generation(gen),
    }


def run_task(
    task: str, args: argparse.Namespace, done: set[tuple], run_command: str
) -> Iterator[dict[str, Any]]:
    """Generate, export, train and evaluate every dataset of `task` whose result is not in
    `done`, yielding each result when its evaluation finished. RuntimeError (naming the log
    to read) or ValueError when a step fails."""
    todo = todo_datasets(task, args, done)
    if not todo:
        _say(task, "every result is in results.jsonl already (--force redoes them)")
        return
    gens = generations(task, args)
    logs = args.work / task / "logs"
    start_commit, dirty = expert_success.git_state(ROOT)
    phases = 1 + (MIXED in todo) + 3 * len(todo)
    phase = 0

    def step(text: str) -> None:
        nonlocal phase
        phase += 1
        _say(task, f"{phase}/{phases} {text}")

    step("CLEAN demonstrations")
    made = {"clean": ensure_demos(task, gens["clean"], args, logs / "generate_clean.log")}
    if MIXED in todo:
        step("RECOVERY demonstrations")
        made["recovery"] = ensure_demos(
            task, gens["recovery"], args, logs / f"generate_{gens['recovery'].data.name}.log"
        )
    for dataset in todo:
        paths = dataset_paths(task, dataset, args)
        parts = ["clean"] + (["recovery"] if dataset == MIXED else [])
        files = [f for part in parts for f in made[part]["files"]]
        demos = {part: made[part]["files"] if part in parts else None for part in made}
        demos.setdefault("recovery", None)
        export = export_command(dataset, gens, paths.dataset, demos)
        episodes = policy_reproduces.exported(paths.dataset)
        export_seconds = None
        if episodes and policy_reproduces.same_files([e["source"] for e in episodes], files):
            step(f"{dataset}: dataset already exported ({paths.dataset})")
        else:
            step(f"{dataset}: export {len(files)} demonstrations (state, no images)")
            _remove(paths.dataset)
            _, export_seconds = baselines.run(export, paths.logs / f"export_{dataset}.log")
            episodes = policy_reproduces.exported(paths.dataset)

        train = train_command(task, dataset, args)
        train_log = paths.logs / f"train_{paths.dataset.parent.name}_{paths.checkpoint.name}.log"
        train_seconds = baselines.trained(paths.checkpoint, train)
        if train_seconds is None:
            _remove(paths.checkpoint)  # lerobot-train refuses an existing directory
            step(
                f"{dataset}: train ACT, {args.steps} steps, batch {args.batch_size} "
                f"(log {train_log})"
            )
            _, train_seconds = baselines.run(train, train_log)
            loss = baselines.final_loss(train_log)
            record = {"command": baselines.shown(train), "seconds": train_seconds}
            baselines.write_json_atomic(
                paths.checkpoint / baselines.TRAINED, {**record, "final_loss": loss}
            )
            _say(task, f"{dataset}: trained in {train_seconds / 60:.1f} min, final loss {loss}")
        else:
            step(f"{dataset}: trained before ({paths.checkpoint})")
            record = json.loads((paths.checkpoint / baselines.TRAINED).read_text())
            loss = record.get("final_loss")
            if loss is None and train_log.exists():
                loss = baselines.final_loss(train_log)

        evaluate = evaluate_command(task, dataset, args)
        eval_log = paths.logs / f"evaluate_{paths.dataset.parent.name}_{paths.eval.name}.log"
        step(
            f"{dataset}: evaluate on {args.eval_episodes} unseen seeds, clean and disturbed "
            f"({','.join(args.disturb)}; log {eval_log})"
        )
        stdout, eval_seconds = baselines.run(evaluate, eval_log)
        report = read_report(stdout)
        scores = scores_from_report(report)
        end_commit, end_dirty = expert_success.git_state(ROOT)
        commands = {"generate_clean": baselines.shown(made["clean"]["command"])}
        if dataset == MIXED:
            commands["generate_recovery"] = baselines.shown(made["recovery"]["command"])
        commands |= {
            "export": baselines.shown(export),
            "train": baselines.shown(train),
            "evaluate": baselines.shown(evaluate),
        }
        result = {
            "task": task,
            "dataset": dataset,
            "settings": settings(dataset, args),
            "demos": {part: len(made[part]["files"]) for part in parts},
            "dataset_seeds": [int(e["seed"]) for e in episodes],
            "marked_frames": marked_frames(paths.dataset),
            "generation": {part: made[part]["summary"] for part in parts},
            "generate_seconds": {
                part: None if made[part]["seconds"] is None else round(made[part]["seconds"], 1)
                for part in parts
            },
            "export_seconds": None if export_seconds is None else round(export_seconds, 1),
            "train_seconds": round(train_seconds, 1),
            "final_loss": loss,
            "eval_seconds": round(eval_seconds, 1),
            **scores,
            "report": report.get("report"),
            "commands": commands,
            "run_command": run_command,
            "commit": policy_reproduces.short_commit(start_commit),
            "dirty": dirty or end_dirty or expert_success.code_changed(start_commit, end_commit),
            "machine": baselines.machine(),
            "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        }
        clean, disturbed = scores["clean"], scores["disturbed"]
        _say(
            task,
            f"{dataset}: clean SR {_pct(clean['SR'])} SSR {_pct(clean['SSR'])}; disturbed SR "
            f"{_pct(disturbed['SR'])} SSR {_pct(disturbed['SSR'])} "
            f"({eval_seconds / 60:.1f} min)",
        )
        yield result


# --------------------------------------------------------------------------- Markdown
def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.1f}"


def _minutes(seconds: float | None) -> str:
    return "reused" if seconds is None else f"{seconds / 60:.1f} min"


def _seeds(seeds: list[int]) -> str:
    """Seeds as ``a, b, c`` (``none`` if empty)."""
    return ", ".join(map(str, seeds)) if seeds else "none"


def _seed_range(seeds: list[int]) -> str:
    return f"{min(seeds)}-{max(seeds)}" if seeds else "-"


def recovery_text(values: dict[str, Any]) -> str:
    """RECOVERY's settings: ``noise 0.005 rad, push``."""
    noise = "no noise" if values["noise"] == "0" else f"noise {values['noise']} rad"
    return f"{noise}, {values['disturb']}"


def dataset_label(r: dict[str, Any]) -> str:
    """``clean`` or ``clean+recovery (noise 0.005 rad, push)``."""
    if r["dataset"] != MIXED:
        return r["dataset"]
    return f"{MIXED} ({recovery_text(r['settings'])})"


def _demos_text(r: dict[str, Any]) -> str:
    demos = r["demos"]
    return " + ".join(str(demos[p]) for p in ("clean", "recovery") if p in demos)


def _marked_text(r: dict[str, Any]) -> str:
    marked = r.get("marked_frames")
    if not marked or not marked[1]:
        return "-"
    return f"{marked[0]} of {marked[1]} ({100 * marked[0] / marked[1]:.1f} %)"


def _stages_text(r: dict[str, Any]) -> str:
    """Per stage: completion clean / disturbed, in percent."""
    clean = r["clean"]["stages"]
    disturbed = dict((name, c) for name, c in r["disturbed"]["stages"])
    return "; ".join(f"{name} {_pct(c)} / {_pct(disturbed.get(name))}" for name, c in clean)


def _paired_text(r: dict[str, Any]) -> str:
    p = r["paired"]
    if not p.get("n"):
        return "-"
    sr, ssr = p["SR"], p["SSR"]
    return (
        f"{p['n']}: SR {_pct(sr.get('clean'))} / {_pct(sr.get('disturbed'))}, "
        f"SSR {_pct(ssr.get('clean'))} / {_pct(ssr.get('disturbed'))}"
    )


def _no_window_text(r: dict[str, Any]) -> str:
    seeds = [seed for seed, _ in r["disturbed"].get("no_disturbed_rollout") or []]
    return f"{len(seeds)}: {_seeds(seeds)}" if seeds else "0"


def _skipped_text(r: dict[str, Any]) -> str:
    seeds = r["clean"].get("skipped") or []
    return f"{len(seeds)}: {_seeds(seeds)}" if seeds else "0"


def _generation_text(name: str, summary: dict[str, Any] | None) -> str:
    if not summary:
        return f"{name}: no manifest"
    failures = ", ".join(f"{k} {n}" for k, n in summary["failures"].items())
    return (
        f"{name}: {summary['kept']} kept of {summary['tried']} seeds tried "
        f"({summary['first']}-{summary['last']})" + (f"; failures: {failures}" if failures else "")
    )


TABLE_HEADER = (
    "| dataset | demos | frames marked disturbed | train steps | batch | train time | final loss "
    "| rollouts clean / disturbed | SR clean | SSR clean | SR disturbed | SSR disturbed "
    "| paired seeds: SR, SSR clean / disturbed | per-stage completion clean / disturbed "
    "| seeds | skipped seeds (expert failed) | seeds without a disturbed rollout "
    "| diverged clean / disturbed | eval time | commit | date |"
)
TABLE_RULE = (
    "|---|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---|---|---|---|---|---|---:|---|---|"
)


def table_row(r: dict[str, Any]) -> str:
    """One result's row of its task's table."""
    s = r["settings"]
    clean, disturbed = r["clean"], r["disturbed"]
    loss = "-" if r.get("final_loss") is None else f"{r['final_loss']:.3f}"
    commit = f"`{r['commit']}`" + (" (dirty)" if r.get("dirty") else "")
    cells = [
        dataset_label(r),
        _demos_text(r),
        _marked_text(r),
        str(s["steps"]),
        str(s["batch_size"]),
        _minutes(r["train_seconds"]),
        loss,
        f"{clean['n']} / {disturbed['n']}",
        _pct(clean["SR"]),
        _pct(clean["SSR"]),
        _pct(disturbed["SR"]),
        _pct(disturbed["SSR"]),
        _paired_text(r),
        _stages_text(r),
        _seed_range(clean["seeds"] + (clean.get("skipped") or [])),
        _skipped_text(r),
        _no_window_text(r),
        f"{clean['diverged']} / {disturbed['diverged']}",
        _minutes(r["eval_seconds"]),
        commit,
        r["date"],
    ]
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def preamble(command: str, results_file: str) -> list[str]:
    """The title and what is compared (no conclusions)."""
    return [
        TITLE,
        "",
        f"Written by `{command}` from `{results_file}` (the latest result of every setting).",
        "",
        "What is compared, per task: state-based ACT (`observation.state` and "
        "`observation.environment_state`, the task objects' poses; the CPU-sized ACT of "
        "`benchmarks/baselines_notes.md`, trained with `lerobot-train` on the CPU) trained with "
        "identical settings (steps, batch size, training seed, model) on two datasets: "
        "*clean*, N plain expert demonstrations, and *clean+recovery*, the same N plus N "
        "demonstrations on other seeds executed with DART action noise and one disturbance of "
        "each kind, from which the expert recovered (`scripts/generate.py --action-noise "
        "--disturb`; their disturbed and recovery frames carry the export's `disturbed` "
        "marker, which is no policy input; nothing is filtered). The clean+recovery dataset "
        "thus also holds twice the demonstrations. Both checkpoints are scored by "
        "`scripts/evaluate.py --split unseen --disturb KINDS` on the same evaluation seeds (the "
        "*seeds* column; disjoint from every generation seed): each seed is rolled out clean "
        "and disturbed with the disturbances the expert's demonstration of that seed gets. "
        "Seeds whose expert fails are skipped (not counted); a seed without a window for a "
        "disturbance has no disturbed rollout (not counted on the disturbed side). SR, SSR and "
        "per-stage completion in percent; *paired*: the seeds with both rollouts and SR, SSR "
        "clean / disturbed on them; *diverged*: rollouts that ended when the physics diverged "
        "(failures). Times are wall times on the machine below.",
    ]


def markdown(results: list[dict[str, Any]], command: str, results_file: str, reading: str) -> str:
    """The report: preamble, a table per task (its demonstrations' seeds above it), the
    machines, the Reading section (`reading`, else the placeholder) and the commands."""
    lines = preamble(command, results_file)
    tasks = list(dict.fromkeys(r["task"] for r in results))
    for task in tasks:
        rows = [r for r in results if r["task"] == task]
        lines += ["", f"## {task}", ""]
        seen: set[str] = set()
        for r in rows:
            for part, summary in (r.get("generation") or {}).items():
                name = "CLEAN" if part == "clean" else f"RECOVERY ({recovery_text(r['settings'])})"
                text = _generation_text(name, summary)
                if text not in seen:
                    seen.add(text)
                    lines.append(f"- demonstrations, {text}")
        lines += ["", TABLE_HEADER, TABLE_RULE, *(table_row(r) for r in rows)]
    if not results:
        lines += ["", "No results yet."]
    lines += ["", "## Machine", ""]
    machines = Counter(r["machine"] for r in results)
    lines += [f"- {m} ({n} result{'s' * (n != 1)})" for m, n in machines.items()] or ["- -"]
    lines += ["", "## Reading", "", reading.strip() or READING_PLACEHOLDER, "", "## Commands"]
    for r in results:
        s = r["settings"]
        lines += [
            "",
            f"### {r['task']}, {dataset_label(r)}, {_demos_text(r)} demos, {s['steps']} steps, "
            f"batch {s['batch_size']}, evaluation --seed {s['eval_seed']} ({r['date']})",
            "",
            *([f"Run by `{r['run_command']}`:", ""] if r.get("run_command") else []),
            "```bash",
            *r["commands"].values(),
            "```",
        ]
        errors = r["clean"].get("errors", []) + r["disturbed"].get("errors", [])
        if errors:
            lines += ["", f"Rollout errors (first {len(errors)}): {errors}"]
    return "\n".join(lines) + "\n"


def existing_reading(text: str) -> str:
    """The text of the "## Reading" section of an earlier report (empty if none, or still the
    placeholder), so a rewrite keeps what its reader wrote."""
    match = re.search(r"^## Reading\n(.*?)(?=^## |\Z)", text, flags=re.S | re.M)
    if not match:
        return ""
    body = match.group(1).strip()
    return "" if body == READING_PLACEHOLDER else body


def write_report(out: Path, results: list[dict[str, Any]], command: str, work: Path) -> None:
    """Rewrite `out` (a temporary file, then renamed) from the latest of `results`."""
    reading = existing_reading(out.read_text()) if out.exists() else ""
    text = markdown(latest_results(results), command, str(work / "results.jsonl"), reading)
    out.parent.mkdir(parents=True, exist_ok=True)
    expert_success.write_atomic(out, text)


# --------------------------------------------------------------------------- CLI
def dry_run(tasks: list[str], args: argparse.Namespace, done: set[tuple]) -> None:
    """Print, per task, the commands a run would start (nothing is run or written)."""
    for task in tasks:
        todo = todo_datasets(task, args, done)
        if not todo:
            _say(task, "every result is in results.jsonl already: nothing to run")
            continue
        _say(task, f"would run (datasets: {', '.join(todo)}; finished steps are reused):")
        for command in planned_commands(task, args, todo):
            print("  " + baselines.shown(command), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Run every task of the command line; 0 when all ran."""
    args = parse_args(argv)
    from bicoord_drake.tasks import list_tasks

    try:
        tasks = expert_success.parse_tasks(",".join(args.tasks), list_tasks()) if args.tasks else []
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    results_file = args.work / "results.jsonl"
    previous = baselines.read_results(results_file)
    done = set() if args.force else {result_key(r) for r in previous}
    command = "python benchmarks/recovery_act.py " + shlex.join(
        sys.argv[1:] if argv is None else argv
    )
    if args.dry_run:
        dry_run([] if args.table_only else tasks, args, done)
        return 0
    if not args.table_only and shutil.which("lerobot-train") is None:
        print(f"error: lerobot-train is not on PATH; install it with: {INSTALL}", file=sys.stderr)
        return 1
    status = 0
    for task in [] if args.table_only else tasks:
        start = time.perf_counter()
        try:
            for result in run_task(task, args, done, command.strip()):
                results_file.parent.mkdir(parents=True, exist_ok=True)
                with open(results_file, "a", encoding="utf-8") as fh:
                    fh.write(json.dumps(result) + "\n")
                write_report(args.out, baselines.read_results(results_file), command, args.work)
                _say(task, f"wrote {args.out}")
        except (RuntimeError, ValueError) as err:
            print(f"[{task}] error: {err}", file=sys.stderr)
            status = 1
            continue
        _say(task, f"done in {(time.perf_counter() - start) / 60:.1f} min")
    results = baselines.read_results(results_file)
    if results or args.table_only:
        write_report(args.out, results, command, args.work)
        print(f"wrote {args.out}", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main())

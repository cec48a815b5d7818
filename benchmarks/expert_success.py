#!/usr/bin/env python
"""Expert success at the current commit, into benchmarks/expert_success.md.

    python benchmarks/expert_success.py --tasks all --seeds 0-29 --workers 2
    python benchmarks/expert_success.py --tasks cook,jigsaw --seeds 0-9
    python benchmarks/expert_success.py --tasks jigsaw --randomize   # section "jigsaw (randomized)"
    python benchmarks/expert_success.py --tasks jigsaw --replay      # also the replay check
    python benchmarks/expert_success.py --tasks cook --data /tmp/es  # keep the episodes there
    python benchmarks/expert_success.py --tasks jigsaw --disturb drop --replay  # recoveries

For each task, runs the library's ``generate()`` without rendering on every seed of the range
(into a temporary directory, removed afterwards, or with ``--data DIR`` into ``DIR/<task>``,
kept: an interrupted run resumes there, and a later ``--replay`` replays them without
generating again) and rewrites that task's section of the
markdown file: kept / tried, each failed seed with its reason, mean episode length, wall time,
the commit and whether the work tree had uncommitted changes, machine and date. Any task runs
on any registered ``--embodiment``, declared in its ``supported_robots`` or not (this script
sets ``BICOORD_ALLOW_UNDECLARED_ROBOTS=1``): a declaration needs this measurement first
(docs/adding_a_robot.md). With ``--replay``
every kept episode is then replayed (its recorded actions, same seed and scene, no rendering)
and the section says how many reproduce every stage. Other tasks' sections are kept. The
file is rewritten (temp name, then rename) after each task, so an interrupted run keeps the
tasks it finished.
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Measure the code of this checkout (the commit the report names), whatever is pip-installed.
sys.path.insert(0, str(ROOT))
DEFAULT_OUT = ROOT / "benchmarks" / "expert_success.md"
MAX_SEED = 2**32
TITLE = "# Expert success at a commit"
PREAMBLE = (
    f"{TITLE}\n\n"
    "Written by `python benchmarks/expert_success.py --tasks all --seeds 0-29 --workers 2`: one "
    "section per task, each from `generate()` without rendering on every seed of the range (an "
    "episode is kept only when the expert ran in physics and every stage verified). A section "
    "names the commit it was measured at; `(dirty)` means the package (`bicoord_drake/`, "
    "`pyproject.toml`) had uncommitted changes or changed during the run.\n"
)


@dataclass
class TaskResult:
    """The outcome of one task on a seed range."""

    task: str
    seeds: range
    kept: int
    tried: int
    failures: list[tuple[int, str]] = field(default_factory=list)
    mean_length: float | None = None
    wall_seconds: float = 0.0
    commit: str = "unknown"
    dirty: bool = False
    date: str = ""
    machine: str = ""
    #: (replays that completed every stage, replays), when the replay check ran
    replay: tuple[int, int] | None = None
    replay_failures: list[tuple[int, str]] = field(default_factory=list)
    #: the run continued episodes kept in an earlier run's data directory (--data)
    resumed: bool = False
    #: the generation workers' seconds over every seed in the data directory (from its manifest)
    worker_seconds: float | None = None
    replay_seconds: float = 0.0


def parse_seeds(text: str) -> range:
    """'0-29' -> range(0, 30); '7' -> range(7, 8). ValueError says what is wrong."""
    m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", text)
    if not m:
        raise ValueError(f"seeds must look like FIRST-LAST (e.g. 0-29) or one seed, got {text!r}")
    first = int(m.group(1))
    last = int(m.group(2)) if m.group(2) is not None else first
    if first > last:
        raise ValueError(f"seed range {text!r} is empty: {first} > {last}")
    if last >= MAX_SEED:
        raise ValueError(f"seeds must be below 2**32 = {MAX_SEED}, got {last}")
    return range(first, last + 1)


def parse_tasks(text: str, valid: list[str]) -> list[str]:
    """'all' or a comma-separated list of registered task names (unknown ones listed)."""
    names = [t.strip() for t in text.split(",") if t.strip()]
    if names == ["all"]:
        return list(valid)
    if not names:
        raise ValueError(f"no task given; choose 'all' or some of: {', '.join(valid)}")
    unknown = [t for t in names if t not in valid]
    if unknown:
        raise ValueError(
            f"unknown task{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}; "
            f"choose 'all' or some of: {', '.join(valid)}"
        )
    return list(dict.fromkeys(names))


#: What decides an expert's result: a change elsewhere (this report, docs, tests) does not.
CODE_PATHS = ("bicoord_drake", "pyproject.toml")


def _git(root: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True)


def git_state(root: Path = ROOT) -> tuple[str, bool]:
    """(commit hash, whether the package's tracked files differ from it); ('unknown', False)
    outside git. This report and other files outside :data:`CODE_PATHS` do not count."""
    try:
        head = _git(root, "rev-parse", "HEAD")
        status = _git(root, "status", "--porcelain", "--untracked-files=no", "--", *CODE_PATHS)
    except OSError:
        return "unknown", False
    if head.returncode or status.returncode:
        return "unknown", False
    return head.stdout.strip(), bool(status.stdout.strip())


def short_commit_of(rev: str, root: Path = ROOT) -> str | None:
    """The short hash of the commit `rev` names (``git rev-parse --verify REV^{commit}``);
    None when git cannot resolve it to a commit."""
    try:
        out = _git(root, "rev-parse", "--verify", "--quiet", "--short", f"{rev}^{{commit}}")
    except OSError:
        return None
    return out.stdout.strip() if out.returncode == 0 and out.stdout.strip() else None


@contextmanager
def worktree(rev: str | None, prefix: str, root: Path = ROOT) -> Iterator[Path | None]:
    """A detached ``git worktree`` of `rev` (``git worktree add --detach TMP/tree REV``, TMP a
    temporary directory named with `prefix`), removed with TMP (``git worktree remove
    --force``) on the way out, also on an error; None without a revision. RuntimeError naming
    `rev` and git's message when git cannot add it."""
    if rev is None:
        yield None
        return
    tree = Path(tempfile.mkdtemp(prefix=prefix)) / "tree"
    try:
        out = _git(root, "worktree", "add", "--detach", str(tree), rev)
        if out.returncode != 0:
            raise RuntimeError(f"git worktree add {rev} failed: {out.stderr.strip()}")
        yield tree
    finally:
        _git(root, "worktree", "remove", "--force", str(tree))
        shutil.rmtree(tree.parent, ignore_errors=True)


def code_changed(old: str, new: str, root: Path = ROOT) -> bool:
    """Whether the package differs between two commits (True if git cannot tell)."""
    if old == new:
        return False
    try:
        return _git(root, "diff", "--quiet", old, new, "--", *CODE_PATHS).returncode != 0
    except OSError:
        return True


def machine() -> str:
    try:
        from importlib.metadata import version

        drake = f", drake {version('drake')}"
    except Exception:  # noqa: BLE001 - the version is only informative
        drake = ""
    python = platform.python_version()
    return f"{platform.machine()}, nproc = {os.cpu_count()}, Python {python}{drake}"


def seed_text(seeds: range) -> str:
    return f"{seeds.start}–{seeds.stop - 1}" if len(seeds) > 1 else str(seeds.start)


def _resumed_note(r: TaskResult) -> str:
    if not r.resumed:
        return ""
    spent = f"{r.worker_seconds / 60:.1f} min" if r.worker_seconds else "an unknown time"
    return (
        " (this run only: it resumed an earlier run's data, whose generation workers spent "
        f"{spent} on all its seeds)"
    )


def format_section(r: TaskResult) -> str:
    """The markdown section of one task (starts with '## <task>')."""
    share = 100 * r.kept / r.tried if r.tried else 0.0
    length = f"{r.mean_length:.0f} control steps" if r.mean_length is not None else "n/a"
    replay = f"**{r.replay[0]}/{r.replay[1]}** reproduce every stage" if r.replay else ""
    lines = [
        f"## {r.task}",
        "",
        f"**{r.kept}/{r.tried} kept** ({share:.0f} %), seeds {seed_text(r.seeds)}.",
        "",
        "| | |",
        "|---|---|",
        f"| commit | `{r.commit}`{' (dirty)' if r.dirty else ''} |",
        f"| mean length of kept episodes | {length} |",
        f"| wall time | {r.wall_seconds / 60:.1f} min{_resumed_note(r)} |",
        *([f"| replay check of the kept episodes | {replay} |"] if replay else []),
        *([f"| replay check wall time | {r.replay_seconds / 60:.1f} min |"] if replay else []),
        f"| date (UTC) | {r.date} |",
        f"| machine | {r.machine} |",
        "",
    ]
    if r.failures:
        kinds = Counter(reason.split(":", 1)[0] for _, reason in r.failures)
        lines.append(
            "Failures by kind: " + ", ".join(f"`{k}` {n}" for k, n in sorted(kinds.items())) + "."
        )
        lines += ["", "| seed | reason |", "|---:|---|"]
        for seed, reason in sorted(r.failures):
            text = re.sub(r"\s+", " ", reason).replace("|", "\\|")
            lines.append(f"| {seed} | {text[:300]} |")
    else:
        lines.append("No seed failed.")
    if r.replay_failures:
        lines += ["", "| replayed seed | why it did not reproduce |", "|---:|---|"]
        lines += [f"| {seed} | {text} |" for seed, text in sorted(r.replay_failures)]
    return "\n".join(lines) + "\n"


def update_markdown(text: str, sections: dict[str, str]) -> str:
    """`text` with the '## <task>' sections in `sections` replaced (or appended); others kept."""
    parts = re.split(r"(?m)^(?=## )", text) if text.strip() else []
    head = parts[0] if parts and not parts[0].startswith("## ") else PREAMBLE
    existing = [p for p in parts if p.startswith("## ")]
    out, done = [], set()
    for part in existing:
        name = part.split("\n", 1)[0][3:].strip()
        if name in sections:
            out.append(sections[name])
            done.add(name)
        else:
            out.append(part)
    out += [body for name, body in sections.items() if name not in done]
    return "\n".join(s.rstrip("\n") + "\n" for s in [head, *out])


def write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def replay_check(
    task: str, data: Path, workers: int, embodiment: str | None = None
) -> tuple[int, int, list[tuple[int, str]]]:
    """Replay every episode of `task` under `data` (no rendering) on `embodiment` (the robot
    that recorded them; None: the default robot): (replays that completed every stage,
    replays, [(seed, why it failed: its error or the stages not reproduced)])."""
    from bicoord_drake.runner.evaluate import (
        EvaluateConfig,
        evaluate,
        find_episodes,
        unmet_stages,
    )

    episodes = len(find_episodes(data, task))
    config = EvaluateConfig(
        task=task,
        policy="replay",
        episodes=episodes,
        data=str(data),
        render=False,
        workers=workers,
        out=str(data / "replay_report"),
        **({} if embodiment is None else {"embodiment": embodiment}),
    )
    report = evaluate(config)
    failures = [
        (r.seed, r.error or unmet_stages(report.stages, r))
        for r in report.rollouts
        if not r.success
    ]
    return sum(r.success for r in report.rollouts), len(report.rollouts), failures


def run_task(
    task: str,
    seeds: range,
    workers: int,
    work_dir: Path,
    randomize: bool = False,
    replay: bool = False,
    embodiment: str | None = None,
    action_noise: float = 0.0,
    disturb: str = "",
) -> TaskResult:
    """Every seed of `seeds` through generate() (no rendering, no video) in `work_dir`; with
    `randomize`, on the randomized scenes (textures, table height, clutter); with `replay`,
    then the replay check of the kept episodes (:func:`replay_check`); `embodiment`: the robot
    (default: the default robot); `action_noise` (rad): the expert's actions executed with
    that noise (generate --action-noise, DART); `disturb`: disturbance kinds (generate
    --disturb), each kept episode one the expert recovered in."""
    from bicoord_drake.data.episode import EpisodeLayout
    from bicoord_drake.runner.generate import GenerateConfig, generate

    config = GenerateConfig(
        task=task,
        episodes=len(seeds),
        seed=seeds.start,
        max_tries=len(seeds),
        out=str(work_dir),
        render=False,
        video=False,
        workers=workers,
        randomize=randomize,
        **({} if embodiment is None else {"embodiment": embodiment}),
        **({"action_noise": action_noise} if action_noise else {}),
        **({"disturb": disturb} if disturb else {}),
    )
    commit, dirty = git_state()
    resumed = EpisodeLayout(work_dir, task, config.config_name).manifest.exists()
    t0 = time.perf_counter()
    summary = generate(config)
    wall = time.perf_counter() - t0
    t1 = time.perf_counter()
    replayed = (
        replay_check(task, work_dir / task, workers, embodiment)
        if replay and summary.kept
        else None
    )
    replay_seconds = time.perf_counter() - t1
    per_episode = summary.seconds_per_episode
    end_commit, end_dirty = git_state()  # the tree may change while the seeds run
    dirty = dirty or end_dirty or code_changed(commit, end_commit)
    return TaskResult(
        task=section_name(task, randomize, embodiment, action_noise, disturb),
        seeds=seeds,
        kept=summary.kept,
        tried=summary.tried,
        failures=[(e.seed, e.reason or "") for e in summary.failures],
        mean_length=summary.mean_length,
        wall_seconds=wall,
        commit=commit,
        dirty=dirty,
        date=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"),
        machine=machine(),
        replay=replayed[:2] if replayed else None,
        replay_failures=replayed[2] if replayed else [],
        resumed=resumed,
        worker_seconds=per_episode * summary.kept if per_episode else None,
        replay_seconds=replay_seconds,
    )


def section_name(
    task: str,
    randomize: bool = False,
    embodiment: str | None = None,
    action_noise: float = 0.0,
    disturb: str = "",
) -> str:
    """The section title: '<task>', '<task> (randomized)', '<task> (franka_pair)',
    '<task> (action noise 0.01 rad)', '<task> (disturbed: drop)', ..."""
    notes = [embodiment] if embodiment else []
    notes += ["randomized"] if randomize else []
    notes += [f"action noise {action_noise:g} rad"] if action_noise else []
    notes += [f"disturbed: {disturb}"] if disturb else []
    return f"{task} ({', '.join(notes)})" if notes else task


#: Lets a task run on a robot it does not declare (``bicoord_drake.tasks.registry``).
ALLOW_UNDECLARED_ENV = "BICOORD_ALLOW_UNDECLARED_ROBOTS"


def main(argv: list[str] | None = None) -> int:
    """The command; undeclared (task, robot) pairs are measured too (the evidence a
    declaration needs), with the variable set in the environment for this run, so worker
    processes inherit it."""
    previous = os.environ.get(ALLOW_UNDECLARED_ENV)
    os.environ[ALLOW_UNDECLARED_ENV] = "1"
    try:
        return _measure(argv)
    finally:
        if previous is None:
            os.environ.pop(ALLOW_UNDECLARED_ENV, None)
        else:
            os.environ[ALLOW_UNDECLARED_ENV] = previous


def _measure(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--tasks", default="all", help="'all' or comma-separated task names")
    parser.add_argument("--seeds", default="0-29", help="FIRST-LAST, inclusive (default 0-29)")
    parser.add_argument("--workers", type=int, default=1, help="parallel processes (default 1)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="markdown file to update")
    parser.add_argument(
        "--randomize",
        action="store_true",
        help="randomized scenes (generate --randomize); sections are named '<task> (randomized)'",
    )
    parser.add_argument(
        "--embodiment",
        help="the robot (a registered name; default: the default robot); sections are named "
        "'<task> (<embodiment>)'",
    )
    parser.add_argument(
        "--action-noise",
        type=float,
        default=0.0,
        help="execute the expert's actions with this Gaussian noise (rad, generate "
        "--action-noise); sections are named '<task> (action noise SIGMA rad)'",
    )
    parser.add_argument(
        "--disturb",
        default="",
        help="disturb each episode (generate --disturb KIND[,KIND]: push, drop, knock); "
        "sections are named '<task> (disturbed: KINDS)'",
    )
    parser.add_argument(
        "--replay",
        action="store_true",
        help="then replay every kept episode and report how many reproduce every stage",
    )
    parser.add_argument(
        "--data",
        type=Path,
        help="keep the episodes under DATA/<task> (resumed if there) instead of a temporary "
        "directory; a later run with --replay then replays them without generating again",
    )
    args = parser.parse_args(argv)

    try:
        seeds = parse_seeds(args.seeds)
        from bicoord_drake.scenario import parse_action_noise

        parse_action_noise(args.action_noise)  # the level's bounds, named
        from bicoord_drake.sim.disturbances import parse_disturb

        args.disturb = ",".join(parse_disturb(args.disturb))  # unknown kinds, named
        if not 1 <= args.workers <= 64:
            raise ValueError(f"--workers must be in [1, 64], got {args.workers}")
        from bicoord_drake.tasks import list_tasks

        tasks = parse_tasks(args.tasks, list_tasks())
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    logging.getLogger("drake").setLevel(logging.ERROR)
    for task in tasks:
        print(f"{task}: seeds {seed_text(seeds)} ...", flush=True)
        if args.data is not None:
            result = run_task(
                task,
                seeds,
                args.workers,
                args.data,
                args.randomize,
                args.replay,
                args.embodiment,
                args.action_noise,
                args.disturb,
            )
        else:
            with tempfile.TemporaryDirectory(prefix=f"expert_success_{task}_") as tmp:
                result = run_task(
                    task,
                    seeds,
                    args.workers,
                    Path(tmp),
                    args.randomize,
                    args.replay,
                    args.embodiment,
                    args.action_noise,
                    args.disturb,
                )
        text = args.out.read_text() if args.out.exists() else ""
        write_atomic(args.out, update_markdown(text, {result.task: format_section(result)}))
        replayed = f", replay {result.replay[0]}/{result.replay[1]}" if result.replay else ""
        print(
            f"{result.task}: kept {result.kept}/{result.tried} "
            f"in {result.wall_seconds / 60:.1f} min{replayed}",
            flush=True,
        )
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

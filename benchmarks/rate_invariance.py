#!/usr/bin/env python
"""Does the control rate change the motion or only its sampling? Experts at several rates.

    python benchmarks/rate_invariance.py --tasks jigsaw,cook --rates 10,15,30,50 --seeds 0-9
    python benchmarks/rate_invariance.py --tasks all --rates 15,50 --seeds 0-2 --workers 2

For every task, rate and seed the expert runs in physics exactly as the generator runs it
(:func:`bicoord_drake.runner.generate.run_expert`, no cameras) and the episode is kept only if
every stage verified. Per task and rate the report gives kept/tried (the failed seeds with
their reasons), the mean demonstration length in seconds, its ratio to the same seed's length
at 15 Hz (seeds kept at both rates), and the fastest commanded joint speed as a share of the
joint's velocity limit (1.0 = at the limit). The table goes to stdout and, with ``--out``,
into a markdown file (temp name, then rename) with the commit, machine and date.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # measure this checkout's code

REFERENCE_RATE = 15.0


@dataclass
class Run:
    """One (task, rate, seed): kept or the reason, length and fastest joint command."""

    task: str
    rate: float
    seed: int
    kept: bool
    reason: str
    steps: int
    speed_share: float
    wall: float

    @property
    def seconds(self) -> float:
        return self.steps / self.rate


def run_one(task: str, rate: float, seed: int) -> Run:
    """The expert of `task` on `seed` at `rate` Hz, without cameras."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.episode_setup import EpisodeSetup
    from bicoord_drake.runner.generate import run_expert

    start = time.perf_counter()
    setup = EpisodeSetup(
        task=task, seed=seed, station=StationConfig(control_rate=rate, render=False)
    )
    try:
        result = run_expert(setup)
    except Exception as err:  # noqa: BLE001 - a crash of one seed is its row, as in generate.py
        wall = time.perf_counter() - start
        reason = f"{type(err).__name__}: {str(err)[:80]}"
        return Run(task, rate, seed, False, reason, 0, float("nan"), wall)
    wall = time.perf_counter() - start
    if not result.success:
        return Run(task, rate, seed, False, str(result.reason), 0, float("nan"), wall)
    actions = result.recorder.actions
    layout = result.recorder.layout
    limits = np.tile(_arm_limits(setup), 2)  # the arms' joints, left then right
    joints = layout.arm_positions(actions)
    first = layout.arm_positions(result.recorder.initial_action[None])
    q = np.vstack([first, joints])
    share = float(np.max(np.abs(np.diff(q, axis=0)) * rate / limits))
    return Run(task, rate, seed, True, "", len(actions), share, wall)


def _child(job: tuple[str, float, int], conn) -> None:
    conn.send(run_one(*job))
    conn.close()


def run_isolated(job: tuple[str, float, int]) -> Run:
    """:func:`run_one` in a process of its own: a seed whose process dies (a native crash,
    such as an abort inside Drake, or the OOM killer) is a failed row with its exit code, and
    the other seeds go on (a process pool would break for all of them)."""
    task, rate, seed = job
    start = time.perf_counter()
    receive, send = multiprocessing.Pipe(duplex=False)
    process = multiprocessing.get_context("fork").Process(target=_child, args=(job, send))
    process.start()
    send.close()
    try:
        run = receive.recv()
    except EOFError:
        run = None
    process.join()
    if run is None:
        wall = time.perf_counter() - start
        why = f"the process died (exit code {process.exitcode}; a native crash prints to stderr)"
        return Run(task, rate, seed, False, why, 0, float("nan"), wall)
    return run


def _arm_limits(setup) -> np.ndarray:
    from bicoord_drake.models.robots import get_embodiment

    arm = get_embodiment(setup.embodiment).arm
    return np.array([j.velocity_limit for j in arm.joints])


def parse_range(text: str) -> list[int]:
    """'0-9' or '0,3,5' -> seeds."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def table(runs: list[Run], tasks: list[str], rates: list[float]) -> str:
    """The markdown table: one row per task and rate."""
    by = {(r.task, r.rate, r.seed): r for r in runs}
    lines = [
        "| task | Hz | kept | mean length (s) | length / 15 Hz (same seeds) | fastest joint "
        "command / limit | failed seeds |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for task in tasks:
        for rate in rates:
            rs = [r for r in runs if r.task == task and r.rate == rate]
            kept = [r for r in rs if r.kept]
            ratios = [
                r.seconds / by[(task, REFERENCE_RATE, r.seed)].seconds
                for r in kept
                if (task, REFERENCE_RATE, r.seed) in by and by[(task, REFERENCE_RATE, r.seed)].kept
            ]
            length = f"{np.mean([r.seconds for r in kept]):.2f}" if kept else "-"
            ratio = f"{min(ratios):.3f}-{max(ratios):.3f}" if ratios else "-"
            speed = f"{max(r.speed_share for r in kept):.2f}" if kept else "-"
            fails = "; ".join(f"{r.seed}: {r.reason[:90]}" for r in rs if not r.kept) or "-"
            lines.append(
                f"| {task} | {rate:g} | {len(kept)}/{len(rs)} | {length} | {ratio} | {speed} | "
                f"{fails} |"
            )
    return "\n".join(lines)


def _commit() -> str:
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "bicoord_drake", "pyproject.toml"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        ).stdout.strip()
        return sha + (" (dirty)" if dirty else "")
    except OSError:
        return "unknown"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", default="all", help="comma-separated task names, or all")
    parser.add_argument("--rates", default="10,15,30,50", help="control rates, Hz (15 is added)")
    parser.add_argument("--seeds", default="0-9", help="e.g. 0-9 or 0,2,5")
    parser.add_argument("--workers", type=int, default=2, help="processes (one per core)")
    parser.add_argument("--out", type=Path, default=None, help="markdown file to write")
    args = parser.parse_args(argv)
    from bicoord_drake.tasks import list_tasks

    tasks = list_tasks() if args.tasks == "all" else [t.strip() for t in args.tasks.split(",")]
    unknown = sorted(set(tasks) - set(list_tasks()))
    if unknown:
        parser.error(f"unknown tasks {unknown}; tasks: {', '.join(list_tasks())}")
    rates = sorted({float(r) for r in args.rates.split(",")} | {REFERENCE_RATE})
    seeds = parse_range(args.seeds)
    jobs = [(t, r, s) for t in tasks for r in rates for s in seeds]
    started = time.time()
    runs: list[Run] = []
    with ThreadPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(run_isolated, job) for job in jobs]
        for i, future in enumerate(futures, 1):
            run = future.result()
            runs.append(run)
            state = (
                f"kept, fastest joint {run.speed_share:.2f} of its limit"
                if run.kept
                else run.reason
            )
            print(
                f"[{i}/{len(jobs)}] {run.task} {run.rate:g} Hz seed {run.seed}: {state} "
                f"({run.seconds if run.kept else 0:.1f} s sim, {run.wall:.0f} s wall)",
                flush=True,
            )
    text = table(runs, tasks, rates)
    header = (
        f"Commit {_commit()}, {platform.machine()} {os.cpu_count()} cores, "
        f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {args.workers} workers, "
        f"{(time.time() - started) / 60:.0f} min. Seeds {args.seeds}.\n\n"
        f"    python benchmarks/rate_invariance.py --tasks {args.tasks} --rates {args.rates} "
        f"--seeds {args.seeds} --workers {args.workers}\n"
    )
    print(text)
    if args.out:
        previous = (
            args.out.read_text() if args.out.exists() else "# Experts at several control rates\n"
        )
        tmp = args.out.with_suffix(".tmp")
        tmp.write_text(
            f"{previous.rstrip()}\n\n## {args.tasks} at {args.rates} Hz\n\n{header}\n{text}\n"
        )
        tmp.replace(args.out)


if __name__ == "__main__":
    main()

"""Generation throughput: simulated seconds of kept demonstrations per wall second.

    python benchmarks/bench_throughput.py --tasks jigsaw,cook --episodes 4 --workers 1,2 \\
        [--render yes|no|both] [--before REV | --versus FIELD=VALUE] [--set FIELD=VALUE] \\
        [--repeats 1] [--embodiment aloha_viperx] \\
        [--out benchmarks/bench_throughput.md]

Every measurement is one run of ``scripts/generate.py`` as a user runs it (a fresh process, so
startup is included) on the same seeds: ``--seed`` upward until ``--episodes`` are kept. Its
wall time is taken around the process; the simulated seconds are the kept episodes' frames over
the recording rate; the split (build, planning, physics, monitor, render, jpeg, encode, write)
is the sum of the workers' per-seed timings in the run's ``manifest.json`` (worker seconds, so
with 2 workers it adds up to about twice the wall time).

``--before REV`` also measures another commit, checked out with ``git worktree`` into a
temporary directory (removed at the end, also on an error: ``expert_success.worktree``),
interleaved with this checkout (same seeds, same background load): the "before" of a speed
change. The 1-minute load average is recorded before every run; compare ratios within one
run, not figures across machines or days. With ``--before`` a second table gives, per task and
setting, the ratio after/before of the whole run's rate and of the physics phase alone
(simulated seconds per worker second spent stepping the plant), and their medians.
``--versus FIELD=VALUE`` instead compares two settings of this checkout the same way (e.g.
``station.cameras.renderer=gl`` against the default VTK): the ratios are with / without.
``--set FIELD=VALUE`` applies to every run; ``--embodiment`` picks the robot.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The robot generate.py uses without --embodiment.
DEFAULT_ROBOT = "aloha_viperx"
sys.path.append(str(Path(__file__).resolve().parent))  # the other benchmark scripts, last

expert_success = importlib.import_module("expert_success")


def measure(
    tree: Path,
    task: str,
    episodes: int,
    seed: int,
    workers: int,
    render: bool,
    embodiment: str = DEFAULT_ROBOT,
    settings: tuple[str, ...] = (),
) -> dict:
    """One generate.py run in `tree` (on `embodiment`, each of `settings` a ``--set
    FIELD=VALUE``); its wall time, kept simulated seconds and phase split."""
    out = Path(tempfile.mkdtemp(prefix="bench-throughput-"))
    cmd = [
        sys.executable,
        str(tree / "scripts" / "generate.py"),
        f"--task={task}",
        f"--episodes={episodes}",
        f"--seed={seed}",
        f"--max-tries={3 * episodes}",
        f"--workers={workers}",
        f"--out={out}",
    ]
    if not render:
        cmd.append("--no-render")
    if embodiment != DEFAULT_ROBOT:
        cmd.append(f"--embodiment={embodiment}")
    for setting in settings:
        cmd += ["--set", setting]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    run = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    manifests = sorted((out / task).glob("*/manifest.json"))  # one settings directory
    if not manifests:
        raise RuntimeError(f"{' '.join(cmd)} wrote no manifest:\n{run.stderr[-2000:]}")
    manifest_path = manifests[0]
    manifest = json.loads(manifest_path.read_text())
    shutil.rmtree(out, ignore_errors=True)
    fps = float(manifest["config"].get("fps", 15.0))
    kept = [e for e in manifest["episodes"] if e["success"]]
    split: dict[str, float] = {}
    for entry in manifest["episodes"]:
        for phase, seconds in entry.get("timings", {}).items():
            split[phase] = split.get(phase, 0.0) + seconds
    simulated = sum(e["frames"] for e in kept) / fps
    return {
        "wall": wall,
        "simulated": simulated,
        "rate": simulated / wall,
        "kept": len(kept),
        "tried": len(manifest["episodes"]),
        "split": split,
        "load": load,
    }


def table(rows: list[dict]) -> str:
    phases = sorted({p for r in rows for p in r["split"]}, key=PHASE_ORDER.index)
    head = "| commit | task | render | workers | kept/tried | sim s | wall s | **sim s / wall s** |"
    head += "".join(f" {p} |" for p in phases) + " load |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        split = "".join(f" {r['split'].get(p, 0.0):.1f} |" for p in phases)
        lines.append(
            f"| {label_of(r)} | {r['task']} | {'yes' if r['render'] else 'no'} | "
            f"{r['workers']} | {r['kept']}/{r['tried']} | {r['simulated']:.1f} | "
            f"{r['wall']:.1f} | **{r['rate']:.2f}** |{split} {r['load']:.1f} |"
        )
    return "\n".join(lines)


def totals(rows: list[dict]) -> str:
    """Per compared side (commit and settings): all its runs together - kept simulated seconds
    over the summed wall time, and each phase's share of the summed worker time."""
    lines = []
    for label in dict.fromkeys(label_of(r) for r in rows):
        mine = [r for r in rows if label_of(r) == label]
        simulated = sum(r["simulated"] for r in mine)
        wall = sum(r["wall"] for r in mine)
        split: dict[str, float] = {}
        for r in mine:
            for phase, seconds in r["split"].items():
                split[phase] = split.get(phase, 0.0) + seconds
        worker = sum(split.values())
        shares = ", ".join(
            f"{p} {100 * split[p] / worker:.0f} %"
            for p in sorted(split, key=PHASE_ORDER.index)
            if worker > 0 and split[p] / worker >= 0.005
        )
        lines.append(
            f"- {label}, {len(mine)} runs: {simulated:.1f} simulated s of kept episodes in "
            f"{wall:.1f} wall s = **{simulated / wall:.2f} simulated s per wall s**; worker "
            f"time {worker:.1f} s: {shares}"
        )
    return "\n".join(lines)


def label_of(row: dict) -> str:
    """A row's commit, and the ``--versus`` settings it ran with."""
    extra = row.get("versus", "")
    return f"`{row['commit']}`" + (f" + {extra}" if extra else "")


def physics_rate(row: dict) -> float | None:
    """Simulated seconds of the run's episodes per worker second of the physics phase."""
    physics = row["split"].get("physics", 0.0)
    return row["simulated"] / physics if physics > 0 and row["simulated"] > 0 else None


def ratio_table(rows: list[dict]) -> str:
    """After/before ratios per (task, render, workers): whole run and physics phase.

    Rows with ``before`` true come from the ``--before`` checkout (or ran without the
    ``--versus`` settings); the others from this one (with them),
    whatever commit it was at when each was measured (a commit landing during a long run
    moves this checkout's HEAD, not what it measures)."""
    olds = {(r["task"], r["render"], r["workers"]): r for r in rows if r.get("before")}
    news = [r for r in rows if not r.get("before")]
    if not olds or not news:
        return ""
    old = ", ".join(dict.fromkeys(label_of(r) for r in olds.values()))
    new = ", ".join(dict.fromkeys(label_of(r) for r in news))
    lines = [
        f"After ({new}) / before ({old}):",
        "",
        "| task | render | workers | run rate ratio | physics rate ratio |",
        "|---|---|---|---|---|",
    ]
    run_ratios, physics_ratios = [], []
    for r_new in news:
        r_old = olds.get((r_new["task"], r_new["render"], r_new["workers"]))
        if r_old is None or r_old["rate"] <= 0:
            continue
        run = r_new["rate"] / r_old["rate"]
        p_new, p_old = physics_rate(r_new), physics_rate(r_old)
        phys = p_new / p_old if p_new and p_old else None
        run_ratios.append(run)
        if phys:
            physics_ratios.append(phys)
        lines.append(
            f"| {r_new['task']} | {'yes' if r_new['render'] else 'no'} | {r_new['workers']} | "
            f"{run:.2f}x | " + (f"{phys:.2f}x |" if phys else "- |")
        )
    if run_ratios:
        med_p = f"{statistics.median(physics_ratios):.2f}x" if physics_ratios else "-"
        lines.append(f"| **median** | | | **{statistics.median(run_ratios):.2f}x** | **{med_p}** |")
    return "\n".join(lines)


PHASE_ORDER = [
    "build",
    "planning",
    "physics",
    "monitor",
    "record",
    "render",
    "jpeg",
    "expert",
    "encode",
    "write",
]


@dataclass(frozen=True)
class Arm:
    """One side of a comparison: the package in `tree`, run with `settings` (``--set``) and
    `versus` (the ``--versus`` settings, also passed with ``--set``); `reference` for the
    side the ratios divide by."""

    tree: Path
    settings: tuple[str, ...]
    versus: tuple[str, ...] = ()
    reference: bool = False


def arms_of(before: Path | None, settings: tuple[str, ...], versus: tuple[str, ...]) -> list[Arm]:
    """What each task is measured with, in the order of the first repeat: the ``--before``
    worktree then this checkout, or this checkout without then with the ``--versus`` settings,
    or this checkout alone."""
    if before is not None:
        return [Arm(before, settings, reference=True), Arm(ROOT, settings)]
    if versus:
        return [Arm(ROOT, settings, reference=True), Arm(ROOT, settings + versus, versus)]
    return [Arm(ROOT, settings)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", default="jigsaw", help="'all' or comma-separated task names")
    parser.add_argument("--episodes", type=int, default=4, help="episodes kept per run")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    parser.add_argument("--repeats", type=int, default=1, help="runs per setting (median)")
    parser.add_argument(
        "--render",
        choices=("yes", "no", "both"),
        default="yes",
        help="with cameras (yes), --no-render (no), or both",
    )
    parser.add_argument("--no-render-too", action="store_true", help="same as --render both")
    parser.add_argument("--before", help="also measure this git revision (the 'before')")
    parser.add_argument(
        "--embodiment",
        default=DEFAULT_ROBOT,
        help=f"the robot (default {DEFAULT_ROBOT}); --tasks all: the tasks it supports",
    )
    parser.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="a scenario setting for every run (generate.py --set); repeatable",
    )
    parser.add_argument(
        "--versus",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="also measure this checkout with these settings (repeatable; e.g. "
        "station.cameras.renderer=gl), interleaved with the runs without them; the ratio "
        "table gives with / without",
    )
    parser.add_argument("--out", type=Path, help="markdown file to write (default: print)")
    args = parser.parse_args()
    if args.before and args.versus:
        parser.error("--before and --versus each make the comparison: give one of them")

    mode = "both" if args.no_render_too else args.render
    renders = {"yes": [True], "no": [False], "both": [True, False]}[mode]
    tasks = args.tasks.split(",")
    if args.tasks == "all":
        from bicoord_drake.tasks.registry import tasks_for_robot

        tasks = tasks_for_robot(args.embodiment)
    rows = []
    with expert_success.worktree(args.before or None, "bench-before-", ROOT) as before:
        arms = arms_of(before, tuple(args.settings), tuple(args.versus))
        for task in tasks:
            for render in renders:
                for workers in (int(w) for w in args.workers.split(",")):
                    runs: dict[Arm, list[dict]] = {arm: [] for arm in arms}
                    for k in range(args.repeats):
                        for arm in arms if k % 2 == 0 else arms[::-1]:
                            runs[arm].append(
                                measure(
                                    arm.tree,
                                    task,
                                    args.episodes,
                                    args.seed,
                                    workers,
                                    render,
                                    args.embodiment,
                                    arm.settings,
                                )
                            )
                    for arm, results in runs.items():
                        median = sorted(results, key=lambda r: r["rate"])[len(results) // 2]
                        row = {
                            **median,
                            "task": task,
                            "render": render,
                            "workers": workers,
                            "commit": expert_success.short_commit_of("HEAD", arm.tree),
                            "before": arm.reference,
                            "versus": " ".join(arm.versus),
                            "rate": statistics.median(r["rate"] for r in results),
                        }
                        rows.append(row)
                        print(table([row]).splitlines()[-1], flush=True)
    text = "\n".join(
        [
            f"Measured {datetime.now(UTC):%Y-%m-%d %H:%M} UTC on {platform.machine()}, "
            f"nproc = {os.cpu_count()}, Python {platform.python_version()}; "
            f"{args.episodes} kept episodes per run from seed {args.seed}, "
            f"median of {args.repeats} run(s), robot {args.embodiment}"
            + "".join(f", --set {x}" for x in args.settings)
            + ". Phase columns: worker seconds.",
            "",
            table(rows),
            "",
            "All runs together:",
            "",
            totals(rows),
            "",
        ]
    )
    if args.before or args.versus:
        text += "\n" + ratio_table(rows) + "\n"
    if args.out:
        args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()

#!/usr/bin/env python
"""Physics cost of a task's scene at rest: ms per control step, contact surfaces and faces.

    python benchmarks/bench_rest_cost.py --task handover_block_with_bowls
    python benchmarks/bench_rest_cost.py --tasks handover_block_with_bowls,stack_bowls \\
        --before 512374c --repeats 5 --out benchmarks/bench_rest_cost.md
    python benchmarks/bench_rest_cost.py --task cook --seed 3 --embodiment franka_pair \\
        --steps 30 --warmup 5

The scene of ``--task`` and ``--seed`` (default 0) on ``--embodiment`` (default: the default
robot), built with ``make_env(task, seed, render=False)`` (no cameras) and reset to that seed;
the arms hold the home action. After ``--warmup`` control steps (5), ``--steps`` control steps
(30, each ``env.step(home)``: the physics and the environment's own bookkeeping, 1/15 s at the
default rate) are timed: CPU (``time.process_time``) and wall milliseconds per control step.
At the end, from the plant's contact results: the hydroelastic contact surfaces, their faces
and the point contacts, and the faces and point contacts summed per pair of bodies (names
sorted; a body name used twice in the plant is prefixed by its model instance). Over the
timed steps: the largest displacement (mm) of any task object from where it was when the
timing began; it must stay about 0 (more than 1 mm is flagged, and the exit status is 1): a
cheap model that lets the scene drift is not a result.

Every measurement is a fresh process running this file with ``--measure-json`` (its last
stdout line: one JSON object), ``--repeats`` times (5) per package; the table gives the
medians (the drift: the largest). The package measured is this checkout's (``PYTHONPATH`` =
this checkout, run from it) and, with ``--before REV``, also that of git revision REV,
checked out with ``git worktree add --detach TMP/tree REV`` (removed at the end, also on an
error: ``expert_success.worktree``) and measured by this same file with that tree first on
``PYTHONPATH`` and as working directory, so both go through identical code. The two packages
alternate (before, after, before, after, ...) so that the machine's load hits both alike; the
ratio before/after of the CPU ms per control step is reported. A REV that git cannot resolve
to a commit exits 2 before anything is measured, one that git cannot check out exits 1.
``--tasks a,b`` gives one row per task and package.

The table is printed; with ``--out FILE`` each task's section ``## <task> (seed S,
<embodiment>)`` of FILE is replaced (or appended; other sections kept; a temporary file, then
renamed): the command, machine, date (UTC), commits (this checkout's, ``(dirty)`` when its
package had uncommitted changes, and REV's), the table, the ratio and the top 10 body pairs
by faces for each package.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import shlex
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterable
from contextlib import ExitStack
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = Path(__file__).resolve().parent
#: A task object that moved more than this (mm) over the timed steps flags the result.
DRIFT_LIMIT_MM = 1.0
#: Body pairs shown per package in a section's face breakdown.
TOP_PAIRS = 10
TITLE = "# Physics cost of task scenes at rest"
PREAMBLE = (
    f"{TITLE}\n\n"
    "Written by `python benchmarks/bench_rest_cost.py`: per task, seed and robot, the scene "
    "without cameras, the arms held at home; CPU and wall milliseconds per control step "
    "(medians over fresh processes), the hydroelastic contact surfaces, their faces and the "
    "point contacts at the end, and how far any task object moved (it must stay about 0). "
    "With `--before REV` the package of REV is measured too, alternating with this "
    "checkout's. `(dirty)` after a commit: the package (`bicoord_drake/`, `pyproject.toml`) "
    "had uncommitted changes.\n"
)

Runner = Callable[..., subprocess.CompletedProcess]


def sibling(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` (expert_success), imported when first used:
    not at the top, since expert_success puts this checkout first on ``sys.path`` and a
    ``--measure-json`` process must import the package its ``PYTHONPATH`` names."""
    if str(BENCHMARKS) not in sys.path:
        sys.path.append(str(BENCHMARKS))
    return importlib.import_module(name)


# --------------------------------------------------------------------------- arguments
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (`tasks` becomes a list; counts are checked)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument(
        "--tasks", "--task", dest="tasks", required=True, help="task name(s), comma-separated"
    )
    parser.add_argument("--seed", type=int, default=0, help="the scene's seed (default 0)")
    parser.add_argument("--embodiment", help="the robot (default: the default robot)")
    parser.add_argument("--warmup", type=int, default=5, help="control steps before timing")
    parser.add_argument("--steps", type=int, default=30, help="timed control steps")
    parser.add_argument("--repeats", type=int, default=5, help="processes per package")
    parser.add_argument("--before", metavar="REV", help="also measure git revision REV")
    parser.add_argument("--out", type=Path, help="markdown file whose task sections to replace")
    parser.add_argument(
        "--measure-json",
        action="store_true",
        help="(internal) measure one task in this process; print one JSON line",
    )
    args = parser.parse_args(argv)
    args.tasks = list(dict.fromkeys(t.strip() for t in args.tasks.split(",") if t.strip()))
    if not args.tasks:
        parser.error("--tasks: no task given")
    if args.measure_json and len(args.tasks) != 1:
        parser.error("--measure-json measures one task")
    if args.warmup < 0:
        parser.error("--warmup must be at least 0")
    if args.steps < 1 or args.repeats < 1:
        parser.error("--steps and --repeats must be at least 1")
    return args


def resolve(rev: str, root: Path = ROOT) -> str | None:
    """The short hash of the commit `rev` names; None when git cannot resolve it."""
    return sibling("expert_success").short_commit_of(rev, root)


# --------------------------------------------------------------------------- one measurement
def body_labels(plant: Any) -> dict[int, str]:
    """Body index -> its name, prefixed by its model instance when the name is not unique."""
    from pydrake.multibody.tree import BodyIndex

    bodies = [plant.get_body(BodyIndex(i)) for i in range(plant.num_bodies())]
    names = [b.name() for b in bodies]
    return {
        int(b.index()): (
            f"{plant.GetModelInstanceName(b.model_instance())}::{b.name()}"
            if names.count(b.name()) > 1
            else b.name()
        )
        for b in bodies
    }


def breakdown(
    surfaces: Iterable[tuple[str, str, int]], points: Iterable[tuple[str, str]] = ()
) -> list[list[Any]]:
    """[body A, body B, faces, point contacts] per pair of bodies (names sorted), the faces of
    its hydroelastic surfaces and its point contacts summed; most faces first (then most point
    contacts, then the names)."""
    pairs: dict[tuple[str, str], list[int]] = {}
    for a, b, faces in surfaces:
        pairs.setdefault(tuple(sorted((a, b))), [0, 0])[0] += int(faces)
    for a, b in points:
        pairs.setdefault(tuple(sorted((a, b))), [0, 0])[1] += 1
    rows = [[a, b, faces, count] for (a, b), (faces, count) in pairs.items()]
    return sorted(rows, key=lambda r: (-r[2], -r[3], r[0], r[1]))


def contacts(plant: Any, scene_graph: Any, context: Any) -> dict[str, Any]:
    """The contact results now: surfaces, faces, point contacts and the per-pair breakdown."""
    results = plant.get_contact_results_output_port().Eval(context)
    inspector = scene_graph.model_inspector()
    labels = body_labels(plant)

    def label(geometry: Any) -> str:
        return labels[int(plant.GetBodyFromFrameId(inspector.GetFrameId(geometry)).index())]

    surfaces = []
    for i in range(results.num_hydroelastic_contacts()):
        surface = results.hydroelastic_contact_info(i).contact_surface()
        surfaces.append((label(surface.id_M()), label(surface.id_N()), surface.num_faces()))
    points = []
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        points.append((labels[int(info.bodyA_index())], labels[int(info.bodyB_index())]))
    return {
        "surfaces": len(surfaces),
        "faces": sum(f for _, _, f in surfaces),
        "points": len(points),
        "pairs": breakdown(surfaces, points),
    }


def positions(sim: Any) -> dict[str, Any]:
    """Each task object's position (m): ``object_poses()`` is xyz then the quaternion wxyz."""
    return {name: pose[:3].copy() for name, pose in sim.object_poses().items()}


def measure(task: str, seed: int, embodiment: str | None, warmup: int, steps: int) -> dict:
    """One measurement in this process, of the ``bicoord_drake`` that ``sys.path`` finds."""
    import logging

    import numpy as np

    import bicoord_drake
    from bicoord_drake.env import make_env

    logging.getLogger("drake").setLevel(logging.ERROR)
    robot = {} if embodiment is None else {"embodiment": embodiment}
    env = make_env(task, seed, render=False, **robot)
    env.reset(seed)
    sim = env.sim
    home = sim.station.embodiment.home_action()
    for _ in range(warmup):
        env.step(home)
    start = positions(sim)
    cpu = wall = drift = 0.0
    for _ in range(steps):
        c, w = time.process_time(), time.perf_counter()
        env.step(home)
        cpu += time.process_time() - c
        wall += time.perf_counter() - w
        now = positions(sim)
        drift = max([drift, *(float(np.linalg.norm(now[k] - p)) for k, p in start.items())])
    station = sim.station
    return {
        "task": task,
        "seed": seed,
        "embodiment": getattr(station.embodiment, "name", "default robot"),
        "package": str(Path(bicoord_drake.__file__).resolve().parent),
        "cpu_ms": 1000 * cpu / steps,
        "wall_ms": 1000 * wall / steps,
        "drift_mm": 1000 * drift,
        **contacts(station.plant, station.scene_graph, sim.plant_context),
    }


# --------------------------------------------------------------------------- the packages
@dataclass(frozen=True)
class Package:
    """A package measured: this checkout's, or that of a worktree of ``--before``."""

    label: str  # "before", "after", or "this checkout"
    tree: Path
    commit: str  # short hash
    dirty: bool = False

    def env(self) -> dict[str, str]:
        """Its processes' environment: its tree first on PYTHONPATH, any robot allowed."""
        path = os.pathsep.join(filter(None, [str(self.tree), os.environ.get("PYTHONPATH")]))
        allow = sibling("expert_success").ALLOW_UNDECLARED_ENV
        return {**os.environ, "PYTHONPATH": path, allow: "1"}

    def text(self) -> str:
        return f"`{self.commit}`" + (" (dirty)" if self.dirty else "")


def measure_command(task: str, args: argparse.Namespace) -> list[str]:
    """This file in ``--measure-json`` mode for `task`."""
    command = [sys.executable, str(Path(__file__).resolve()), "--measure-json", "--task", task]
    command += ["--seed", str(args.seed), "--warmup", str(args.warmup), "--steps", str(args.steps)]
    return command + ([] if args.embodiment is None else ["--embodiment", args.embodiment])


def measure_in(
    package: Package, task: str, args: argparse.Namespace, runner: Runner = subprocess.run
) -> dict:
    """One measurement of `package` in a fresh process (run from its tree); its JSON line.
    RuntimeError if the process failed or imported another package."""
    command = measure_command(task, args)
    out = runner(command, cwd=package.tree, env=package.env(), capture_output=True, text=True)
    lines = out.stdout.strip().splitlines()
    if out.returncode != 0 or not lines:
        raise RuntimeError(
            f"{package.label} ({package.commit}): {shlex.join(command)} failed "
            f"(exit {out.returncode}):\n{out.stderr[-2000:]}"
        )
    result = json.loads(lines[-1])
    if not Path(result["package"]).is_relative_to(package.tree.resolve()):
        raise RuntimeError(
            f"{package.label}: imported bicoord_drake from {result['package']}, "
            f"not from {package.tree}"
        )
    return result


def alternate(
    labels: Iterable[str], repeats: int, measure_one: Callable[[str], dict]
) -> dict[str, list[dict]]:
    """`repeats` measurements per label, the labels taking turns (before, after, before, ...)."""
    labels = list(labels)
    runs: dict[str, list[dict]] = {label: [] for label in labels}
    for _ in range(repeats):
        for label in labels:
            runs[label].append(measure_one(label))
    return runs


def summary(runs: list[dict]) -> dict[str, Any]:
    """The medians of a package's measurements (the drift: the largest), and the contacts and
    pair breakdown of its last one."""

    def median(key: str) -> float:
        return statistics.median(r[key] for r in runs)

    last = runs[-1]
    return {
        "cpu_ms": median("cpu_ms"),
        "wall_ms": median("wall_ms"),
        "surfaces": median("surfaces"),
        "faces": median("faces"),
        "points": median("points"),
        "drift_mm": max(r["drift_mm"] for r in runs),
        "pairs": last["pairs"],
        "embodiment": last["embodiment"],
        "runs": len(runs),
    }


def ratio(stats: dict[str, dict[str, Any]]) -> float | None:
    """CPU ms per control step of "before" over that of "after" (None without both)."""
    if "before" not in stats or "after" not in stats or stats["after"]["cpu_ms"] <= 0:
        return None
    return stats["before"]["cpu_ms"] / stats["after"]["cpu_ms"]


# --------------------------------------------------------------------------- output
def _count(value: float) -> str:
    return f"{value:g}"


def _drift(value: float) -> str:
    text = f"{value:.3f}"
    return f"**{text}** (moved)" if value > DRIFT_LIMIT_MM else text


HEADER = (
    "| task | package | commit | CPU ms / step | wall ms / step | surfaces | faces | "
    "point contacts | drift, mm |"
)


def table_rows(task: str, packages: list[Package], stats: dict[str, dict[str, Any]]) -> list[str]:
    """One row per package of `task`."""
    rows = []
    for p in packages:
        s = stats[p.label]
        rows.append(
            f"| {task} | {p.label} | {p.text()} | {s['cpu_ms']:.1f} | {s['wall_ms']:.1f} | "
            f"{_count(s['surfaces'])} | {_count(s['faces'])} | {_count(s['points'])} | "
            f"{_drift(s['drift_mm'])} |"
        )
    return rows


def table(rows: list[str]) -> str:
    return "\n".join([HEADER, "|---|---|---|---:|---:|---:|---:|---:|---:|", *rows])


def pairs_table(pairs: list[list[Any]], top: int = TOP_PAIRS) -> list[str]:
    """The `top` body pairs by faces, and how many pairs there were."""
    lines = ["| body A | body B | faces | point contacts |", "|---|---|---:|---:|"]
    lines += [f"| {a} | {b} | {faces} | {points} |" for a, b, faces, points in pairs[:top]]
    shown = min(top, len(pairs))
    return [*lines, "", f"{shown} of {len(pairs)} body pairs in contact."]


def section_name(task: str, seed: int, embodiment: str) -> str:
    return f"{task} (seed {seed}, {embodiment})"


def format_section(
    task: str,
    args: argparse.Namespace,
    packages: list[Package],
    stats: dict[str, dict[str, Any]],
    command: str,
    before_rev: str | None = None,
) -> str:
    """The markdown section of one task (starts with '## <task> (seed S, <embodiment>)')."""
    expert_success = sibling("expert_success")
    robot = args.embodiment or stats[packages[-1].label]["embodiment"]
    commits = [f"{p.label} {p.text()}" for p in packages]
    if before_rev is not None:
        commits[0] += f" (`--before {before_rev}`)"
    order = ", ".join(p.label for p in packages)
    lines = [
        f"## {section_name(task, args.seed, robot)}",
        "",
        "| | |",
        "|---|---|",
        f"| command | `{command}` |",
        f"| machine | {expert_success.machine()} |",
        f"| date (UTC) | {datetime.now(UTC):%Y-%m-%d %H:%M} |",
        f"| commits | {'; '.join(commits)} |",
        f"| measured | {args.steps} control steps after {args.warmup} warm-up steps, arms at "
        f"home, no cameras; medians of {args.repeats} processes per package (in turn: "
        f"{order}); drift: the largest |",
        "",
        table(table_rows(task, packages, stats)),
        "",
    ]
    value = ratio(stats)
    if value is not None:
        lines += [f"CPU ms per control step, before / after: **{value:.2f}x**.", ""]
    if any(s["drift_mm"] > DRIFT_LIMIT_MM for s in stats.values()):
        lines += [f"A task object moved more than {DRIFT_LIMIT_MM:g} mm: not a result.", ""]
    for p in packages:
        lines += [f"### Faces by body pair, {p.label} ({p.text()})", ""]
        lines += [*pairs_table(stats[p.label]["pairs"]), ""]
    return "\n".join(lines)


def write_sections(out: Path, sections: dict[str, str]) -> None:
    """Replace (or append) `sections` of `out`, keeping the others; atomically."""
    expert_success = sibling("expert_success")
    text = out.read_text() if out.exists() else PREAMBLE
    out.parent.mkdir(parents=True, exist_ok=True)
    expert_success.write_atomic(out, expert_success.update_markdown(text, sections))


# --------------------------------------------------------------------------- CLI
def packages_of(tree: Path | None, before: str | None) -> list[Package]:
    """The packages measured, in turn: the worktree's ("before") with ``--before``, then this
    checkout's."""
    head, dirty = sibling("expert_success").git_state(ROOT)
    if tree is None or before is None:
        return [Package("this checkout", ROOT, head[:7], dirty)]
    return [Package("before", tree, before), Package("after", ROOT, head[:7], dirty)]


def run(
    args: argparse.Namespace,
    packages: list[Package],
    command: str,
    runner: Runner = subprocess.run,
) -> tuple[list[str], bool]:
    """Every task measured; each task's section written as it finishes. (table rows, whether
    some task object moved more than :data:`DRIFT_LIMIT_MM`)."""
    rows, moved = [], False
    by_label = {p.label: p for p in packages}
    for task in args.tasks:

        def one(label: str, task: str = task) -> dict:
            result = measure_in(by_label[label], task, args, runner)
            print(
                f"{task} {label}: {result['cpu_ms']:.1f} CPU ms / step, "
                f"{result['faces']} faces, drift {result['drift_mm']:.3f} mm",
                flush=True,
            )
            return result

        runs = alternate(by_label, args.repeats, one)
        stats = {label: summary(results) for label, results in runs.items()}
        rows += table_rows(task, packages, stats)
        moved = moved or any(s["drift_mm"] > DRIFT_LIMIT_MM for s in stats.values())
        value = ratio(stats)
        if value is not None:
            rows.append(f"| {task} | before / after | | **{value:.2f}x** | | | | | |")
        if args.out is not None:
            section = format_section(task, args, packages, stats, command, args.before)
            write_sections(args.out, {section.split("\n", 1)[0][3:].strip(): section})
    return rows, moved


def main(argv: list[str] | None = None) -> int:
    """The command: 0, 1 when a task object drifted, a measurement failed or git could not
    check --before out, 2 for bad arguments (an unknown task, a --before that git cannot
    resolve)."""
    args = parse_args(argv)
    if args.measure_json:
        result = measure(args.tasks[0], args.seed, args.embodiment, args.warmup, args.steps)
        print(json.dumps(result), flush=True)
        return 0
    before = None
    if args.before is not None:
        before = resolve(args.before)
        if before is None:
            print(
                f"error: --before {args.before}: not a commit of this repository "
                f"(git rev-parse --verify {shlex.quote(args.before + '^{commit}')} failed)",
                file=sys.stderr,
            )
            return 2
    expert_success = sibling("expert_success")
    from bicoord_drake.tasks import list_tasks

    try:
        args.tasks = expert_success.parse_tasks(",".join(args.tasks), list_tasks())
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    command = "python benchmarks/bench_rest_cost.py " + shlex.join(
        sys.argv[1:] if argv is None else argv
    )
    with ExitStack() as cleanup:  # the worktree of --before, removed also on an error
        try:
            tree = cleanup.enter_context(expert_success.worktree(before, "bench-rest-cost-", ROOT))
        except RuntimeError as err:  # git worktree add failed: err names REV and git's message
            print(f"error: {err}", file=sys.stderr)
            return 1
        try:
            rows, moved = run(args, packages_of(tree, before), command.strip())
        except RuntimeError as err:
            print(f"[bench_rest_cost] error: {err}", file=sys.stderr)
            return 1
    print()
    print(table(rows))
    if args.out is not None:
        print(f"wrote {args.out}")
    return 1 if moved else 0


if __name__ == "__main__":
    sys.exit(main())

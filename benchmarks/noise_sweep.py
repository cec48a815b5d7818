#!/usr/bin/env python
"""Expert success against action-noise level (DART), into benchmarks/noise_sweep.md.

    python benchmarks/noise_sweep.py --tasks all --sigmas 0.005,0.01,0.02 --seeds 0-9
    python benchmarks/noise_sweep.py --tasks cook,jigsaw --sigmas 0.01 --seeds 0-29 --workers 2

For every task and every level SIGMA of ``--sigmas`` (rad), runs the experts as
``scripts/generate.py --action-noise SIGMA`` does (no rendering; :func:`expert_success.run_task`:
an episode is kept only when every stage verified with the noisy execution) on the seed range,
and writes one Markdown file: a table of kept / tried per task and level, the default level it
supports (the largest level measured at which every task of the table keeps at least
``--goal`` of its seeds, 80 % by default: issue #54's bar) and one section per (task, level)
with its failed seeds and reasons (expert_success.py's section). Each finished cell is stored
at once in ``<out>.json`` beside the file (the file is rewritten from it, temp name then
rename): an interrupted sweep resumes, skipping cells already measured at the same commit and
seeds; ``--force`` measures them again. Exit status 0, or 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import logging
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DEFAULT_OUT = ROOT / "benchmarks" / "noise_sweep.md"
#: issue #54: every task keeps at least this share of its seeds at the default level
DEFAULT_GOAL = 0.8


def _expert_success():
    """benchmarks/expert_success.py (a script beside this one, not a package module)."""
    spec = importlib.util.spec_from_file_location(
        "expert_success", Path(__file__).with_name("expert_success.py")
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("expert_success", module)
    spec.loader.exec_module(module)
    return module


es = _expert_success()

TITLE = "# Expert success under action noise (DART)"


def parse_sigmas(text: str) -> list[float]:
    """'0.005,0.01' -> [0.005, 0.01] (sorted, unique); each level within the generator's
    bounds (:func:`bicoord_drake.scenario.parse_action_noise` names them)."""
    from bicoord_drake.scenario import parse_action_noise

    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items:
        raise ValueError("--sigmas: give at least one level in rad, e.g. 0.005,0.01,0.02")
    levels = []
    for item in items:
        level = parse_action_noise(item)
        if isinstance(level, tuple):
            raise ValueError(f"--sigmas takes single levels, not a range: {item!r}")
        levels.append(float(level))
    return sorted(set(levels))


def cell_key(task: str, sigma: float) -> str:
    return f"{task}@{sigma:g}"


def load_cells(path: Path) -> dict[str, dict]:
    """The stored cells (none when the file is missing or unreadable)."""
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError):
        return {}


def to_record(result) -> dict:
    """An expert_success.TaskResult as JSON (the seed range as [first, last])."""
    record = asdict(result)
    record["seeds"] = [result.seeds.start, result.seeds.stop - 1]
    return record


def from_record(record: dict):
    """The TaskResult a stored cell holds."""
    data = dict(record)
    first, last = data.pop("seeds")
    data["failures"] = [tuple(f) for f in data.get("failures", [])]
    data["replay_failures"] = [tuple(f) for f in data.get("replay_failures", [])]
    if data.get("replay") is not None:
        data["replay"] = tuple(data["replay"])
    return es.TaskResult(seeds=range(first, last + 1), **data)


def default_level(cells: dict[str, dict], tasks: list[str], sigmas: list[float], goal: float):
    """The largest level at which every task in `tasks` was measured and keeps >= `goal`, with
    the levels below it also passing (success is not assumed monotone in the level); None if
    even the smallest fails or is unmeasured."""
    best = None
    for sigma in sigmas:
        rows = [cells.get(cell_key(t, sigma)) for t in tasks]
        if any(r is None or not r["tried"] or r["kept"] / r["tried"] < goal for r in rows):
            break
        best = sigma
    return best


def render(cells: dict[str, dict], tasks: list[str], sigmas: list[float], goal: float) -> str:
    """The whole Markdown file from the stored cells of `tasks` x `sigmas`."""
    lines = [
        TITLE,
        "",
        "Written by `python benchmarks/noise_sweep.py`: each task's expert run with "
        "`scripts/generate.py --action-noise SIGMA` (per-joint Gaussian noise of SIGMA rad on the "
        "executed arm joint targets, grippers untouched, the expert's label recorded; no "
        "rendering) on the seeds given. An episode is kept only when every stage verified. "
        "`(dirty)`: the package had uncommitted changes.",
        "",
        "| task | " + " | ".join(f"σ = {s:g} rad" for s in sigmas) + " |",
        "|---|" + "---:|" * len(sigmas),
    ]
    for task in tasks:
        row = []
        for sigma in sigmas:
            r = cells.get(cell_key(task, sigma))
            if r is None:
                row.append("-")
                continue
            share = 100 * r["kept"] / r["tried"] if r["tried"] else 0.0
            low = " **<**" if r["tried"] and r["kept"] / r["tried"] < goal else ""
            row.append(f"{r['kept']}/{r['tried']} ({share:.0f} %){low}")
        lines.append(f"| {task} | " + " | ".join(row) + " |")
    commits = sorted(
        {f"`{r['commit'][:7]}`{' (dirty)' if r['dirty'] else ''}" for r in cells.values()}
    )
    best = default_level(cells, tasks, sigmas, goal)
    lines += [
        "",
        f"**<**: below the goal of {100 * goal:.0f} % of the seeds. Commits: {', '.join(commits)}.",
        "",
        (
            f"**Default level supported: σ = {best:g} rad** (the largest level measured at which "
            f"every task above keeps >= {100 * goal:.0f} %, every smaller level too)."
            if best is not None
            else f"**No level measured keeps >= {100 * goal:.0f} % on every task above.**"
        ),
        "",
    ]
    sections = [
        es.format_section(from_record(cells[cell_key(t, s)]))
        for t in tasks
        for s in sigmas
        if cell_key(t, s) in cells
    ]
    return "\n".join(lines) + "\n" + "\n".join(sections)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--tasks", default="all", help="'all' or comma-separated task names")
    parser.add_argument(
        "--sigmas", default="0.005,0.01,0.02", help="comma-separated noise levels (rad)"
    )
    parser.add_argument("--seeds", default="0-9", help="FIRST-LAST, inclusive (default 0-9)")
    parser.add_argument("--workers", type=int, default=1, help="parallel processes (default 1)")
    parser.add_argument(
        "--goal", type=float, default=DEFAULT_GOAL, help="share of seeds a level must keep"
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="markdown file to write")
    parser.add_argument("--force", action="store_true", help="measure stored cells again")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        from bicoord_drake.tasks import list_tasks

        tasks = es.parse_tasks(args.tasks, list_tasks())
        sigmas = parse_sigmas(args.sigmas)
        seeds = es.parse_seeds(args.seeds)
        if not 1 <= args.workers <= 64:
            raise ValueError(f"--workers must be in [1, 64], got {args.workers}")
        if not 0.0 < args.goal <= 1.0:
            raise ValueError(f"--goal must be a share in (0, 1], got {args.goal}")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    logging.getLogger("drake").setLevel(logging.ERROR)
    store = args.out.with_suffix(".json")
    cells = load_cells(store)
    commit, _ = es.git_state()
    for task in tasks:
        for sigma in sigmas:
            key = cell_key(task, sigma)
            old = cells.get(key)
            if (
                not args.force
                and old is not None
                and old["commit"] == commit
                and old["seeds"] == [seeds.start, seeds.stop - 1]
            ):
                print(f"{key}: measured before ({old['kept']}/{old['tried']})", flush=True)
                continue
            print(f"{key}: seeds {es.seed_text(seeds)} ...", flush=True)
            with tempfile.TemporaryDirectory(prefix=f"noise_sweep_{task}_") as tmp:
                result = es.run_task(task, seeds, args.workers, Path(tmp), action_noise=sigma)
            cells[key] = to_record(result)
            es.write_atomic(store, json.dumps(cells, indent=1))
            es.write_atomic(args.out, render(cells, tasks, sigmas, args.goal))
            print(f"{key}: kept {result.kept}/{result.tried}", flush=True)
    es.write_atomic(args.out, render(cells, tasks, sigmas, args.goal))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Physics levers judged closed loop: each task's expert run in each variant of the physics.

    python benchmarks/bench_expert_physics.py --tasks all --seeds 0-2 \\
        --variants "sap (today)","lagged" [--jobs 2] [--out benchmarks/bench_expert_physics.md]

A variant is a set of :class:`~bicoord_drake.config.StationConfig` fields (``VARIANTS``). For
every (task, variant) the expert of the task runs on each seed in a fresh process, exactly as
the generator runs it (:func:`~bicoord_drake.runner.generate.run_expert`, no cameras): it plans
in its own model, executes in the variant's physics, and the stage monitor verifies the episode.
Per cell the table gives kept/tried, the failure reasons, and the physics speed: simulated
seconds per second spent advancing the simulator (wall time of the ``physics`` phase, summed
over the seeds; the per-task ratio against the first variant is what to compare). Jobs run
interleaved, variant by variant within a task, so background load hits the variants alike.

This is how a lever is judged (issue #31): by the expert's success in that physics, never by
replaying actions recorded in another. A variant that keeps every task here still needs the
30-seed measurement (``benchmarks/expert_success.py``) at the commit that adopts it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: name -> StationConfig fields changed from the defaults (SAP with near-rigid threshold 0,
#: 1/120 s, margin 1e-4 m since #31; the names keep the labels of the screens in
#: bench_expert_physics.md).
VARIANTS: dict[str, dict] = {
    # The defaults before issue #31 (SAP at 1/300 s, no margin): the baseline of the ratios.
    "sap (today)": {"contact_approximation": "sap", "time_step": 1 / 300, "hydroelastic_margin": 0},
    "lagged": {"contact_approximation": "lagged", "time_step": 1 / 300, "hydroelastic_margin": 0},
    "similar": {"contact_approximation": "similar", "time_step": 1 / 300, "hydroelastic_margin": 0},
    "lagged 1/225 s": {"time_step": 1 / 225, "hydroelastic_margin": 0},
    "lagged 1/180 s": {"time_step": 1 / 180, "hydroelastic_margin": 0},
    "lagged 1/150 s": {"time_step": 1 / 150, "hydroelastic_margin": 0},
    "sap 1/180 s": {"contact_approximation": "sap", "time_step": 1 / 180, "hydroelastic_margin": 0},
    "lagged 1/120 s": {"time_step": 1 / 120, "hydroelastic_margin": 0},
    "lagged 1/150 s + margin": {
        "contact_approximation": "lagged",
        "time_step": 1 / 150,
        "hydroelastic_margin": 1e-4,
    },
    "lagged 1/120 s + margin": {
        "contact_approximation": "lagged",
        "time_step": 1 / 120,
        "hydroelastic_margin": 1e-4,
    },
    "sap 1/120 s + margin": {
        "contact_approximation": "sap",
        "time_step": 1 / 120,
        "hydroelastic_margin": 1e-4,
    },
    "sap 1/120 s + margin beta 0.1": {
        "contact_approximation": "sap",
        "time_step": 1 / 120,
        "hydroelastic_margin": 1e-4,
        "sap_near_rigid_threshold": 0.1,
    },
    "sap 1/120 s + margin beta 0.5": {
        "contact_approximation": "sap",
        "time_step": 1 / 120,
        "hydroelastic_margin": 1e-4,
        "sap_near_rigid_threshold": 0.5,
    },
    "sap 1/120 s + margin beta 0": {
        "contact_approximation": "sap",
        "time_step": 1 / 120,
        "hydroelastic_margin": 1e-4,
        "sap_near_rigid_threshold": 0.0,
    },
    # Today's defaults (SAP, near-rigid threshold 0, 1/120 s, margin 1e-4 m) ...
    "default": {},
    # ... with the bowls (and plates, cups, skillets: BowlShape) and pots rigid-hydroelastic.
    "rigid bowls+pots": {"rigid_object_kinds": ("bowl", "pot")},
    "rigid bowls": {"rigid_object_kinds": ("bowl",)},
    # Pads ten times stiffer than the robots' 2 MPa (a rigid wall jolted into a 2 MPa pad can
    # cross its middle and wedge in the finger; see "Rigid-hydroelastic bowls and pots"), alone
    # and with the bowls and pots rigid.
    "stiff pads": {"pad_modulus": 2e7},
    "stiff pads + rigid bowls+pots": {"pad_modulus": 2e7, "rigid_object_kinds": ("bowl", "pot")},
}


def parse_seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def run_cell(task: str, variant: str, seeds: list[int]) -> list[dict]:
    """Run the expert of `task` in `variant` for `seeds` in this process; one record per seed."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.episode_setup import EpisodeSetup
    from bicoord_drake.runner.generate import run_expert

    config = StationConfig(render=False, **VARIANTS[variant])
    records = []
    for seed in seeds:
        cpu0 = time.process_time()
        result = run_expert(EpisodeSetup(task=task, seed=seed, station=config))
        frames = len(result.recorder) if result.recorder is not None else 0
        records.append(
            {
                "seed": seed,
                "success": result.success,
                "reason": result.reason,
                "frames": frames,
                "sim_seconds": frames / config.control_rate,
                "physics_wall": result.timings.get("physics", 0.0),
                "cpu": time.process_time() - cpu0,
            }
        )
    return records


def _cell_in_subprocess(task: str, variant: str, seeds: list[int]) -> list[dict]:
    cmd = [sys.executable, __file__, "--worker", f"--tasks={task}", f"--variants={variant}"]
    cmd.append(f"--seeds={seeds[0]}-{seeds[-1]}")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run(cmd, capture_output=True, text=True, env=env)
    lines = [line for line in run.stdout.splitlines() if line.startswith("{")]
    if run.returncode != 0 or not lines:
        tail = run.stderr.strip().splitlines()[-1:] or ["no output"]
        return [{"seed": s, "success": False, "reason": f"crashed: {tail[0]}"} for s in seeds]
    return json.loads(lines[-1])["records"]


def _summary(records: list[dict]) -> dict:
    kept = sum(r["success"] for r in records)
    sim = sum(r.get("sim_seconds", 0.0) for r in records if r["success"])
    wall = sum(r.get("physics_wall", 0.0) for r in records if r["success"])
    reasons = sorted({f"{r['seed']}: {r['reason']}" for r in records if not r["success"]})
    return {
        "kept": kept,
        "tried": len(records),
        "speed": sim / wall if wall else None,
        "frames": statistics.mean(r["frames"] for r in records if r["success"]) if kept else None,
        "reasons": reasons,
    }


def render_markdown(results: dict, variants: list[str], seeds: list[int], args: str) -> str:
    """The table: per task and variant kept/tried and physics speed (ratio to the first)."""
    head = ["task"] + [f"{v}: kept, speed (ratio)" for v in variants]
    lines = [
        f"## Closed-loop physics levers, seeds {seeds[0]}-{seeds[-1]}",
        "",
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; `python benchmarks/bench_expert_physics.py {args}`. "
        "Speed: simulated s per wall s of the physics phase over the kept seeds; ratio to "
        f"'{variants[0]}' of the same task in the same run.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    failures = []
    ratios: dict[str, list[float]] = {v: [] for v in variants}
    for task, cells in results.items():
        base = cells[variants[0]]["speed"]
        row = [task]
        for v in variants:
            c = cells[v]
            ratio = c["speed"] / base if c["speed"] and base else None
            if ratio:
                ratios[v].append(ratio)
            speed = f"{c['speed']:.2f}" if c["speed"] else "-"
            row.append(
                f"{c['kept']}/{c['tried']}, {speed} ({ratio:.2f}x)"
                if ratio
                else f"{c['kept']}/{c['tried']}, {speed}"
            )
            failures += [f"- {task}, {v}: seed {r}" for r in c["reasons"]]
        lines.append("| " + " | ".join(row) + " |")
    medians = [f"{statistics.median(ratios[v]):.2f}x" if ratios[v] else "-" for v in variants]
    lines.append("| median ratio | " + " | ".join(medians) + " |")
    lines += ["", "Failures:" if failures else "No failures.", *failures, ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", default="all", help="'all' or comma-separated task names")
    ap.add_argument("--seeds", default="0-2", help="FIRST-LAST, inclusive")
    ap.add_argument("--variants", default="sap (today),lagged", help="comma-separated names")
    ap.add_argument("--jobs", type=int, default=2, help="processes at once")
    ap.add_argument("--out", type=Path, default=None, help="append the Markdown table here")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from bicoord_drake.tasks import list_tasks

    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        ap.error(f"unknown variants {unknown}; known: {list(VARIANTS)}")
    tasks = list_tasks() if args.tasks == "all" else args.tasks.split(",")
    seeds = parse_seeds(args.seeds)
    if args.worker:
        print(json.dumps({"records": run_cell(tasks[0], variants[0], seeds)}))
        return 0

    jobs = [(t, v) for t in tasks for v in variants]
    with ThreadPoolExecutor(args.jobs) as pool:
        futures = {job: pool.submit(_cell_in_subprocess, *job, seeds) for job in jobs}
        results: dict = {}
        for (task, variant), fut in futures.items():
            summary = _summary(fut.result())
            results.setdefault(task, {})[variant] = summary
            print(
                f"{task} / {variant}: {summary['kept']}/{summary['tried']} kept, "
                f"speed {summary['speed']}, {summary['reasons']}",
                flush=True,
            )
    cli = " ".join(sys.argv[1:])
    text = render_markdown(results, variants, seeds, cli)
    print(text)
    if args.out:
        with args.out.open("a") as f:
            f.write("\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

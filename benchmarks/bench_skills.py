#!/usr/bin/env python
"""Acceptance runs of the dynamic skills in physics: toss into a held bowl, mid-air handover.

    python benchmarks/bench_skills.py [--seeds 10] [--skills toss handover]

Each seed samples a scene (cube position by up to 3 cm per axis, size 2.8-3.2 cm, mass
25-35 g; for the toss also the bowl position by up to 3 cm), plans with the skills package and runs
every action through ``Simulation.step`` (objects move only because fingers push them).
The trials are the ones in ``tests/planning/test_skills_dynamic.py`` (``-m slow`` runs the
same 10 seeds).
Prints a Markdown table per skill, then the totals.

Toss success: after settling, the cube is inside the bowl (off the bowl axis by less than the
inner radius, above the bowl's base and below its rim), the bowl is still held by the catcher and
the thrower no longer touches the cube. Handover success: both grippers touch the cube after the
receiver closes, only the receiver after the giver lets go, and after the receiver carries it
16 cm away the cube sits where the plan expects it (within 1 cm) in the receiver's grip only.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

TRIALS = Path(__file__).resolve().parents[1] / "tests" / "planning" / "test_skills_dynamic.py"


def _trials():
    spec = importlib.util.spec_from_file_location("skills_trials", TRIALS)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        return platform.processor() or "unknown"


def run(skill: str, seeds: int) -> list[dict]:
    trial = getattr(_trials(), f"{skill}_trial")
    rows = []
    for seed in range(seeds):
        start = time.perf_counter()
        try:
            row = trial(seed)
        except Exception as err:  # a planning failure counts as a failed seed
            row = {"seed": seed, "success": False, "error": f"{type(err).__name__}: {err}"[:120]}
        row["wall"] = time.perf_counter() - start
        rows.append(row)
    return rows


def table(skill: str, rows: list[dict]) -> str:
    if skill == "toss":
        head = (
            "| seed | success | rim crossing error (mm) | cube off bowl axis (mm) | bowl tilt (°) |"
        )
        cols = [("rim_error", 1000, ".1f"), ("off_axis", 1000, ".0f"), ("bowl_tilt_deg", 1, ".1f")]
    else:
        head = "| seed | success | both touching at the exchange | after | carry error (mm) |"
        cols = [("both_held", None, ""), ("held_after", None, ""), ("carry_error", 1000, ".2f")]
    lines = [head + " sim s | wall s |", "|" + "---|" * (head.count("|") + 1)]
    for r in rows:
        cells = [str(r["seed"]), "yes" if r["success"] else "**no**"]
        for key, scale, fmt in cols:
            v = r.get(key)
            if v is None:
                cells.append(r.get("error", "–") if key == cols[0][0] else "–")
            elif scale is None:
                cells.append("+".join(v) or "none")
            else:
                cells.append(format(v * scale, fmt))
        cells += [format(r.get("sim_seconds", float("nan")), ".1f"), format(r["wall"], ".1f")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per skill")
    parser.add_argument("--skills", nargs="+", default=["toss", "handover"])
    args = parser.parse_args()
    print(
        f"machine: {_cpu()}, nproc {os.cpu_count()}; {time.strftime('%Y-%m-%d')}; "
        f"python {platform.python_version()}\n"
    )
    summary = []
    for skill in args.skills:
        rows = run(skill, args.seeds)
        wins = sum(r["success"] for r in rows)
        walls = [r["wall"] for r in rows]
        sims = [r["sim_seconds"] for r in rows if "sim_seconds" in r]
        print(f"## {skill}: {wins}/{len(rows)}\n\n{table(skill, rows)}\n")
        rtf = sum(sims) / sum(walls) if sims else float("nan")
        summary.append(
            f"| {skill} | {wins}/{len(rows)} | {statistics.median(walls):.1f} s | {rtf:.2f} |"
        )
        if skill == "toss":
            errs = [r["rim_error"] for r in rows if np.isfinite(r.get("rim_error", np.nan))]
            if errs:
                print(
                    f"rim crossing error: median {1000 * statistics.median(errs):.1f} mm, "
                    f"max {1000 * max(errs):.1f} mm\n"
                )
    print("| skill | successes | median wall time per seed | sim s / wall s |\n|---|---|---|---|")
    print("\n".join(summary))


if __name__ == "__main__":
    main()

"""The per-task coordination table of benchmarks/coordination.md: both movement tests, d0 and
distances in metres, path length, against an earlier table's rows and the paper's Table 1.

    python scripts/metrics.py DIR/*/ --json > after.json
    git show REV:benchmarks/coordination.md > before.md
    python benchmarks/coordination_table.py after.json --before before.md

`after.json` is `scripts/metrics.py --json` of the kept episodes (one directory per task);
`--before` is an earlier coordination.md whose per-task "**after**" rows (N, SMP, MRD, ARD,
STI, TL, SN, ON, PL under the jitter-free test at d0 = 0.50 m) become this table's "before".
Prints the markdown table, the mean of the tasks (a plain mean of the per-task rows, the
issue's measure), and each target of issue #57 item 4 with its measured value.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

PAPER = {"SMP": 92.81, "MRD": 29.59, "ARD": 55.77, "STI": 42.16, "TL": 361.0}
BEFORE_COLUMNS = ("N", "SMP", "MRD", "ARD", "STI", "TL", "SN", "ON", "PL")


def read_before(path: Path) -> dict[str, dict[str, float]]:
    """Per task, the "**after**" row of an earlier coordination.md (the row under the task's)."""
    rows: dict[str, dict[str, float]] = {}
    task = None
    for line in path.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 11:
            continue
        if re.fullmatch(r"[a-z_]+", cells[0]):
            task = cells[0]
        elif cells[0] == "" and cells[1] == "**after**" and task:
            values = {}
            for name, cell in zip(BEFORE_COLUMNS, cells[2:11], strict=False):
                try:
                    values[name] = float(cell)
                except ValueError:
                    values[name] = float("nan")
            rows[task] = values
            task = None
    return rows


def fmt(x: float, digits: int = 2) -> str:
    return "" if x is None or x != x else f"{x:.{digits}f}"


def table(
    after: dict, before: dict[str, dict[str, float]], counts: dict[str, int]
) -> tuple[str, dict]:
    head = (
        "| Task | | N | SMP % paper | SMP % jitter-free | d0 (m) | MRD % | MRD (m) | ARD % | "
        "ARD (m) | STI % paper | STI % jitter-free | TL | SN | ON | PL (rad) | PL after/before |"
    )
    lines = [head, "|" + "---|" * 2 + "---:|" * 15]
    tasks = sorted(after)
    for task in tasks:
        a, b = after[task], before.get(task, {})
        pl_ratio = a["PL"] / b["PL"] if b.get("PL") else float("nan")
        if b:
            lines.append(
                f"| {task} | before (d0 0.50 m) | {b['N']:.0f} | | {fmt(b['SMP'])} | 0.500 | "
                f"{fmt(b['MRD'])} | {fmt(b['MRD'] * 0.005, 3)} | {fmt(b['ARD'])} | "
                f"{fmt(b['ARD'] * 0.005, 3)} | | {fmt(b['STI'])} | {fmt(b['TL'], 1)} | "
                f"{fmt(b['SN'])} | {fmt(b['ON'])} | {fmt(b['PL'])} | |"
            )
        lines.append(
            f"| {task if not b else ''} | **after** | {counts.get(task, '')} | "
            f"{fmt(a['SMP (paper test)'])} | {fmt(a['SMP (jitter-free)'])} | "
            f"{fmt(a['d0 (m)'], 3)} | {fmt(a['MRD'])} | {fmt(a['MRD (m)'], 3)} | "
            f"{fmt(a['ARD'])} | {fmt(a['ARD (m)'], 3)} | **{fmt(a['STI (paper test)'])}** | "
            f"{fmt(a['STI (jitter-free)'])} | {fmt(a['TL'], 1)} | {fmt(a['SN'])} | "
            f"{fmt(a['ON'])} | {fmt(a['PL'])} | {fmt(pl_ratio, 3)} |"
        )
    mean = {k: sum(after[t][k] for t in tasks) / len(tasks) for k in after[tasks[0]]}
    lines.append(
        f"| **mean of the {len(tasks)} tasks** | **after** | {sum(counts.values())} | "
        f"{fmt(mean['SMP (paper test)'])} | {fmt(mean['SMP (jitter-free)'])} | "
        f"{fmt(mean['d0 (m)'], 3)} | {fmt(mean['MRD'])} | {fmt(mean['MRD (m)'], 3)} | "
        f"{fmt(mean['ARD'])} | {fmt(mean['ARD (m)'], 3)} | **{fmt(mean['STI (paper test)'])}** | "
        f"{fmt(mean['STI (jitter-free)'])} | {fmt(mean['TL'], 1)} | {fmt(mean['SN'])} | "
        f"{fmt(mean['ON'])} | {fmt(mean['PL'])} | |"
    )
    lines.append(
        f"| BiCoord (paper, Table 1) | | | {PAPER['SMP']} | | ~0.61 | {PAPER['MRD']} | | "
        f"{PAPER['ARD']} | | {PAPER['STI']} | | {PAPER['TL']:.0f} | 4.27 | 3.66 | | |"
    )
    return "\n".join(lines), mean


def targets(after: dict, before: dict, mean: dict, tl_before: float) -> str:
    """Issue #57 item 4's targets, each with its measured value and whether it is met."""
    rows = []

    def check(name: str, value: str, ok: bool) -> None:
        rows.append(f"| {name} | {value} | {'met' if ok else '**not met**'} |")

    check(
        "mean STI (paper test) >= 42.2",
        fmt(mean["STI (paper test)"]),
        mean["STI (paper test)"] >= 42.2,
    )
    check(
        "mean SMP (paper test) >= 92.8",
        fmt(mean["SMP (paper test)"]),
        mean["SMP (paper test)"] >= 92.8,
    )
    low = {t: a["STI (paper test)"] for t, a in after.items() if a["STI (paper test)"] < 15}
    check(
        "every task STI (paper test) >= 15",
        ", ".join(f"{t} {fmt(v)}" for t, v in low.items()) or "all",
        not low,
    )
    check(
        "mean STI (jitter-free) >= 33",
        fmt(mean["STI (jitter-free)"]),
        mean["STI (jitter-free)"] >= 33,
    )
    low = {
        t: a["SMP (jitter-free)"]
        for t, a in after.items()
        if t != "cook" and a["SMP (jitter-free)"] < 75
    }
    check(
        "every task but cook SMP (jitter-free) >= 75",
        ", ".join(f"{t} {fmt(v)}" for t, v in low.items()) or "all",
        not low,
    )
    check(f"mean TL <= {tl_before:.0f} + 5 %", fmt(mean["TL"], 1), mean["TL"] <= tl_before * 1.05)
    over = {
        t: a["PL"] / before[t]["PL"]
        for t, a in after.items()
        if before.get(t, {}).get("PL") and a["PL"] > 1.10 * before[t]["PL"]
    }
    check(
        "every task PL <= before + 10 %",
        ", ".join(f"{t} {fmt(v, 3)}" for t, v in over.items()) or "all",
        not over,
    )
    return "| target | measured | |\n|---|---|---|\n" + "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "after", type=Path, help="scripts/metrics.py --json output of the kept episodes"
    )
    ap.add_argument("--before", type=Path, required=True, help="an earlier coordination.md")
    ap.add_argument("--tl-before", type=float, default=343.0, help="the issue's TL baseline")
    ap.add_argument("--data", type=Path, help="the episodes' root (DIR/<task>/...): N per task")
    args = ap.parse_args()
    data = json.loads(args.after.read_text())
    after = data["per_task"]
    counts = {}
    if args.data is not None:
        counts = {t: len(list((args.data / t).rglob("*.hdf5"))) for t in after}
    before = read_before(args.before)
    text, mean = table(after, before, counts)
    print(text)
    print()
    print(targets(after, before, mean, args.tl_before))


if __name__ == "__main__":
    main()

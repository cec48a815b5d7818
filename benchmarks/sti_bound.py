"""How far overlapping phases alone can raise STI (issue #32).

    python benchmarks/sti_bound.py DATA/*/default/data/episode*.hdf5

STI = (1/L) sum_t m^l_t m^r_t max(0, 1 - r_t) (PRODUCT.md). Timing (which arm acts when) changes
only the m factors. With both arms acting at every step the same TCP paths would give
mean_t max(0, 1 - r_t): the most an expert could reach by keeping both arms busy along the
paths it already takes. Past that bound STI rises only if the arms work closer together
(lower r), not through more overlap. Per episode: length, SMP, STI, the bound, ARD (percent);
then per task the means, and their mean over the tasks.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bicoord_drake.data.readers import read_trajectory
from bicoord_drake.metrics import coordination_metrics


def row(path: Path) -> tuple[str, int, float, float, float, float]:
    """(task, L, SMP %, STI %, STI bound %, ARD %) of one episode file."""
    t = read_trajectory(path)
    m = coordination_metrics(t.left_xyz, t.right_xyz, t.left_gripper, t.right_gripper)
    closed = np.zeros(len(t.left_gripper))  # a closed gripper counts as acting at every step
    bound = coordination_metrics(t.left_xyz, t.right_xyz, closed, closed)
    return t.task, m.length, 100 * m.smp, 100 * m.sti, 100 * bound.sti, 100 * m.ard


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("episodes", nargs="+", type=Path, help="episode files (.hdf5)")
    rows = [row(p) for p in parser.parse_args().episodes]
    print("| task | L | SMP % | STI % | STI if both always act % | ARD % |")
    print("|---|---:|---:|---:|---:|---:|")
    for task, length, smp, sti, bound, ard in rows:
        print(f"| {task} | {length} | {smp:.1f} | {sti:.1f} | {bound:.1f} | {ard:.1f} |")
    a = np.array([r[2:] for r in rows])
    smp, sti, bound, ard = a.mean(axis=0)
    print(f"| mean of {len(rows)} | | {smp:.1f} | {sti:.1f} | {bound:.1f} | {ard:.1f} |")
    tasks = sorted({r[0] for r in rows})
    print("\n| task | N | SMP % | STI % | STI if both always act % | overlap can add | ARD % |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    per_task = []
    for task in tasks:
        of_task = np.array([r[2:] for r in rows if r[0] == task])
        per_task.append(of_task.mean(axis=0))
        smp, sti, bound, ard = per_task[-1]
        line = f"{smp:.1f} | {sti:.1f} | {bound:.1f} | {bound - sti:+.1f} | {ard:.1f}"
        print(f"| {task} | {len(of_task)} | {line} |")
    smp, sti, bound, ard = np.mean(per_task, axis=0)
    line = f"{smp:.1f} | {sti:.1f} | **{bound:.1f}** | {bound - sti:+.1f} | {ard:.1f}"
    print(f"| **mean of the {len(tasks)} tasks** | {len(rows)} | {line} |")


if __name__ == "__main__":
    main()

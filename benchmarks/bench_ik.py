"""Bimanual IK on reachable random target pairs: success rate and time per solve.

Targets are the TCP poses (FK) of random configurations within the joint limits that are
collision-free with 3 cm between the arms and 1 cm to everything else, with both TCPs above the
table ('cubes' scene, five cubes as obstacles). IK is seeded from home, never from the sampled
configuration, and must return any configuration meeting the targets (1 mm per axis, 0.01 rad)
and both clearances. Issue target: >= 95 % of 200 pairs, median <= 10 ms.

    python benchmarks/bench_ik.py                       # 200 pairs, 3 repetitions, both modes
    python benchmarks/bench_ik.py --pairs 200 --repeats 5 --mode closed_form
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bicoord_drake.models.scene import demo_scene  # noqa: E402
from bicoord_drake.planning.errors import PlanningError  # noqa: E402
from bicoord_drake.planning.ik import BimanualIK  # noqa: E402
from bicoord_drake.planning.model import PlanningModel  # noqa: E402
from tests.planning.conftest import reachable_targets  # noqa: E402

MODES = {"closed_form": True, "snopt_only": False}


def run_once(ik: BimanualIK, cases: list) -> dict:
    times, cpu, solved, methods, reasons = [], [], 0, {}, {}
    for targets in cases:
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            ik.solve(targets, clearance=0.03, env_clearance=0.01)
            solved += 1
            methods[ik.last_method] = methods.get(ik.last_method, 0) + 1
        except PlanningError as err:
            reasons[err.reason] = reasons.get(err.reason, 0) + 1
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    t = np.array(times) * 1e3
    return {
        "solved": solved,
        "median_ms": float(np.median(t)),
        "median_cpu_ms": float(np.median(cpu) * 1e3),
        "p90_ms": float(np.percentile(t, 90)),
        "max_ms": float(t.max()),
        "methods": methods,
        "failures": reasons,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--mode", choices=[*MODES, "both"], default="both")
    args = parser.parse_args()

    model = PlanningModel(demo_scene("cubes"))
    cases = reachable_targets(model, np.random.default_rng(args.seed), args.pairs)
    modes = list(MODES) if args.mode == "both" else [args.mode]
    for mode in modes:
        ik = BimanualIK(model, analytic=MODES[mode])
        runs = [run_once(ik, cases) for _ in range(args.repeats)]
        for k, r in enumerate(runs):
            print(
                f"{mode} run {k}: {r['solved']}/{args.pairs} solved, median {r['median_ms']:.2f}"
                f" ms (CPU {r['median_cpu_ms']:.2f} ms), p90 {r['p90_ms']:.2f} ms, "
                f"max {r['max_ms']:.1f} ms, "
                f"by {r['methods']}, failures {r['failures']}"
            )
        med = statistics.median(r["median_ms"] for r in runs)
        med_cpu = statistics.median(r["median_cpu_ms"] for r in runs)
        p90 = statistics.median(r["p90_ms"] for r in runs)
        print(
            f"{mode}: {runs[0]['solved']}/{args.pairs} solved "
            f"({100 * runs[0]['solved'] / args.pairs:.1f} %), median of medians {med:.2f} ms "
            f"(CPU {med_cpu:.2f} ms), median p90 {p90:.2f} ms"
        )


if __name__ == "__main__":
    main()

"""Swapping sides: collision-free joint paths with the arms crossing through each other's space.

Each case: a home-like start (home + N(0, 0.05 rad), collision-free) and an IK goal (seeded
from home, 3 cm clearance) whose TCP targets are FK of a random valid configuration with the
left TCP on the right half of the table and the right TCP on the left half ('cubes' scene).
``plan_path`` (1 cm clearance between the arms, 5 mm to the rest, 1 cm resolution) must return
waypoints whose straight segments are collision-free; every path is re-checked here one
configuration at a time at 1 cm resolution with zero padding. Issue target: >= 95 % of 100.

    python benchmarks/bench_motion.py                   # 100 swaps, 3 repetitions
    python benchmarks/bench_motion.py --swaps 100 --repeats 3 --refine 20
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
from bicoord_drake.planning.motion import plan_path  # noqa: E402
from tests.planning.conftest import swap_cases  # noqa: E402
from tests.planning.test_motion import independently_collision_free  # noqa: E402


def run_once(model: PlanningModel, cases: list, refine: bool = False) -> dict:
    times, cpu, solved, verified, waypoints, reasons = [], [], 0, 0, [], {}
    for start, goal in cases:
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            path = plan_path(model, start, goal, refine=refine)
        except PlanningError as err:
            reasons[err.reason] = reasons.get(err.reason, 0) + 1
            continue
        finally:
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        solved += 1
        waypoints.append(len(path))
        verified += independently_collision_free(model, path, 0.01)
    t = np.array(times) * 1e3
    return {
        "solved": solved,
        "verified": verified,
        "median_ms": float(np.median(t)),
        "median_cpu_ms": float(np.median(cpu) * 1e3),
        "p90_ms": float(np.percentile(t, 90)),
        "max_ms": float(t.max()),
        "median_waypoints": float(np.median(waypoints)) if waypoints else 0.0,
        "failures": reasons,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--swaps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--refine", type=int, default=0, help="also time refine=True on N cases")
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()

    model = PlanningModel(demo_scene("cubes"))
    t0 = time.perf_counter()
    cases = swap_cases(model, BimanualIK(model), np.random.default_rng(args.seed), args.swaps)
    print(f"{len(cases)} swap cases in {time.perf_counter() - t0:.1f} s")
    model.set_padding(0.0, 0.0)
    blocked = sum(not model.edge_free(s, g, 0.01) for s, g in cases)
    print(f"straight joint line collides in {blocked}/{len(cases)} cases")

    runs = [run_once(model, cases) for _ in range(args.repeats)]
    for k, r in enumerate(runs):
        print(
            f"run {k}: {r['solved']}/{len(cases)} solved, {r['verified']} verified at 1 cm, "
            f"median {r['median_ms']:.1f} ms (CPU {r['median_cpu_ms']:.1f} ms), "
            f"p90 {r['p90_ms']:.1f} ms, max {r['max_ms']:.0f} ms,"
            f" median waypoints {r['median_waypoints']:.0f}, failures {r['failures']}"
        )
    print(
        f"plan_path: median of medians {statistics.median(r['median_ms'] for r in runs):.1f} ms"
        f" (CPU {statistics.median(r['median_cpu_ms'] for r in runs):.1f} ms),"
        f" median p90 {statistics.median(r['p90_ms'] for r in runs):.1f} ms"
    )
    if args.refine:
        r = run_once(model, cases[: args.refine], refine=True)
        print(
            f"refine=True on {args.refine}: {r['solved']} solved, {r['verified']} verified, "
            f"median {r['median_ms']:.0f} ms (CPU {r['median_cpu_ms']:.0f} ms), "
            f"p90 {r['p90_ms']:.0f} ms, max {r['max_ms']:.0f} ms"
        )


if __name__ == "__main__":
    main()

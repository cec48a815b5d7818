"""Panda IK for one arm: the closed form swept over q7 vs the numerical (SNOPT) IK.

Targets: the right TCP poses (FK) of `--n` random right-arm configurations of ``franka_pair``
within the joint limits, collision-free with 1 cm to everything else and 3 cm from the left
arm (at home), the TCP above the table ('cubes' scene, five cubes as obstacles). Both solvers
start from home, never from the sampled configuration.

- analytic: ``panda_ik_near(model, "right", X_WT, home)``: every exact solution for q7 = home's
  q7 + each of the 15 default offsets (within +-1 rad), sorted by joint distance to home;
  again with q7 on a 0.2 rad grid over its whole range (29 values). Solved = at least one
  solution; "+ clearance" also times the collision checks down the sorted list until the
  first one with the planner's clearances (3 cm to the other arm, 5 mm to the rest:
  ``SkillContext``'s defaults; solved = such a solution exists).
- numerical: ``BimanualIK(model).solve_single("right", TcpTarget(X_WT), q_left_home,
  seed=home, clearance=0.03, env_clearance=0.005)`` - the call ``planning.skills.arm.solve_tcp``
  makes (1 mm / 0.01 rad tolerances, clearances, SNOPT with restarts, IPOPT fallback).

    python benchmarks/bench_panda_ik.py            # 200 targets, seed 2024
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bicoord_drake.models.scene import demo_scene  # noqa: E402
from bicoord_drake.planning.errors import PlanningError  # noqa: E402
from bicoord_drake.planning.ik import BimanualIK, TcpTarget  # noqa: E402
from bicoord_drake.planning.model import PlanningModel  # noqa: E402
from bicoord_drake.planning.motion import table_region  # noqa: E402
from bicoord_drake.planning.panda_ik import Q7_OFFSETS, panda_ik_near  # noqa: E402

SIDE = "right"
CLEARANCE, ENV_CLEARANCE = 0.03, 0.005
#: Offsets covering joint 7's whole range from any seed (those beyond the limits are skipped).
FULL_RANGE = tuple(np.round(np.arange(-5.8, 5.81, 0.2), 6))


def targets(model: PlanningModel, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """`n` right-arm configurations (left arm at home), collision-free with 3 cm / 1 cm, the
    TCP above the table."""
    sl = model.side_slice(SIDE)
    lo, hi = table_region()
    out = []
    with model.padded(0.03, 0.01):
        while len(out) < n:
            q = model.home.copy()
            q[sl] = rng.uniform(model.lower[sl], model.upper[sl])
            p = model.tcp_pose(q, SIDE).translation()
            if np.all(p >= lo) and np.all(p <= hi) and model.collision_free(q):
                out.append(q)
    return out


def summary(name: str, times: list[float], solved: int, n: int, dist: list[float]) -> str:
    t = np.array(times) * 1e3
    return (
        f"{name}: {solved}/{n} solved ({100 * solved / n:.1f} %), median {np.median(t):.2f} ms,"
        f" p90 {np.percentile(t, 90):.2f} ms, max {t.max():.1f} ms; joint distance of the answer"
        f" to home: median {np.median(dist):.3f} rad"
    )


def analytic(model: PlanningModel, X: list, home: np.ndarray, name: str, offsets) -> None:
    """panda_ik_near over `offsets`, then down its list to the first collision-free answer."""
    sl = model.side_slice(SIDE)
    ta, tc, da, dc, solved_a, solved_c, nsol = [], [], [], [], 0, 0, []
    for X_WT in X:
        t0 = time.perf_counter()
        sols = panda_ik_near(model, SIDE, X_WT, home, q7_offsets=offsets)
        t1 = time.perf_counter()
        free = None
        with model.padded(CLEARANCE, ENV_CLEARANCE):
            for q in sols:
                q_both = model.home.copy()
                q_both[sl] = q
                if model.collision_free(q_both):
                    free = q
                    break
        t2 = time.perf_counter()
        ta.append(t1 - t0)
        tc.append(t2 - t0)
        nsol.append(len(sols))
        if sols:
            solved_a += 1
            da.append(float(np.linalg.norm(sols[0] - home)))
        if free is not None:
            solved_c += 1
            dc.append(float(np.linalg.norm(free - home)))
    print(summary(name, ta, solved_a, len(X), da))
    print(f"  solutions per target: median {np.median(nsol):.0f}, min {min(nsol)}")
    print(summary("  + clearance check", tc, solved_c, len(X), dc))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=200)
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()

    t_start = time.perf_counter()
    model = PlanningModel(demo_scene("cubes"), "franka_pair")
    sl = model.side_slice(SIDE)
    home = model.home[sl]
    cases = targets(model, np.random.default_rng(args.seed), args.n)
    X = [model.tcp_pose(q, SIDE) for q in cases]
    print(f"{len(cases)} targets in {time.perf_counter() - t_start:.1f} s")

    for name, offsets in (
        ("analytic near home's q7 (15 values, +-1 rad)", Q7_OFFSETS),
        ("analytic over q7's whole range (0.2 rad grid)", FULL_RANGE),
    ):
        analytic(model, X, home, name, offsets)

    # numerical, as solve_tcp calls it
    ik = BimanualIK(model)
    tn, dn, solved_n, failures, errors = [], [], 0, {}, []
    q_left = model.home[model.side_slice("left")]
    for X_WT in X:
        target = TcpTarget(X_WT)
        t0 = time.perf_counter()
        try:
            q = ik.solve_single(
                SIDE,
                target,
                q_left,
                seed=model.home.copy(),
                clearance=CLEARANCE,
                env_clearance=ENV_CLEARANCE,
            )
            solved_n += 1
            dn.append(float(np.linalg.norm(q[sl] - home)))
            errors.append(target.error(model.tcp_pose(q, SIDE)))
        except PlanningError as err:
            failures[err.reason] = failures.get(err.reason, 0) + 1
        tn.append(time.perf_counter() - t0)
    print(summary("numerical (BimanualIK.solve_single)", tn, solved_n, len(X), dn or [np.nan]))
    if errors:
        e = np.array(errors)
        print(
            f"  failures {failures}; pose error of the answers: max {e[:, 0].max() * 1e3:.3f} mm,"
            f" {e[:, 1].max():.4f} rad"
        )
    print(f"total {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()

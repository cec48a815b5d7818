"""Speed of the ruckig timing layer: paths, rendezvous, throws, and the grasp generator.

Prints, per case, the median wall time per call over repetitions (each repetition times
`--calls` calls on seeded random inputs) plus the min and max, and the mean number of samples
a call produces at 15 Hz.

    python benchmarks/bench_timing.py                  # 7 repetitions of 50 calls
    python benchmarks/bench_timing.py --repeats 11 --calls 100
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from ruckig import DurationDiscretization, InputParameter, Ruckig, Trajectory

from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import demo_scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import arm_base, grasp_candidates
from bicoord_drake.planning.throwing import throw_release
from bicoord_drake.planning.timing import JointLimits, rendezvous, time_path


def random_paths(limits: JointLimits, k: int, count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    centre, half = (limits.lower + limits.upper) / 2, (limits.upper - limits.lower) / 2
    return [centre + rng.uniform(-0.6, 0.6, size=(k, limits.n)) * half for _ in range(count)]


def make_cases(calls: int) -> dict[str, tuple[Callable[[int], object], int]]:
    emb = get_embodiment("aloha_viperx")
    limits = JointLimits.from_embodiment(emb)
    arm = limits.arm("left")
    cases: dict[str, tuple[Callable[[int], object], int]] = {}

    def ruckig_1dof(i: int) -> object:
        inp = InputParameter(1)
        inp.current_position, inp.target_position = [0.0], [1.0]
        inp.max_velocity, inp.max_acceleration = [1.0 + 0.01 * i], [3.0]
        inp.max_jerk = [30.0]
        inp.duration_discretization = DurationDiscretization.Discrete
        traj = Trajectory(1)
        Ruckig(1, 1 / 15).calculate(inp, traj)
        return traj

    cases["raw ruckig 1-DoF calculate (reference)"] = (ruckig_1dof, 0)
    for k in (2, 5, 10):
        paths = random_paths(limits, k, calls, seed=k)
        cases[f"time_path 12-DoF, {k} waypoints"] = (lambda i, p=paths: time_path(p[i], limits), 1)
    lp = random_paths(arm, 3, calls, seed=20)
    rp = random_paths(arm, 3, calls, seed=21)
    cases["rendezvous, 3 + 3 waypoints"] = (lambda i: rendezvous(lp[i], rp[i], limits), 1)
    paths = random_paths(limits, 5, calls, seed=5)
    timed = [time_path(p, limits) for p in paths]
    cases["stretched (+20 %), 5 waypoints"] = (
        lambda i: timed[i].stretched(int(timed[i].num_steps * 1.2)),
        1,
    )
    rng = np.random.default_rng(30)
    home = np.array(emb.home)
    throws = []
    while len(throws) < calls:
        q_rel = home + rng.uniform(-0.3, 0.3, 6) * [1, 0.5, 0.3, 1, 0.5, 1]
        v = rng.uniform(-1.2, 1.2, 6) * [1, 1, 0.5, 0.5, 1, 0.5]
        try:
            throw_release(home, q_rel, arm, qd_release=v)
        except PlanningError:
            continue
        throws.append((q_rel, v))
    cases["throw_release 6-DoF"] = (
        lambda i: throw_release(home, throws[i][0], arm, qd_release=throws[i][1]),
        2,
    )
    scene = demo_scene("demo")
    base = arm_base(emb, "left")
    objs = [scene.objects[i % len(scene.objects)] for i in range(calls)]
    cases["grasp_candidates (demo scene objects)"] = (
        lambda i: grasp_candidates(objs[i], emb.arm.gripper, base=base),
        0,
    )
    return cases


def samples_of(result: object, kind: int) -> int:
    if kind == 1:
        return len(result.q)  # type: ignore[attr-defined]
    if kind == 2:
        return len(result.trajectory.q)  # type: ignore[attr-defined]
    return 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="repetitions (median reported)")
    parser.add_argument("--calls", type=int, default=50, help="calls per repetition")
    args = parser.parse_args()
    cases = make_cases(args.calls)
    print(f"{'case':<42} {'median':>10} {'min':>10} {'max':>10} {'samples':>8}")
    for name, (fn, kind) in cases.items():
        per_call, samples = [], []
        for _ in range(args.repeats):
            start = time.perf_counter()
            results = [fn(i) for i in range(args.calls)]
            per_call.append((time.perf_counter() - start) / args.calls)
            samples = [samples_of(r, kind) for r in results]
        med, lo, hi = statistics.median(per_call), min(per_call), max(per_call)
        mean_samples = f"{np.mean(samples):.0f}" if kind else "-"
        print(f"{name:<42} {_fmt(med):>10} {_fmt(lo):>10} {_fmt(hi):>10} {mean_samples:>8}")


def _fmt(seconds: float) -> str:
    return f"{seconds * 1e6:.0f} us" if seconds < 1e-3 else f"{seconds * 1e3:.2f} ms"


if __name__ == "__main__":
    main()

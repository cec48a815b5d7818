"""Throughput of ``coordination_metrics``: 1000 trajectories of 400 frames, frames per second.

Target (issue): >= 1,000,000 frames/s. Prints the median over repetitions plus the spread.

    python benchmarks/bench_metrics.py                 # 7 repetitions
    python benchmarks/bench_metrics.py --repeats 11 --trajectories 2000 --frames 400
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from bicoord_drake.metrics import coordination_metrics, smp_curve


def make_trajectories(n: int, frames: int, seed: int = 0) -> list[tuple[np.ndarray, ...]]:
    """Random-walk TCPs with pauses and gripper open/close phases, like demonstrations."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        moving = rng.uniform(size=(2, frames, 1)) < 0.7
        steps = rng.normal(scale=0.005, size=(2, frames, 3)) * moving
        left = np.cumsum(steps[0], axis=0) + [-0.3, 0.5, 0.9]
        right = np.cumsum(steps[1], axis=0) + [0.3, 0.5, 0.9]
        grip = (
            np.sin(np.linspace(0, rng.uniform(3, 12), frames))[None]
            > rng.uniform(-0.5, 0.5, size=(2, 1))
        ).astype(np.float64)
        out.append((left, right, grip[0], grip[1]))
    return out


def run_once(trajectories: list[tuple[np.ndarray, ...]], fn) -> float:
    start = time.perf_counter()
    for signals in trajectories:
        fn(*signals)
    elapsed = time.perf_counter() - start
    return sum(len(s[0]) for s in trajectories) / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trajectories", type=int, default=1000)
    parser.add_argument("--frames", type=int, default=400)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()

    trajectories = make_trajectories(args.trajectories, args.frames)
    thresholds = 1.0 - np.linspace(0.0, 1.0, 201)
    cases = {
        "coordination_metrics": coordination_metrics,
        "smp_curve (201 thresholds)": lambda *s: smp_curve(*s, thresholds),
    }
    print(f"{args.trajectories} trajectories x {args.frames} frames, {args.repeats} repetitions")
    for name, fn in cases.items():
        run_once(trajectories[:50], fn)  # warm-up
        rates = [run_once(trajectories, fn) for _ in range(args.repeats)]
        print(
            f"{name}: median {statistics.median(rates):,.0f} frames/s "
            f"(min {min(rates):,.0f}, max {max(rates):,.0f})"
        )


if __name__ == "__main__":
    main()

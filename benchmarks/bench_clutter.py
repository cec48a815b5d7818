"""What randomized clutter costs the physics: CPU time of the plant at rest, plain vs randomized.

    python benchmarks/bench_clutter.py [--tasks all] [--seeds 3] [--steps 30] [--repeats 3] \\
        [--out benchmarks/bench_clutter.md]

For every task and seed: the CPU seconds of `--steps` control steps (15 Hz) with both arms
holding home, on the plain scene and on its randomized scene (same task objects plus 2-8
distractors), without cameras; plain and randomized alternate, `--repeats` times, and the median
of each is kept. The ratio is what clutter adds to the physics of an episode (at rest: the
distractors' contacts with the table; motion costs are the same in both).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from datetime import UTC, datetime
from pathlib import Path

from bicoord_drake.config import StationConfig
from bicoord_drake.models.scene import Scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.tasks import get_task, list_tasks


def rest_cpu_seconds(scene: Scene, steps: int) -> float:
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    home = sim.station.embodiment.home_action()
    t0 = time.process_time()
    for _ in range(steps):
        sim.step(home)
    return time.process_time() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", default="all", help="'all' or comma-separated task names")
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0..N-1 per task")
    parser.add_argument("--steps", type=int, default=30, help="control steps per measurement")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path(__file__).with_name("bench_clutter.md"))
    args = parser.parse_args()
    tasks = list_tasks() if args.tasks == "all" else args.tasks.split(",")
    rows = []
    for task in tasks:
        for seed in range(args.seeds):
            plain = get_task(task).sample_scene(seed)
            randomized = plain.randomized("seen")
            times: dict[str, list[float]] = {"plain": [], "randomized": []}
            for _ in range(args.repeats):
                times["plain"].append(rest_cpu_seconds(plain, args.steps))
                times["randomized"].append(rest_cpu_seconds(randomized, args.steps))
            p, r = (statistics.median(times[k]) for k in ("plain", "randomized"))
            rows.append((task, seed, len(randomized.distractors), p, r))
            print(
                f"{task} seed {seed}: {len(randomized.distractors)} distractors, "
                f"plain {p:.2f} s, randomized {r:.2f} s, x{r / p:.2f}",
                flush=True,
            )
    sim_s = args.steps / StationConfig().control_rate
    lines = [
        "# bench_clutter: physics cost of randomized clutter",
        "",
        f"`python benchmarks/bench_clutter.py --seeds {args.seeds} --steps {args.steps} "
        f"--repeats {args.repeats}`: CPU seconds for {sim_s:.1f} simulated s with both arms at "
        "home, plain scene vs the same scene randomized (2-8 distractors), no cameras; median of "
        f"{args.repeats} alternating runs.",
        "",
        f"Machine: {platform.machine()}, nproc = {os.cpu_count()}, Python "
        f"{platform.python_version()}; {datetime.now(UTC):%Y-%m-%d %H:%M} UTC.",
        "",
        "| task | seed | distractors | plain CPU s | randomized CPU s | ratio |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    lines += [f"| {t} | {s} | {n} | {p:.2f} | {r:.2f} | {r / p:.2f} |" for t, s, n, p, r in rows]
    ratios = [r / p for *_, p, r in rows]
    lines += ["", f"Median ratio over all rows: **{statistics.median(ratios):.2f}**.", ""]
    tmp = args.out.with_suffix(".md.tmp")
    tmp.write_text("\n".join(lines))
    os.replace(tmp, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python
"""Three-camera render time per frame against Mesa's rasterizer thread count (LP_NUM_THREADS).

    python benchmarks/bench_render_threads.py [--tasks balance_roller,match_blocks_with_signs]
        [--threads 0,1,2] [--frames 45] [--repeats 3] [--out benchmarks/bench_render_threads.md]

Each measurement is a fresh process (Mesa reads LP_NUM_THREADS once, when it starts): it
assembles the task's seed-0 scene, builds the kept-episode renderer (`FrameRenderer`, three
320x240 RGB cameras), renders one warm-up frame, then `--frames` frames with both arms moving
between frames, and prints the wall milliseconds per frame (all three cameras). Settings are
interleaved within each repeat, so a ratio compares runs made under the same load; the table
gives the median over repeats. ``LP_NUM_THREADS=0`` makes llvmpipe rasterize in the calling
thread; ``1`` hands every frame to one rasterizer thread.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

WORKER = """
import sys, time
import numpy as np
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup, assemble
from bicoord_drake.sim.frame_renderer import FrameRenderer

task, frames = sys.argv[1], int(sys.argv[2])
setup = EpisodeSetup(task=task, seed=0, station=StationConfig())
episode = assemble(setup.without_cameras())
plant = episode.sim.station.plant
x0 = plant.GetPositionsAndVelocities(episode.sim.plant_context).copy()
renderer = FrameRenderer(episode.scene, setup.station)
renderer.render(x0)

def moving(n):
    for k in range(n):
        x = x0.copy()
        x[:14] += 0.02 * np.sin(k / 5 + np.arange(14))
        yield x

t0 = time.perf_counter()
for _ in renderer.render_all(moving(frames)):
    pass
print(1000 * (time.perf_counter() - t0) / frames)
"""


def measure(task: str, threads: str, frames: int) -> float:
    env = {**os.environ, "LP_NUM_THREADS": threads, "OMP_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-c", WORKER, task, str(frames)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default="balance_roller,match_blocks_with_signs")
    parser.add_argument("--threads", default="0,1,2", help="LP_NUM_THREADS values to compare")
    parser.add_argument("--frames", type=int, default=45)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None, help="append the table to this file")
    args = parser.parse_args()
    tasks, settings = args.tasks.split(","), args.threads.split(",")
    times: dict[tuple[str, str], list[float]] = {(t, s): [] for t in tasks for s in settings}
    for repeat in range(args.repeats):
        for task in tasks:
            for threads in settings:
                ms = measure(task, threads, args.frames)
                times[task, threads].append(ms)
                print(f"repeat {repeat} {task} LP_NUM_THREADS={threads}: {ms:.1f} ms", flush=True)
    base = settings[0]
    lines = [
        f"Measured {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC on "
        f"{platform.machine()}, nproc = {os.cpu_count()}, Python {platform.python_version()}; "
        f"{args.frames} frames per run, median of {args.repeats} interleaved runs; 1-minute "
        f"load at the end {os.getloadavg()[0]:.1f}.",
        "",
        "| task | LP_NUM_THREADS | ms per frame (3 cameras) | runs | vs " + base + " |",
        "|---|---|---:|---|---:|",
    ]
    for task in tasks:
        ref = statistics.median(times[task, base])
        for threads in settings:
            runs = times[task, threads]
            med = statistics.median(runs)
            spread = ", ".join(f"{r:.1f}" for r in runs)
            lines.append(f"| {task} | {threads} | **{med:.1f}** | {spread} | {med / ref:.2f}x |")
    table = "\n".join(lines) + "\n"
    print(table)
    if args.out is not None:
        with args.out.open("a") as f:
            f.write("\n" + table)


if __name__ == "__main__":
    main()

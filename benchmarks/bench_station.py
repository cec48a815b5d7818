#!/usr/bin/env python
"""Station performance: real-time factor and three-camera render time.

    python benchmarks/bench_station.py [--repeats 3] [--seconds 4]

Real-time factor: both arms sweep sinusoidally every control step while 5 free cubes rest on the
table (hydroelastic, SAP), no rendering; simulated seconds per wall second, for several time
steps. Render: the three 320x240 RGB cameras, arms moving between frames, ms per frame set.
Prints a Markdown table; medians over --repeats runs.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time

import numpy as np

from bicoord_drake.config import StationConfig
from bicoord_drake.models.scene import demo_scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.snapshot import pose_action
from bicoord_drake.sim.station import build_station


def sweep(config: StationConfig, k: int) -> np.ndarray:
    a = pose_action(config, "reach")
    phase = 2 * np.pi * k / config.control_rate * 0.5  # 0.5 Hz
    a[[0, 7]] += 0.3 * np.sin(phase) * np.array([1, -1])
    a[[1, 8]] += 0.2 * np.sin(phase)
    a[[2, 9]] -= 0.2 * np.sin(phase)
    return a


def real_time_factor(time_step: float, seconds: float) -> float:
    config = StationConfig(time_step=time_step, render=False)
    sim = Simulation(build_station(demo_scene("cubes"), config))
    steps = int(seconds * config.control_rate)
    start = time.perf_counter()
    for k in range(steps):
        sim.step(sweep(config, k))
    return sim.time / (time.perf_counter() - start)


def render_ms(frames: int) -> float:
    config = StationConfig()
    sim = Simulation(build_station(demo_scene("cubes"), config))
    sim.step(sweep(config, 0))
    sim.images()  # first frame: lazy renderer setup, not counted
    total = 0.0
    for k in range(1, frames + 1):
        sim.step(sweep(config, k))
        start = time.perf_counter()
        sim.images()
        total += time.perf_counter() - start
    return 1000 * total / frames


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args()
    cpu = next(
        (
            line.split(":", 1)[1].strip()
            for line in open("/proc/cpuinfo")
            if line.startswith("model name")
        ),
        platform.processor(),
    )
    print(
        f"machine: {cpu}, {__import__('os').cpu_count()} cores; "
        f"{time.strftime('%Y-%m-%d')}; medians of {args.repeats} runs\n"
    )
    print("| time step | real-time factor (5 free cubes, arms sweeping) |\n|---|---|")
    for dt in (0.002, 1 / 300, 0.005):
        rtf = statistics.median(real_time_factor(dt, args.seconds) for _ in range(args.repeats))
        default = " (default)" if dt == StationConfig().time_step else ""
        print(f"| {dt * 1000:.2f} ms{default} | {rtf:.2f} |")
    ms = statistics.median(render_ms(30) for _ in range(args.repeats))
    print(f"\nthree 320x240 RGB frames (VTK, no shadows): {ms:.1f} ms")


if __name__ == "__main__":
    main()

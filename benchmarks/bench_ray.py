"""Speed-up of generation with 2 Ray workers against 1, and bytes per episode through Ray.

    python benchmarks/bench_ray.py [--task jigsaw] [--episodes 2] [--repeats 3] [--bytes]

One local Ray instance (``ray.init(num_cpus=2)``) serves every run. Each repeat generates the
same seeds (``--seed`` .. ``--seed + episodes - 1``, no rendering) once with ``--workers 1`` and
once with ``--workers 2``, interleaved (the order alternates between repeats) so both see the
same background load; the 1-minute load average is recorded before every run. The speed-up is
the ratio of the median wall times. ``--bytes`` adds one rendered episode (default 320x240 RGB,
head-camera MP4) and reports the size of what a worker returns to the driver: the episode's
HDF5, MP4 and JSON files.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import ray

from bicoord_drake.runner.generate import GenerateConfig, generate


def timed_run(task: str, episodes: int, seed: int, workers: int, out: Path) -> dict:
    shutil.rmtree(out, ignore_errors=True)
    config = GenerateConfig(
        task=task,
        episodes=episodes,
        seed=seed,
        max_tries=episodes,
        render=False,
        out=str(out),
        backend="ray",
        workers=workers,
    )
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    summary = generate(config)
    wall = time.perf_counter() - t0
    return {"workers": workers, "wall": round(wall, 1), "kept": summary.kept, "load": load}


def episode_bytes(task: str, seed: int, out: Path) -> dict:
    shutil.rmtree(out, ignore_errors=True)
    config = GenerateConfig(
        task=task, episodes=1, seed=seed, max_tries=1, out=str(out), backend="ray", workers=1
    )
    generate(config)
    root = out / task / "default"
    sizes = {
        "hdf5": (root / "data" / "episode0.hdf5").stat().st_size,
        "mp4": (root / "video" / "episode0.mp4").stat().st_size,
        "json": (root / "instructions" / "episode0.json").stat().st_size
        + (root / "stages" / "episode0.json").stat().st_size,
    }
    frames = json.loads((root / "manifest.json").read_text())["episodes"][0]["frames"]
    return {**sizes, "total": sum(sizes.values()), "frames": frames}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="jigsaw")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--bytes", action="store_true", help="also measure a rendered episode")
    args = parser.parse_args()

    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    work = Path(tempfile.mkdtemp(prefix="bench_ray_"))
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"ray {ray.__version__}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    runs = []
    for r in range(args.repeats):
        for workers in (1, 2) if r % 2 == 0 else (2, 1):
            run = timed_run(args.task, args.episodes, args.seed, workers, work / f"w{workers}")
            runs.append(run)
            print(f"repeat {r}: {run}", flush=True)
    median = {w: statistics.median(x["wall"] for x in runs if x["workers"] == w) for w in (1, 2)}
    print(
        f"median wall: 1 worker {median[1]:.1f} s, 2 workers {median[2]:.1f} s, "
        f"speed-up {median[1] / median[2]:.2f}x; "
        f"load average {min(x['load'] for x in runs):.1f}-{max(x['load'] for x in runs):.1f}"
    )
    if args.bytes:
        print("bytes per rendered episode:", episode_bytes(args.task, args.seed, work / "bytes"))
    shutil.rmtree(work, ignore_errors=True)
    ray.shutdown()


if __name__ == "__main__":
    main()

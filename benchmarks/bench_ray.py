"""Speed-up of generation with 2 Ray workers against 1, and bytes per episode through Ray.

    python benchmarks/bench_ray.py [--task jigsaw] [--episodes 2] [--repeats 3] [--bytes]

One local Ray instance (``ray.init(num_cpus=2)``) serves every run. Each repeat generates the
same seeds (``--seed`` .. ``--seed + episodes - 1``, no rendering) once with ``--workers 1`` and
once with ``--workers 2``, interleaved (the order alternates between repeats) so both see the
same background load; the 1-minute load average is recorded before every run. The speed-up is
the ratio of the median wall times. ``--bytes`` adds one rendered episode (default settings:
three 320x240 RGB cameras, head-camera MP4) run as a Ray job, and reports the size of what the
worker returns to the driver: the episode's files, and the whole pickled result with the files
(default) and with paths only (``--shared-fs``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pickle
import platform
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import ray

from bicoord_drake.runner.backends import RayBackend
from bicoord_drake.runner.generate import GenerateConfig, generate, produce_episode


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


def episode_bytes(task: str, seed: int, staging: Path) -> dict:
    """Run one rendered episode as a Ray job (default settings) and size what comes back."""
    config = GenerateConfig(task=task, episodes=1, seed=seed, backend="ray", workers=1)
    backend = RayBackend(workers=1)
    outcome = backend.result(backend.wait([backend.submit(produce_episode, config, seed, None)]))
    if not outcome.success:
        raise RuntimeError(f"seed {seed} failed: {outcome.reason}")
    sizes = {kind: len(data) for kind, data in outcome.files.items()}
    paths = {kind: str(staging / f"seed{seed}" / kind / "episode0") for kind in sizes}
    shared = dataclasses.replace(outcome, files=None, staged=paths)
    return {
        **sizes,
        "frames": outcome.frames,
        "pickled (default)": len(pickle.dumps(outcome)),
        "pickled (--shared-fs)": len(pickle.dumps(shared)),
    }


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
    if runs:
        median = {
            w: statistics.median(x["wall"] for x in runs if x["workers"] == w) for w in (1, 2)
        }
        loads = [x["load"] for x in runs]
        print(
            f"median wall: 1 worker {median[1]:.1f} s, 2 workers {median[2]:.1f} s, "
            f"speed-up {median[1] / median[2]:.2f}x; load average {min(loads):.1f}-{max(loads):.1f}"
        )
    if args.bytes:
        staging = Path("/shared/out") / args.task / "default" / ".staging"
        print("bytes per rendered episode:", episode_bytes(args.task, args.seed, staging))
    shutil.rmtree(work, ignore_errors=True)
    ray.shutdown()


if __name__ == "__main__":
    main()

"""Randomized appearance: contact sheets to look at, and what textures, lights and shadows cost.

    python benchmarks/bench_appearance.py [--tasks all] [--seeds 16] [--repeats 20] \\
        [--out benchmarks/appearance]

For every task: ``<out>/<task>.png``, the first head-camera frame of seeds 0..N-1 randomized
(appearance, table height, clutter; seen split, the last row from the unseen split), 4 per row,
as a 256-colour PNG (a third of the size of full colour; fine for looking at layouts).
Then (unless ``--sheets-only``), on one scene, the median wall time of one frame of the three
320x240 cameras (arms moving between frames) for: the plain look, randomized, and randomized
with shadows (``CameraConfig.shadows``).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from PIL import Image

from bicoord_drake.config import CameraConfig, StationConfig
from bicoord_drake.models.scene import Scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.tasks import get_task, list_tasks


def contact_sheet(task: str, seeds: int, out: Path) -> Path:
    frames = []
    for seed in range(seeds):
        split = "unseen" if seed >= seeds - 4 else "seen"
        scene = get_task(task).sample_scene(seed).randomized(split)
        frames.append(Simulation(build_station(scene, StationConfig())).images()["head_camera"])
    rows = [np.concatenate(frames[i : i + 4], axis=1) for i in range(0, len(frames), 4)]
    path = out / f"{task}.png"
    sheet = Image.fromarray(np.concatenate(rows, axis=0))
    sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    return path


def frame_ms(scene: Scene, config: StationConfig, repeats: int) -> float:
    sim = Simulation(build_station(scene, config))
    home = sim.station.embodiment.home_action()
    sim.images()  # the renderer's lazy setup
    times = []
    for k in range(repeats):
        action = home.copy()
        action[0] += 0.02 * (k % 5)
        sim.step(action)
        t0 = time.perf_counter()
        sim.images()
        times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", default="all")
    parser.add_argument("--seeds", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/appearance"))
    parser.add_argument(
        "--sheets-only", action="store_true", help="contact sheets only, no render-cost timing"
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    tasks = list_tasks() if args.tasks == "all" else args.tasks.split(",")
    for task in tasks:
        print(contact_sheet(task, args.seeds, args.out), flush=True)
    if args.sheets_only:
        return

    scene = get_task(tasks[0]).sample_scene(0)
    shadows = StationConfig(cameras=CameraConfig(shadows=True))
    cases = {
        "plain": (scene, StationConfig()),
        "randomized": (scene.randomized(), StationConfig()),
        "randomized + shadows": (scene.randomized(), shadows),
    }
    rows = []
    for _ in range(3):  # interleaved rounds: the cases see the same background load
        for name, (s, config) in cases.items():
            rows.append((name, frame_ms(s, config, args.repeats), os.getloadavg()[0]))
    lines = [
        f"Measured {datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {platform.machine()}, "
        f"nproc = {os.cpu_count()}, scene: {tasks[0]} seed 0; three 320x240 RGB cameras, "
        f"median of {args.repeats} frames per round, 3 interleaved rounds.",
        "",
        "| look | ms per 3-camera frame (median of rounds) | rounds | load |",
        "|---|---|---|---|",
    ]
    for name in cases:
        ms = [m for n, m, _ in rows if n == name]
        loads = [lo for n, _, lo in rows if n == name]
        lines.append(
            f"| {name} | **{statistics.median(ms):.1f}** | "
            f"{', '.join(f'{m:.1f}' for m in ms)} | {max(loads):.1f} |"
        )
    text = "\n".join(lines) + "\n"
    (args.out / "render_cost.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()

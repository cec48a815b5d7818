"""Contact sheet of every task's first head-camera frame on one robot: a look at the layouts.

    python benchmarks/first_frames.py [--embodiment franka_pair] [--seed 0] [--tasks all] \\
        [--columns 6] [--out benchmarks/first_frames_franka_pair.png]

Each tile is the plain scene of `--seed` as the episode starts (arms at home, nothing stepped),
captioned with the task's name; tiles run left to right in the registry's order. Written as a
256-colour PNG (a third of the size of full colour; enough to judge where arms and objects are)
through a temporary file, so a partial sheet never appears under the final name.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image
from tqdm import tqdm

from bicoord_drake.config import StationConfig
from bicoord_drake.models.robots import EMBODIMENTS
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.snapshot import contact_sheet
from bicoord_drake.sim.station import build_station
from bicoord_drake.tasks import get_task, list_tasks


def first_frame(task: str, seed: int, embodiment: str) -> np.ndarray:
    """The head camera's image of `task`'s plain scene of `seed` before the first step."""
    scene = get_task(task).sample_scene(seed)
    station = build_station(scene, StationConfig(embodiment=embodiment))
    return Simulation(station).images()["head_camera"]


def sheet(tasks: list[str], seed: int, embodiment: str, columns: int) -> Image.Image:
    """`columns` captioned tiles per row; a short last row is padded with white tiles."""
    tiles = [(t, first_frame(t, seed, embodiment)) for t in tqdm(tasks, desc=embodiment)]
    blank = np.full_like(tiles[0][1], 255)
    while len(tiles) % columns:
        tiles.append(("", blank))
    rows = [contact_sheet(tiles[i : i + columns]) for i in range(0, len(tiles), columns)]
    out = Image.new("RGB", (rows[0].width, sum(r.height for r in rows)), "white")
    y = 0
    for row in rows:
        out.paste(row, (0, y))
        y += row.height
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--embodiment", default="franka_pair", choices=sorted(EMBODIMENTS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tasks", default="all", help="comma-separated task names, or all")
    parser.add_argument("--columns", type=int, default=6)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    tasks = (
        list_tasks() if args.tasks == "all" else [get_task(t).name for t in args.tasks.split(",")]
    )
    out = args.out or Path(f"benchmarks/first_frames_{args.embodiment}.png")
    image = sheet(tasks, args.seed, args.embodiment, args.columns)
    fd, tmp = tempfile.mkstemp(dir=out.parent, suffix=".png.tmp")
    os.close(fd)
    try:
        image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(tmp, format="PNG")
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    print(out)


if __name__ == "__main__":
    main()

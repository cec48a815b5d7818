"""Free flight of the rolls in saved cook episodes (issue #7 acceptance).

For each roll: the frames before it first lies in the skillet at which it moves faster than
0.3 m/s more than 6 cm from both grippers (``bicoord_drake.tasks.cook.free_flight_frames``),
the nearest TCP and the top speed over those frames.

    python benchmarks/cook_free_flight.py data/cook/default
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("root", type=Path, help="a cook dataset (<out>/cook/<config>)")
    args = parser.parse_args(argv)

    from bicoord_drake.data.episode import read_episode
    from bicoord_drake.tasks.cook import ROLLS, free_flight_frames

    files = sorted((args.root / "data").glob("episode*.hdf5"), key=lambda p: int(p.stem[7:]))
    if not files:
        print(f"error: no episodes under {args.root / 'data'}", file=sys.stderr)
        return 2
    counts = []
    for path in files:
        ep = read_episode(path, images=False)
        tcps = np.stack([ep.left_endpose[:, :3], ep.right_endpose[:, :3]], axis=1)
        cells = []
        for roll in ROLLS:
            frames = free_flight_frames(ep.objects, tcps, roll, fps=ep.fps)
            counts.append(len(frames))
            if len(frames) == 0:
                cells.append(f"{roll}: none")
                continue
            p = ep.objects[roll][:, :3]
            speed = np.linalg.norm(np.diff(p, axis=0), axis=1) * ep.fps
            near = np.min(np.linalg.norm(tcps[frames] - p[frames, None, :], axis=2), axis=1)
            cells.append(
                f"{roll}: {len(frames)} frames, nearest TCP {near.min() * 100:.1f} cm, "
                f"up to {speed[frames - 1].max():.2f} m/s"
            )
        print(f"{path.name} (seed {ep.seed}): " + "; ".join(cells))
    counts = np.array(counts)
    print(
        f"{len(files)} episodes: {np.sum(counts >= 1)}/{len(counts)} rolls in free flight "
        f"(frames per roll {counts.min()}-{counts.max()}, median {np.median(counts):g})"
    )
    return 0 if np.all(counts >= 1) else 1


if __name__ == "__main__":
    sys.exit(main())

"""Time the LeRobot export (v3.0 and v2.1) and the dataset report on a generated dataset.

    python benchmarks/bench_export.py DATA_DIR [--runs 3]

Prints the median wall time of each over --runs runs, with frames per second of export.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from bicoord_drake.data.export import export_lerobot
from bicoord_drake.report import write_report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("data")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    for name in ("v3.0", "v2.1", "report"):
        times, frames = [], 0
        for run in range(args.runs):
            with tempfile.TemporaryDirectory() as tmp:
                start = time.perf_counter()
                if name == "report":
                    write_report([args.data], Path(tmp) / "report.html")
                else:
                    frames = export_lerobot(
                        [args.data], Path(tmp) / f"out{run}", codebase=name
                    ).frames
                times.append(time.perf_counter() - start)
        median = statistics.median(times)
        rate = f", {frames / median:.1f} frames/s" if frames else ""
        print(f"{name}: median {median:.1f} s over {args.runs} runs{rate} ({times})")


if __name__ == "__main__":
    main()

#!/usr/bin/env python
"""Write a self-contained HTML report of a generated dataset.

Examples:
    python scripts/report.py data --out report.html
    python scripts/report.py data/jigsaw data/cook --out report.html --episodes-shown 5

DATA_DIR is the --out of scripts/generate.py (or any directories of episode files). The page
embeds everything (images as data URIs): per task the episodes kept / seeds tried and failure
reasons, the coordination metrics beside the paper's Table 1, STI curves, an episode-length
histogram, stage timelines and first/last camera frames of a few episodes, and one video.
"""

from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[1],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("paths", nargs="+", metavar="DATA_DIR", help="dataset directories")
    parser.add_argument("--out", default="report.html", help="HTML file (default report.html)")
    parser.add_argument(
        "--episodes-shown",
        type=int,
        default=3,
        help="episodes per task with timelines and frames (default 3)",
    )
    args = parser.parse_args(argv)
    if args.episodes_shown < 0:
        parser.error(f"--episodes-shown must be >= 0, got {args.episodes_shown}")

    from bicoord_drake.report import write_report

    try:
        out = write_report(args.paths, args.out, args.episodes_shown)
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Generate verified expert demonstrations of a BiCoord task.

Examples:
    python scripts/generate.py --task jigsaw                       # 10 episodes into data/
    python scripts/generate.py --task jigsaw --episodes 3 --out data --seed 0
    python scripts/generate.py --task jigsaw --resolution 640x480 --depth
    python scripts/generate.py --task jigsaw --no-render           # states and actions only

Seeds are tried from --seed upward until --episodes succeed; an episode is kept only if the
expert ran in physics and every stage verified. Failures and their reasons go to
<out>/<task>/<config>/manifest.json. Running the same command again resumes where it stopped.
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
    parser.add_argument("--task", required=True, help="task name (see the list on a wrong name)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes to keep (default 10)")
    parser.add_argument(
        "--seed", type=int, default=0, help="first seed to try, in [0, 2**32) (default 0)"
    )
    parser.add_argument("--out", default="data", help="output root (default: data)")
    parser.add_argument("--resolution", default="320x240", help="camera WIDTHxHEIGHT")
    parser.add_argument("--fps", type=float, default=15.0, help="control/recording rate, Hz")
    parser.add_argument("--depth", action="store_true", help="also record depth (mm, uint16)")
    parser.add_argument(
        "--no-render",
        action="store_true",
        help="no cameras: record states and actions only (much faster)",
    )
    parser.add_argument(
        "--config-name",
        default="default",
        help="name of the settings directory under <out>/<task>/",
    )
    parser.add_argument(
        "--max-tries",
        type=int,
        default=0,
        help="stop after this many seeds (default: 5 x episodes)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        help="seeds run in parallel processes (default 1; try the core count)",
    )
    parser.add_argument("--verbose", action="store_true", help="show Drake's solver log")
    args = parser.parse_args(argv)

    import logging

    from pydantic import ValidationError

    from bicoord_drake.config import validation_message
    from bicoord_drake.runner.generate import GenerateConfig, format_failure, generate
    from bicoord_drake.tasks import list_tasks

    # Drake logs solver fallbacks and checker setup at INFO/WARNING; the manifest has what
    # matters. Set after pydrake's import, which resets the level.
    logging.getLogger("drake").setLevel(logging.DEBUG if args.verbose else logging.ERROR)

    if args.task not in list_tasks():
        print(
            f"error: unknown task {args.task!r}; tasks: {', '.join(list_tasks())}", file=sys.stderr
        )
        return 2
    try:
        config = GenerateConfig(
            task=args.task,
            episodes=args.episodes,
            seed=args.seed,
            out=args.out,
            resolution=args.resolution,
            fps=args.fps,
            depth=args.depth,
            render=not args.no_render,
            config_name=args.config_name,
            max_tries=args.max_tries,
            workers=args.workers,
        )
    except ValidationError as err:
        print(f"error: {validation_message(err, as_option=True)}", file=sys.stderr)
        return 2

    from tqdm import tqdm

    bar = tqdm(total=config.episodes, unit="episode", dynamic_ncols=True)

    def progress(kept: int, tried: int, target: int, message: str) -> None:
        bar.n = kept
        bar.set_postfix_str(f"tried {tried} | {message[:60]}")
        bar.refresh()

    try:
        summary = generate(config, progress)
    except KeyboardInterrupt:
        bar.close()
        print(
            "interrupted: finished episodes are kept; run the same command to resume",
            file=sys.stderr,
        )
        return 130
    except (ValueError, OSError) as err:
        bar.close()
        print(f"error: {format_failure(err)}", file=sys.stderr)
        return 1
    bar.close()
    print(f"\n{summary.root}: kept {summary.kept} / tried {summary.tried}")
    if summary.mean_length is not None:
        print(
            f"mean length {summary.mean_length:.0f} steps; "
            f"{summary.seconds_per_episode:.1f} s per kept episode"
        )
    for failure in summary.failures:
        print(f"  seed {failure.seed} failed: {failure.reason}")
    if summary.metrics_table:
        print("\n" + summary.metrics_table)
    return 0 if summary.kept >= config.episodes else 1


if __name__ == "__main__":
    sys.exit(main())

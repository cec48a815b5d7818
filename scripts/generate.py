#!/usr/bin/env python
"""Generate verified expert demonstrations of a BiCoord task.

Examples:
    python scripts/generate.py --task jigsaw                       # 10 episodes into data/
    python scripts/generate.py --task jigsaw --episodes 3 --out data --seed 0
    python scripts/generate.py --task jigsaw --resolution 640x480 --depth
    python scripts/generate.py --task jigsaw --no-render           # states and actions only
    python scripts/generate.py --task jigsaw --randomize       # into <out>/jigsaw/randomized
    python scripts/generate.py --task jigsaw --embodiment NAME    # another robot: <out>/jigsaw/NAME
    python scripts/generate.py --task all --episodes 50 --workers 2  # every task, 2 processes
    python scripts/generate.py --task jigsaw,cook --backend ray      # a local Ray instance
    python scripts/generate.py --task all --backend ray --ray-address auto   # join a cluster

Seeds are tried from --seed upward until --episodes succeed; an episode is kept only if the
expert ran in physics and every stage verified. Failures and their reasons go to
<out>/<task>/<config>/manifest.json; <out>/dataset_<config>.json lists the run's tasks.
Running the same command again resumes where it stopped. Exit status: 0 when every task has
its episodes, 1 when some could not be made (or on an error), 2 for bad arguments, 75 when the
Ray cluster has no live node left (nothing recorded for the seeds in flight: run it again),
130 when interrupted.
"""

from __future__ import annotations

import argparse
import sys
import time

from bicoord_drake.runner.backends import add_backend_arguments

EXIT_CLUSTER_LOST = 75
"""Exit status when the Ray cluster lost its last node (sysexits' EX_TEMPFAIL: run it again)."""
RESUME_HINT = (
    "finished episodes are kept and the seeds in flight were not recorded: run the same "
    "command again to resume (with --ray-address, once the cluster is back)"
)


def main(argv: list[str] | None = None) -> int:
    started = time.perf_counter()
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[1],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--task", required=True, help="task name, a comma list, or all (a wrong name lists them)"
    )
    parser.add_argument(
        "--episodes", type=int, default=10, help="episodes to keep per task (default 10)"
    )
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
        "--randomize",
        action="store_true",
        help="randomized textures (seen set), lights, table height, head-camera pose and 2-8 "
        "distractor objects",
    )
    parser.add_argument(
        "--embodiment",
        default="aloha_viperx",
        help="the robot (default: aloha_viperx, two ViperX 300s arms; a wrong name lists them)",
    )
    parser.add_argument(
        "--config-name",
        help="name of the settings directory under <out>/<task>/ (default: default, or "
        "randomized with --randomize; for another robot its name, or NAME_randomized)",
    )
    parser.add_argument(
        "--max-tries",
        type=int,
        default=0,
        help="stop after this many seeds (default: 5 x episodes)",
    )
    add_backend_arguments(parser, "seeds")
    parser.add_argument(
        "--shared-fs",
        action="store_true",
        help="Ray workers write episode files to --out themselves (it must be on a file system "
        "every node mounts); default: they send them to this process",
    )
    parser.add_argument("--verbose", action="store_true", help="show Drake's and Ray's logs")
    args = parser.parse_args(argv)

    import logging

    from pydantic import ValidationError

    from bicoord_drake.config import validation_message
    from bicoord_drake.runner.backends import ClusterLost
    from bicoord_drake.runner.generate import (
        GenerateConfig,
        RunProgress,
        default_config_name,
        format_counts,
        format_failure,
        generate_dataset,
        resolve_tasks,
    )

    # Drake logs solver fallbacks and checker setup at INFO/WARNING; the manifest has what
    # matters. Set after pydrake's import, which resets the level.
    logging.getLogger("drake").setLevel(logging.DEBUG if args.verbose else logging.ERROR)

    try:
        tasks = resolve_tasks(args.task)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
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
            randomize=args.randomize,
            embodiment=args.embodiment,
            config_name=args.config_name or default_config_name(args.randomize, args.embodiment),
            max_tries=args.max_tries,
            workers=args.workers,
            backend=args.backend,
            ray_address=args.ray_address,
            shared_fs=args.shared_fs,
            verbose=args.verbose,
        )
    except ValidationError as err:
        print(f"error: {validation_message(err, as_option=True)}", file=sys.stderr)
        return 2

    from tqdm import tqdm

    bar = tqdm(total=config.episodes * len(tasks), unit="episode", dynamic_ncols=True)
    last: RunProgress | None = None

    def progress(status: RunProgress) -> None:
        nonlocal last
        if last is None:  # episodes kept by an earlier run do not count toward the rate (ETA)
            bar.initial = bar.n = bar.last_print_n = status.kept
        last = status
        bar.update(status.kept - bar.n)
        bar.set_postfix_str(status.postfix())

    try:
        result = generate_dataset(config, progress)
    except KeyboardInterrupt:
        bar.close()
        if last is not None and len(last.counts) > 1:
            print(format_counts(last.counts), file=sys.stderr)
        print(
            "interrupted: finished episodes are kept; run the same command to resume",
            file=sys.stderr,
        )
        return 130
    except ClusterLost as err:
        bar.close()
        print(f"stopped: {err}; {RESUME_HINT}", file=sys.stderr)
        return EXIT_CLUSTER_LOST
    except (ValueError, OSError, ImportError) as err:
        bar.close()
        print(f"error: {format_failure(err)}", file=sys.stderr)
        return 1
    bar.close()
    for summary in result.tasks.values():
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
    if len(result.tasks) > 1:
        print(f"\n{result.manifest}: {len(result.tasks)} tasks, {result.seconds:.0f} s")
        print(format_counts(result.counts))
    print("\n" + result.throughput.describe(time.perf_counter() - started))
    return 0 if result.complete else 1


if __name__ == "__main__":
    sys.exit(main())

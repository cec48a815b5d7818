#!/usr/bin/env python
"""Generate verified expert demonstrations of a BiCoord task.

Examples:
    python scripts/generate.py --task jigsaw                       # 10 episodes into data/
    python scripts/generate.py --task jigsaw --episodes 3 --out data --seed 0
    python scripts/generate.py --task jigsaw --resolution 640x480 --depth
    python scripts/generate.py --task jigsaw --no-render           # states and actions only
    python scripts/generate.py --task jigsaw --randomize       # into <out>/jigsaw/randomized
    python scripts/generate.py --task jigsaw --embodiment NAME    # another robot: <out>/jigsaw/NAME
    python scripts/generate.py --list-tasks                        # tasks, step limits, robots
    python scripts/generate.py --task all --episodes 50 --workers 2  # every task, 2 processes
    python scripts/generate.py --task all --embodiment franka_pair   # every task it supports
    python scripts/generate.py --task jigsaw,cook --backend ray      # a local Ray instance
    python scripts/generate.py --task all --backend ray --ray-address auto   # join a cluster
    python scripts/generate.py --scenario scenarios/aloha_50hz.yaml --task jigsaw
    python scripts/generate.py --scenario scenarios/benchmark.yaml:randomized --task all
    python scripts/generate.py --task jigsaw --set station.kp_scale=2 --config-name stiff
    python scripts/generate.py --task jigsaw --action-noise 0.01  # DART: into .../default_noisy
    python scripts/generate.py --task jigsaw --action-noise 0.005-0.02   # a level per episode
    python scripts/generate.py --task jigsaw --disturb push    # into .../default_disturbed
    python scripts/generate.py --scenario data/jigsaw/default/data/episode3.hdf5 --out again
    python scripts/generate.py --scenario scenarios/aloha_50hz.yaml --print-scenario

What the data is - task, seeds, randomization, split, robot, rate, cameras, physics - is a
scenario (docs/scenarios.md): the values of a --scenario file, then --set FIELD=VALUE, then the
flags given. Each task runs on the robots it declares (--list-tasks): another robot is refused
before anything runs, and --task all means every task that supports the robot (the others are
named as skipped). Seeds are tried from --seed upward until --episodes succeed; an episode is kept
only if the expert ran in physics and every stage verified. Every episode file records its
scenario: --scenario EPISODE.hdf5 makes that episode again (only its seed is tried) and says
whether the actions are the recorded ones, bit for bit. --action-noise SIGMA (rad; or LO-HI,
one level per episode drawn from its seed) executes the expert's arm joint targets with
Gaussian noise (DART): joint_action/vector keeps the expert's label, joint_action/executed what
ran, and the episode is kept only if every stage still verified. --disturb KIND[,KIND] (push,
drop, knock) disturbs each episode once per kind, at a step drawn from its seed where the kind
applies (push: an external force through the plant on a free task object before the expert's
next plan; drop: a holding gripper forced open; knock: a force on a placed object); the
disturbance and a recovery row are recorded in the episode file, its replay applies it again,
and the episode is kept only if every stage still verified. Failures and their reasons go to
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
from bicoord_drake.scenario import (
    GENERATION_DEFAULTS,
    ScenarioError,
    add_scenario_arguments,
    is_episode_file,
    scenario_from_args,
)

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
        "--list-tasks",
        action="store_true",
        help="print every task with its step limit (at 15 Hz) and the robots it supports, and exit",
    )
    add_scenario_arguments(
        parser,
        notes={
            "task": "a wrong name lists them",
            "episodes": "per task",
            "randomize": "into <out>/<task>/randomized by default",
            "action_noise": "into <out>/<task>/<config>_noisy by default",
            "disturb": "into <out>/<task>/<config>_disturbed by default",
        },
    )
    parser.add_argument("--out", default="data", help="output root (default: data)")
    parser.add_argument(
        "--config-name",
        help="name of the settings directory under <out>/<task>/ (default: the scenario's name "
        "- NAME of FILE.yaml:NAME, else the file's stem; without a file, or from an episode: "
        "default, or randomized with --randomize; for another robot its name, or "
        "NAME_randomized)",
    )
    parser.add_argument(
        "--max-tries",
        type=int,
        help="stop after this many seeds (default: 5 x episodes; 1 from an episode file)",
    )
    parser.add_argument("--no-video", action="store_true", help="no head-camera MP4 per episode")
    add_backend_arguments(parser, "seeds")
    parser.add_argument(
        "--shared-fs",
        action="store_true",
        help="Ray workers write episode files to --out themselves (it must be on a file system "
        "every node mounts); default: they send them to this process",
    )
    parser.add_argument("--verbose", action="store_true", help="show Drake's and Ray's logs")
    args = parser.parse_args(argv)

    def usage(message: str) -> int:
        print(f"error: {message}", file=sys.stderr)
        return 2

    if args.list_tasks:
        from bicoord_drake.tasks.registry import task_table

        print(task_table())
        return 0
    try:
        scenario, name = scenario_from_args(args, GENERATION_DEFAULTS)
    except ScenarioError as err:
        return usage(str(err))
    if args.print_scenario:
        print(scenario.to_yaml(), end="")
        return 0

    import logging

    from pydantic import ValidationError

    from bicoord_drake.config import validation_message
    from bicoord_drake.runner.backends import ClusterLost
    from bicoord_drake.runner.generate import (
        GenerateConfig,
        RunProgress,
        compare_regenerated,
        default_config_name,
        format_counts,
        format_failure,
        generate_dataset,
        resolve_tasks,
        skipped_tasks,
    )

    # Drake logs solver fallbacks and checker setup at INFO/WARNING; the manifest has what
    # matters. Set after pydrake's import, which resets the level.
    logging.getLogger("drake").setLevel(logging.DEBUG if args.verbose else logging.ERROR)

    if scenario.task is None:
        return usage("no task: give --task (or a --scenario with task)")
    try:
        tasks = resolve_tasks(scenario.task, scenario.embodiment)
        skipped = skipped_tasks(scenario.task, scenario.embodiment)
    except ValueError as err:
        return usage(str(err))
    if skipped:
        print(
            f"skipped (they do not support {scenario.embodiment}; --list-tasks): "
            + ", ".join(skipped),
            file=sys.stderr,
        )
    episode = args.scenario if is_episode_file(args.scenario) else None
    try:
        config = GenerateConfig(
            scenario=scenario,
            out=args.out,
            config_name=args.config_name
            or name
            or default_config_name(
                scenario.randomize, scenario.embodiment, scenario.noisy, scenario.disturbed
            ),
            max_tries=args.max_tries if args.max_tries is not None else (1 if episode else 0),
            video=not args.no_video,
            workers=args.workers,
            backend=args.backend,
            ray_address=args.ray_address,
            shared_fs=args.shared_fs,
            verbose=args.verbose,
        )
    except ValidationError as err:
        return usage(validation_message(err, as_option=True, model=GenerateConfig))

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
    if episode is not None and scenario.task in result.tasks:
        print(compare_regenerated(episode, result.tasks[scenario.task].root, scenario.seed))
    return 0 if result.complete else 1


if __name__ == "__main__":
    sys.exit(main())

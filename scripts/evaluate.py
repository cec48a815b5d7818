#!/usr/bin/env python
"""Score a policy on a BiCoord task: SR, SSR, TL and per-stage completion.

Examples:
    python scripts/evaluate.py --task jigsaw --policy my_pkg.policies:MyPolicy   # 100 seeds
    python scripts/evaluate.py --task jigsaw --policy replay --data data/jigsaw --no-render
    python scripts/evaluate.py --task jigsaw --policy replay --data data/jigsaw --stage 2
    python scripts/evaluate.py --task jigsaw --policy noop --episodes 5 --no-expert-check --json
    python scripts/evaluate.py --task jigsaw --policy expert --episodes 3 --video videos/
    python scripts/evaluate.py --task jigsaw --policy lerobot:outputs/train/act_jigsaw
    python scripts/evaluate.py --task jigsaw --policy openpi:gpu-box:8000        # remote server
    python scripts/evaluate.py --task jigsaw --policy lerobot-dataset:lr/jigsaw --data data/jigsaw
    python scripts/evaluate.py --task jigsaw --policy my_pkg.policies:MyPolicy --backend ray
    python scripts/evaluate.py --scenario scenarios/aloha_50hz.yaml --task jigsaw --policy noop
    python scripts/evaluate.py --task jigsaw --policy noop --set station.kp_scale=2
    python scripts/evaluate.py --task jigsaw --policy my_pkg.policies:MyPolicy --disturb push

The rollouts' settings - task, seeds, randomization, split, robot, rate, cameras, physics - are
a scenario (docs/scenarios.md): the values of a --scenario file, then --set FIELD=VALUE, then
the flags given; the split is unseen unless one is set. The task's step limit (TASKS.md, at
15 Hz) scales with the control rate.

Policies: a built-in (replay: the recorded actions of the --data episodes; expert: the task's
planner in closed loop; noop: hold still) or package.module:name - a class with
reset(instruction) and act(obs) -> action, or a function act(obs); lerobot:PATH, a LeRobot
checkpoint; openpi:HOST:PORT, a policy server; lerobot-dataset:DIR, a LeRobot export's own
actions played back on its episodes' seeds (with --data, the episode files it was exported
from: each rollout plays the dataset's episode of its seed). Evaluation seeds start at
100000 * (1 + --seed) (seeds are below 2**32); a seed whose expert fails is skipped and reported
(the verdict is cached in ~/.cache/bicoord_drake/expert_check/, or $BICOORD_CACHE), except with
--policy expert, where it is a failed rollout counted in SR and SSR. With --data the rollouts
are the demonstrations' own seeds and scenes, at the rate and physics each was recorded with.
A rollout ends at success, at the step limit, or early - a failure, with its reason in the
report - when nothing can be saved: a task object on the floor or outside the workspace, or the
physics diverged (--no-early-stop: only divergence ends one early). A slow policy keeps its
whole step limit.
--disturb KIND[,KIND] (push, drop, knock) evaluates robustness: each seed is rolled out twice,
clean and disturbed (two rollouts per seed, and one traced expert run per seed, cached with the
expert check), and the report gives SR, SSR, TL and the stages of both side by side. A seed's
disturbances are those the expert's demonstration of that seed gets (generate.py --disturb:
drawn from the seed in a window found by a clean expert run); a seed without a window for a kind
has no disturbed rollout (listed with the reason, not a failure). With --data, a demonstration
generated with the kinds supplies its recorded ones, and its clean rollout gets none.
The report (report.json, stage_success.png) goes to <out>/<task>/<policy>/. Locally or with
--backend ray the rollouts run in parallel (one environment and policy instance per worker; by
default one per core, --workers 1 runs them in this process); the report is the same as a
sequential run's. Exit status: 0 when the report was written, 1 on an error, 2 for bad
arguments, 75 when the Ray cluster has no live node left (run it again), 130 when interrupted.
"""

from __future__ import annotations

import argparse
import json
import sys

from bicoord_drake.runner.backends import add_backend_arguments
from bicoord_drake.scenario import (
    EVALUATION_DEFAULTS,
    ScenarioError,
    add_scenario_arguments,
    scenario_from_args,
)

SEED_HINT = "evaluation seeds start at 100000 * (1 + SEED), below 2**32: SEED <= 42948"
EXIT_CLUSTER_LOST = 75
"""Exit status when the Ray cluster lost its last node (sysexits' EX_TEMPFAIL: run it again)."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[1],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_scenario_arguments(
        parser,
        notes={
            "task": "one task (a wrong name lists them)",
            "seed": "here SEED <= 42948",
            "fps": "with --data: each file's own, and its physics",
            "embodiment": "with --data: the demonstrations' robot",
            "disturb": "here: every seed is rolled out clean and disturbed, scores side by side",
        },
    )
    parser.add_argument(
        "--policy",
        help="replay | expert | noop | package.module:name | lerobot:PATH (lerobot-train output) "
        "| openpi:HOST:PORT (a policy server, docs/remote_policies.md) | lerobot-dataset:DIR (a "
        "LeRobot export's actions played back on its seeds, with --data); required",
    )
    parser.add_argument("--data", help="demonstrations (directory or file): their seeds, scenes")
    parser.add_argument(
        "--stage", type=int, help="start every rollout at this stage (0-based) of its demo"
    )
    parser.add_argument("--video", help="write a head-camera MP4 per rollout into this directory")
    parser.add_argument("--out", default="eval", help="report root (default: eval)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument(
        "--action-mode", default="qpos", choices=("qpos", "endpose"), help="what act() returns"
    )
    parser.add_argument(
        "--step-limit",
        type=int,
        help="override the task's step limit (default: TASKS.md's, scaled to the control rate)",
    )
    parser.add_argument(
        "--no-early-stop",
        action="store_true",
        help="run rollouts whose task object left the table (on the floor, or more than 15 cm "
        "outside the table) to the step limit instead of ending them at once as failures",
    )
    parser.add_argument(
        "--no-expert-check", action="store_true", help="do not skip seeds the expert fails"
    )
    parser.add_argument(
        "--max-tries", type=int, default=0, help="seeds to try at most (default: 3 x episodes)"
    )
    add_backend_arguments(parser, "rollouts")
    parser.add_argument("--verbose", action="store_true", help="show Drake's and Ray's logs")
    args = parser.parse_args(argv)

    def usage(message: str) -> int:
        print(f"error: {message}", file=sys.stderr)
        return 2

    try:
        scenario, _ = scenario_from_args(args, EVALUATION_DEFAULTS, hints={"seed": SEED_HINT})
    except ScenarioError as err:
        return usage(str(err))
    if args.print_scenario:
        print(scenario.to_yaml(), end="")
        return 0

    import logging

    from pydantic import ValidationError

    from bicoord_drake.config import validation_message
    from bicoord_drake.policies import (
        PolicyLoadError,
        action_size_of,
        close_policy,
        load_policy_for,
    )
    from bicoord_drake.runner.backends import ClusterLost, WorkerLost
    from bicoord_drake.runner.evaluate import EvaluateConfig, evaluate, find_episodes
    from bicoord_drake.runner.generate import format_failure
    from bicoord_drake.tasks import list_tasks

    # Drake logs checker setup and solver fallbacks at INFO/WARNING; the report has what matters.
    # (Set after pydrake is imported: its import configures the "drake" logger.)
    logging.getLogger("drake").setLevel(logging.DEBUG if args.verbose else logging.ERROR)

    if not args.policy:
        return usage("the --policy to evaluate is required")
    if scenario.task is None:
        return usage("no task: give --task (or a --scenario with task)")
    if scenario.task not in list_tasks():
        return usage(f"unknown task {scenario.task!r}; tasks: {', '.join(list_tasks())}")
    try:
        config = EvaluateConfig(
            scenario=scenario,
            policy=args.policy,
            data=args.data,
            stage=args.stage,
            video=args.video,
            out=args.out,
            action_mode=args.action_mode,
            step_limit=args.step_limit,
            early_stop=not args.no_early_stop,
            expert_check=not args.no_expert_check,
            max_tries=args.max_tries,
            workers=args.workers,
            backend=args.backend,
            ray_address=args.ray_address,
            verbose=args.verbose,
        )
    except ValidationError as err:
        return usage(validation_message(err, as_option=True, model=EvaluateConfig))
    total = config.episodes
    try:
        size = action_size_of(config.embodiment, config.action_mode)
        policy = load_policy_for(config.policy, action_size=size)  # fail fast, no simulation
        try:
            problem = playback_problem(policy, config, find_episodes)
        finally:
            close_policy(policy)
        if problem:
            return usage(problem)
        if config.data:
            total = min(total, len(find_episodes(config.data, config.task)))
    except (PolicyLoadError, ValueError) as err:
        return usage(format_failure(err).split(": ", 1)[-1])

    from tqdm import tqdm

    total *= 2 if config.disturb else 1  # a clean and a disturbed rollout per seed
    bar = tqdm(total=total, unit="rollout", dynamic_ncols=True, file=sys.stderr)

    def progress(result, message: str) -> None:
        if result is not None:
            bar.update(1)
        bar.set_postfix_str(message[:60])

    try:
        report = evaluate(config, progress)
    except KeyboardInterrupt:
        bar.close()
        print("interrupted", file=sys.stderr)
        return 130
    except PolicyLoadError as err:
        bar.close()
        return usage(format_failure(err).split(": ", 1)[-1])
    except ClusterLost as err:
        bar.close()
        print(
            f"stopped: {err}; no report was written: run the same command again "
            "(with --ray-address, once the cluster is back)",
            file=sys.stderr,
        )
        return EXIT_CLUSTER_LOST
    except (ValueError, OSError, ImportError, WorkerLost) as err:
        bar.close()
        print(f"error: {format_failure(err)}", file=sys.stderr)
        return 1
    bar.close()
    if args.json:
        print(json.dumps(report.to_json(), indent=2))
    else:
        print(report.format_text())
    return 0


def playback_problem(policy, config, find_episodes) -> str | None:
    """Why a dataset playback (``--policy lerobot-dataset:DIR``) cannot play the evaluation's
    seeds - those of the --data episodes, else the first evaluation seed - (None when it can,
    or for any other policy)."""
    if not config.policy.startswith("lerobot-dataset:"):
        return None
    missing_seeds = policy.missing_seeds
    if config.data:
        import h5py

        seeds = []
        for path in find_episodes(config.data, config.task)[: config.episodes]:
            with h5py.File(path, "r") as f:
                seeds.append(int(f.attrs["seed"]))
        problem = missing_seeds(config.task, seeds)
        return problem and f"{problem} (the --data episodes' seeds are played back)"
    from bicoord_drake.scenario import evaluation_seed

    problem = missing_seeds(config.task, [evaluation_seed(config.seed)])
    return problem and (
        f"{problem}: play them back on their own seeds and scenes with --data and the episode "
        "files the dataset was exported from (its meta/bicoord_episodes.jsonl names them)"
    )


if __name__ == "__main__":
    sys.exit(main())

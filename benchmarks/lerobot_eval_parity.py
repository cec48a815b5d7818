#!/usr/bin/env python
"""Does LeRobot's own evaluator score a checkpoint as scripts/evaluate.py does, seed for seed?

    python benchmarks/lerobot_eval_parity.py --task balance_roller \\
        --checkpoint out/policy_reproduces/balance_roller/act_state_3demos_20000steps_e603c6e8 \\
        --data out/policy_reproduces/data/balance_roller/default --episodes 3

1. ``scripts/evaluate.py --policy lerobot:CHECKPOINT --data DATA --episodes N --no-render``
   rolls the checkpoint out on the seeds (and scenes) of the first N demonstrations in DATA;
2. ``lerobot-eval --env.type=bicoord --env.seed_offset=0 --seed=S --eval.n_episodes=K`` (one
   run per contiguous block of those seeds: lerobot-eval resets episode i with seed S + i) rolls
   the same checkpoint out on the same seeds, with the observation the checkpoint was trained
   on (``--env.obs_type=state``; ``--env.environment_state=true`` when it reads the objects'
   poses) and ``--eval.batch_size`` environments in one vector env;
3. the success of every seed is compared, and the Markdown section of ``--out`` for the task
   (other sections kept; temp file, then rename) gives both success rates, the per-seed table,
   the exact commands, machine, date and commit.

Both evaluators run the task's own step limit and the seed's plain scene (``--data`` takes the
scene recorded in the episode file, lerobot-eval samples it from the seed: equal for plain
scenes, so a difference there would show as a differing seed). Exit status: 0 when every seed
agrees, 1 when one differs or a run fails, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import sys
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

# benchmarks/ is on sys.path when this runs as a script
import baselines  # noqa: E402
import expert_success  # noqa: E402

DEFAULT_OUT = ROOT / "benchmarks" / "lerobot_eval_parity.md"
TITLE = "# lerobot-eval against scripts/evaluate.py, seed for seed"
PREAMBLE = (
    f"{TITLE}\n\n"
    "Written by `python benchmarks/lerobot_eval_parity.py`: one LeRobot checkpoint evaluated by "
    "`scripts/evaluate.py --policy lerobot:CKPT --data DATA` and by LeRobot's own `lerobot-eval "
    "--env.type=bicoord` on the same seeds; the success of every seed compared.\n"
)


def pretrained_dir(checkpoint: Path) -> Path:
    """The ``pretrained_model`` directory lerobot-eval's ``--policy.path`` takes, from a
    lerobot-train output directory (its last checkpoint) or that directory itself."""
    for candidate in (
        checkpoint,
        checkpoint / "pretrained_model",
        checkpoint / "checkpoints" / "last" / "pretrained_model",
    ):
        if (candidate / "config.json").is_file():
            return candidate
    raise ValueError(
        f"{checkpoint}: no pretrained_model with a config.json (a lerobot-train output?)"
    )


def reads_environment_state(pretrained: Path) -> bool:
    """Whether the checkpoint's inputs include the objects' poses."""
    config = json.loads((pretrained / "config.json").read_text())
    return "observation.environment_state" in config.get("input_features", {})


def seed_blocks(seeds: list[int]) -> list[tuple[int, int]]:
    """Contiguous runs of `seeds` as (first, count): [0, 2, 3] -> [(0, 1), (2, 2)]."""
    blocks: list[tuple[int, int]] = []
    for seed in seeds:
        if blocks and blocks[-1][0] + blocks[-1][1] == seed:
            blocks[-1] = (blocks[-1][0], blocks[-1][1] + 1)
        else:
            blocks.append((seed, 1))
    return blocks


def evaluate_command(args: argparse.Namespace) -> list[str]:
    return [
        sys.executable,
        "scripts/evaluate.py",
        "--task",
        args.task,
        "--policy",
        f"lerobot:{args.checkpoint}",
        "--data",
        str(args.data),
        "--episodes",
        str(args.episodes),
        "--no-render",
        "--workers",
        "1",
        "--json",
        "--out",
        str(args.work / "evaluate"),
    ]


def lerobot_eval_command(
    args: argparse.Namespace, pretrained: Path, first: int, count: int
) -> list[str]:
    return [
        "lerobot-eval",
        "--env.discover_packages_path=bicoord_drake",
        "--env.type=bicoord",
        f"--env.task={args.task}",
        "--env.obs_type=state",
        f"--env.environment_state={str(reads_environment_state(pretrained)).lower()}",
        "--env.seed_offset=0",
        f"--seed={first}",
        f"--eval.n_episodes={count}",
        f"--eval.batch_size={min(args.batch_size, count)}",
        f"--policy.path={pretrained}",
        "--policy.device=cpu",
        f"--output_dir={lerobot_eval_dir(args, first, count)}",
    ]


def lerobot_eval_dir(args: argparse.Namespace, first: int, count: int) -> Path:
    """Where the lerobot-eval run of seeds first..first+count-1 writes (eval_info.json)."""
    return args.work / f"lerobot_eval_{first}_{count}"


def lerobot_successes(info: dict) -> list[bool]:
    """Per-episode success from lerobot-eval's eval_info.json (its one task's metrics)."""
    tasks = info.get("per_task") or []
    if len(tasks) != 1:
        raise ValueError(f"eval_info.json: expected one task, found {len(tasks)}")
    return [bool(s) for s in tasks[0]["metrics"]["successes"]]


def format_section(r: dict) -> str:
    same = all(row["evaluate"] == row["lerobot_eval"] for row in r["rows"])
    sr = {k: sum(row[k] for row in r["rows"]) for k in ("evaluate", "lerobot_eval")}
    n = len(r["rows"])
    lines = [
        f"## {section_name(r['task'], r['batch_size'])}",
        "",
        f"**scripts/evaluate.py {sr['evaluate']}/{n}, lerobot-eval {sr['lerobot_eval']}/{n}: "
        + ("every seed agrees.**" if same else "they differ.**"),
        "",
        "| | |",
        "|---|---|",
        f"| checkpoint | `{r['checkpoint']}` |",
        f"| lerobot-eval batch size | {r['batch_size']} |",
        f"| wall time | evaluate.py {r['seconds']['evaluate']:.0f} s, lerobot-eval "
        f"{r['seconds']['lerobot_eval']:.0f} s |",
        f"| commit | `{r['commit'][:7]}`{' (dirty)' if r['dirty'] else ''} |",
        f"| date (UTC) | {r['date']} |",
        f"| machine | {r['machine']} |",
        "",
        "| seed | scripts/evaluate.py | lerobot-eval |",
        "|---:|---|---|",
        *(
            f"| {row['seed']} | {'success' if row['evaluate'] else 'failure'} | "
            f"{'success' if row['lerobot_eval'] else 'failure'} |"
            for row in r["rows"]
        ),
        "",
        "```bash",
        *r["commands"],
        "```",
    ]
    return "\n".join(lines) + "\n"


def section_name(task: str, batch_size: int) -> str:
    """'<task>' for one environment at a time, '<task> (batch N)' for a vector env of N."""
    return task if batch_size == 1 else f"{task} (batch {batch_size})"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--task", required=True, help="the task")
    parser.add_argument("--checkpoint", type=Path, required=True, help="lerobot-train output")
    parser.add_argument("--data", type=Path, required=True, help="demonstrations (their seeds)")
    parser.add_argument("--episodes", type=int, default=3, help="rollouts (first N episodes)")
    parser.add_argument("--batch-size", type=int, default=1, help="lerobot-eval environments")
    parser.add_argument("--work", type=Path, default=ROOT / "out" / "lerobot_eval_parity")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="markdown file to update")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.batch_size < 1:
        parser.error("--episodes and --batch-size must be at least 1")
    if shutil.which("lerobot-eval") is None:
        parser.error("lerobot-eval is not on PATH (pip install --no-deps lerobot==0.4.4)")
    try:
        args.pretrained = pretrained_dir(args.checkpoint.resolve())
    except ValueError as err:
        parser.error(str(err))
    args.checkpoint, args.data = args.checkpoint.resolve(), args.data.resolve()
    args.work = (args.work / args.task).resolve()
    args.out = args.out.resolve()
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    commit, dirty = expert_success.git_state()
    evaluate = evaluate_command(args)
    try:
        stdout, seconds_evaluate = baselines.run(evaluate, args.work / "evaluate.log")
        report = json.loads(stdout)
        ours = {int(r["seed"]): bool(r["success"]) for r in report["rollouts"]}
        seeds = sorted(ours)
        theirs: dict[int, bool] = {}
        commands = [shlex.join(["python", *evaluate[1:]])]
        seconds_lerobot = 0.0
        for first, count in seed_blocks(seeds):
            command = lerobot_eval_command(args, args.pretrained, first, count)
            commands.append(shlex.join(command))
            out = lerobot_eval_dir(args, first, count)
            _, seconds = baselines.run(command, out.with_suffix(".log"))
            seconds_lerobot += seconds
            successes = lerobot_successes(json.loads((out / "eval_info.json").read_text()))
            theirs.update(zip(range(first, first + count), successes, strict=True))
    except (RuntimeError, ValueError, KeyError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    end_commit, end_dirty = expert_success.git_state()
    result = {
        "task": args.task,
        "checkpoint": str(args.checkpoint),
        "batch_size": args.batch_size,
        "rows": [{"seed": s, "evaluate": ours[s], "lerobot_eval": theirs[s]} for s in seeds],
        "seconds": {"evaluate": seconds_evaluate, "lerobot_eval": seconds_lerobot},
        "commit": commit,
        "dirty": dirty or end_dirty or expert_success.code_changed(commit, end_commit),
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"),
        "machine": baselines.machine(),
        "commands": commands,
    }
    section = format_section(result)
    text = args.out.read_text() if args.out.exists() else PREAMBLE
    expert_success.write_atomic(
        args.out,
        expert_success.update_markdown(text, {section_name(args.task, args.batch_size): section}),
    )
    print(section)
    return 0 if all(r["evaluate"] == r["lerobot_eval"] for r in result["rows"]) else 1


if __name__ == "__main__":
    sys.exit(main())

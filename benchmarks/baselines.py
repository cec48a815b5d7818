"""Baselines: ACT and Diffusion Policy trained with ``lerobot-train``, scored by the benchmark.

    python benchmarks/baselines.py --data data --tasks balance_roller,jigsaw --demos 50 \\
        --policies act,diffusion --steps 20000 --eval-episodes 50 \\
        --work baselines_work --out benchmarks/baselines.md

For every task: the first ``--demos`` demonstrations of the task under ``--data`` (a directory
of generated episodes, e.g. ``scripts/generate.py --no-render`` output) are exported state-based
(``scripts/export.py --environment-state --no-images``: ``observation.state`` and
``observation.environment_state``, the task objects' poses); each policy is trained on that
dataset with ``lerobot-train`` (no training code here; the exact command is recorded) and
evaluated with ``scripts/evaluate.py --policy lerobot:DIR --no-render --split unseen`` on
``--eval-episodes`` evaluation seeds from ``100000 * (1 + --eval-seed)`` upward (disjoint from
the generation seeds; seeds whose expert fails are skipped and reported). Each result goes to
``<work>/results.jsonl``, keyed by its task, policy and every training and evaluation setting
(:data:`SETTINGS`: inputs, resolution, demonstrations, steps, batch size, training seed, extra
training arguments, first evaluation seed, rollouts); a rerun skips the results whose key is
already there (``--force`` redoes them), and each training has its own checkpoint directory
(:func:`checkpoint_name`). ``--out`` is rewritten from the latest result of every key: SR, SSR,
TL, per-stage completion, training steps, batch size, extra arguments, time and final loss, the
seeds evaluated and those skipped, the machine, the date, the exact commands, and the paper's
single-task Diffusion Policy numbers (image-based, GPU, RoboTwin 2.0 settings, 100
demonstrations per task) beside ours.

Training runs on the CPU with lerobot's default policy configuration plus
``--train-args POLICY=ARGS`` (e.g. ``--train-args "diffusion=--policy.down_dims=[128,256,512]"``)
and ``--batch-size``. Everything runs one process at a time. Cost seen in the smoke run (2 shared
cores, load about 5): lerobot's default ACT (40 M parameters, chunks of 100) 4-8 s per training
step at batch 4, so a CPU baseline needs a smaller one (``--train-args "act=--policy.dim_model=
256 ..."``); Diffusion Policy with ``--policy.down_dims=[64,128,256]`` (5 M) 0.4-0.5 s per step,
and with ``--policy.num_inference_steps=10`` 2-5 min per 300-step rollout.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
POLICIES = ("act", "diffusion")
#: Arguments every training run gets besides the dataset, the policy type and the output.
COMMON_TRAIN_ARGS = (
    "--policy.device=cpu",
    "--policy.push_to_hub=false",
    "--num_workers=0",
    "--eval_freq=0",
    "--wandb.enable=false",
)
#: Per policy type: what a state-only CPU run needs beyond lerobot's defaults.
POLICY_TRAIN_ARGS = {
    "act": ("--policy.pretrained_backbone_weights=null",),
    "diffusion": (),
}
#: The paper's single-task Diffusion Policy (Table 2): SR, SSR in percent (image-based, trained
#: with RoboTwin 2.0's configuration on GPUs, 100 rollouts).
PAPER_DP = {
    "balance_roller": (34.0, 67.0),
    "build_bridge": (68.0, 69.5),
    "build_tower_with_blocks": (0.0, 1.5),
    "clean_table": (0.0, 28.5),
    "collect_pens": (1.0, 46.8),
    "cook": (8.0, 31.2),
    "divide_block_tower": (7.0, 28.9),
    "exchange_mics": (58.0, 77.0),
    "exchange_pots": (90.0, 93.5),
    "extract_bottom_block_to_top": (80.0, 80.5),
    "fetch_block_with_roller": (4.0, 52.0),
    "handover_block_with_bowls": (1.0, 49.5),
    "jigsaw": (0.0, 0.8),
    "match_blocks_with_signs": (2.0, 16.0),
    "place_plate_and_cup": (71.0, 89.2),
    "put_objects_cabinet": (67.0, 81.0),
    "stack_bowls": (21.0, 41.3),
    "sweep_block": (83.0, 83.0),
}
_LOSS = re.compile(r"\bloss:([0-9.eE+-]+)")


def final_loss(train_log: Path) -> float | None:
    """The last training loss lerobot-train printed to `train_log` (None: none printed)."""
    losses = _LOSS.findall(train_log.read_text())
    return float(losses[-1]) if losses else None


# --------------------------------------------------------------------------- environment
def subprocess_env() -> dict[str, str]:
    """This checkout first on PYTHONPATH, no network, no wandb."""
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path, "HF_HUB_OFFLINE": "1", "WANDB_MODE": "disabled"}


def machine() -> str:
    """CPU model, cores, Python, torch and lerobot versions."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = []
    for package in ("torch", "lerobot"):
        try:
            from importlib.metadata import version

            versions.append(f"{package} {version(package)}")
        except Exception:
            versions.append(f"{package} ?")
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, " + ", ".join(
        versions
    )


def shown(command: list[str]) -> str:
    """`command` as recorded: this Python as ``python``, lerobot-train by its name."""
    names = {sys.executable: "python", shutil.which("lerobot-train"): "lerobot-train"}
    return shlex.join(names.get(part, part) for part in command)


def run(
    command: list[str],
    log: Path,
    *,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
) -> tuple[str, float]:
    """Run `command` (output to `log` as well) in `cwd` (default: this checkout) with `env`
    (default: :func:`subprocess_env`); returns (stdout, seconds). RuntimeError with the log's
    tail if it fails."""
    log.parent.mkdir(parents=True, exist_ok=True)
    where = "" if cwd is None else f"cd {shlex.quote(str(cwd))} && "
    if env is not None:
        where += f"PYTHONPATH={shlex.quote(env.get('PYTHONPATH', ''))} "
    start = time.perf_counter()
    out = subprocess.run(
        command,
        capture_output=True,
        text=True,
        env=subprocess_env() if env is None else env,
        cwd=ROOT if cwd is None else cwd,
    )
    seconds = time.perf_counter() - start
    log.write_text(f"$ {where}{shlex.join(command)}\n{out.stdout}\n--- stderr ---\n{out.stderr}")
    if out.returncode != 0:
        raise RuntimeError(
            f"{shlex.join(command[:4])} ... failed; see {log}:\n{out.stderr[-2000:]}"
        )
    return out.stdout, seconds


# --------------------------------------------------------------------------- result keys
#: The settings a result is keyed by, besides its task and policy: every training setting
#: (what the policy saw, at which resolution, how many demonstrations, steps, batch size, seed
#: and the extra lerobot-train arguments) and every evaluation setting (the first evaluation
#: seed, ``scripts/evaluate.py --seed``, and the number of rollouts). Two results that differ
#: in any of them are different rows; a rerun skips only a result with all of them equal.
SETTINGS = (
    "inputs",
    "resolution",
    "demos",
    "steps",
    "batch_size",
    "train_seed",
    "train_args",
    "eval_seed",
    "eval_episodes",
)


def normalized_args(text: str) -> str:
    """Extra lerobot-train arguments as one canonical string (shell-split and re-joined)."""
    return shlex.join(shlex.split(text or ""))


def run_settings(policy: str, args: argparse.Namespace) -> dict[str, Any]:
    """The :data:`SETTINGS` of `policy`'s run with `args` (resolution: None for state
    inputs, where no camera is rendered)."""
    return {
        "inputs": args.inputs,
        "resolution": args.resolution if args.inputs == "images" else None,
        "demos": args.demos,
        "steps": args.steps,
        "batch_size": args.batch_size,
        "train_seed": args.train_seed,
        "train_args": normalized_args(args.train_args.get(policy, "")),
        "eval_seed": args.eval_seed,
        "eval_episodes": args.eval_episodes,
    }


def _option(tokens: list[str], name: str) -> str | None:
    """The value of ``name=VALUE`` or ``name VALUE`` in `tokens` (the last one), else None."""
    value = None
    for k, token in enumerate(tokens):
        if token.startswith(name + "="):
            value = token.split("=", 1)[1]
        elif token == name and k + 1 < len(tokens):
            value = tokens[k + 1]
    return value


def settings_of(result: dict[str, Any]) -> dict[str, Any]:
    """A result's :data:`SETTINGS`: its ``settings``, or for a result written before they
    were recorded, read from its fields and its exact commands (the extra training arguments
    are what :func:`train_command` puts between ``--seed=`` and ``--output_dir=``)."""
    if "settings" in result:
        return {name: result["settings"].get(name) for name in SETTINGS}
    train = shlex.split(result.get("commands", {}).get("train", ""))
    evaluate = shlex.split(result.get("commands", {}).get("evaluate", ""))
    extra = ""
    seeds = [k for k, t in enumerate(train) if t.startswith("--seed=")]
    ends = [k for k, t in enumerate(train) if t.startswith("--output_dir=")]
    if seeds and ends and seeds[-1] < ends[-1]:
        extra = shlex.join(train[seeds[-1] + 1 : ends[-1]])
    inputs = result.get("inputs", "state")

    def number(value: Any) -> int | None:
        return None if value is None else int(value)

    return {
        "inputs": inputs,
        "resolution": result.get("resolution") if inputs == "images" else None,
        "demos": result.get("demos"),
        "steps": result.get("steps"),
        "batch_size": number(result.get("batch_size", _option(train, "--batch_size"))),
        "train_seed": number(_option(train, "--seed")),
        "train_args": extra,
        "eval_seed": number(_option(evaluate, "--seed")),
        "eval_episodes": number(_option(evaluate, "--episodes")),
    }


def result_key(result: dict[str, Any]) -> tuple:
    """What identifies a result: its task, policy and :data:`SETTINGS` (hashable)."""
    settings = settings_of(result)
    return (result["task"], result["policy"], *(settings[name] for name in SETTINGS))


def settings_key(task: str, policy: str, args: argparse.Namespace) -> tuple:
    """The :func:`result_key` the run of `policy` on `task` with `args` will have."""
    settings = run_settings(policy, args)
    return (task, policy, *(settings[name] for name in SETTINGS))


def latest_results(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One result per :func:`result_key`, the last one written, in the order first seen."""
    latest: dict[tuple, dict[str, Any]] = {}
    for r in results:
        latest[result_key(r)] = r
    return list(latest.values())


def checkpoint_name(policy: str, args: argparse.Namespace) -> str:
    """The checkpoint directory of `policy`'s training with `args`: readable settings and a
    short hash of the training settings, so two trainings that differ in any (batch size,
    seed, extra arguments, resolution) do not share one."""
    import hashlib

    settings = run_settings(policy, args)
    training = {k: v for k, v in settings.items() if not k.startswith("eval_")}
    digest = hashlib.sha256(json.dumps(training, sort_keys=True).encode()).hexdigest()[:8]
    return f"{policy}_{args.inputs}_{args.demos}demos_{args.steps}steps_{digest}"


# --------------------------------------------------------------------------- one task
#: Written into a checkpoint directory once its training finished: the command and its time.
TRAINED = "baselines_trained.json"


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """`data` as JSON at `path`, written to a temporary file first."""
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data))
    tmp.replace(path)


def trained(output: Path, train: list[str]) -> float | None:
    """Training seconds if `output` holds a finished training by the same command (an
    interrupted run resumes at its evaluation), else None."""
    try:
        record = json.loads((output / TRAINED).read_text())
    except (OSError, ValueError):
        return None
    return float(record["seconds"]) if record.get("command") == shown(train) else None


def export_command(
    files: list[Path], dataset: Path, inputs: str, source: Path | None = None
) -> list[str]:
    """scripts/export.py for a dataset of `files` with the policy's `inputs`: ``state`` (the
    robot's state and the task objects' poses, no images) or ``images`` (the robot's state and
    the cameras). `source`: a directory whose first ``len(files)`` episodes are `files`
    (exported with ``--max-episodes``, a shorter command)."""
    paths = [str(source), "--max-episodes", str(len(files))] if source else list(map(str, files))
    options = ["--environment-state", "--no-images"] if inputs == "state" else []
    command = [sys.executable, "scripts/export.py", *paths, "--to", "lerobot"]
    return [*command, "--out", str(dataset), *options]


def common_source(files: list[Path]) -> Path | None:
    """The deepest directory whose episode files start with `files`, in order (None if none)."""
    from bicoord_drake.data.readers import find_episode_files

    parent = Path(os.path.commonpath([f.parent for f in files]))
    found, _ = find_episode_files([parent])
    return parent if found[: len(files)] == files else None


def train_command(
    policy: str, task: str, dataset: Path, output: Path, args: argparse.Namespace
) -> list[str]:
    """The lerobot-train command of one policy."""
    train = shutil.which("lerobot-train") or "lerobot-train"
    return [
        train,
        f"--dataset.repo_id=bicoord_drake/{task}",
        f"--dataset.root={dataset}",
        f"--policy.type={policy}",
        *COMMON_TRAIN_ARGS,
        *POLICY_TRAIN_ARGS[policy],
        f"--steps={args.steps}",
        f"--batch_size={args.batch_size}",
        f"--save_freq={args.steps}",
        f"--log_freq={max(1, min(200, args.steps // 10))}",
        f"--seed={args.train_seed}",
        *shlex.split(args.train_args.get(policy, "")),
        f"--output_dir={output}",
    ]


def evaluate_command(task: str, checkpoint: Path, out: Path, args: argparse.Namespace) -> list[str]:
    """scripts/evaluate.py on unseen-split evaluation seeds (cameras only for image inputs)."""
    return [
        sys.executable,
        "scripts/evaluate.py",
        "--task",
        task,
        "--policy",
        f"lerobot:{checkpoint}",
        "--episodes",
        str(args.eval_episodes),
        "--seed",
        str(args.eval_seed),
        "--split",
        "unseen",
        *(["--no-render"] if args.inputs == "state" else ["--resolution", args.resolution]),
        "--workers",
        str(args.eval_workers),
        "--json",
        "--out",
        str(out),
    ]


def demonstrations(data: Path, task: str, count: int) -> list[Path]:
    """The first `count` episode files of `task` under `data`."""
    from bicoord_drake.runner.rollouts import find_episodes

    files = find_episodes(data, task)
    if len(files) < count:
        raise ValueError(f"{data}: {len(files)} {task} demonstrations, {count} asked for")
    return files[:count]


def run_task(task: str, args: argparse.Namespace, done: set[tuple]) -> list[dict]:
    """Export, train and evaluate every policy of `args` on `task` whose :func:`settings_key`
    is not in `done`; returns the new results."""
    from bicoord_drake.runner.rollouts import DIVERGED

    work = Path(args.work) / task
    dataset = work / f"dataset_{args.inputs}_{args.demos}"
    files = demonstrations(Path(args.data), task, args.demos)
    export = export_command(files, dataset, args.inputs, common_source(files))
    todo = [p for p in args.policies if settings_key(task, p, args) not in done]
    if not todo:
        return []
    if not dataset.exists():
        print(f"[{task}] export {len(files)} demonstrations", flush=True)
        run(export, work / "logs" / "export.log")
    results = []
    for policy in todo:
        output = work / checkpoint_name(policy, args)
        train = train_command(policy, task, dataset, output, args)
        train_log = work / "logs" / f"train_{output.name}.log"
        train_seconds = trained(output, train)
        if train_seconds is None:
            if output.exists():
                shutil.rmtree(output)  # lerobot-train refuses an existing directory
            print(f"[{task}] train {policy}: {args.steps} steps", flush=True)
            _, train_seconds = run(train, train_log)
            write_json_atomic(output / TRAINED, {"command": shown(train), "seconds": train_seconds})
        else:
            print(f"[{task}] {policy}: trained before ({output}), evaluating it", flush=True)
        loss = final_loss(train_log)
        evaluate = evaluate_command(task, output, work / "eval", args)
        print(f"[{task}] evaluate {policy}: {args.eval_episodes} rollouts", flush=True)
        stdout, eval_seconds = run(evaluate, work / "logs" / f"evaluate_{output.name}.log")
        report = json.loads(stdout)
        errors = [r["error"] for r in report["rollouts"] if r.get("error")]
        diverged = sum(1 for e in errors if e.startswith(DIVERGED))
        results.append(
            {
                "task": task,
                "policy": policy,
                "inputs": args.inputs,
                **({"resolution": args.resolution} if args.inputs == "images" else {}),
                "demos": len(files),
                "steps": args.steps,
                "batch_size": args.batch_size,
                "settings": run_settings(policy, args),
                "train_seconds": round(train_seconds, 1),
                "final_loss": loss,
                "eval_seconds": round(eval_seconds, 1),
                "n": report["n"],
                "SR": report["SR"],
                "SSR": report["SSR"],
                "TL": report["TL"],
                "stages": [[s["subgoal"], s["completed"]] for s in report["stages"]],
                "skipped": len(report["skipped"]),
                "skipped_seeds": [s["seed"] for s in report["skipped"]],
                "seeds": [r["seed"] for r in report["rollouts"]],
                "diverged": diverged,
                "errors": errors[:3],
                "commands": {
                    "export": shown(export),
                    "train": shown(train),
                    "evaluate": shown(evaluate),
                },
                "machine": machine(),
                "date": f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC",
            }
        )
        print(
            f"[{task}] {policy}: SR {100 * report['SR']:.1f} %, SSR {100 * report['SSR']:.1f} %",
            flush=True,
        )
    return results


# --------------------------------------------------------------------------- the table
def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.1f}"


def inputs_text(result: dict[str, Any]) -> str:
    """What the policy saw: state (robot + task objects) or the cameras at a resolution."""
    if result.get("inputs", "state") == "state":
        return "state"
    return f"images {result.get('resolution', '?')} + robot state"


def seeds_text(result: dict[str, Any]) -> str:
    """The evaluation seeds tried, ``first-last`` (the rollouts' and the skipped ones)."""
    seeds = list(result.get("seeds") or []) + list(result.get("skipped_seeds") or [])
    if seeds:
        return f"{min(seeds)}-{max(seeds)}"
    eval_seed = settings_of(result)["eval_seed"]
    skipped = result.get("skipped")
    if eval_seed is None or not isinstance(skipped, int):
        return "-"
    first = 100000 * (1 + eval_seed)
    return f"{first}-{first + result['n'] + skipped - 1}"


def skipped_text(result: dict[str, Any]) -> str:
    """The evaluation seeds skipped because their expert failed: how many, and which."""
    seeds = result.get("skipped_seeds")
    if seeds is None:
        return str(result.get("skipped", "-"))
    return f"{len(seeds)}: {', '.join(map(str, seeds))}" if seeds else "0"


def markdown(results: list[dict[str, Any]], command: str, notes: str = "") -> str:
    """The baselines table, its settings, `notes` (Markdown) and the exact commands of every
    row."""
    extras: dict[str, str] = {}  # extra training arguments -> their label in the table
    for r in results:
        extra = settings_of(r)["train_args"]
        if extra and extra not in extras:
            extras[extra] = f"a{len(extras) + 1}"
    lines = [
        "# Baselines: ACT and Diffusion Policy trained with lerobot-train",
        "",
        f"Written by `{command}` from `results.jsonl` of its work directory.",
        "Inputs: *state* = `observation.state` and `observation.environment_state` (the task "
        "objects' poses; no images); *images* = `observation.state` and the three cameras at "
        "the generated resolution (the evaluation renders at that resolution). Trained on the "
        "CPU with `lerobot-train` (lerobot's default configuration of each policy plus the "
        "extra arguments of the *train args* column, listed below the table, at the batch size "
        "and training seed of the commands below), "
        "scored with `scripts/evaluate.py` on unseen-split evaluation seeds (the *seeds* "
        "column: the first is 100000 (1 + `--eval-seed`); seeds whose expert fails are skipped, "
        "the *skipped* column). SR, SSR in percent; TL in control steps of the "
        "successful rollouts; per-stage completion: the share of rollouts in which each stage "
        "counted. Diverged: rollouts that ended when the physics diverged (counted as failures; "
        "bench_expert_physics.md, 'Thin bodies spinning'). Paper DP: the paper's single-task "
        "Diffusion Policy (image-based, GPU, "
        "RoboTwin 2.0 settings, 100 demonstrations per task, 100 rollouts), for reference "
        "only: the inputs and the number of demonstrations differ.",
        "",
        "| task | policy | inputs | demos | train steps | batch | train args | train time "
        "| final loss | rollouts | seeds | skipped | diverged | SR | SSR | TL "
        "| per-stage completion | paper DP SR / SSR | machine | date |",
        "|---|---|---|---:|---:|---:|---|---:|---:|---:|---|---|---:|---:|---:|---:"
        "|---|---|---|---|",
    ]
    for r in results:
        settings = settings_of(r)
        stages = "; ".join(f"{name} {_pct(c)}" for name, c in r["stages"])
        paper = PAPER_DP.get(r["task"])
        paper_text = f"{paper[0]:.1f} / {paper[1]:.1f}" if paper else "-"
        loss = "-" if r["final_loss"] is None else f"{r['final_loss']:.3f}"
        batch = settings["batch_size"] if settings["batch_size"] is not None else "-"
        extra = extras.get(settings["train_args"], "-")
        lines.append(
            f"| {r['task']} | {r['policy']} | {inputs_text(r)} | {r['demos']} | {r['steps']} | "
            f"{batch} | {extra} | {r['train_seconds'] / 60:.1f} min | {loss} | {r['n']} | "
            f"{seeds_text(r)} | {skipped_text(r)} | {r.get('diverged', '-')} | "
            f"{_pct(r['SR'])} | "
            f"{_pct(r['SSR'])} | {r['TL'] if r['TL'] is not None else '-'} | {stages} | "
            f"{paper_text} | {r['machine']} | {r['date']} |"
        )
    if extras:
        lines += ["", "Extra training arguments (*train args*):", ""]
        lines += [f"- {label}: `{extra}`" for extra, label in extras.items()]
    if notes.strip():
        lines += ["", notes.strip()]
    lines += ["", "## Commands", ""]
    for r in results:
        settings = settings_of(r)
        label = extras.get(settings["train_args"])
        what = [f"{r['steps']} steps"]
        if settings["batch_size"] is not None:
            what.append(f"batch {settings['batch_size']}")
        if label:
            what.append(f"train args {label}")
        if settings["eval_seed"] is not None:
            what.append(f"evaluation --seed {settings['eval_seed']}")
        lines += [f"### {r['task']}, {r['policy']} ({inputs_text(r)}), {', '.join(what)}", ""]
        lines += ["```bash"]
        lines += [r["commands"][k] for k in ("export", "train", "evaluate")]
        lines += ["```", ""]
        if r["errors"]:
            lines += [f"Rollout errors (first {len(r['errors'])}): {r['errors']}", ""]
    return "\n".join(lines)


def read_results(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


# --------------------------------------------------------------------------- CLI
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--data", default=".", help="generated episodes (searched recursively)")
    parser.add_argument("--tasks", default="", help="comma-separated task names")
    parser.add_argument("--demos", type=int, default=50, help="demonstrations per task")
    parser.add_argument(
        "--policies", default="act,diffusion", help=f"comma list of {', '.join(POLICIES)}"
    )
    parser.add_argument(
        "--inputs",
        choices=("state", "images"),
        default="state",
        help="state: robot + task objects' poses, no cameras (default); images: robot state + "
        "the cameras (episodes generated with cameras at --resolution)",
    )
    parser.add_argument(
        "--resolution",
        default="128x96",
        help="camera WIDTHxHEIGHT of the generated episodes and the evaluation (--inputs images)",
    )
    parser.add_argument("--steps", type=int, default=20000, help="training steps")
    parser.add_argument("--batch-size", type=int, default=8, help="training batch size")
    parser.add_argument("--train-seed", type=int, default=1000, help="lerobot-train --seed")
    parser.add_argument(
        "--train-args",
        action="append",
        default=[],
        metavar="POLICY=ARGS",
        help="extra lerobot-train arguments for one policy type (repeatable)",
    )
    parser.add_argument("--eval-episodes", type=int, default=50, help="rollouts per policy")
    parser.add_argument("--eval-seed", type=int, default=0, help="scripts/evaluate.py --seed")
    parser.add_argument("--eval-workers", type=int, default=1, help="scripts/evaluate.py --workers")
    parser.add_argument("--work", required=True, help="datasets, checkpoints, logs, results")
    parser.add_argument("--out", required=True, help="the Markdown table to (re)write")
    parser.add_argument("--force", action="store_true", help="redo results already in --work")
    parser.add_argument(
        "--table-only",
        action="store_true",
        help="only rewrite --out from the results in --work (run nothing)",
    )
    parser.add_argument(
        "--notes", help="a Markdown file placed between the table and the commands (analysis)"
    )
    args = parser.parse_args(argv)
    args.tasks = [t for t in args.tasks.split(",") if t]
    if not args.tasks and not args.table_only:
        parser.error("--tasks is required (unless --table-only)")
    args.policies = [p for p in args.policies.split(",") if p]
    unknown = sorted(set(args.policies) - set(POLICIES))
    if unknown:
        parser.error(f"unknown policies {unknown}; choose from {', '.join(POLICIES)}")
    extra: dict[str, str] = {}
    for item in args.train_args:
        policy, sep, value = item.partition("=")
        if not sep or policy not in POLICIES:
            parser.error(f"--train-args {item!r}: expected POLICY=ARGS with POLICY in {POLICIES}")
        extra[policy] = f"{extra.get(policy, '')} {value}".strip()
    args.train_args = extra
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if shutil.which("lerobot-train") is None:
        print(
            "error: lerobot-train is not on PATH (see README: Train and evaluate)", file=sys.stderr
        )
        return 1
    results_file = Path(args.work) / "results.jsonl"
    results_file.parent.mkdir(parents=True, exist_ok=True)
    previous = [] if args.force else read_results(results_file)
    done = {result_key(r) for r in previous}
    for task in [] if args.table_only else args.tasks:
        for result in run_task(task, args, done):
            with open(results_file, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(result) + "\n")
    command = "python benchmarks/baselines.py " + shlex.join(sys.argv[1:] if argv is None else argv)
    latest = latest_results(read_results(results_file))
    notes = Path(args.notes).read_text() if args.notes else ""
    Path(args.out).write_text(markdown(latest, command, notes) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

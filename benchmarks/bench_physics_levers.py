"""What the physics levers of issue #17 would buy: one recorded episode per task, replayed.

    python benchmarks/bench_physics_levers.py --tasks jigsaw,handover_block_with_bowls,cook \\
        [--seed 0] [--repeats 3] [--variants all] [--data /tmp/bench-levers] [--out FILE.md]

For each task the script generates (or reuses, in ``--data``) one episode of `--seed` with the
defaults and no cameras, then replays its recorded actions open loop under each variant of the
physics, each replay in a fresh process (a variant may change the arm model, which a process
builds once). Per replay: the CPU seconds spent advancing the simulator (``process_time``, which
a busy neighbour disturbs less than wall time), the simulated seconds, their ratio (the
real-time factor of the physics alone), the mean number of hydroelastic contact-surface faces
per control step (every face is a SAP constraint) and whether the replay still completes every
stage. Variants run interleaved, repeat by repeat, so background load hits them alike; the table
gives medians.

An open-loop replay is a stricter test than the closed-loop expert (which re-plans from what it
sees), so a variant whose replay fails may still pass the expert; a variant whose replay passes
still needs every task's 30-seed expert success re-measured before it can become a default.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: name -> (StationConfig fields, rigid finger pads)
VARIANTS: dict[str, tuple[dict, bool]] = {
    "default (1/300 s)": ({}, False),
    "step 1/225 s": ({"time_step": 1 / 225}, False),
    "step 1/180 s": ({"time_step": 1 / 180}, False),
    "step 1/150 s": ({"time_step": 1 / 150}, False),
    "rigid pads": ({}, True),
    "step 1/180 s + rigid pads": ({"time_step": 1 / 180}, True),
}


def episode_path(data: Path, task: str, seed: int) -> Path:
    """The recorded episode of `task` and `seed` in `data`, generated if missing."""
    out = data / task
    found = sorted(out.rglob("episode*.hdf5"))
    if not found:
        cmd = [sys.executable, str(ROOT / "scripts" / "generate.py"), f"--task={task}"]
        cmd += [f"--seed={seed}", "--episodes=1", "--max-tries=1", "--no-render", f"--out={out}"]
        run = subprocess.run(cmd, capture_output=True, text=True)
        found = sorted(out.rglob("episode*.hdf5"))
        if not found:
            raise RuntimeError(f"{task} seed {seed}: no episode kept\n{run.stderr[-2000:]}")
    return found[0]


def use_rigid_pads() -> None:
    """Make the finger pads rigid-hydroelastic in this process (before any arm is built)."""
    from bicoord_drake.models import embodiment, geometry

    class RigidPadProps(geometry.ContactProps):
        def __init__(self, **kwargs) -> None:
            if kwargs.get("hydroelastic") == "compliant":
                kwargs["hydroelastic"] = "rigid"
            super().__init__(**kwargs)

    embodiment.ContactProps = RigidPadProps


def replay_once(path: Path, variant: str) -> dict:
    """Replay the episode at `path` under `variant` in this process; the measurements."""
    import numpy as np

    fields, rigid_pads = VARIANTS[variant]
    if rigid_pads:
        use_rigid_pads()
    from bicoord_drake.config import StationConfig
    from bicoord_drake.data.episode import read_episode
    from bicoord_drake.env import Env
    from bicoord_drake.episode_setup import EpisodeSetup

    episode = read_episode(path, False)
    station = StationConfig(render=False, embodiment=episode.embodiment, **fields)
    env = Env(EpisodeSetup(task=episode.task, seed=episode.seed, station=station))
    env.reset(episode=episode)
    plant, physics, faces = env.sim.station.plant, 0.0, []
    advance = env.sim.step

    def timed_step(action: np.ndarray) -> None:
        nonlocal physics
        start = time.process_time()
        advance(action)
        physics += time.process_time() - start
        results = plant.get_contact_results_output_port().Eval(env.sim.plant_context)
        faces.append(
            sum(
                results.hydroelastic_contact_info(i).contact_surface().num_faces()
                for i in range(results.num_hydroelastic_contacts())
            )
        )

    env.sim.step = timed_step
    for action in episode.joint_action:
        if env.done:
            break
        env.step(np.asarray(action, dtype=float))
    simulated = env.steps / episode.fps
    return {
        "simulated_s": simulated,
        "physics_cpu_s": physics,
        "faces": float(np.mean(faces)),
        "success": bool(env.info()["success"]),
    }


def measure(path: Path, variant: str) -> dict:
    cmd = [sys.executable, __file__, "--one", str(path), variant]
    run = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ})
    if run.returncode:
        raise RuntimeError(f"{variant} on {path}: {run.stderr[-2000:]}")
    return json.loads(run.stdout.strip().splitlines()[-1])


def table(results: dict[str, dict[str, list[dict]]]) -> str:
    lines = [
        "| task | variant | replay succeeds | physics CPU s (median) | simulated s "
        "| **real-time factor** | vs default | faces per step |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for task, by_variant in results.items():
        base = None
        for variant, runs in by_variant.items():
            cpu = statistics.median(r["physics_cpu_s"] for r in runs)
            simulated = runs[0]["simulated_s"]
            rtf = simulated / cpu
            base = base or rtf
            ok = sum(r["success"] for r in runs)
            lines.append(
                f"| {task} | {variant} | {ok}/{len(runs)} | {cpu:.1f} | {simulated:.1f} "
                f"| **{rtf:.2f}** | {rtf / base:.2f}x | {runs[0]['faces']:.0f} |"
            )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", default="jigsaw,handover_block_with_bowls,cook")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--variants", default="all", help="'all' or comma-separated names")
    parser.add_argument("--data", type=Path, default=Path("/tmp/bench-levers"))
    parser.add_argument("--out", type=Path, help="append the table to this markdown file")
    parser.add_argument("--one", nargs=2, metavar=("EPISODE", "VARIANT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(replay_once(Path(args.one[0]), args.one[1])))
        return 0
    variants = list(VARIANTS) if args.variants == "all" else args.variants.split(",")
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown variants {unknown}; valid: {list(VARIANTS)}")
    tasks = args.tasks.split(",")
    paths = {task: episode_path(args.data, task, args.seed) for task in tasks}
    results: dict[str, dict[str, list[dict]]] = {t: {v: [] for v in variants} for t in tasks}
    loads = []
    for repeat in range(args.repeats):
        for task in tasks:
            for variant in variants:
                loads.append(os.getloadavg()[0])
                results[task][variant].append(measure(paths[task], variant))
                print(f"repeat {repeat + 1}, {task}, {variant}: {results[task][variant][-1]}")
    machine = f"{platform.machine()}, nproc = {os.cpu_count()}, Python {platform.python_version()}"
    report = (
        f"\n## {datetime.now(UTC):%Y-%m-%d %H:%M} UTC, seed {args.seed}, "
        f"{args.repeats} repeats\n\n"
        f"`python benchmarks/bench_physics_levers.py --tasks {args.tasks} --seed {args.seed} "
        f"--repeats {args.repeats}`; {machine}; 1-minute load {min(loads):.1f}-{max(loads):.1f}."
        f"\n\n{table(results)}\n"
    )
    print(report)
    if args.out:
        with args.out.open("a") as f:
            f.write(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())

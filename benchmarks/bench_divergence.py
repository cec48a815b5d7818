"""Recorded policy actions replayed under physics variants: does the simulation stay sane?

    python benchmarks/bench_divergence.py                         # all recorded streams
    python benchmarks/bench_divergence.py --variants default,sap --out table.md

Each file in ``benchmarks/data/divergence`` is the action stream (``(T, 14)`` joint targets and
openings, ``.npy``) a Diffusion Policy baseline produced closed loop on one evaluation seed of a
task, named ``<task>__<seed>.npy``; the streams are stored as the servos would follow them (each
target moving no faster than its joint's ``velocity_limit``, the openings no faster than the
fingers' speed, from the home action), so what they ask of the robot is physically possible.
Every stream is replayed open loop on its seed's scene in each variant (``StationConfig``
fields) without cameras. Per variant the table gives how many replays diverged (a non-finite
state: :class:`~bicoord_drake.sim.simulation.PhysicsDivergedError`), the highest speed any task
object reached (a cube struck by a finger moving at the servos' speed leaves at a few m/s; tens
of m/s means the contact solver added energy), and the CPU time of the replays.

This is a stress test of the physics, not a judgement of a variant: a variant is adopted only if
the experts keep working in it (``benchmarks/bench_expert_physics.py``). Results and the
mechanism: bench_expert_physics.md, "Policy actions under the lagged approximation".
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE / "data" / "divergence"

#: Physics variants: StationConfig fields over the defaults.
VARIANTS: dict[str, dict] = {
    "default": {},
    "sap": {"contact_approximation": "sap"},
    "similar": {"contact_approximation": "similar"},
    "lagged 1/180 s": {"time_step": 1 / 180},
    "lagged 1/240 s": {"time_step": 1 / 240},
    "sap 1/90 s": {"contact_approximation": "sap", "time_step": 1 / 90},
    "sap beta 0.1": {"contact_approximation": "sap", "sap_near_rigid_threshold": 0.1},
    "sap beta 0": {"contact_approximation": "sap", "sap_near_rigid_threshold": 0.0},
    "lagged": {"contact_approximation": "lagged"},
}


def servo_limited(actions: np.ndarray, embodiment, start: np.ndarray, period: float) -> np.ndarray:
    """`actions` as targets that move no faster than the servos: each step's change clipped to
    the joint velocity limits and the fingers' speed (as a fraction of the stroke) times the
    control period, starting from the action `start`."""
    max_step = embodiment.action_speed_limits() * period
    out, current = np.empty_like(actions), np.asarray(start, dtype=float)
    for k, a in enumerate(actions):
        current = current + np.clip(a - current, -max_step, max_step)
        out[k] = current
    return out


def replay(task: str, seed: int, actions: np.ndarray, fields: dict) -> dict:
    """Replay `actions` on `task`'s scene for `seed` in the physics `fields`."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.env import Env
    from bicoord_drake.episode_setup import EpisodeSetup
    from bicoord_drake.sim.simulation import PhysicsDivergedError

    env = Env(EpisodeSetup(task=task, seed=seed, station=StationConfig(render=False, **fields)))
    env.reset(seed)
    plant, context = env.sim.station.plant, env.sim.plant_context
    bodies = [plant.get_body(i) for i in plant.GetFloatingBaseBodies()]
    peak, diverged, steps = 0.0, False, 0
    t0 = time.process_time()
    try:
        for action in actions:
            if env.done:
                break
            env.step(action)
            steps += 1
            for body in bodies:
                v = body.EvalSpatialVelocityInWorld(context).translational()
                peak = max(peak, float(np.linalg.norm(v)))
    except PhysicsDivergedError:
        diverged = True
    return {"peak": peak, "diverged": diverged, "steps": steps, "cpu": time.process_time() - t0}


def streams(directory: Path) -> list[tuple[str, int, Path]]:
    found = []
    for path in sorted(directory.glob("*__*.npy")):
        task, _, seed = path.stem.rpartition("__")
        found.append((task, int(seed), path))
    if not found:
        raise SystemExit(f"no <task>__<seed>.npy action streams in {directory}")
    return found


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="default,sap,lagged 1/240 s", help="comma-separated")
    ap.add_argument("--actions", type=Path, default=DATA, help="directory of action streams")
    ap.add_argument("--out", type=Path, help="append the Markdown table here")
    args = ap.parse_args()
    names = args.variants.split(",")
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        ap.error(f"unknown variants {unknown}; known: {list(VARIANTS)}")
    files = streams(args.actions)
    rows = [
        "| variant | diverged | peak object speed, median / max (m/s) | CPU s |",
        "|---|---:|---:|---:|",
    ]
    for name in names:
        results = []
        for task, seed, path in files:
            r = replay(task, seed, np.load(path), VARIANTS[name])
            print(f"{name:16s} {task} {seed}: {r}", flush=True)
            results.append(r)
        peaks = [r["peak"] for r in results]
        rows.append(
            f"| {name} | {sum(r['diverged'] for r in results)}/{len(results)} | "
            f"{np.median(peaks):.1f} / {max(peaks):.1f} | {sum(r['cpu'] for r in results):.0f} |"
        )
    table = "\n".join(rows)
    print(table)
    if args.out:
        with args.out.open("a") as f:
            f.write(table + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

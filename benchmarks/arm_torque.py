#!/usr/bin/env python
"""Peak arm joint torque an expert asks for, against the actuators' effort limits.

Runs a task's expert in physics (no rendering) for some seeds and, at every plant step, reads
per arm joint the torque the plant applies (its net actuation output: the PD, which SAP
integrates implicitly, plus the gravity feed-forward, after the effort limit). Prints per joint:
the limit, the peak applied torque and the control step where it happened, the share of plant
steps spent at the limit (where the limit binds, the motion wanted more), and the peak joint
speed against its limit.

    python benchmarks/arm_torque.py --task cook --seeds 0-2
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np


def measure(task_name: str, seed: int) -> dict:
    """Peaks of one expert episode: per side, per joint applied torque (and when) and speed."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.planning.errors import PlanningError
    from bicoord_drake.sim.simulation import Simulation
    from bicoord_drake.sim.station import build_station
    from bicoord_drake.stages import StageMonitor, WorldState
    from bicoord_drake.tasks import get_task
    from bicoord_drake.tasks.base import WorldView, expert_actions

    task = get_task(task_name)
    scene = task.sample_scene(seed)
    sim = Simulation(build_station(scene, StationConfig(render=False)))
    st = sim.station
    plant = st.plant
    joints = st.embodiment.arm.joints
    peaks = {
        side: {
            "step": np.zeros(6, dtype=int),
            "applied": np.zeros(6),
            "speed": np.zeros(6),
            "over": np.zeros(6),
        }
        for side in st.arms
    }
    count = [0]

    def monitor(root):
        pc = plant.GetMyContextFromRoot(root)
        count[0] += 1
        for side, inst in st.arms.items():
            v = plant.GetVelocities(pc, inst)[:6]
            applied = np.abs(plant.get_net_actuation_output_port(inst).Eval(pc)[:6])
            p = peaks[side]
            p["step"] = np.where(applied > p["applied"], sim.steps, p["step"])
            p["applied"] = np.maximum(p["applied"], applied)
            p["speed"] = np.maximum(p["speed"], np.abs(v))
            p["over"] += applied >= 0.999 * limits
        from pydrake.systems.framework import EventStatus

        return EventStatus.Succeeded()

    limits = np.array([j.effort_limit for j in joints])
    sim.simulator.set_monitor(monitor)
    monitor_ = StageMonitor(task.stages(scene))
    action = st.embodiment.home_action()
    outcome = "kept"
    try:
        for action in expert_actions(task, scene, WorldView(sim)):
            if sim.steps >= task.step_limit:
                outcome = "step_limit"
                break
            sim.step(action)
            monitor_.update(WorldState.capture(sim, action, scene))
    except PlanningError as err:
        outcome = f"planning: {err}"
    monitor_.finish(WorldState.capture(sim, action, scene))
    if outcome == "kept" and not monitor_.success:
        outcome = "stage_not_verified"
    for p in peaks.values():
        p["over"] = p["over"] / max(count[0], 1)
    return {"outcome": outcome, "peaks": peaks, "steps": sim.steps}


def parse_seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--task", required=True)
    parser.add_argument("--seeds", default="0", help="e.g. 0-2")
    args = parser.parse_args()
    from bicoord_drake.models.viperx import aloha_viperx

    logging.getLogger("drake").setLevel(logging.ERROR)
    joints = aloha_viperx().arm.joints
    rows = []  # per seed and side: applied peaks, their steps, share at limit, speeds
    for seed in parse_seeds(args.seeds):
        t0 = time.perf_counter()
        result = measure(args.task, seed)
        print(
            f"seed {seed}: {result['outcome']}, {result['steps']} steps, "
            f"{time.perf_counter() - t0:.0f} s"
        )
        for side, p in result["peaks"].items():
            print(f"  {side:5s} applied " + " ".join(f"{x:6.2f}" for x in p["applied"]))
            rows.append((seed, side, p))
    print(f"\n{args.task}, seeds {args.seeds}, both arms, worst over seeds")
    print(
        "| joint | effort limit N·m | peak applied N·m (seed, side, control step) "
        "| steps at limit | peak speed rad/s | speed limit rad/s |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for i, j in enumerate(joints):
        seed, side, p = max(rows, key=lambda r: r[2]["applied"][i])
        over = max(r[2]["over"][i] for r in rows)
        speed = max(r[2]["speed"][i] for r in rows)
        print(
            f"| {j.name} | {j.effort_limit:.1f} | {p['applied'][i]:.2f} "
            f"({seed}, {side}, {p['step'][i]}) | {100 * over:.1f} % | {speed:.2f} | "
            f"{j.velocity_limit:.2f} |"
        )


if __name__ == "__main__":
    main()

#!/usr/bin/env python
"""Physics cost of place_plate_and_cup's plates and cups, before and after the cheap models.

    python benchmarks/bench_plate_physics.py [--repeats 5] [--steps 30]

"before" is the model of commit fed6977 (wall slabs reaching down to the table, the plate's
hydroelastic mesh 3 cm, the cup's the default 1 cm); "after" is the task's current model (walls
standing on the base disc, meshes 3 cm and 3.5 cm). Scenes, no rendering, arms at rest:

- empty: the table and the two arms only;
- plate at rest / cup at rest: one plate or one cup of seed 0 on the table;
- cup on plate: a cup standing on a plate's floor;
- rim grasp: the whole seed-0 scene, the expert run until stage 1 counts (the left holds a plate
  by its rim, the right a cup), then that last action held.

Per scene: CPU and wall milliseconds per control step (1/15 s, 20 plant steps), medians over
--repeats consecutive blocks of --steps steps after 5 warm-up steps, and how far the objects
moved during a block (they must stay put: at rest, or in the grasp). Prints Markdown.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from importlib.metadata import version

import numpy as np

from bicoord_drake.config import StationConfig
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.sim.simulation import Simulation, build_station
from bicoord_drake.stages import WorldState
from bicoord_drake.tasks import place_plate_and_cup as ppc
from bicoord_drake.tasks.base import WorldView, expert_actions

SEED = 0
#: The models compared: walls standing on the base?, plate and cup hydroelastic mesh sizes.
MODELS = {
    "before": (False, 0.03, None),
    "after": (True, ppc.PLATE_RESOLUTION, ppc.CUP_RESOLUTION),
}
SCENES = ("empty", "plate at rest", "cup at rest", "cup on plate", "rim grasp")


def task_scene(model: str) -> Scene:
    """Seed 0's scene with the plates and cups of `model`."""
    walls_on_base, plate_hint, cup_hint = MODELS[model]
    scene = ppc.PlacePlateAndCup().sample_scene(SEED)
    objects = []
    for obj in scene.objects:
        if obj.name in ppc.PLATES + ppc.CUPS:
            hint = plate_hint if obj.name in ppc.PLATES else cup_hint
            shape = obj.shape.model_copy(update={"walls_on_base": walls_on_base})
            obj = obj.model_copy(update={"shape": shape, "resolution_hint": hint})
        objects.append(obj)
    return scene.model_copy(update={"objects": tuple(objects)})


def probe_scene(model: str, which: str) -> Scene:
    """A scene of only the objects `which` names (the cup moved onto the plate's floor)."""
    full = task_scene(model)
    plate, cup = full.object("plate_0"), full.object("cup_0")
    objects = {
        "empty": [],
        "plate at rest": [plate],
        "cup at rest": [cup],
        "cup on plate": [
            plate,
            cup.model_copy(
                update={"pose": Pose(xyz=(*plate.pose.xyz[:2], TABLE_TOP + ppc.PLATE.wall))}
            ),
        ],
    }[which]
    return full.model_copy(update={"objects": tuple(objects)})


def ready(model: str, which: str) -> tuple[Simulation, np.ndarray]:
    """A simulation of `which` and the action to hold in it."""
    config = StationConfig(render=False)
    if which != "rim grasp":
        sim = Simulation(build_station(probe_scene(model, which), config))
        return sim, sim.station.embodiment.home_action()
    task = ppc.PlacePlateAndCup()
    scene = task_scene(model)
    sim = Simulation(build_station(scene, config))
    lifted = task.stages(scene)[0].predicate  # a plate and a cup lifted together
    for action in expert_actions(task, scene, WorldView(sim)):
        sim.step(action)
        if lifted(WorldState.capture(sim, action, scene)) == 1:
            return sim, action
    raise RuntimeError(f"{model}: the expert ended before stage 1 counted")


def measure(model: str, which: str, steps: int, repeats: int) -> list[tuple[float, float, float]]:
    """Per block of `steps`: CPU and wall ms per control step, and the largest object drift
    (mm) during the block; `repeats` consecutive blocks after 5 warm-up steps."""
    sim, action = ready(model, which)
    for _ in range(5):
        sim.step(action)
    blocks = []
    for _ in range(repeats):
        start = {k: v[:3].copy() for k, v in sim.object_poses().items()}
        cpu, wall = time.process_time(), time.perf_counter()
        for _ in range(steps):
            sim.step(action)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        end = sim.object_poses()
        drift = max((np.linalg.norm(end[k][:3] - p) for k, p in start.items()), default=0.0)
        blocks.append((1000 * cpu / steps, 1000 * wall / steps, 1000 * float(drift)))
    return blocks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument(
        "--scenes", default=",".join(SCENES), help="comma list of: " + ", ".join(SCENES)
    )
    args = parser.parse_args()
    machine = platform.processor() or platform.machine()
    print(f"Machine: {machine}, drake {version('drake')}, Python {platform.python_version()}; ")
    print(f"medians of {args.repeats} blocks x {args.steps} steps")
    print()
    print("| scene | model | CPU ms / control step | wall ms / control step | drift, mm |")
    print("|---|---|---|---|---|")
    scenes = [w.strip() for w in args.scenes.split(",")]
    unknown = [w for w in scenes if w not in SCENES]
    if unknown:
        parser.error(f"unknown scenes {unknown}; valid: {', '.join(SCENES)}")
    for which in scenes:
        for model in MODELS:
            runs = measure(model, which, args.steps, args.repeats)
            cpu, wall, drift = (statistics.median(col) for col in zip(*runs, strict=True))
            print(f"| {which} | {model} | {cpu:.1f} | {wall:.1f} | {drift:.2f} |", flush=True)


if __name__ == "__main__":
    main()

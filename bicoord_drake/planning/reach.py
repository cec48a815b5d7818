"""Where an arm reaches: which table points a robot's TCP reaches with the gripper pointing
straight down, by inverse kinematics on a plant built from the embodiment alone (no scene, no
station). A robot-independent tool for placing a new robot's bases (docs/adding_a_robot.md;
the Panda's placement: benchmarks/franka_reach.md, tests/models/test_franka.py).

    python -m bicoord_drake.planning.reach                # franka_pair, 5 cm grid, kinematic
    python -m bicoord_drake.planning.reach --collisions   # 10 cm grid, collision-free
"""

from __future__ import annotations

import numpy as np
from pydrake.all import (
    AddMultibodyPlantSceneGraph,
    Box,
    DiagramBuilder,
    InverseKinematics,
    Parser,
    ProximityProperties,
    RigidTransform,
    RollPitchYaw,
    SnoptSolver,
)

from bicoord_drake.models.embodiment import SIDES, Embodiment, arm_sdf
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.models.table import TABLE_SIZE, TABLE_THICKNESS


def table_grid(step: float, heights: tuple[float, ...]) -> np.ndarray:
    """(N, 3) points covering the table top (1.2 m x 0.7 m, edges included) every `step` m,
    at each of `heights` (world z)."""
    sx, sy = TABLE_SIZE
    xs = np.linspace(-sx / 2, sx / 2, int(round(sx / step)) + 1)
    ys = np.linspace(-sy / 2, sy / 2, int(round(sy / step)) + 1)
    return np.array([(x, y, z) for z in heights for y in ys for x in xs])


def reachable_down(
    embodiment: Embodiment,
    side: str,
    points: np.ndarray,
    *,
    avoid_collisions: bool = False,
    restarts: int = 8,
    seed: int = 0,
) -> np.ndarray:
    """Which world `points` that arm's TCP reaches with the gripper pointing straight down
    (any yaw, fingers open), by IK (pydrake InverseKinematics + SNOPT) on a plant built from
    :func:`arm_sdf`: seeded from the previous point's solution and from home, then from up to
    `restarts` random configurations. With `avoid_collisions` the arm must also keep clear
    (signed distance >= 0) of itself, of the table top and of the other arm, which stands at
    home."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.0)
    arms = {}
    for s in SIDES if avoid_collisions else (side,):
        (arms[s],) = Parser(plant).AddModelsFromString(arm_sdf(embodiment, f"{s}_arm"), "sdf")
        base = embodiment.base_pose(s)
        plant.WeldFrames(
            plant.world_frame(),
            plant.GetFrameByName(embodiment.arm.base.name, arms[s]),
            RigidTransform(RollPitchYaw(base.rpy), base.xyz),
        )
    if avoid_collisions:
        plant.RegisterCollisionGeometry(
            plant.world_body(),
            RigidTransform([0.0, 0.0, TABLE_TOP - TABLE_THICKNESS / 2]),
            Box(*TABLE_SIZE, TABLE_THICKNESS),
            "table_top",
            ProximityProperties(),
        )
    plant.Finalize()
    diagram = builder.Build()
    context = plant.GetMyMutableContextFromRoot(diagram.CreateDefaultContext())
    inst = arms[side]
    tcp = plant.GetFrameByName("tcp", inst)
    n = embodiment.num_arm_joints
    open_ = embodiment.arm.gripper.finger_max
    # every arm at its home with open fingers; this arm's entries of the position vector
    q_home = np.zeros(plant.num_positions())
    for arm_side, other in arms.items():
        home = np.concatenate([embodiment.home_of(arm_side), [open_, open_]])
        plant.SetPositionsInArray(other, home, q_home)
    mine = plant.GetPositionsFromArray(inst, np.arange(plant.num_positions())).astype(int)
    lower, upper = plant.GetPositionLowerLimits()[mine], plant.GetPositionUpperLimits()[mine]
    rng = np.random.default_rng(seed)
    solver = SnoptSolver()

    def solve(p: np.ndarray, q0: np.ndarray) -> np.ndarray | None:
        ik = InverseKinematics(plant, context)
        q = ik.q()
        # two points of the gripper's x axis pin the TCP and point the gripper down (a
        # well-conditioned form of "angle = 0"); the yaw about the vertical stays free
        ik.AddPositionConstraint(tcp, [0, 0, 0], plant.world_frame(), p - 1e-4, p + 1e-4)
        below = p - [0.0, 0.0, 0.1]
        ik.AddPositionConstraint(tcp, [0.1, 0, 0], plant.world_frame(), below - 1e-4, below + 1e-4)
        fixed = np.setdiff1d(np.arange(plant.num_positions()), mine[:n])  # fingers, other arm
        ik.get_mutable_prog().AddBoundingBoxConstraint(q_home[fixed], q_home[fixed], q[fixed])
        if avoid_collisions:
            ik.AddMinimumDistanceLowerBoundConstraint(0.0, 0.01)
        q_init = q_home.copy()
        q_init[mine] = q0
        try:
            result = solver.Solve(ik.prog(), q_init)
        except RuntimeError:  # FCL's GJK occasionally fails on nearly touching capsules
            return None
        return result.GetSolution(q)[mine] if result.is_success() else None

    ok = np.zeros(len(points), dtype=bool)
    last = home
    for i, p in enumerate(np.asarray(points, dtype=float)):
        seeds = [last, home] + [
            np.concatenate([rng.uniform(lower[:n], upper[:n]), [open_, open_]])
            for _ in range(restarts)
        ]
        for q0 in seeds:
            q = solve(p, q0)
            if q is not None:
                ok[i], last = True, q
                break
    return ok


if __name__ == "__main__":  # python -m bicoord_drake.planning.reach [--collisions]
    import sys
    import time

    from bicoord_drake.models.franka import franka_pair

    e = franka_pair()
    avoid = "--collisions" in sys.argv
    step = 0.1 if avoid else 0.05
    pts = table_grid(step, (0.76, 0.85, 0.95))
    t0 = time.time()
    reach = {s: reachable_down(e, s, pts, avoid_collisions=avoid) for s in SIDES}
    either, both = reach["left"] | reach["right"], reach["left"] & reach["right"]
    print(f"{len(pts)} points ({step * 100:.0f} cm grid x 3 heights), collisions avoided: {avoid}")
    for z in np.unique(pts[:, 2]):
        m = pts[:, 2] == z
        print(
            f"z={z:.2f}: left {reach['left'][m].mean():.1%} right {reach['right'][m].mean():.1%}"
            f" either {either[m].mean():.1%} both {both[m].mean():.1%}"
        )
    centre = (np.abs(pts[:, 0]) <= 0.15) & (np.abs(pts[:, 1]) <= 0.15)
    print(f"centre |x|,|y| <= 0.15: both arms {both[centre].mean():.1%}")
    for p in pts[~either]:
        print("unreached", p)
    print(f"{time.time() - t0:.1f} s")

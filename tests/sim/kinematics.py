"""Small kinematic helpers for station tests (the planning library has the real IK)."""

from __future__ import annotations

import numpy as np
from pydrake.all import InverseKinematics, RigidTransform, RotationMatrix, Solve

from bicoord_drake.sim.station import Station

#: Gripper x down (approach), fingers closing along world x.
R_TOP_DOWN = RotationMatrix(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]]))


def solve_arm_ik(
    station: Station, side: str, X_WT: RigidTransform, q_seed: np.ndarray, opening: float = 1.0
) -> np.ndarray:
    """Six joint angles putting `side`'s TCP at X_WT (1 mm, 0.01 rad); asserts success."""
    plant = station.control_plant
    arms = {
        "left": plant.GetModelInstanceByName("left_arm"),
        "right": plant.GetModelInstanceByName("right_arm"),
    }
    ik = InverseKinematics(plant)
    tcp = plant.GetFrameByName("tcp", arms[side])
    p = X_WT.translation()
    ik.AddPositionConstraint(tcp, [0, 0, 0], plant.world_frame(), p - 1e-3, p + 1e-3)
    ik.AddOrientationConstraint(tcp, RotationMatrix(), plant.world_frame(), X_WT.rotation(), 0.01)
    prog = ik.get_mutable_prog()
    q = ik.q()
    finger = station.embodiment.arm.gripper.finger_position(opening)
    q0 = plant.GetPositions(plant.CreateDefaultContext()).copy()
    for s, inst in arms.items():
        idx = [
            plant.GetJointByName(n, inst).position_start()
            for n in station.embodiment.arm.joint_names
        ]
        fidx = [
            plant.GetJointByName(n, inst).position_start()
            for n in ("left_finger_joint", "right_finger_joint")
        ]
        for i in fidx:
            prog.AddBoundingBoxConstraint(finger, finger, q[i])
            q0[i] = finger
        if s == side:
            q0[idx] = q_seed
            prog.AddQuadraticErrorCost(np.eye(6), q_seed, q[idx])
        else:
            for i in idx:
                prog.AddBoundingBoxConstraint(q0[i], q0[i], q[i])
    result = Solve(prog, q0)
    assert result.is_success(), f"test IK failed for {side} at {p}"
    sol = result.GetSolution(q)
    return sol[
        [
            plant.GetJointByName(n, arms[side]).position_start()
            for n in station.embodiment.arm.joint_names
        ]
    ]


def joint_ramp(q_from: np.ndarray, q_to: np.ndarray, steps: int) -> np.ndarray:
    """Cosine-eased joint interpolation, `steps` samples excluding the start."""
    s = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, steps + 1)[1:])
    return q_from + s[:, None] * (q_to - q_from)

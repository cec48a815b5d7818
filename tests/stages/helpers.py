"""Synthetic scenes and world states for stage tests (no Drake)."""

from __future__ import annotations

import math

import numpy as np

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BowlShape, CylinderShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.stages.stage import WorldState

IDENTITY = (1.0, 0.0, 0.0, 0.0)


def scene() -> Scene:
    """Two cubes (4 and 6 cm), a bowl and a roller lying along x."""
    return Scene(
        name="synthetic",
        seed=0,
        objects=(
            cube("small", -0.1, 0.0, size=0.04),
            cube("large", 0.1, 0.0, size=0.06),
            SceneObject(
                name="bowl",
                shape=BowlShape(radius=0.07, base_radius=0.045, height=0.05),
                pose=Pose(xyz=(0.2, -0.1, TABLE_TOP)),
            ),
            SceneObject(
                name="roller",
                shape=CylinderShape(radius=0.02, length=0.35),
                pose=Pose(xyz=(0.0, -0.2, TABLE_TOP + 0.02), rpy=(0.0, math.pi / 2, 0.0)),
            ),
        ),
    )


def quat_about(axis: str, angle: float) -> tuple[float, float, float, float]:
    """Quaternion wxyz of a rotation by `angle` about a world axis."""
    v = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}[axis]
    s = math.sin(angle / 2)
    return (math.cos(angle / 2), v[0] * s, v[1] * s, v[2] * s)


def pose(x: float, y: float, z: float, quat=IDENTITY) -> np.ndarray:
    return np.array([x, y, z, *quat], dtype=float)


def state(
    sc: Scene | None = None,
    *,
    poses: dict | None = None,
    openings: tuple[float, float] = (1.0, 1.0),
    contacts: dict | None = None,
    finger_contacts: dict | None = None,
    velocities: dict | None = None,
    step: int = 0,
) -> WorldState:
    """The scene's initial state with some poses, gripper commands, contacts overridden.

    `contacts` are the robot contacts (any arm body); `finger_contacts` default to them."""
    sc = sc or scene()
    base = WorldState.initial(sc)
    object_poses = {**base.object_poses, **(poses or {})}
    action = np.zeros(14)
    action[6], action[13] = openings
    return WorldState(
        scene=sc,
        step=step,
        time=step / 15,
        object_poses=object_poses,
        action=action,
        contacts=contacts or {},
        finger_contacts=finger_contacts,
        object_velocities={**base.object_velocities, **(velocities or {})},
    )

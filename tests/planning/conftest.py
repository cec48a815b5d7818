"""Shared fixtures and case generators of the IK and motion tests."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.all import RigidTransform, RollPitchYaw, RotationMatrix

from bicoord_drake.models.scene import demo_scene
from bicoord_drake.planning.ik import BimanualIK, TcpTarget
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.motion import sample_configuration, table_region

#: TCPs of a "swap" goal: the left one on the right half of the table and vice versa.
SWAP_X = 0.02


@pytest.fixture(scope="module")
def cubes_model() -> PlanningModel:
    """The 'cubes' demo scene; tests that change its state must undo it."""
    return PlanningModel(demo_scene("cubes"))


@pytest.fixture(scope="module")
def cubes_ik(cubes_model) -> BimanualIK:
    return BimanualIK(cubes_model)


def top_down(x: float, y: float, z: float, yaw: float = 0.0) -> RigidTransform:
    """A TCP pose with the gripper's approach axis (x) pointing down."""
    R = RotationMatrix.MakeZRotation(yaw) @ RotationMatrix(RollPitchYaw(0.0, np.pi / 2, 0.0))
    return RigidTransform(R, [x, y, z])


def reachable_targets(model: PlanningModel, rng: np.random.Generator, n: int):
    """`n` target pairs: FK of random collision-free configurations (3 cm between the arms,
    1 cm to the rest) with both TCPs above the table."""
    region = table_region()
    out = []
    for _ in range(n):
        q = sample_configuration(model, rng, tcp_regions={"left": region, "right": region})
        out.append({side: TcpTarget(model.tcp_pose(q, side)) for side in ("left", "right")})
    return out


def swap_cases(model: PlanningModel, ik: BimanualIK, rng: np.random.Generator, n: int):
    """`n` (start, goal) pairs: a home-like start and an IK goal (seeded from home) whose TCP
    targets have the arms crossed - left TCP on the right half of the table, right on the left.
    """
    lo, hi = table_region()
    regions = {
        "left": (np.array([SWAP_X, lo[1], lo[2]]), hi),
        "right": (lo, np.array([-SWAP_X, hi[1], hi[2]])),
    }
    cases = []
    while len(cases) < n:
        q = sample_configuration(model, rng, tcp_regions=regions)
        goal = ik.solve({s: TcpTarget(model.tcp_pose(q, s)) for s in ("left", "right")})
        while True:
            start = model.home + rng.normal(0.0, 0.05, 12)
            model.set_padding(0.03, 0.01)
            if model.collision_free(start):
                break
        cases.append((start, goal))
    return cases

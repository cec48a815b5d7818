"""Sliding a held object: :func:`pull` drags it along a straight line, TCP orientation kept.

A side-grasped block can be pulled out from under a stack (or off a platform) this way: the
TCP follows the line exactly at every control sample (:func:`~.tracking.track`), so the block
slides on its support without lifting off or swinging aside.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.skills.core import ArmPlan, SkillContext
from bicoord_drake.planning.skills.tracking import track


def pull(
    ctx: SkillContext,
    side: str,
    direction: Sequence[float],
    distance: float,
    *,
    ignore: Iterable[str] = (),
    label: str | None = None,
) -> ArmPlan:
    """Drag what `side` holds `distance` (m) along the world `direction` in a straight line,
    the gripper's orientation unchanged. Objects in `ignore` (the support it slides on) are
    not collision-checked; the held object is."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to pull")
    d = np.asarray(direction, dtype=float)
    norm = float(np.linalg.norm(d))
    if norm < 1e-9 or distance <= 0:
        raise ValueError(f"pull needs a direction and a positive distance, got {d}, {distance}")
    d = d / norm * distance
    X = ctx.model.tcp_pose(ctx.q, side)
    p0 = X.translation()

    def pose_at(s: float) -> RigidTransform:
        return RigidTransform(X.rotation(), p0 + s * d)

    name = label or f"pull {held.name}"
    return track(ctx, side, pose_at, distance, 0.0, label=name, ignore=ignore)

"""A move above clean_table's bin, shared by the turn-taking tests."""

import numpy as np
from pydrake.all import RigidTransform

import bicoord_drake.tasks.clean_table as ct
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.skills import ArmPlan, SkillContext, move_tcp


def to_bin(ctx: SkillContext, side: str, dx: float = 0.0) -> ArmPlan:
    """Move `side`'s TCP 0.2 m above the bin, `dx` along x from its centre, the hand held as at
    home with the waist straight (fingers along world x; the homes' outward spread aside)."""
    straight = np.tile(ctx.model.embodiment.home, 2)
    X = ctx.model.tcp_pose(straight, side)
    above = [ct.BIN_XY[0] + dx, ct.BIN_XY[1], TABLE_TOP + 0.2]
    return move_tcp(ctx, side, RigidTransform(X.rotation(), above))

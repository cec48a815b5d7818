"""balance_roller: both hands lift a long roller level and balance it on a small cube."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from pydrake.all import AngleAxis, RigidTransform, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import CylinderShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.planning.skills import (
    carry_together,
    hold_still,
    merge,
    pick_together,
    release_together,
    retreat,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    at_rest,
    held_by,
    held_for,
    level,
    lifted,
    on_table,
    released,
    rests_on,
    vertical,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

ROLLER, BLOCK = "roller", "block"
#: Roller length and diameter ranges (m), and its density (light wood).
LENGTH = (0.33, 0.37)
DIAMETER = (0.038, 0.042)
ROLLER_DENSITY = 450.0  # kg/m^3: 0.17-0.23 kg
ROLLER_COLOR = (0.78, 0.6, 0.4, 1.0)
#: Where the roller's centre lies (its axis along x) and where the cube stands.
ROLLER_X = (-0.15, 0.15)
ROLLER_Y = (-0.25, -0.15)
BLOCK_XY = (-0.1, 0.1)
BLOCK_EDGE = 0.05
BLOCK_MASS = 0.1
#: Least y distance (m) between the cube's centre and the roller's axis: the fingers
#: straddling the roller must not land on the cube.
MIN_GAP_Y = 0.09
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: Stage 1: the roller's bottom at least this high above the table (m), within this tilt.
LIFT_HEIGHT = 0.06
MAX_TILT = math.radians(10)
#: Stage 2: the roller's centre within this xy distance (m) of the cube's, seen resting there
#: this long (s) after the release.
XY_TOL = 0.03
STILL_FOR = 1.0
#: Expert: lift (m, the roller's bottom ends LIFT + 2 cm above the table),
#: clearance over the cube while carrying (m).
LIFT = LIFT_HEIGHT + 0.025
HOVER = 0.03
#: Seconds both arms hold still at the end, after the retreat.
SETTLE = 0.27


@register_task
class BalanceRoller(Task):
    """Lift the roller with both hands, level, and balance it on the cube.

    Description: a wooden roller (about 35 cm long, 4 cm across) lies along x in front of the
    robot; a 5 cm cube stands further out. The left hand grasps the roller's left end and the
    right hand its right end (each 4 cm in from the end, from above), both close on the same
    control step and lift it level together; the two hands carry it, their relative pose fixed
    by the one rigid roller, over the cube, lower it onto the cube's top, open on the same step
    and retreat. The roller must stay balanced on the cube.

    Randomization: roller length 33-37 cm and diameter 3.8-4.2 cm; its centre at
    x in [-0.15, 0.15], y in [-0.25, -0.15]; the cube at x, y in [-0.1, 0.1] (the reference's
    ranges; the cube's centre at least 9 cm in y from the roller's axis so that the fingers
    straddling the roller do not land on it) and its colour.

    Stages: (1) both grippers closed on the roller, its bottom at least 6 cm above the table,
    its axis within 10 degrees of horizontal (transient); (2) the roller resting on the cube
    (centre within 3 cm of the cube's in xy, its lowest point on the cube's top), level, both
    grippers open and no finger touching it, the cube upright on the table - all of it without
    a break for 1 s - and the roller at rest (persistent).

    Success: stage 2 holds when the rollout ends: the roller lies released and still on the
    cube and has been there for at least 1 s.
    """

    name = "balance_roller"
    step_limit = 300
    supported_robots = ("aloha_viperx", "franka_pair")
    expert_speed = 0.8
    instructions_seen = (
        "Lift the roller with both hands and balance it on the block.",
        "Pick up the wooden roller with two hands and rest it on top of the cube.",
        "Use both arms to raise the roller level and set it across the block.",
        "Carry the long roller over to the cube with both hands and balance it there.",
        "Hold the roller at both ends, lift it and lay it on the block so it stays put.",
        "Together, lift the rolling pin and balance it on the small cube.",
        "Grab both ends of the roller, bring it over the block and let it rest on top.",
    )
    instructions_unseen = (
        "Balance the wooden cylinder on the cube using both grippers.",
        "Two-handed: move the roller onto the block and leave it balanced.",
        "Lift the long rod together and place it so it balances on the cube.",
        "Set the roller down on top of the coloured block, holding it with both hands.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        length = float(rng.uniform(*LENGTH))
        diameter = float(rng.uniform(*DIAMETER))
        roller_xy = [float(rng.uniform(*ROLLER_X)), float(rng.uniform(*ROLLER_Y))]
        while True:
            block_xy = [float(v) for v in rng.uniform(*BLOCK_XY, size=2)]
            if block_xy[1] - roller_xy[1] >= MIN_GAP_Y:
                break
        color = str(rng.choice(sorted(COLORS)))
        radius = diameter / 2
        roller = SceneObject(
            name=ROLLER,
            shape=CylinderShape(radius=radius, length=length),
            color=ROLLER_COLOR,
            mass=ROLLER_DENSITY * math.pi * radius**2 * length,
            pose=Pose(xyz=(*roller_xy, TABLE_TOP + radius), rpy=(0.0, math.pi / 2, 0.0)),
        )
        block = cube(BLOCK, *block_xy, size=BLOCK_EDGE, color=COLORS[color], mass=BLOCK_MASS)
        return Scene(
            name=self.name,
            seed=seed,
            objects=(roller, block),
            draws={
                "roller_length": length,
                "roller_diameter": diameter,
                "roller_xy": roller_xy,
                "block_xy": block_xy,
                "color": color,
            },
        )

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        lifted_level = all_of(
            held_by(ROLLER, "both"),
            lifted(ROLLER, LIFT_HEIGHT, reference="table"),
            level(ROLLER, axis="z", max_tilt=MAX_TILT),
        )
        balanced = all_of(
            rests_on(ROLLER, BLOCK, xy_tol=XY_TOL),
            level(ROLLER, axis="z", max_tilt=MAX_TILT),
            released(ROLLER),
            vertical(BLOCK, max_tilt=MAX_TILT),
            on_table(BLOCK),
        )
        return [
            Stage(
                "lift the roller together",
                "grasp the left end, lift",
                "grasp the right end, lift",
                0.5,
                lifted_level,
                "transient",
            ),
            Stage(
                "balance it on the block",
                "lower, release, retreat",
                "lower, release, retreat",
                0.5,
                all_of(held_for(balanced, STILL_FOR), at_rest(ROLLER)),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        radius = scene.draws["roller_diameter"] / 2
        block_top = TABLE_TOP + BLOCK_EDGE

        run = partial(follow, ctx, view)

        # ---- stage 1: both hands grasp the ends, close on the same step, lift it level
        yield from run(pick_together(ctx, ROLLER, lift=LIFT))
        # ---- stage 2: carry it over the cube, lower it onto the top, let go together, retreat
        X_WR = ctx.model.held_pose("left", ctx.q)
        R_level = _levelled(X_WR.rotation())
        xy = ctx.model.object_pose(BLOCK).translation()[:2]
        over = RigidTransform(R_level, [*xy, block_top + radius + HOVER])
        yield from run(carry_together(ctx, over, label="carry over the block"))
        on = RigidTransform(R_level, [*xy, block_top + radius + 0.001])
        lower = carry_together(ctx, on, label="lower onto the block", ignore=[ROLLER])
        release = release_together(ctx, gentle=True, ignore=[BLOCK])
        yield from run(lower.then(release))
        away = merge(ctx, retreat(ctx, "left"), retreat(ctx, "right"))
        final = hold_still(ctx, SETTLE)
        yield from away.then(final).actions()


def _levelled(R_WO: RotationMatrix) -> RotationMatrix:
    """The smallest turn of a roller's orientation that brings its axis (z) horizontal."""
    a = R_WO.matrix()[:, 2]
    target = np.array([a[0], a[1], 0.0])
    target /= np.linalg.norm(target)
    axis = np.cross(a, target)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        return R_WO
    angle = math.atan2(s, float(a @ target))
    return RotationMatrix(AngleAxis(angle, axis / s)) @ R_WO

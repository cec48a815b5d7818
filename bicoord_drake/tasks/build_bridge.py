"""build_bridge: each arm sets a pier, then both hands lay a beam across the two piers."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from pydrake.all import RigidTransform, RollPitchYaw

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.planning.clearance import hands_gap, roomy_first
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import Grasp, arm_base, grasp_candidates
from bicoord_drake.planning.skills import (
    ArmPlan,
    SkillContext,
    carry_together,
    hold_still,
    merge,
    pick,
    pick_together,
    place,
    plan_both,
    release_together,
    retreat,
)
from bicoord_drake.planning.skills.pick_place import hand_params
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    hands_free,
    held_by,
    level,
    lifted,
    on_table,
    settled,
    spaced,
    spans,
    untouched,
    vertical,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

BEAM, LEFT_PIER, RIGHT_PIER = "beam", "pier_left", "pier_right"
PIERS = (LEFT_PIER, RIGHT_PIER)
#: Beam length and section side (m); the piers are cubes of the section side.
LENGTH = (0.24, 0.32)
SECTION = (0.04, 0.06)
BEAM_DENSITY = 400.0  # kg/m^3: 0.15-0.46 kg
BEAM_COLOR = (0.72, 0.55, 0.36, 1.0)
PIER_MASS = 0.1
#: Where the beam lies (its length along x) and where the piers start (yaw in +-PIER_YAW).
BEAM_X = (-0.05, 0.05)
BEAM_Y = (0.06, 0.10)
PIER_X = {LEFT_PIER: (-0.15, -0.05), RIGHT_PIER: (0.05, 0.15)}
PIER_Y = (-0.10, -0.05)
PIER_YAW = 0.75
#: The bridge site: the piers go at y = SITE_Y, centred on the beam's x, (length - side) apart.
SITE_Y = -0.04
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: Stage 1: each pier raised this much (m). Stage 2: spacing tolerance (m). Stage 3: the
#: beam raised this much (m), within this tilt of level.
PIER_LIFT = 0.03
SPACING_TOL = 0.04
BEAM_LIFT = 0.03
MAX_TILT = math.radians(10)
#: Expert: beam lift above the piers' tops (m), hover before lowering (m),
#: the release ramps (s).
CLEAR = 0.03
HOVER = 0.02
#: Seconds both arms hold still at the end (the placements must be seen settled).
SETTLE = 0.53


@register_task
class BuildBridge(Task):
    """Set two cubes as piers the beam's length apart, then lay the beam across them together.

    Description: a wooden beam lies along x beyond two cubes of its section side. Each arm picks
    the cube on its side and both place them at once at the bridge site (y = -0.04, centred on
    the beam's x), their centres the beam's length minus one side apart, so that each beam end
    rests on a whole pier. Then both hands grasp the beam near its ends (from above, close on
    the same step), lift it level over the piers, carry it to the site, lower it onto both piers,
    open on the same step and retreat.

    Randomization: beam length 24-32 cm; section side s 4-6 cm (the reference draws 4-8 cm; our
    grippers open to 9 cm, so an 8 cm cube does not fit between the pads), the cubes' side s;
    the beam at x in [-0.05, 0.05], y in [0.06, 0.10]; the left cube at x in [-0.15, -0.05], the
    right at [0.05, 0.15], both at y in [-0.10, -0.05], yaw in +-0.75 rad (the reference's
    ranges); the cubes' colour.

    Stages: (1) both cubes lifted 3 cm (transient); (2) both cubes on the table, upright, no
    finger on them, their centres (length - s) apart within 4 cm (persistent); (3) the beam held
    by both hands, lifted 3 cm, within 10 degrees of level (transient); (4) the beam across both
    piers (each pier's top centre under the beam, the beam's bottom on both tops), both grippers
    open and no finger on the beam or the piers, all three at rest for 0.3 s (persistent).

    Success: stages 2 and 4 hold when the rollout ends: the piers stand the beam's length apart
    and the released beam rests on both.
    """

    name = "build_bridge"
    step_limit = 900
    supported_robots = ("aloha_viperx", "franka_pair")
    expert_speed = 0.8
    instructions_seen = (
        "Place the two blocks as piers and lay the beam across them with both hands.",
        "Build a bridge: set the cubes apart, then put the beam on top of both.",
        "Use each arm to position a block, then lift the beam together and rest it on the blocks.",
        "Make a little bridge out of the two cubes and the long wooden beam.",
        "Put the cubes a beam's length apart and bridge them with the beam.",
        "Set up two supports with the blocks and lay the plank over them using both grippers.",
        "Move the blocks into place as pillars, then carry the beam over and set it across.",
    )
    instructions_unseen = (
        "Construct a bridge from the beam and the two cubes.",
        "Arrange the two blocks so the beam can span them, then place the beam on both.",
        "Both arms: position the piers, then lay the long bar across them.",
        "Stand the cubes apart and balance the wooden beam on top of the pair.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        length = float(rng.uniform(*LENGTH))
        side = float(rng.uniform(*SECTION))
        beam_xy = [float(rng.uniform(*BEAM_X)), float(rng.uniform(*BEAM_Y))]
        piers = {
            name: [
                float(rng.uniform(*PIER_X[name])),
                float(rng.uniform(*PIER_Y)),
                float(rng.uniform(-PIER_YAW, PIER_YAW)),
            ]
            for name in PIERS
        }
        color = str(rng.choice(sorted(COLORS)))
        beam = SceneObject(
            name=BEAM,
            shape=BoxShape(size=(length, side, side)),
            color=BEAM_COLOR,
            mass=BEAM_DENSITY * length * side * side,
            pose=Pose(xyz=(*beam_xy, TABLE_TOP + side / 2)),
        )
        cubes = [
            cube(n, x, y, size=side, color=COLORS[color], mass=PIER_MASS, yaw=yaw)
            for n, (x, y, yaw) in piers.items()
        ]
        return Scene(
            name=self.name,
            seed=seed,
            objects=(beam, *cubes),
            draws={
                "beam_length": length,
                "section": side,
                "beam_xy": beam_xy,
                **{f"{name}_xy_yaw": xyy for name, xyy in piers.items()},
                "color": color,
            },
        )

    @staticmethod
    def sites(scene: Scene) -> dict[str, tuple[float, float]]:
        """Where the expert sets each pier: centred on the beam's x, (length - s) apart."""
        half = (scene.draws["beam_length"] - scene.draws["section"]) / 2
        x = scene.draws["beam_xy"][0]
        return {LEFT_PIER: (x - half, SITE_Y), RIGHT_PIER: (x + half, SITE_Y)}

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        spacing = scene.draws["beam_length"] - scene.draws["section"]
        piers_set = all_of(
            *[on_table(p) for p in PIERS],
            *[vertical(p, max_tilt=MAX_TILT) for p in PIERS],
            *[untouched(p) for p in PIERS],
            spaced(LEFT_PIER, RIGHT_PIER, spacing, tol=SPACING_TOL),
        )
        beam_up = all_of(
            held_by(BEAM, "both"),
            lifted(BEAM, BEAM_LIFT),
            level(BEAM, axis="x", max_tilt=MAX_TILT),
        )
        laid = all_of(
            spans(BEAM, PIERS),
            hands_free([BEAM, *PIERS]),
            settled([BEAM, *PIERS]),
        )
        return [
            Stage(
                "pick the piers",
                "pick the left cube",
                "pick the right cube",
                0.0,
                all_of(*[lifted(p, PIER_LIFT) for p in PIERS]),
                "transient",
            ),
            Stage(
                "place the piers",
                "place the cube at the left pier spot",
                "place the cube at the right pier spot",
                0.5,
                piers_set,
                "persistent",
            ),
            Stage(
                "lift the beam",
                "grasp the left end, lift",
                "grasp the right end, lift",
                0.0,
                beam_up,
                "transient",
            ),
            Stage(
                "lay the beam",
                "lower onto the left pier, release",
                "lower onto the right pier, release",
                0.5,
                laid,
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        side = scene.draws["section"]
        top = TABLE_TOP + side  # the piers' tops

        run = partial(follow, ctx, view)

        # ---- stage 1: each arm picks the cube on its side, at the same time
        picks = {
            side: partial(pick, ctx, side, pier) for side, pier in zip(SIDES, PIERS, strict=True)
        }
        try:
            both = plan_both(ctx, picks)
        except PlanningError:  # the hands meet over the piers: grasps that keep them apart
            apart = {
                side: partial(_pick_apart, ctx, side, pier, other)
                for side, pier, other in zip(SIDES, PIERS, PIERS[::-1], strict=True)
            }
            both = plan_both(ctx, apart)
        yield from run(merge(ctx, *both))
        # ---- stage 2: both set their cube at its pier spot, square to the beam, at once
        goals = {
            p: RigidTransform([x, y, TABLE_TOP + side / 2])
            for p, (x, y) in self.sites(scene).items()
        }
        places = {
            side: partial(place, ctx, side, goals[pier], gentle_release=True)
            for side, pier in zip(SIDES, PIERS, strict=True)
        }
        yield from run(merge(ctx, *plan_both(ctx, places)))
        # ---- stage 3: both hands grasp the beam's ends, close together, lift it over the piers
        yield from run(pick_together(ctx, BEAM, lift=side + CLEAR))
        # ---- stage 4: carry it over the piers, lower it onto both, let go together, retreat
        X_WB = ctx.model.held_pose("left", ctx.q)
        piers = [ctx.model.object_pose(p).translation() for p in PIERS]
        mid = (piers[0] + piers[1]) / 2
        # the beam's length along the line through the piers, turned the least from now
        yaw = RollPitchYaw(X_WB.rotation()).yaw_angle()
        line = math.atan2(piers[1][1] - piers[0][1], piers[1][0] - piers[0][0])
        yaw = line + math.pi * round((yaw - line) / math.pi)
        R = RollPitchYaw(0.0, 0.0, yaw).ToRotationMatrix()
        over = RigidTransform(R, [mid[0], mid[1], top + side / 2 + HOVER])
        yield from run(carry_together(ctx, over, label="carry over the piers"))
        on = RigidTransform(R, [mid[0], mid[1], top + side / 2 + 0.001])
        lower = carry_together(ctx, on, label="lower onto the piers", ignore=[BEAM])
        release = release_together(ctx, gentle=True, ignore=list(PIERS))
        yield from run(lower.then(release))
        away = merge(ctx, retreat(ctx, "left"), retreat(ctx, "right"))
        final = hold_still(ctx, SETTLE)
        yield from away.then(final).actions()


# -------------------------------------------------------------------- expert helpers
#: Lifts (m) tried by :func:`_pick_apart`, least first (pick's default first).
APART_LIFTS = (0.10, 0.15, 0.20)


def _pier_grasps(ctx: SkillContext, side: str, pier: str) -> list[Grasp]:
    """The grasps `pick` would generate for `pier` with `side` (best first)."""
    return grasp_candidates(
        ctx.model.object(pier),
        ctx.model.embodiment.arm.gripper,
        X_WO=ctx.model.object_pose(pier),
        base=arm_base(ctx.model.embodiment, side),
        params=hand_params(ctx),
    )


def _pick_apart(ctx: SkillContext, side: str, pier: str, other: str) -> ArmPlan:
    """Pick `pier` with `side` and lift it out of the other hand's way. The piers stand
    14-15 cm apart, too close for two wide hands to hold both at once, so the arm planned
    first (the other holding nothing yet) lifts its pier by the least of APART_LIFTS (m) at
    which its hand (``ArmSpec.hand_boxes``) keeps the arms' clearance (``ctx.clearance``)
    from the other hand at one of its grasps of `other` and their pregrasps
    (:func:`hands_gap`), by the grasps that do first; the arm planned second picks plainly
    (:func:`pick`), around the first's lifted hand."""
    them = other_side(side)
    if them in ctx.model.held:  # planned second: around the other's lifted hand
        return pick(ctx, side, pier)
    boxes = ctx.model.hand_boxes
    mine = _pier_grasps(ctx, side, pier)
    theirs = _pier_grasps(ctx, them, other)

    def margin(g: Grasp, lift: float) -> float:
        up = RigidTransform(g.X_WG.rotation(), g.X_WG.translation() + [0.0, 0.0, lift])
        gaps = [min(hands_gap(boxes, up, X) for X in (h.X_WG, h.X_WPre)) for h in theirs]
        return max(gaps, default=float("inf")) - ctx.clearance

    for lift in APART_LIFTS:
        margins = [margin(g, lift) for g in mine]
        if max(margins, default=0.0) >= 0.0:
            break
    return pick(ctx, side, pier, lift=lift, grasps=roomy_first(mine, margins))

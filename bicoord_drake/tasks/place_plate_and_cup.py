"""place_plate_and_cup: set two places, the left arm laying each plate while the right arm
brings its cup.

Measurements of the expert in physics: benchmarks/bench_task_place_plate_and_cup.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import replace
from functools import partial

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BowlShape, CylinderShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, flat_marker
from bicoord_drake.planning.clearance import roomy_first
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    GraspParams,
    arm_base,
    cylinder_grasps,
    grasp_candidates,
    stack_target,
    table_target,
)
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    SkillContext,
    carry_above,
    hold_still,
    merge,
    pick,
    place,
    plan_both,
    retreat,
)
from bicoord_drake.planning.skills.pick_place import (
    carry_margin,
    hand_params,
    wall_close_opening,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    Predicate,
    all_of,
    any_of,
    count_true,
    hands_free,
    lifted,
    on_table,
    settled,
    stands_in,
    untouched,
    upright,
    within_xy,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

#: A dish held by its rim: a straight 12 mm wall (what holds level in a rim grasp,
#: benchmarks/bench_skills.md), 15 cm across, 3 cm high (a rim grasp needs > 2.25 cm). Its
#: walls stand on its base disc: one contact patch with the table instead of thirteen, ~3x
#: cheaper physics at rest (benchmarks/bench_plate_physics.md); the cup's likewise.
PLATE = BowlShape(
    radius=0.075, base_radius=0.075, height=0.03, wall=0.012, segments=12, walls_on_base=True
)
PLATE_MASS = 0.10
#: Hydroelastic mesh size of the plate (m): its 15 cm base is its only part touching the table
#: (the walls stand on it); 3 cm instead of the default 1 cm makes it cheaper
#: (benchmarks/bench_plate_physics.md).
PLATE_RESOLUTION = 0.03
#: Rim grasp of a plate: its fingertips stay this far (m) above the plate's floor (the top of
#: its 12 mm base), so the 35 mm pads hold the 18 mm of wall above the base (standing above the
#: rim) and never press on the base. With the pads' top 3 mm below the rim, as for a deep bowl,
#: the inside fingertip pressed into the base: the jaw stopped half open on it (the plate hung
#: on that tip) and, under SAP contact, the tip still carried the plate off when the open hand
#: backed off after laying it down. 1 mm (17 mm of wall between the pads; 5 mm tipped the plate
#: up to 40 deg in the hand on seed 6): the closed jaw squeezes the wall lightly (the ViperX's
#: about 6 N), so what resists the plate's tipping is the height of wall it holds.
PLATE_TIP_CLEARANCE = 0.001
#: A cup: 7 cm across, 8 cm high, straight 12 mm wall, picked across its outside at the rim.
CUP = BowlShape(
    radius=0.035, base_radius=0.035, height=0.08, wall=0.012, segments=12, walls_on_base=True
)
CUP_MASS = 0.08
#: Hydroelastic mesh size of the cup (m): its base on the plate's base is a compliant-compliant
#: contact, ~35 % cheaper with 3.5 cm than with the default 1 cm (bench_plate_physics.md).
CUP_RESOLUTION = 0.035
#: Target 1 (left side) and target 2 (right side), table-centred (TASKS.md: (-0.12, -0.15) and
#: (0.15, -0.15)), each jittered by up to TARGET_JITTER; the grey squares are TARGET wide.
TARGETS = ((-0.12, -0.15), (0.15, -0.15))
TARGET_JITTER = 0.015
TARGET = 0.17
#: Where plates (left half) and cups (right half) start, and their least spacing.
PLATE_X, PLATE_Y, PLATE_GAP = (-0.32, -0.10), (-0.02, 0.09), 0.17
CUP_X, CUP_Y, CUP_GAP = (0.08, 0.32), (-0.04, 0.09), 0.10
#: A plate counts as on its target within this (m, xy), a cup as standing on the plate's floor
#: when its bottom is at most CUP_GAP_Z above it.
ON_TARGET = 0.03
CUP_GAP_Z = 0.008
#: Where the cup waits (offset of its bottom from the target and height above the plate's
#: rim, m; the first that plans) while the plate is laid.
HOVER_OFFSETS = (
    (0.0, 0.0, 0.10),
    (0.07, 0.0, 0.10),
    (0.07, 0.05, 0.10),
    (0.0, 0.08, 0.10),
    (0.1, 0.0, 0.15),
    (0.1, 0.08, 0.15),
)
#: Hover goals whose hand room (``carry_margin``, from the hands' boxes) is below this (m) are
#: tried after the others: the boxes read up to 2 cm roomier than the planner's collision
#: geometry between the two grippers (seed 0: 1.2 cm to spare by the boxes, 2.2 cm of the 3 cm
#: clearance found by IK), and such a goal's IK fails only after every yaw's ten restarts
#: (8 x 0.4-0.9 s; the planning was 5 s of seed 0's 7.5 s).
HOVER_ROOM = 0.02
SETTLE = 0.53
PLATE_COLORS = {
    "white": (0.95, 0.95, 0.92, 1.0),
    "cream": (0.95, 0.9, 0.78, 1.0),
    "light blue": (0.75, 0.85, 0.95, 1.0),
}
CUP_COLORS = {
    "red": (0.8, 0.2, 0.2, 1.0),
    "blue": (0.2, 0.35, 0.8, 1.0),
    "green": (0.25, 0.6, 0.3, 1.0),
    "yellow": (0.9, 0.75, 0.2, 1.0),
    "orange": (0.95, 0.5, 0.15, 1.0),
}
PLATES, CUPS = ("plate_0", "plate_1"), ("cup_0", "cup_1")


@register_task
class PlacePlateAndCup(Task):
    """Set two places: each plate on a grey target with a cup standing on it.

    Description: two dishes (15 cm, 3 cm high, straight 12 mm rim, 100 g) lie on the left half
    and two cups (7 cm, 8 cm high, 80 g) stand on the right half; two grey 17 cm squares mark
    the places, target 1 on the left near (-0.12, -0.15) and target 2 on the right near
    (0.15, -0.15). The left arm lifts a plate by its rim while the right arm picks a cup from
    above, across its outside, both at once; the left lays the plate on target 1 while the
    right brings the cup over it and, as soon as the plate is down, sets the cup on it. While
    the right sets the cup, the left picks the second plate; the left carries it over target 2
    while the right picks the second cup; then the second place is set the same way. Layout as
    in TASKS.md; the plates and cups start within y in [-0.04, 0.09] (within reach).

    Randomization: plate positions (x in [-0.32, -0.10], y in [-0.02, 0.09], >= 17 cm apart)
    and cup positions (x in [0.08, 0.32], y in [-0.04, 0.09], >= 10 cm apart and clear of
    target 2); each target +-1.5 cm; the plates' colour and each cup's colour.

    Stages: (1) a plate and a cup lifted together (transient); (2) one place set: a plate on a
    target with a cup standing on it (0.5, persistent); (3) the next plate and cup lifted
    together (transient); (4) both places set, both grippers open (0.5, persistent). A place is
    set when the plate lies flat on the table within 3 cm of the target, the cup stands upright
    inside it on its floor (bottom within 8 mm), no finger touches either and both have been at
    rest for 0.3 s. Any plate with any cup sets either target.

    Success: both targets hold a plate with a cup standing on it, released and at rest, both
    grippers open, at the end.
    """

    name = "place_plate_and_cup"
    step_limit = 700
    supported_robots = ("aloha_viperx", "franka_pair")
    instructions_seen = (
        "Put each plate on a grey mark and set a cup on it.",
        "Lay the two plates on the targets and place a cup on each plate.",
        "Set two places: a plate on each grey square with a cup on top.",
        "Place the plates on the grey targets and stand the cups on them.",
        "Move both plates to the marked spots and put one cup on each.",
        "Use the left hand for the plates and the right for the cups to set both places.",
        "Lay out two plates on the grey squares, each with a cup standing on it.",
    )
    instructions_unseen = (
        "Set the table for two: plates on the marks, a cup on every plate.",
        "Put the dishes on the grey squares and a cup on each dish.",
        "Arrange both plates on the targets and place the cups onto them.",
        "Place a plate and then a cup on it at each of the two grey spots.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        jitter = rng.uniform(-TARGET_JITTER, TARGET_JITTER, size=(2, 2))
        targets = [
            _round((x + dx, y + dy)) for (x, y), (dx, dy) in zip(TARGETS, jitter, strict=True)
        ]
        plates = _spaced(rng, PLATE_X, PLATE_Y, PLATE_GAP, avoid=[])
        cups = _spaced(rng, CUP_X, CUP_Y, CUP_GAP, avoid=[(targets[1], 0.13)])
        plate_color = str(rng.choice(sorted(PLATE_COLORS)))
        cup_colors = [str(c) for c in rng.choice(sorted(CUP_COLORS), size=2, replace=False)]
        objects = [flat_marker(f"target_{k}", xy, TARGET) for k, xy in enumerate(targets)]
        objects += [
            _dish(name, PLATE, xy, PLATE_COLORS[plate_color], PLATE_MASS, PLATE_RESOLUTION)
            for name, xy in zip(PLATES, plates, strict=True)
        ]
        objects += [
            _dish(name, CUP, xy, CUP_COLORS[c], CUP_MASS, CUP_RESOLUTION)
            for name, xy, c in zip(CUPS, cups, cup_colors, strict=True)
        ]
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "target_xy": [list(xy) for xy in targets],
                "plate_xy": [list(xy) for xy in plates],
                "cup_xy": [list(xy) for xy in cups],
                "plate_color": plate_color,
                "cup_colors": cup_colors,
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 4  # two plates, two cups

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        targets = [tuple(xy) for xy in scene.draws["target_xy"]]
        places = [place_set(PLATES, CUPS, xy) for xy in targets]
        return [
            Stage(
                "pick a plate and a cup",
                "pick a plate by its rim",
                "pick a cup from above",
                0.0,
                _plate_and_cup_lifted(),
                "transient",
            ),
            Stage(
                "set the first place",
                "lay the plate on target 1",
                "set the cup onto that plate as it lands",
                0.5,
                count_true(places, 1),
                "persistent",
            ),
            Stage(
                "pick the second plate and cup",
                "pick the second plate, carry it over target 2",
                "pick the second cup",
                0.0,
                _plate_and_cup_lifted(),
                "transient",
            ),
            Stage(
                "set the second place",
                "lay the plate on target 2, retreat",
                "set the cup onto that plate",
                0.5,
                all_of(count_true(places, 2), hands_free(PLATES + CUPS)),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        targets = [tuple(xy) for xy in scene.draws["target_xy"]]
        plates = _order(scene, PLATES, targets[0])  # the nearer plate to target 1 first
        cups = _order(scene, CUPS, targets[0])

        run = partial(follow, ctx, view)

        def plate_goal(xy):
            return table_target(xy, PLATE)

        def cup_goal(plate: str) -> RigidTransform:
            X_WP = view.object_transforms()[plate]
            upright_plate = RigidTransform(X_WP.translation())
            return stack_target(upright_plate, PLATE, CUP, yaw=0.0)

        def hover(xy) -> ArmPlan:
            """Right brings its cup over `xy` (or beside it, clear of the left gripper)."""
            reasons = []
            goals = [
                table_target((xy[0] + dx, xy[1] + dy), CUP, support_z=TABLE_TOP + PLATE.height + dz)
                for dx, dy, dz in HOVER_OFFSETS
            ]
            # the goals where the hand has room first (a wide hand meets the left one at most)
            margins = [carry_margin(ctx, "right", goal, height=0.0) - HOVER_ROOM for goal in goals]
            for goal in roomy_first(goals, margins):
                try:
                    return carry_above(ctx, "right", goal, height=0.0)
                except PlanningError as err:
                    reasons.append(err.reason)
            raise PlanningError("hover_failed", f"right cannot hold its cup near {xy} ({reasons})")

        def pick_plate(name: str):
            """Left picks plate `name` by its rim, the pads pressed at most half their
            thickness into the wall (closed fully, the Franka Hand's pads held the wall and
            dragged the plate 3 cm off its target as they opened: franka seeds 3, 5, 13, 20)."""
            close = wall_close_opening(ctx, PLATE.wall)
            return pick(
                ctx, "left", name, grasps=plate_grasps(ctx, "left", name), close_opening=close
            )

        def pick_cup(name: str):
            return pick(ctx, "right", name, grasps=cup_grasps(ctx, "right", name))

        # ---- stage 1: left picks plate 1 by its rim, right picks cup 1 (the left planned
        # first; only where the right then finds no pick, the right first and the left around
        # it: a wide hand over cup 1 met the left one lifting its plate, franka seeds 11, 23)
        left, right = plan_both(
            ctx, {"left": lambda: pick_plate(plates[0]), "right": lambda: pick_cup(cups[0])}
        )
        yield from run(merge(ctx, left, right))
        # ---- stage 2: left lays plate 1 on target 1, right holds cup 1 over it; then right
        # sets the cup on the plate while left picks plate 2. A plate is let go
        # gently (franka seed 8: the lighter grip's plate, let go at once, bounced and caught a
        # finger backing off)
        left = place(ctx, "left", plate_goal(targets[0]), gentle_release=True)
        right = hover(targets[0])
        yield from run(merge(ctx, left, right))
        # (left is planned first: it leaves the plate, so the cup's descent plans around
        # where it goes; merge() delays the cup while the two would meet)
        yield from run(set_cup(ctx, lambda: pick_plate(plates[1]), cup_goal(plates[0])))
        # ---- stage 3: left carries plate 2 over target 2 while right picks cup 2
        # (right is planned first: it leaves plate 1 for its own side, out of the left arm's
        # way across the table)
        right = pick_cup(cups[1])
        left = carry_above(ctx, "left", plate_goal(targets[1]), height=0.08)
        yield from run(merge(ctx, left, right))
        # ---- stage 4: left lays plate 2, right holds cup 2 over it, then sets it
        left = place(ctx, "left", plate_goal(targets[1]), gentle_release=True)
        right = hover(targets[1])
        yield from run(merge(ctx, left, right))
        yield from run(set_cup(ctx, lambda: retreat(ctx, "left"), cup_goal(plates[1])))
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- expert helpers
def set_cup(
    ctx: SkillContext, plan_left: Callable[[], ArmPlan], X_WO_goal: RigidTransform
) -> Motion:
    """The right arm sets its cup at `X_WO_goal` while the left does what `plan_left` plans
    (leaving the plate): the cup is carried above its goal in the same motion, then lowered
    and released. The left's part is planned first, the carry around where it ends; only where
    the carry then has no plan, the carry first and the left's part around it (`plan_both`:
    franka seed 19, the right hand over plate 1 met the left one lifting plate 2).
    A merged motion leaves out of its arm-against-arm check every object released
    or picked in it, so a whole place (it releases the cup) beside the left's motion would not
    see the held cup: the left's wrist, leaving the plate, swept through the cup the right
    was bringing over it and knocked it out of the hand (seeds 10, 11, 19, 28, 29; on seed 23
    it came to lean on the right's fingers, and the next pick started in collision). Carried
    still held, the cup is checked with the right hand, and merge() delays it until the left
    is clear; the lowering runs after the left is done."""
    left, right = plan_both(
        ctx, {"left": plan_left, "right": lambda: carry_above(ctx, "right", X_WO_goal)}
    )
    both = merge(ctx, left, right)
    return both.then(merge(ctx, None, place(ctx, "right", X_WO_goal)))


def plate_grasps(ctx: SkillContext, side: str, name: str) -> list[Grasp]:
    """Rim grasps of a plate, best first, the fingertips PLATE_TIP_CLEARANCE above its floor
    (the pads on the wall above the base, not on the base)."""
    params = hand_params(ctx, GraspParams(rim_floor=PLATE_TIP_CLEARANCE))
    return grasp_candidates(
        ctx.model.object(name),
        ctx.model.embodiment.arm.gripper,
        X_WO=ctx.model.object_pose(name),
        base=arm_base(ctx.model.embodiment, side),
        kinds=("rim",),
        params=params,
    )


def cup_grasps(ctx: SkillContext, side: str, name: str) -> list[Grasp]:
    """Top-down grasps of an upright cup across its outside, pads on the outer wall from the
    rim down (a rim grasp puts a finger inside the cup, which caught the inner wall and
    lifted the cup again when backing off after the release), best first. The pads clear the
    cup by the usual 8 mm per side on the way down, less (down to 1 mm short of the jaw's
    full stroke) for a gripper that opens little wider than the cup."""
    X_WO = ctx.model.object_pose(name)
    X_WC = X_WO @ RigidTransform([0.0, 0.0, CUP.height / 2])  # the solid's centre
    solid = CylinderShape(radius=CUP.radius, length=CUP.height)
    gripper = ctx.model.embodiment.arm.gripper
    base = arm_base(ctx.model.embodiment, side)
    margin = min(GraspParams().margin, gripper.finger_max - CUP.radius - 0.001)
    params = GraspParams(margin=margin)
    grasps = cylinder_grasps(X_WC, solid, gripper, base=base, kinds=("top",), params=params)
    X_OW = X_WO.inverse()
    return [replace(g, X_OG=X_OW @ g.X_WG) for g in grasps]


# -------------------------------------------------------------------- predicates
def place_set(plates, cups, target_xy) -> Predicate:
    """Some plate lies flat on the table within ON_TARGET of `target_xy` with some cup standing
    upright on its floor, neither touched by a finger, both at rest for 0.3 s."""
    pairs = []
    for p in plates:
        for c in cups:
            pairs.append(
                all_of(
                    within_xy(p, target_xy, ON_TARGET),
                    on_table(p, z_tol=0.01),
                    upright(p, math.radians(10)),
                    stands_in(c, p, gap=CUP_GAP_Z, max_tilt=math.radians(10)),
                    untouched(p),
                    untouched(c),
                    settled([p, c]),
                )
            )
    xy = tuple(round(float(v), 3) for v in target_xy)
    pred = any_of(*pairs)
    pred.name = f"place_set(target={xy})"
    return pred


def _plate_and_cup_lifted() -> Predicate:
    """Some plate and some cup both raised at least 5 cm above where they started (a set
    plate or a cup on it sits at most 1.2 cm higher than it started)."""
    return all_of(
        any_of(*[lifted(p, 0.05) for p in PLATES]), any_of(*[lifted(c, 0.05) for c in CUPS])
    )


# -------------------------------------------------------------------- scene helpers
def _spaced(rng, xs, ys, gap, avoid) -> list[tuple[float, float]]:
    """Two points in the box xs x ys at least `gap` apart and clear of every (point, distance)
    in `avoid`, drawn until they are."""
    while True:
        pts = [_round((rng.uniform(*xs), rng.uniform(*ys))) for _ in range(2)]
        if math.dist(*pts) < gap:
            continue
        if all(math.dist(p, a) >= d for p in pts for a, d in avoid):
            return pts


def _round(xy) -> tuple[float, float]:
    """A drawn point as recorded (6 decimals), so the scene is rebuilt from its draws."""
    return (round(float(xy[0]), 6), round(float(xy[1]), 6))


def _order(scene: Scene, names, xy) -> list[str]:
    """`names` sorted by distance from `xy` (nearest first)."""
    return sorted(names, key=lambda n: math.dist(scene.object(n).pose.xyz[:2], xy))


def _dish(name: str, shape: BowlShape, xy, color, mass: float, hint=None) -> SceneObject:
    return SceneObject(
        name=name,
        shape=shape,
        color=color,
        mass=mass,
        pose=Pose(xyz=(xy[0], xy[1], TABLE_TOP)),
        resolution_hint=hint,
    )

"""clean_table: the two arms take turns dropping four small objects into a bin."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from scipy.spatial import Delaunay

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.geometry import Pose, transform_points
from bicoord_drake.models.objects import (
    BinShape,
    BoxShape,
    CompoundShape,
    SceneObject,
    Shape,
    domed_box,
    toy_car,
)
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    GraspParams,
    arm_base,
    bounding_box_grasps,
    box_grasps,
)
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    SkillContext,
    drop_into,
    hold_still,
    leave_as_arrives,
    merge,
    pick_sliding,
    retreat,
    take_turn,
    wait_beside,
)
from bicoord_drake.stages import Stage, WorldState
from bicoord_drake.stages.predicates import (
    Predicate,
    all_of,
    count_true,
    hands_free,
    inside,
    lifted,
    settled,
    untouched,
    world_hull_points,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task
from bicoord_drake.tasks.turn_taking import alternating_stages, hold_until_still

#: The static bin: 19 x 17 cm outside, 8 cm tall, 6 mm walls, at the spec's spot, on a 2 cm
#: solid base: an object dropped in reaches 1.4 m/s, 12 mm per plant step, and through a 6 mm
#: floor it met the table as well and was thrown back up into the fingers (under SAP). The
#: floor is compliant-hydroelastic (``compliant_parts``): on a rigid floor a block landing flat
#: was thrown out at 2-8 m/s, spinning at 100-150 rad/s (seeds 2, 5, 11, 12, 18 at 2127adf;
#: benchmarks/bench_flat_landing.md).
BIN = BinShape(size=(0.19, 0.17, 0.08), wall=0.006, floor=0.02)
BIN_XY = (-0.03, -0.05)
#: The small objects, in drop order (the first arm's first, the other's first, ...).
OBJECTS = tuple(f"object_{k}" for k in range(1, 5))
#: The kinds of small objects (each <= 125 cm^3): shape, mass (kg), colour.
KINDS: dict[str, tuple[Shape, float, tuple[float, float, float, float]]] = {
    "block": (BoxShape(size=(0.045, 0.045, 0.045)), 0.06, (0.85, 0.25, 0.2, 1.0)),
    "toy_car": (toy_car(), 0.06, (0.2, 0.45, 0.85, 1.0)),
    "mouse": (domed_box((0.085, 0.05, 0.02), 0.017), 0.07, (0.25, 0.25, 0.27, 1.0)),
    "bread": (domed_box((0.085, 0.048, 0.02), 0.018), 0.04, (0.8, 0.58, 0.3, 1.0)),
    "card_box": (BoxShape(size=(0.09, 0.055, 0.022)), 0.05, (0.95, 0.8, 0.2, 1.0)),
    "soap": (BoxShape(size=(0.08, 0.05, 0.025), rounding=0.01), 0.08, (0.55, 0.85, 0.75, 1.0)),
}
#: Where the objects lie: x in X_RANGE[side], y in Y_RANGE, yaw within YAW of the x axis, at
#: least MIN_GAP apart (centres; more than any two footprints need). X_RANGE keeps them >= 18 cm
#: from the bin's centre in x, as the spec asks.
X_RANGE = {"left": (-0.3, BIN_XY[0] - 0.18), "right": (BIN_XY[0] + 0.18, 0.25)}
Y_RANGE = (-0.1, 0.1)
YAW = math.radians(60)
MIN_GAP = 0.11
#: Default drop points in the bin, from its centre (m): each arm over its own half, the first
#: two drops to the far side, the last two to the near side.
DROP_DX = 0.03
DROP_DY = (0.02, 0.02, -0.02, -0.02)
#: Drop spots searched (:func:`_drop_spots`): the held object's centre on a DROP_GRID (m) grid
#: over the bin's inner floor, turned by each of DROP_YAWS (rad), its footprint (sampled every
#: FOOTPRINT_STEP, m) at least DROP_WALL (m) inside the inner walls. Dropped onto an object
#: already in the bin, a light object lands tilted on it and (under SAP) rocks there or tips
#: off for a second and can stay propped up above the rim; dropped against a wall it can flip
#: over the rim. So a spot costs the footprint samples that fall on the objects in the bin
#: (grown by CROWD_MARGIN, about as far as a dropped object bounces) plus WALL_WEIGHT per
#: sample within WALL_BAND of a wall; the cheapest is used (ties: the one nearest the default
#: drop point), the next ones (DROP_TRIES in all) where the arm cannot reach it.
DROP_GRID = 0.01
DROP_YAWS = tuple(k * math.pi / 4 for k in range(4))
DROP_WALL = 0.008
FOOTPRINT_STEP = 0.005
CROWD_MARGIN = 0.02
WALL_BAND = 0.02
WALL_WEIGHT = 0.5
DROP_TRIES = 6
#: The held object's bottom is let go DROP_GAP (m) above what lies under its footprint (the
#: inner floor, or the top of an object in the bin it overlaps): lowered straight into the bin
#: from DROP_LOWER (m) above the old release height, FALL (m) above the rim, and backed off
#: straight up to DROP_RETREAT (m) above that height. Let go FALL above the rim, a light
#: object fell 8.5 cm and hit the floor at 1.3 m/s, and (under SAP) could bounce off a corner
#: and flip over the rim or into the opening fingers; from DROP_GAP it lands at 0.8 m/s (a
#: lower release let a flat box tilt against the opening fingers and be carried up by them).
#: Where the arm cannot reach that low at any of the spots, the object is let go FALL above
#: the rim.
DROP_GAP = 0.03
DROP_LOWER = 0.04
DROP_RETREAT = 0.05
FALL = 0.025
#: A dropped object is let go gently (``gentle_release``). Opened at once (3 steps), the jaw
#: leaving last dragged the Franka Hand's objects 1.5-2 cm sideways as they fell (under SAP), off
#: their spots and onto each other; let go over 6 steps, a loaf could still tip and catch on a
#: Franka fingertip; over 6 or more, the ViperX's long fingers kept hold of a loaf (seed 2).
#: While one arm leaves the bin and the other brings the next object, the bringing arm's TCP
#: comes within CLEAR_RADIUS (xy, m) of the bin's centre only CLEAR_LAG (s) after the leaving
#: arm's TCP has gone out of it (merge's check leaves out the object let go within the
#: motion, so it cannot see that object fall onto the other arm's carried object).
CLEAR_RADIUS = 0.12
CLEAR_LAG = 0.2
#: Where the second arm waits with its object while the first drops: TCP WAIT_AT[0] beside
#: the bin's centre in x on its own side, WAIT_AT[1] past it in y, WAIT_AT[2] above the table.
WAIT_AT = (0.2, 0.05, 0.2)
#: Seconds both arms hold still at the end: the objects must be seen at rest for 0.3 s.
SETTLE = 0.67
#: An object whose lowest point lies less than this (m) above the table top, outside the bin,
#: is on the table: it bounced out (under SAP a dropped object can land on the others and be
#: thrown over the rim, or be caught by an opening finger) and is put back (``_put_back``).
STRAY_HEIGHT = 0.01
#: Fingertips stay this far above the table in a grasp (m; the planner keeps 5 mm).
TIP_CLEARANCE = 0.006
#: An object counts as lifted this far (m) above where it lay.
LIFT = 0.05
#: Where no grasp at the object's middle plans (a wide hand's housing over the bin's wall or
#: a neighbour), the grasps are tried again slid this far (m) along the object either way,
#: as far as the pads stay a pad's height inside its ends.
SLIDES = (0.01, 0.02, 0.03)


@register_task
class CleanTable(Task):
    """Drop four small objects into the bin, the arms taking turns at it.

    Description: a bin stands near the middle of the table; four small everyday objects
    (from a block, a toy car, a mouse, a loaf of bread, a card box and a soap bar) lie two on
    each side. Both arms pick the object nearer the bin on their side at once; the first arm
    drops its object into the bin while the other waits beside it with its own; then the
    second arm drops while the first picks its other object, the first drops while the second
    picks its last, and the second drops the last while the first retreats (its way home timed
    to end with that drop). Each arm arrives over the bin as the other leaves it (the arrival
    is timed against the other arm's departure, not after it). Turn-taking at the bin is
    forced by the task: the bin takes one hand at a time, so the arms alternate there, and
    while one drops the other is picking its next object or holding it at its waiting point
    beside the bin. Which arm drops first is drawn per seed. Each object is lowered into the
    bin and let go 3 cm above what lies under it (the floor, or an object already there), at
    the spot and yaw where it covers least of the objects already in the bin and keeps off its
    walls (where the arm cannot reach that low, 2.5 cm above the rim); the arms then hold
    still until everything in the bin has come to rest.

    Randomization: which arm drops first; which four of the six kinds of object (without
    repeats) and which side each is on; positions x in [-0.3, -0.21] (left) or [0.15, 0.25]
    (right), y in [-0.1, 0.1], at least 11 cm apart, yaw within +-60 deg. The bin is fixed at
    (-0.03, -0.05) (the spec's spot), 19 x 17 x 8 cm.

    Stages: (1) the first two objects both lifted 5 cm; (2)-(4) one, two, three objects in
    the bin (each object inside the bin's real cavity - above its inner floor, within its
    inner walls, below its rim - and no finger touching it); (5) all four in the bin, both
    grippers open, no finger touching any object, all at rest for 0.3 s. Stages (2)-(5)
    score 0.25 each and must still hold at the end (an object that bounces out stops
    counting).

    Success: all four objects inside the bin, both grippers open, none touched, all at rest
    for 0.3 s.
    """

    name = "clean_table"
    step_limit = 1000
    supported_robots = ("aloha_viperx", "franka_pair")
    ci_seed = 0
    instructions_seen = (
        "Put all four objects on the table into the bin.",
        "Clean the table by dropping everything into the bin.",
        "Throw the four small items into the trash bin, taking turns with both hands.",
        "Clear the table: every object goes into the bin.",
        "Drop the toys and other things on the table into the bin.",
        "Use both arms to put the objects into the bin one after another.",
        "Tidy up the table by putting all the items in the bin.",
    )
    instructions_unseen = (
        "Get rid of the clutter on the table by dropping it in the bin.",
        "Move each of the four objects into the container in the middle.",
        "Alternate hands and fill the bin with the things lying on the table.",
        "Collect the items from both sides of the table into the bin.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        first = str(rng.choice(SIDES))
        other = other_side(first)
        kinds = [str(k) for k in rng.choice(sorted(KINDS), size=4, replace=False)]
        poses = _positions(rng)
        # drop order: first arm's near object, other's near, first's far, other's far
        order = [(first, 0), (other, 0), (first, 1), (other, 1)]
        placed = {name: poses[side][k] for name, (side, k) in zip(OBJECTS, order, strict=True)}
        objects = [
            SceneObject(
                name="bin",
                shape=BIN,
                color=(0.35, 0.42, 0.5, 1.0),
                fixed=True,
                compliant_parts=(0,),  # the floor: see BIN
                pose=Pose(xyz=(*BIN_XY, TABLE_TOP)),
            )
        ]
        for name, kind in zip(OBJECTS, kinds, strict=True):
            shape, mass, color = KINDS[kind]
            x, y, yaw = placed[name]
            z = TABLE_TOP + (shape.size[2] / 2 if isinstance(shape, BoxShape) else 0.0)
            objects.append(
                SceneObject(
                    name=name,
                    shape=shape,
                    color=color,
                    color_fixed=kind == "bread",  # a loaf stays loaf-coloured when randomized
                    mass=mass,
                    pose=Pose(xyz=(x, y, z), rpy=(0.0, 0.0, yaw)),
                )
            )
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "first_side": first,
                "kinds": kinds,
                **{f"{n}_pose": placed[n] for n in OBJECTS},
                "bin_xy": list(BIN_XY),
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 5  # four objects and the bin

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        subgoals = [
            ("pick an object", "pick an object"),
            ("drop it into the bin", "hold it, stay clear"),
            ("pick the next object", "drop it into the bin"),
            ("drop it into the bin", "pick the last object"),
            ("retreat", "drop the last object into the bin"),
        ]
        names = ("both pick", "first drop", "second drop", "third drop", "last drop")
        preds: list[Predicate] = [
            all_of(lifted(OBJECTS[0], LIFT), lifted(OBJECTS[1], LIFT)),
            in_bin_count(1),
            in_bin_count(2),
            in_bin_count(3),
            all_of(in_bin_count(4), hands_free(OBJECTS), settled(OBJECTS)),
        ]
        return alternating_stages(scene.draws["first_side"], subgoals, names, preds)

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)

        run = partial(follow, ctx, view)

        first = scene.draws["first_side"]
        second = other_side(first)
        o1, o2, o3, o4 = OBJECTS

        # take_turn's fallbacks: the fingers of an arm letting go low in the bin come within
        # merge's padding of the bin and of the objects in it (its plan kept its own clearance
        # from them, which no timing changes)
        ignore = (*OBJECTS, "bin")

        def turn(leaver: ArmPlan, arriver: ArmPlan) -> Motion:
            return take_turn(
                ctx, leaver, arriver, BIN_XY, CLEAR_RADIUS, lag=CLEAR_LAG, ignore=ignore
            )

        # ---- stage 1: both arms pick the object nearer the bin on their side
        plans = {first: _pick(ctx, first, o1)}
        plans[second] = _pick(ctx, second, o2)
        yield from run(merge(ctx, plans["left"], plans["right"]))
        # ---- stage 2: the first arm drops its object in; the other carries its object to its
        # waiting point (planned first: the first arm plans around it)
        plans = {second: wait_beside(ctx, second, BIN_XY, WAIT_AT)}
        plans[first] = _drop(ctx, first, 0)
        yield from run(merge(ctx, plans["left"], plans["right"]))
        # ---- stages 3-4: each arm leaves to pick its next object as the other arrives
        yield from run(turn(_pick(ctx, first, o3), _drop(ctx, second, 1)))
        yield from run(turn(_pick(ctx, second, o4), _drop(ctx, first, 2)))
        # ---- stage 5: the first arm leaves for home as the second drops the last object in,
        # its way home timed to end with the drop
        leaving = retreat(ctx, first)
        dropping = _drop(ctx, second, 3)
        yield from run(
            leave_as_arrives(
                ctx,
                leaving,
                dropping,
                BIN_XY,
                CLEAR_RADIUS,
                lag=CLEAR_LAG,
                ignore=ignore,
            )
        )
        # ---- both hold still until the objects have come to rest (the last one can rock on or
        # slide off the others for a second), then SETTLE more
        yield from hold_until_still(ctx, view, OBJECTS)
        # ---- an object that bounced out of the bin onto the table is picked up where it lies
        # and dropped in again, once each, by the arm on its side of the bin
        strays = strays_on_table(view.state(view.embodiment.home_action()))
        for name in strays:
            try:
                yield from run(_put_back(ctx, name))
            except PlanningError:
                continue  # the episode ends with it outside, as it would have
        if strays:
            yield from hold_until_still(ctx, view, OBJECTS)
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- predicates
def in_bin(obj: str) -> Predicate:
    """`obj` inside the bin's real cavity (:func:`inside` with the bin's inner box) and no
    finger touching it: one held inside the bin, or lying on its rim, does not count."""
    return all_of(inside(obj, "bin"), untouched(obj))


def in_bin_count(k: int) -> Predicate:
    """At least `k` of the four objects :func:`in_bin`."""
    return count_true([in_bin(o) for o in OBJECTS], k)


# -------------------------------------------------------------------- expert helpers
def strays_on_table(state: WorldState) -> list[str]:
    """The objects lying on the table outside the bin: not in it, their lowest point less than
    STRAY_HEIGHT above the table top (one on the rim or on the others is not)."""
    return [
        name
        for name in OBJECTS
        if not inside(name, "bin")(state)
        and world_hull_points(state, name)[:, 2].min() < TABLE_TOP + STRAY_HEIGHT
    ]


def _put_back(ctx: SkillContext, name: str) -> Motion:
    """The arm on `name`'s side of the bin picks it up where it lies and drops it into the
    bin (:func:`_pick`, :func:`_drop`), the other arm going home meanwhile."""
    x = ctx.model.object_pose(name).translation()[0]
    side = "left" if x < BIN_XY[0] else "right"
    with ctx.transaction():  # nothing planned stays tracked when it cannot be planned
        plans = {side: _pick(ctx, side, name).then(_drop(ctx, side, len(OBJECTS) - 1))}
        plans[other_side(side)] = retreat(ctx, other_side(side))
        return merge(ctx, plans["left"], plans["right"])


def _pick(ctx: SkillContext, side: str, name: str) -> ArmPlan:
    """Pick `name` with `side` from above, the fingertips TIP_CLEARANCE above the table (a
    card box is flatter than the pads are long); a compound object (car, mouse, bread) across
    its bounding box, the fingertips TIP_CLEARANCE above its bottom, so that the pads reach
    its widest part, the base (short pads held higher straddled the mouse's ledge, dome above
    base, and it stuck to a fingertip when let go). Where no grasp plans, the grasps slid
    along the object (``pick_sliding``)."""
    obj = ctx.model.object(name)
    gripper = ctx.model.embodiment.arm.gripper
    lo = min(p.trimesh().bounds[0][2] for p in obj.shape.primitives())
    hi = max(p.trimesh().bounds[1][2] for p in obj.shape.primitives())
    half_pad = gripper.pad_length / 2
    deepest = hi - lo - half_pad - TIP_CLEARANCE
    compound = isinstance(obj.shape, CompoundShape)
    params = GraspParams(depth=deepest if compound else min(half_pad, deepest))
    X_WO = ctx.model.object_pose(name)
    base = arm_base(ctx.model.embodiment, side)
    if compound:
        grasps = bounding_box_grasps(X_WO, obj.shape, gripper, base=base, params=params)
    else:
        grasps = box_grasps(X_WO, obj.shape, gripper, base=base, kinds=("top",), params=params)
    return pick_sliding(ctx, side, name, grasps, SLIDES)


def _drop(ctx: SkillContext, side: str, k: int) -> ArmPlan:
    """Drop what `side` holds into the bin at the best of :func:`_drop_spots` that `side` can
    reach (the k-th default drop point, over `side`'s half, in an empty bin), let go low
    (DROP_GAP above what is under it) where it can, FALL above the rim where not."""
    sign = 1.0 if side == "right" else -1.0
    default = np.asarray(BIN_XY) + [sign * DROP_DX, DROP_DY[k]]
    spots = _drop_spots(ctx, side, default)[:DROP_TRIES]
    rim = TABLE_TOP + BIN.size[2]
    reasons = []
    for low in (True, False):
        for xy, yaws, support in spots:
            fall = min(FALL, support + DROP_GAP - rim) if low else FALL
            offset = xy - np.asarray(BIN_XY)
            try:
                with ctx.transaction():  # a failed try leaves the tracked state as it was
                    return drop_into(
                        ctx,
                        side,
                        "bin",
                        offset_xy=offset,
                        fall=fall,
                        lower=DROP_LOWER + FALL - fall,
                        retreat=DROP_RETREAT + FALL - fall,
                        yaws=yaws,
                        gentle_release=True,
                    )
            except PlanningError as err:
                reasons.append(err.reason)
    raise PlanningError("place_failed", f"{side} cannot drop into the bin ({', '.join(reasons)})")


def _drop_spots(
    ctx: SkillContext, side: str, default: np.ndarray
) -> list[tuple[np.ndarray, tuple[float, ...], float]]:
    """Drop spots in the bin for what `side` holds, cheapest first (see DROP_GRID; ties:
    nearest `default`): (world xy, the yaws of least cost there with their half turns, the
    height (world z) of what the footprint would land on at those yaws)."""
    crowd = [(_grown_hull(ctx, name), _world_hull(ctx, name)[:, 2].max()) for name in _in_bin(ctx)]
    floor = TABLE_TOP + BIN.floor_thickness
    local = _footprint(ctx.model.object(ctx.model.held[side].name).shape)
    half = np.asarray(BIN.inner_half)
    spots = []
    for x in np.arange(-half[0], half[0], DROP_GRID):
        for y in np.arange(-half[1], half[1], DROP_GRID):
            costs = {}
            for yaw in DROP_YAWS:
                c, s = math.cos(yaw), math.sin(yaw)
                pts = local @ np.array([[c, s], [-s, c]]) + [x, y]  # bin frame
                if np.any(np.abs(pts) > half - DROP_WALL):
                    continue
                hits = [
                    (np.count_nonzero(h.find_simplex(pts + BIN_XY) >= 0), top) for h, top in crowd
                ]
                walled = np.count_nonzero(np.any(np.abs(pts) > half - WALL_BAND, axis=1))
                support = max([floor] + [top for n, top in hits if n])
                costs[yaw] = (sum(n for n, _ in hits) + WALL_WEIGHT * walled, support)
            if costs:
                least = min(cost for cost, _ in costs.values())
                best = [yaw for yaw, (cost, _) in costs.items() if cost == least]
                yaws = tuple(a for yaw in best for a in (yaw, yaw + math.pi))
                support = max(costs[yaw][1] for yaw in best)
                xy = np.asarray(BIN_XY) + [x, y]
                spots.append((least, float(np.hypot(*(xy - default))), xy, yaws, float(support)))
    spots.sort(key=lambda spot: spot[:2])
    return [(xy, yaws, support) for _, _, xy, yaws, support in spots]


def _in_bin(ctx: SkillContext) -> list[str]:
    """The objects lying in the bin (their centre within its inner walls; not held)."""
    out = []
    for name in OBJECTS:
        if ctx.model.holders(name):
            continue
        centre = _world_hull(ctx, name)[:, :2].mean(axis=0) - np.asarray(BIN_XY)
        if np.all(np.abs(centre) <= np.asarray(BIN.inner_half)):
            out.append(name)
    return out


def _grown_hull(ctx: SkillContext, name: str) -> Delaunay:
    """The xy outline of `name` as it lies, grown by CROWD_MARGIN (its hull's points moved
    that far out each of 8 ways), for point-in-hull tests."""
    pts = _world_hull(ctx, name)[:, :2]
    ways = np.linspace(0.0, 2 * math.pi, 8, endpoint=False)
    ring = CROWD_MARGIN * np.stack([np.cos(ways), np.sin(ways)], -1)
    return Delaunay((pts[:, None] + ring[None]).reshape(-1, 2))


def _world_hull(ctx: SkillContext, name: str) -> np.ndarray:
    """(N, 3) vertices of `name`'s primitives, in world, as the planning model last saw it."""
    X = ctx.model.object_pose(name)
    pts = np.concatenate([p.trimesh().vertices for p in ctx.model.object(name).shape.primitives()])
    return transform_points(X, pts)


def _footprint(shape: Shape) -> np.ndarray:
    """(N, 2) points every FOOTPRINT_STEP over the xy box of the shape's primitives in its own
    frame (its outline standing upright)."""
    pts = np.concatenate([p.trimesh().vertices[:, :2] for p in shape.primitives()])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    axes = [np.arange(lo[i], hi[i] + 1e-9, FOOTPRINT_STEP) for i in range(2)]
    return np.stack(np.meshgrid(*axes), -1).reshape(-1, 2)


def _positions(rng: np.random.Generator) -> dict[str, list[list[float]]]:
    """Two (x, y, yaw) per side, MIN_GAP apart, the one nearer the bin first (rejection
    sampling from `rng`)."""
    for _ in range(1000):
        out = {
            side: [
                [
                    float(rng.uniform(*X_RANGE[side])),
                    float(rng.uniform(*Y_RANGE)),
                    float(rng.uniform(-YAW, YAW)),
                ]
                for _ in range(2)
            ]
            for side in SIDES
        }
        if all(np.hypot(a[0] - b[0], a[1] - b[1]) >= MIN_GAP for a, b in out.values()):
            return {
                side: sorted(v, key=lambda p: float(np.hypot(p[0] - BIN_XY[0], p[1] - BIN_XY[1])))
                for side, v in out.items()
            }
    raise RuntimeError("no object layout found in 1000 draws")  # pragma: no cover

"""collect_pens: the two arms take turns standing four pens and markers in a pen holder.

Expert success on seeds 0-29: 28/30 at 99c4cea (fails 15: the fourth pen comes to rest on the
three standing pens; 24: arm_conflict in stage 3). See benchmarks/bench_task_collect_pens.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from pydrake.all import RigidTransform, RotationMatrix

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import SceneObject
from bicoord_drake.models.pens import PenShape, max_lean, pen_holder, random_pen
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    arm_base,
    gripper_frame,
    naturalness,
)
from bicoord_drake.planning.skills import (
    ArmPlan,
    SkillContext,
    hold_still,
    pick_sliding,
    place,
    wait_beside,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    Predicate,
    all_of,
    at_rest,
    count_true,
    hands_free,
    held_by,
    lifted,
    settled,
    tip_in,
    untouched,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task
from bicoord_drake.tasks.turn_taking import (
    alternating_expert,
    alternating_stages,
    hold_until_still,
)

#: The static pen holder: a straight cup 8 cm across and 10 cm tall, 4 mm walls.
HOLDER = pen_holder(radius=0.04, height=0.10, wall=0.004)
HOLDER_XY = (-0.06, -0.05)
#: The pens, in drop order (the first arm's first, the other's first, ...).
PENS = tuple(f"pen_{k}" for k in range(1, 5))
#: Where the pens lie (centre x per side, y per row: the spec's ranges; the left side's x is
#: shifted 4 cm outwards, away from the holder, which a 14 cm pen at the spec's x = -0.15
#: pointing at it would cross). Yaw: the tip points along k * 45 deg.
X_RANGE = {"left": (-0.24, -0.19), "right": (0.23, 0.25)}
Y_RANGE = ((0.02, 0.07), (-0.10, -0.05))
#: Lying pens keep this much room (m) between their surfaces, and from the holder's wall.
PEN_GAP = 0.035
HOLDER_GAP = 0.025
#: Room (m) from a pen's grasp point to the other pen on its side (surface): the fingers,
#: open APPROACH_MARGIN beside the pen, reach about 3 cm from its axis.
GRASP_ROOM = 0.045
APPROACH_MARGIN = 0.01
#: Grasp: the TCP sits GRASP_BACK (m) from the pen's middle towards its back end (more pen
#: below the fingers once it hangs tip down), the fingertips TIP_CLEARANCE above the table,
#: as low as they go so that the pen's axis lies as far up the pads as a lying pen allows
#: (5-7.5 mm above their lower edge; 1-3.5 mm with the earlier 6 mm, where the Franka Hand's
#: pens crept out of the grip: benchmarks/franka_experts.md). The pads' middle (9.5 mm up
#: the Franka Hand's, 17.5 mm up the ViperX's) is out of reach of a pen lying on the table.
#: The pick is planned PICK_TABLE_CLEARANCE (m) clear of the table (the skills' default is
#: more than the fingertips' 2 mm).
GRASP_BACK = 0.035
TIP_CLEARANCE = 0.002
PICK_TABLE_CLEARANCE = 0.001
#: Where no grasp at GRASP_BACK plans (a wide hand's housing, along the finger axis across
#: the pen, over the holder 2.5 cm away), the grasps are tried again slid this far (m) along
#: the pen either way, the pads a pad's height inside its ends.
SLIDES = (0.01, 0.02, 0.03)
#: The tip is let go INSERTS[0] (m) below the rim, 4.6 cm above the holder's floor, where the
#: arm can take it there clear of the pens already standing, else INSERTS[1] below it (with
#: GRASP_BACK that keeps the gripper above the top of a pen standing straight in the holder).
#: Let go 2.5 cm below the rim, a pen fell 7 cm, hit the floor at 1.2 m/s and (under SAP)
#: could bounce up, tilt over the rim and, after seeming to settle, tip out onto the table.
#: (Let go 2.6 cm above the floor, the pens stood steeper and one could creep for seconds.)
INSERTS = (0.05, 0.025)
#: The pen is carried over the holder this much (m) higher and lowered straight from there.
LOWER = 0.06
#: Release jaw gap (m): the fingers part to about 5 cm, clear of the pens already standing
#: (the robot's gripper turns it into an opening command).
RELEASE_GAP = 0.0531
#: The pen is squeezed with about HOLD_FORCE (N) (:func:`_close_opening`). Closed fully, the
#: Franka Hand (its fingers closing to 0) squeezed a pen with 21-28 N, at the pads' lower
#: edge (the pen's axis 1 mm above the fingertips, then 6 mm over the table),
#: and the pen crept out past the fingertips while carried (under SAP) and fell or was let
#: go tilted; at 17 N it stays. The ViperX's fingers stop 4 mm from the middle, so a closed
#: ViperX grip squeezes at most 17 N: its command stays fully closed.
HOLD_FORCE = 17.0
#: An insert lets go to RELEASE_GAP at the fingers' speed, not gently: let go over the gentle
#: release's 0.8 s the last pen of seed 3 did not end in the holder (seeds 0-4, 2026-12-06).
#:
#: The yaws (rad) about the vertical the pen may hang at over the holder. The LEAST_TURNS of
#: them that turn the hand least from where it holds the pen (:func:`_least_turn_yaws`) are
#: tried first, one by one, then all of them, the most natural hand first. (Chosen by
#: naturalness alone, the joint-space carry could swing the pen the long way round, through
#: tip up, and at the Franka's wrist accelerations the pen, held at the pads' lower edge,
#: slid out of the fingers at the end of the swing.)
INSERT_YAWS = tuple(k * math.pi / 6 for k in range(12))
LEAST_TURNS = 4
#: Candidate tip points in the holder: its centre and two rings around it (radii, m); the
#: one farthest from the pens already in it is used.
DROP_RINGS = (0.012, 0.022)
#: Turn-taking zone around the holder (xy radius, m) and the lag (s).
CLEAR_RADIUS = 0.12
CLEAR_LAG = 0.2
#: Where the second arm waits with its pen (TCP offset from the holder's centre, m): within
#: 0.16 m (x) of the holder, as the reference drops at x = +-0.16 (TASKS.md section 5).
WAIT_AT = (0.16, 0.06, 0.2)
#: Seconds both arms hold still at the end (the pens must be seen at rest for 0.3 s).
SETTLE = 0.67
#: A pen counts as lifted this far (m) above where it lay.
LIFT = 0.05
#: Slack (rad) on the holder's geometric lean limit (compliant contact, the wall polygon).
LEAN_SLACK = math.radians(3)


def lean_limit(pens: list[PenShape]) -> float:
    """The most a pen standing on the holder's floor can lean (rad), for the thinnest of
    `pens`, plus LEAN_SLACK. The inner radius is the wall polygon's corner radius."""
    inner = (HOLDER.radius - HOLDER.wall) / math.cos(math.pi / HOLDER.segments)
    depth = HOLDER.height - HOLDER.wall
    return LEAN_SLACK + max(max_lean(inner, depth, p.radius, p.tip_radius) for p in pens)


@register_task
class CollectPens(Task):
    """Stand four pens and markers in the pen holder, the arms taking turns at it.

    Description: a pen holder (a cup 8 cm across, 10 cm tall) stands near the middle of the
    table; two pens or markers lie flat on each side. Both arms pick the pen nearer the
    holder on their side at once, from above, across the pen 3.5 cm behind its middle; the
    first arm turns its wrist so the pen hangs tip down, carries it over the holder, lowers
    the tip 5 cm into the cup (2.5 cm where its gripper would meet the pens already standing)
    and lets go (the pen drops to the floor and leans on the rim), while the other waits
    beside the holder with its own pen. Then the second arm puts its
    pen in while the first picks its other one, the first puts that in while the second picks
    its last, and the second puts the last one in while the first retreats. Each arm arrives
    over the holder as the other leaves it (the arrival is timed against the other's
    departure; where no such timing keeps the arms apart, the arriver starts once the leaver is
    done). The tip goes where it is farthest from the pens already standing in the cup.
    Which arm goes first is drawn per seed.

    Randomization: which arm goes first; each of the four is a pen (1.4-1.5 cm thick,
    13-14.5 cm long) or a marker (1.8-1.9 cm, 12-13.5 cm), with its body and accent colours,
    size and mass drawn; positions x in [-0.24, -0.19] (left; the spec's [-0.2, -0.15]
    shifted 4 cm outwards so that a pen pointing at the holder does not cross it) or
    [0.23, 0.25] (right), on each side one at y in [0.02, 0.07] and one at y in
    [-0.10, -0.05]; each tip points one of 8 ways (multiples of 45 deg); layouts where two
    pens come within 3.5 cm of each other or 2.5 cm of the holder, or a grasp point within
    4.5 cm of the other pen on its side, are drawn again. The
    holder is fixed at (-0.06, -0.05) (the spec's spot).

    Stages: (1) the first two pens both lifted 5 cm, each in its arm's closed gripper;
    (2)-(4) one, two, three pens standing in the holder (a pen's tip inside the holder's
    real cavity - within its inner wall, below its rim, not below its floor - the pen tilted
    at most as far as the holder lets a pen standing on its floor lean (its geometry: about
    32 deg, + 3 deg), no finger touching it and at rest); (5) all four standing in it, both
    grippers open, all at rest for 0.3 s. Stages (2)-(5) score 0.25 each and must still hold
    at the end.

    Success: all four pens standing tip first in the holder, both grippers open, none
    touched, all at rest for 0.3 s.
    """

    name = "collect_pens"
    step_limit = 900
    supported_robots = ("aloha_viperx", "franka_pair")
    ci_seed = 0
    instructions_seen = (
        "Put all four pens into the pen holder.",
        "Collect the pens and markers from the table into the holder.",
        "Stand every pen in the pen cup, tip down, taking turns with both hands.",
        "Tidy the desk: the pens and markers go into the holder.",
        "Pick up the pens on both sides and drop them into the pen holder.",
        "Use both arms to put the pens in the cup one after another.",
        "Gather the markers and pens into the pen holder.",
    )
    instructions_unseen = (
        "Clear the writing tools off the table into the pen cup.",
        "Alternate hands and fill the pen holder with the pens lying around.",
        "Put each pen and marker tip first into the holder.",
        "Store the four pens in the cup in the middle of the table.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        first = str(rng.choice(SIDES))
        other = other_side(first)
        kinds = [str(k) for k in rng.choice(["pen", "marker"], size=4)]
        pens = [random_pen(rng, k) for k in kinds]
        # drop order: first arm's near pen, other's near, first's far, other's far
        order = [(first, 0), (other, 0), (first, 1), (other, 1)]
        poses = _positions(
            rng,
            {side: [pens[i][0] for i, (s, _) in enumerate(order) if s == side] for side in SIDES},
        )
        placed = {name: poses[side][k] for name, (side, k) in zip(PENS, order, strict=True)}
        objects = [
            SceneObject(
                name="holder",
                shape=HOLDER,
                color=(0.3, 0.32, 0.36, 1.0),
                fixed=True,
                pose=Pose(xyz=(*HOLDER_XY, TABLE_TOP)),
            )
        ]
        for name, (shape, mass, color) in zip(PENS, pens, strict=True):
            x, y, yaw = placed[name]
            objects.append(
                SceneObject(
                    name=name,
                    shape=shape,
                    color=color,
                    mass=mass,
                    pose=Pose(xyz=(x, y, TABLE_TOP + shape.radius), rpy=(0.0, -math.pi / 2, yaw)),
                    resolution_hint=0.004,
                )
            )
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "first_side": first,
                "kinds": kinds,
                **{f"{n}_pose": placed[n] for n in PENS},
                "holder_xy": list(HOLDER_XY),
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 5  # four pens and the holder

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        first = scene.draws["first_side"]
        second = other_side(first)
        limit = lean_limit([scene.object(p).shape for p in PENS])
        subgoals = [
            ("pick a pen", "pick a pen"),
            ("put it in the holder, tip down", "hold it, stay clear"),
            ("pick the next pen", "put it in the holder, tip down"),
            ("put it in the holder, tip down", "pick the last pen"),
            ("retreat", "put the last pen in the holder"),
        ]
        names = ("both pick", "first pen in", "second pen in", "third pen in", "last pen in")
        preds: list[Predicate] = [
            all_of(
                lifted(PENS[0], LIFT),
                lifted(PENS[1], LIFT),
                held_by(PENS[0], first),
                held_by(PENS[1], second),
            ),
            in_holder_count(1, limit),
            in_holder_count(2, limit),
            in_holder_count(3, limit),
            all_of(in_holder_count(4, limit), hands_free(PENS), settled(PENS)),
        ]
        return alternating_stages(first, subgoals, names, preds)

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        ctx.picker = partial(_pick, ctx)  # a fallen pen is picked up as the pens are

        run = partial(follow, ctx, view)

        # take_turn's fallbacks: a finger leaving the holder can graze a pen standing in it
        # (each plan kept its own clearance from it when it was made)
        yield from alternating_expert(
            ctx,
            run,
            scene.draws["first_side"],
            PENS,
            pick=lambda side, name: _pick(ctx, side, name),
            put=lambda side, k: _insert(ctx, side),
            wait=lambda side: wait_beside(ctx, side, HOLDER_XY, WAIT_AT),
            spot_xy=HOLDER_XY,
            clear_radius=CLEAR_RADIUS,
            lag=CLEAR_LAG,
            ignore=PENS,
        )
        # ---- both hold still until the pens have come to rest (the last one may still slide
        # down into its lean), then SETTLE more
        yield from hold_until_still(ctx, view, PENS)
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- predicates
def in_holder(pen: str, limit: float) -> Predicate:
    """`pen` stands tip first in the holder (:func:`tip_in`, leaning at most `limit`), no
    finger touching it, at rest."""
    return all_of(tip_in(pen, "holder", limit), untouched(pen), at_rest(pen))


def in_holder_count(k: int, limit: float) -> Predicate:
    """At least `k` of the four pens :func:`in_holder`."""
    return count_true([in_holder(p, limit) for p in PENS], k)


# -------------------------------------------------------------------- expert helpers
def pen_grasps(ctx: SkillContext, side: str, name: str) -> list[Grasp]:
    """Top grasps across the lying pen `name`, GRASP_BACK behind its middle, fingertips
    TIP_CLEARANCE above the table. Of the two finger directions, the one whose gripper z
    points to the pen's back end comes first: once the pen hangs tip down, that wrist is
    upright."""
    obj = ctx.model.object(name)
    shape: PenShape = obj.shape
    gripper = ctx.model.embodiment.arm.gripper
    X_WO = ctx.model.object_pose(name)
    axis = X_WO.rotation().col(2)  # tip -> back
    p = X_WO.translation() + GRASP_BACK * axis
    p[2] = TABLE_TOP + TIP_CLEARANCE + gripper.pad_length / 2
    across = np.cross([0.0, 0.0, 1.0], axis)
    base = arm_base(ctx.model.embodiment, side)
    out = []
    for sign in (1.0, -1.0):
        X_WG = gripper_frame(np.array([0.0, 0.0, -1.0]), sign * across, p)
        upright_later = float(X_WG.rotation().col(2) @ axis) > 0
        X_WPre = RigidTransform(X_WG.rotation(), p + [0.0, 0.0, 0.08])
        score = (1.0 if upright_later else 0.0) + 0.1 * naturalness(X_WG, base)
        out.append(
            Grasp("top", X_WG, X_WPre, X_WO.inverse() @ X_WG, 2 * shape.radius, float(score))
        )
    return sorted(out, key=lambda g: -g.score)


def _pick(ctx: SkillContext, side: str, name: str) -> ArmPlan:
    """Pick `name` across (:func:`pen_grasps`), the jaw open only APPROACH_MARGIN beside the
    pen on the way down (clear of the other pen on that side); where none of those plans, the
    grasps slid along the pen by SLIDES."""
    gripper = ctx.model.embodiment.arm.gripper
    shape: PenShape = ctx.model.object(name).shape
    opening = float(gripper.opening(shape.radius + APPROACH_MARGIN))
    close = _close_opening(ctx, shape)
    grasps = pen_grasps(ctx, side, name)
    try:
        with ctx.tuned(env_clearance=PICK_TABLE_CLEARANCE):
            return pick_sliding(
                ctx,
                side,
                name,
                grasps,
                SLIDES,
                # plan the approach with the fingers that narrow
                prepare=lambda: ctx.model.set_gripper(side, opening),
                approach_opening=opening,
                close_opening=close,
            )
    finally:
        ctx.model.set_gripper(side, ctx.model.embodiment.home_opening)


def _close_opening(ctx: SkillContext, shape: PenShape) -> float:
    """The closing command that squeezes the pen with about HOLD_FORCE N: the jaw gap
    HOLD_FORCE / finger_kp per finger inside the pen's width (fully closed where that is
    past the fingers' stroke)."""
    gripper = ctx.model.embodiment.arm.gripper
    return gripper.opening_for_gap(2 * shape.radius - 2 * HOLD_FORCE / gripper.finger_kp)


def _insert(ctx: SkillContext, side: str) -> ArmPlan:
    """Turn the held pen tip down over the holder, lower its tip into the cup (the deepest of
    INSERTS the arm can reach) at the point farthest from the pens already standing in it,
    let go, back off up."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to put in the holder")
    reasons = []
    for insert in INSERTS:
        try:
            with ctx.transaction():  # a failed try leaves the tracked state as it was
                plan = _insert_to(ctx, side, held.name, insert)
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        plan.label = f"put {held.name} in the holder"
        return plan
    raise PlanningError(
        "place_failed", f"{side} cannot put {held.name!r} in the holder ({', '.join(reasons)})"
    )


def _insert_to(ctx: SkillContext, side: str, held: str, insert: float) -> ArmPlan:
    """Put the pen `held` in with its tip let go `insert` (m) below the rim, lowered straight
    from LOWER (m) above INSERTS[-1] below it (where the shallowest insert starts), and backed
    off as far up."""
    shape: PenShape = ctx.model.object(held).shape
    X_WH = ctx.model.object_pose("holder")
    rim = X_WH.translation()[2] + HOLDER.height
    tip = _drop_point(ctx, X_WH, held, insert)
    p = [tip[0], tip[1], rim - insert - shape.tip_point()[2]]
    deeper = insert - INSERTS[-1]
    goal = RigidTransform(RotationMatrix(), p)

    def put(yaws: list[float]) -> ArmPlan:
        return place(
            ctx,
            side,
            goal,
            approach_height=LOWER + deeper,
            retreat=0.05 + deeper,
            opening=ctx.model.embodiment.arm.gripper.opening_for_gap(RELEASE_GAP),
            yaws=yaws,
            gentle_release=False,
        )

    # the LEAST_TURNS least turns one by one, then every yaw (the most natural hand first)
    for yaw in _least_turn_yaws(ctx, side, goal)[:LEAST_TURNS]:
        try:
            with ctx.transaction():
                return put([yaw])
        except PlanningError:
            continue
    return put(list(INSERT_YAWS))


def _least_turn_yaws(ctx: SkillContext, side: str, goal: RigidTransform) -> list[float]:
    """INSERT_YAWS (rad, about the vertical through `goal`) ordered by how far the hand turns
    from where it is to hold the pen there: the least turn first (the pen, squeezed at the
    pads' lower edge, creeps out of the grip in a long fast swing)."""
    held = ctx.model.held[side]
    X_TO = RigidTransform([-ctx.model.embodiment.arm.gripper.tcp_x, 0, 0]) @ held.X_GO
    R_now = ctx.model.tcp_pose(ctx.q, side).rotation()

    def turn(yaw: float) -> float:
        R_goal = RotationMatrix.MakeZRotation(yaw) @ goal.rotation() @ X_TO.rotation().inverse()
        return float((R_now.inverse() @ R_goal).ToAngleAxis().angle())

    return sorted(INSERT_YAWS, key=turn)


def _drop_point(ctx: SkillContext, X_WH: RigidTransform, held: str, insert: float) -> np.ndarray:
    """The xy (world) in the holder, of its centre and the DROP_RINGS around it, that is
    farthest from the axes of the pens already standing in the cup (over the height the
    held pen's tip passes through, down to `insert` below the rim)."""
    c = X_WH.translation()
    cands = [c[:2]] + [
        c[:2] + r * np.array([math.cos(a), math.sin(a)])
        for r in DROP_RINGS
        for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)
    ]
    segs = []
    for name in PENS:
        if name == held or ctx.model.holders(name):
            continue
        X = ctx.model.object_pose(name)
        L = ctx.model.object(name).shape.length
        a, b = X @ np.array([0, 0, -L / 2]), X @ np.array([0, 0, L / 2])
        if np.hypot(*(a[:2] - c[:2])) < HOLDER.radius and a[2] < c[2] + HOLDER.height:
            segs.append((a, b))
    if not segs:
        return np.asarray(c[:2], dtype=float)
    z0, z1 = c[2] + HOLDER.height - insert - 0.01, c[2] + HOLDER.height + 0.02

    def clearance(xy: np.ndarray) -> float:
        out = math.inf
        for a, b in segs:
            for z in np.linspace(z0, z1, 5):
                t = (z - a[2]) / (b[2] - a[2]) if abs(b[2] - a[2]) > 1e-6 else 0.5
                q = a + np.clip(t, 0.0, 1.0) * (b - a)
                out = min(out, float(np.hypot(*(q[:2] - xy))))
        return out

    return np.asarray(max(cands, key=clearance), dtype=float)


def _segment_distance(a0, a1, b0, b1) -> float:
    """Least distance between segments a0-a1 and b0-b1 (sampled finely)."""
    t = np.linspace(0.0, 1.0, 41)
    pa = a0[None] + t[:, None] * (a1 - a0)[None]
    pb = b0[None] + t[:, None] * (b1 - b0)[None]
    return float(np.min(np.linalg.norm(pa[:, None] - pb[None], axis=2)))


def _ends(x: float, y: float, yaw: float, length: float) -> tuple[np.ndarray, np.ndarray]:
    d = np.array([math.cos(yaw), math.sin(yaw)]) * length / 2
    return np.array([x, y]) + d, np.array([x, y]) - d


def _positions(
    rng: np.random.Generator, shapes: dict[str, list[PenShape]]
) -> dict[str, list[list[float]]]:
    """(x, y, yaw) of the two pens per side (rejection sampling from `rng`): one per row,
    the pens PEN_GAP apart and HOLDER_GAP from the holder; the one nearer the holder first.
    `shapes[side]` are that side's pens in the order they will be picked (near one first)."""
    h = np.asarray(HOLDER_XY)
    for _ in range(2000):
        out = {}
        for side in SIDES:
            rows = [0, 1] if rng.random() < 0.5 else [1, 0]
            draws = [
                [
                    float(rng.uniform(*X_RANGE[side])),
                    float(rng.uniform(*Y_RANGE[r])),
                    float(int(rng.integers(8)) * math.pi / 4),
                ]
                for r in rows
            ]
            draws.sort(key=lambda p: float(np.hypot(p[0] - h[0], p[1] - h[1])))
            out[side] = draws
        if all(_layout_ok(out[s], shapes[s]) for s in out):
            return out
    raise RuntimeError("no pen layout found in 2000 draws")  # pragma: no cover


def _layout_ok(poses: list[list[float]], shapes: list[PenShape]) -> bool:
    """The two pens of one side are PEN_GAP apart and HOLDER_GAP from the holder, and each
    one's grasp point GRASP_ROOM from the other."""
    segs = [_ends(x, y, yaw, s.length) for (x, y, yaw), s in zip(poses, shapes, strict=True)]
    h = np.asarray(HOLDER_XY)
    for (a, b), s in zip(segs, shapes, strict=True):
        if _segment_distance(a, b, h, h) < HOLDER.radius + s.radius + HOLDER_GAP:
            return False
    gap = _segment_distance(*segs[0], *segs[1]) - shapes[0].radius - shapes[1].radius
    if gap < PEN_GAP:
        return False
    for k in (0, 1):  # the fingers at one pen's grasp point stay clear of the other pen
        x, y, yaw = poses[k]
        back = np.array([x, y]) - GRASP_BACK * np.array([math.cos(yaw), math.sin(yaw)])
        other = segs[1 - k]
        if _segment_distance(back, back, *other) - shapes[1 - k].radius < GRASP_ROOM:
            return False
    return True

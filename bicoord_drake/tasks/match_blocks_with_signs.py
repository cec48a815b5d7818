"""match_blocks_with_signs: three long cuboids, each handed from the left arm to the right and
stood upright on the grey square of its size."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from functools import partial

import numpy as np
from pydrake.all import RigidTransform, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, flat_marker
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    GraspParams,
    arm_base,
    box_grasps,
    gripper_frame,
    place_candidates,
)
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    SkillContext,
    first_step_in_zone,
    handover,
    hold_still,
    merge,
    move_tcp,
    pick,
    place,
    retreat,
    slowed_after,
    solve_tcp,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    Predicate,
    all_of,
    hands_free,
    held_by,
    lifted,
    not_touched_by,
    settled,
    stands_upright_at,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

#: The cuboids: length (m) and the side of their square ends (m), one per cuboid.
LENGTH = 0.12
ENDS = (0.04, 0.05, 0.06)
CUBOIDS = ("cuboid_4", "cuboid_5", "cuboid_6")
DENSITY = 450.0  # kg/m^3, painted wood: 86-194 g
#: Where the cuboids lie (along y): the spec's three x slots, shuffled; y; jitter (m, rad).
CUBOID_X = (-0.3, -0.2, -0.1)
CUBOID_Y = -0.05
JITTER = 0.01
YAW_JITTER = 0.1
#: The grey squares (side = the matching cuboid's end): x and the three y slots, shuffled. The
#: spec's y slots (0.15, 0.03, -0.10) moved 2-4 cm toward the robot: the right arm cannot hold
#: a standing cuboid top-down 6 cm above y = 0.15 (measured), it can above y = 0.11.
SQUARE_X = 0.15
SQUARE_Y = (0.11, 0.0, -0.12)
SQUARES = ("square_4", "square_5", "square_6")
#: A cuboid counts when it stands within this (m, xy) of its square's centre, long axis within
#: 15 deg of vertical.
ON_SQUARE_TOL = 0.03
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}

# ---- expert
#: The left arm grips a lying cuboid top-down this far (m) from its middle toward one end:
#: stood up for the handover, that end is the bottom, and the upper end is free for the right
#: arm's top-down grasp, which is the grasp it stands the cuboid up with.
END_OFFSET = 0.03
#: Fingertips at least this far (m) above the table under a lying cuboid gripped top-down.
TIP_CLEARANCE = 0.012
#: Pad-to-cuboid gap (m) per side of the left's narrowed jaw as it comes down on a cuboid.
PICK_MARGIN = 0.008
#: Where the cuboid's centre is at the handover (tried in order).
MEETS = (
    (-0.04, -0.10, TABLE_TOP + 0.17),
    (-0.02, -0.05, TABLE_TOP + 0.17),
    (-0.06, -0.12, TABLE_TOP + 0.20),
)
#: Yaws (rad) of the upright cuboid at the meeting that are tried.
MEET_YAWS = tuple(np.radians(np.arange(0, 360, 30)))
#: At the meeting the left's approach points this much along +x at least (cosine).
MIN_INWARD = 0.4
LIFT = 0.08
#: Where the right arm's TCP waits (gripper down) while the left picks the first cuboid.
WAIT = (0.06, -0.10, TABLE_TOP + 0.32)
#: How far (m) the left backs off along its approach once it let go at the handover.
BACK_OFF = 0.10
#: The left arm has retreated once its TCP is this far (m) from the last cuboid.
RETREATED = 0.15
#: After the last handover the left's way home keeps its own pace until its TCP is this far
#: (xy, m) from where it let go (then it is timed to end with the right's return).
LEAVE_ZONE = 0.25
SETTLE = 0.53


@register_task
class MatchBlocksWithSigns(Task):
    """Stand three long cuboids upright on the grey squares of their sizes, each handed over.

    Description: three 12 cm cuboids with square ends of 4, 5 and 6 cm lie along y on the left
    of the table (x in {-0.3, -0.2, -0.1}, shuffled, y = -0.05), each in its own colour; three
    grey squares, 4, 5 and 6 cm, are marked on the right (x = 0.15, y in {0.15, 0.03, -0.10},
    shuffled). Three rounds, the farthest square's cuboid first: the left arm picks a cuboid
    top-down near one end, turns it upright (that end down) and meets the right arm above the
    middle of the table; the right grasps the free upper end top-down and closes, then the left
    opens and backs off; the right stands the cuboid upright on the square of its size while
    the left already picks the next cuboid. The handover and the placement are planned
    together: the right's grasp at the meeting is taken only if the right can stand the cuboid
    on its square with it (the cuboid upright, the grasp top-down). After the last handover
    the left goes home while the right places and goes home (the left's way back timed to
    end with the right's once it is clear of the meeting). The spec's layout is kept except
    the squares' y slots, moved 2-4 cm toward the robot (from 0.15, 0.03, -0.10): our right
    arm cannot hold a standing 12 cm cuboid top-down above y = 0.15.

    Randomization: the order of the cuboids in the three x slots and of the squares in the
    three y slots; each cuboid's centre within 1 cm and its yaw within +-0.1 rad of its slot;
    the three colours (from six).

    Stages: per cuboid, in the order of their squares from the farthest: L picks it (0); the
    handover, R holding it, L not touching it (0); it stands upright on the square of its size
    (1/3, while L picks the next); after the last handover L retreats (0) before the last
    placement - ten stages.

    Success: each cuboid stands on its end on the table (long axis within 15 deg of vertical),
    its centre within 3 cm (xy) of the centre of the grey square of its size, both grippers
    open, no finger touching a cuboid, every cuboid at rest for 0.3 s.
    """

    name = "match_blocks_with_signs"
    step_limit = 1300
    supported_robots = ("aloha_viperx", "franka_pair")
    instructions_seen = (
        "Stand each long block upright on the grey square that matches its size.",
        "Pass the blocks from the left hand to the right and set each one upright on its "
        "matching square.",
        "Match every block to the square of its size, standing it on end.",
        "Hand the three bars over one by one and stand them up on the right-sized squares.",
        "Put each lying block upright on the grey sign with the same size as its end.",
        "One at a time, give the blocks to the right hand and stand them on their squares.",
        "Sort the three cuboids onto the grey squares by size, standing them up.",
    )
    instructions_unseen = (
        "Stand the blocks on end, each on the square that fits its base.",
        "Move the three lying bars onto the matching grey squares, upright.",
        "Using both hands, stand every block on the sign that matches its thickness.",
        "Take each block with the left hand, pass it to the right, and stand it on its square.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        slots = [int(i) for i in rng.permutation(3)]
        square_slots = [int(i) for i in rng.permutation(3)]
        color_names = [str(c) for c in rng.choice(sorted(COLORS), size=3, replace=False)]
        xy = [
            [
                round(CUBOID_X[s] + float(rng.uniform(-JITTER, JITTER)), 4),
                round(CUBOID_Y + float(rng.uniform(-JITTER, JITTER)), 4),
            ]
            for s in slots
        ]
        yaws = [round(float(rng.uniform(-YAW_JITTER, YAW_JITTER)), 4) for _ in CUBOIDS]
        squares = [[SQUARE_X, SQUARE_Y[s]] for s in square_slots]
        objects = [
            flat_marker(name, sq, end, (0.55, 0.55, 0.57, 1.0))
            for name, sq, end in zip(SQUARES, squares, ENDS, strict=True)
        ]
        objects += [
            _cuboid(name, p, yaw, end, COLORS[c])
            for name, p, yaw, end, c in zip(CUBOIDS, xy, yaws, ENDS, color_names, strict=True)
        ]
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "cuboid_slots": slots,
                "square_slots": square_slots,
                "colors": color_names,
                "cuboid_xy": xy,
                "cuboid_yaws": yaws,
                "square_xy": squares,
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 6  # three cuboids and the three squares they are matched to

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        order = placement_order(scene)
        stages: list[Stage] = []
        for k, i in enumerate(order):
            name, square = CUBOIDS[i], scene.draws["square_xy"][i]
            stages.append(
                Stage(
                    f"pick the {_cm(i)} block",
                    f"pick the {_cm(i)} block near one end, lift it",
                    "come above the meeting" if k == 0 else "stand the last block up, come back",
                    0.0,
                    all_of(held_by(name, "left"), lifted(name, 0.04)),
                    "transient",
                )
            )
            stages.append(
                Stage(
                    f"hand the {_cm(i)} block over",
                    "stand it up at the meeting, let go once the right holds it",
                    "grasp its upper end from above",
                    0.0,
                    all_of(
                        held_by(name, "right"),
                        not_touched_by(name, "left"),
                        lifted(name, 0.08, reference="table"),
                    ),
                    "transient",
                )
            )
            last = k == len(order) - 1
            if last:
                stages.append(
                    Stage(
                        "left retreats",
                        "go home",
                        f"carry the {_cm(i)} block to its square",
                        0.0,
                        all_of(
                            held_by(name, "right"),
                            not_touched_by(name, "left"),
                            tcp_away("left", name, RETREATED),
                        ),
                        "transient",
                    )
                )
            standing = stands_upright_at(name, square, ON_SQUARE_TOL)
            final = [hands_free(list(CUBOIDS)), settled(list(CUBOIDS))] if last else []
            stages.append(
                Stage(
                    f"stand the {_cm(i)} block on its square",
                    "go home" if last else f"pick the {_cm(order[k + 1])} block",
                    f"stand the {_cm(i)} block upright on the {_cm(i)} square",
                    1.0 / 3.0,
                    all_of(standing, settled([name]), *final),
                    "persistent",
                )
            )
        return stages

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        order = [CUBOIDS[i] for i in placement_order(scene)]
        squares = {CUBOIDS[i]: scene.draws["square_xy"][i] for i in range(3)}

        run = partial(follow, ctx, view)

        with narrow_jaw(ctx, order[0]):
            left = pick_near_end(ctx, order[0])
            motion = merge(ctx, left, come_to_wait(ctx))
        yield from run(motion)
        for k, name in enumerate(order):
            # L stands the cuboid up and meets R, whose grasp is one it can stand it up with
            yield from run(handover_to_stand(ctx, name, squares[name]))
            # R stands it on its square while L picks the next (or retreats after the last)
            if k + 1 < len(order):
                with narrow_jaw(ctx, order[k + 1]):
                    right = stand_up(ctx, name, squares[name])
                    motion = merge(ctx, pick_near_end(ctx, order[k + 1]), right)
            else:
                motion = _stand_last(ctx, name, squares[name])
            yield from run(motion)
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


def _stand_last(ctx: SkillContext, name: str, square_xy: Sequence[float]) -> Motion:
    """R stands the last cuboid on its square and goes home while L goes home from the
    meeting: L's way back runs at its own pace until its TCP is LEAVE_ZONE (xy) from where it
    let go, then is slowed (:func:`slowed_after`, the same path) to end with R's return, so
    neither arm stands idle while the other finishes. If the two would meet, the arms go one
    after the other as before (L home during the stand-up, then R home)."""
    right = stand_up(ctx, name, square_xy)
    left = retreat(ctx, "left")
    right_home = retreat(ctx, "right")
    start = ctx.model.tcp_pose(ctx.with_arm("left", left.q[0]), "left").translation()
    out = first_step_in_zone(ctx, left, start[:2], LEAVE_ZONE, inside=False)
    both_home = right.then(right_home)
    try:
        return merge(ctx, slowed_after(ctx, left, out, both_home.num_steps), both_home)
    except PlanningError as err:
        if err.reason != "arm_conflict":
            raise
    return merge(ctx, left, right).then(merge(ctx, None, right_home))


# -------------------------------------------------------------------- scene parts
def placement_order(scene: Scene) -> list[int]:
    """Cuboid indices in the order they are placed: the farthest square (largest y) first, so
    the right arm never reaches over a cuboid it has stood up."""
    return sorted(range(3), key=lambda i: -scene.draws["square_xy"][i][1])


def _cm(i: int) -> str:
    return f"{round(ENDS[i] * 100)} cm"


def _cuboid(name: str, xy: Sequence[float], yaw: float, end: float, color) -> SceneObject:
    """A cuboid lying on a side face, its long axis (its frame's z) along the world y."""
    return SceneObject(
        name=name,
        shape=BoxShape(size=(end, end, LENGTH)),
        color=color,
        mass=DENSITY * end * end * LENGTH,
        pose=Pose(xyz=(xy[0], xy[1], TABLE_TOP + end / 2), rpy=(np.pi / 2, 0.0, yaw)),
    )


# -------------------------------------------------------------------- predicates
def tcp_away(side: str, obj: str, distance: float) -> Predicate:
    """The TCP of `side` at least `distance` (m) from `obj`'s centre."""

    def check(s) -> bool:
        tcp = s.tcp_poses.get(side)
        return tcp is not None and bool(np.linalg.norm(tcp[:3] - s.position(obj)) >= distance)

    return Predicate(check, f"tcp_away({side!r}, {obj!r}, {distance})")


# -------------------------------------------------------------------- expert helpers
def end_grasps(ctx: SkillContext, side: str, name: str) -> list[Grasp]:
    """Top-down grasps of a lying cuboid across its width, END_OFFSET from its middle toward
    either end, best first."""
    X_WO = ctx.model.object_pose(name)
    shape = ctx.model.object(name).shape
    grasps = box_grasps(
        X_WO,
        shape,
        ctx.model.embodiment.arm.gripper,
        base=arm_base(ctx.model.embodiment, side),
        kinds=["top"],
        params=GraspParams(tip_clearance=TIP_CLEARANCE),
    )
    axis = X_WO.rotation().matrix()[:, 2]  # the long axis
    out = []
    for g in grasps:
        for s in (-1.0, 1.0):
            shift = s * END_OFFSET * axis
            X_WG = RigidTransform(g.X_WG.rotation(), g.X_WG.translation() + shift)
            X_pre = RigidTransform(g.X_WPre.rotation(), g.X_WPre.translation() + shift)
            out.append(Grasp(g.kind, X_WG, X_pre, X_WO.inverse() @ X_WG, g.width, g.score))
    if not out:
        raise PlanningError("no_grasp", f"no top grasp across {name!r}")
    return out


def pick_opening(ctx: SkillContext, name: str) -> float:
    """The left's jaw on the way down onto a lying cuboid: PICK_MARGIN (m) per side wider
    than it (the fingers fit between the neighbouring cuboids)."""
    width = ctx.model.object(name).shape.size[0]
    return float(np.clip(ctx.model.embodiment.arm.gripper.opening(width / 2 + PICK_MARGIN), 0, 1))


@contextmanager
def narrow_jaw(ctx: SkillContext, name: str) -> Iterator[None]:
    """Plan (and check merged motions) with the left's fingers as far apart as when it comes
    down on cuboid `name` (:func:`pick_opening`), then back to the open jaw."""
    ctx.model.set_gripper("left", pick_opening(ctx, name))
    try:
        yield
    finally:
        ctx.model.set_gripper("left", ctx.model.embodiment.home_opening)


def pick_near_end(ctx: SkillContext, name: str) -> ArmPlan:
    """The left arm picks a lying cuboid top-down near one end and lifts it, its jaw only
    :func:`pick_opening` wide on the way in (plan it, and merge it, in :func:`narrow_jaw`)."""
    grasps = end_grasps(ctx, "left", name)
    opening = pick_opening(ctx, name)
    return pick(ctx, "left", name, lift=LIFT, grasps=grasps, approach_opening=opening)


def standing_orientations(ctx: SkillContext, side: str) -> list[RotationMatrix]:
    """Upright orientations of the cuboid `side` (the left) holds with the gripped end down (its
    frame's z up if the grip is on its -z half, else down), turned by MEET_YAWS, the left's
    approach pointing toward +x (its wrist on its own side of the cuboid: it then backs off
    away from the right arm's way to the squares)."""
    held = ctx.model.held[side]
    X_OT = held.X_GO.inverse() @ RigidTransform([ctx.model.embodiment.arm.gripper.tcp_x, 0, 0])
    below = X_OT.translation()[2] < 0
    R_up = RotationMatrix() if below else RotationMatrix.MakeXRotation(np.pi)
    out = []
    for yaw in MEET_YAWS:
        R = RotationMatrix.MakeZRotation(float(yaw)) @ R_up
        if (R @ X_OT.rotation()).matrix()[0, 0] >= MIN_INWARD:
            out.append(R)
    return out


def standing_goal(R_WO: RotationMatrix, xy: Sequence[float], length: float) -> RigidTransform:
    """The cuboid standing at `xy` with orientation `R_WO` (upright), 2 mm above the table."""
    return RigidTransform(R_WO, [xy[0], xy[1], TABLE_TOP + length / 2 + 0.002])


def stand_grasps(ctx: SkillContext, name: str, square_xy: Sequence[float]):
    """Receiver grasps for :func:`handover`: top-down on the upright cuboid's upper end, kept
    only if the right arm can then stand the cuboid on its square with that very grasp (its
    pre-place and place poses solve): the handover grasp is chosen for the placement."""
    shape = ctx.model.object(name).shape
    gripper = ctx.model.embodiment.arm.gripper
    base = arm_base(ctx.model.embodiment, "right")

    def grasps(X_WO: RigidTransform, X_WTg: RigidTransform) -> Iterator[Grasp]:
        goal = standing_goal(X_WO.rotation(), square_xy, shape.size[2])
        for g in box_grasps(X_WO, shape, gripper, base=base, kinds=["top"]):
            X_TO = g.X_WG.inverse() @ X_WO
            if _can_stand(ctx, X_TO, goal, shape):
                yield g

    return grasps


def _can_stand(ctx: SkillContext, X_TO: RigidTransform, goal: RigidTransform, shape) -> bool:
    """Whether the right arm reaches the pre-place and place poses of some symmetric yaw."""
    base = arm_base(ctx.model.embodiment, "right")
    for cand in place_candidates(X_TO, goal, shape, base=base, lift=0.06):
        try:
            q_above = solve_tcp(ctx, "right", TcpTarget(cand.X_WPre))
            solve_tcp(ctx, "right", TcpTarget(cand.X_WG), seed_arm=q_above, env_clearance=0.0)
        except PlanningError:
            continue
        return True
    return False


def handover_to_stand(ctx: SkillContext, name: str, square_xy: Sequence[float]) -> Motion:
    """Left to right handover of the cuboid, upright, at the first of MEETS that works."""
    reasons = []
    for meet in MEETS:
        try:
            return handover(
                ctx,
                "left",
                "right",
                meet=meet,
                orientations=standing_orientations(ctx, "left"),
                receiver_grasps=stand_grasps(ctx, name, square_xy),
                retreat=BACK_OFF,
            )
        except PlanningError as err:
            reasons.append(str(err))
    raise PlanningError("handover_failed", f"no handover of {name!r} ({', '.join(reasons)})")


def come_to_wait(ctx: SkillContext) -> ArmPlan | None:
    """The right arm comes above the meeting, gripper down, to wait for the first cuboid
    (None if that pose is out of reach: it then waits at home)."""
    X = gripper_frame(np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0]), np.array(WAIT))
    try:
        return move_tcp(ctx, "right", X, label="come above the meeting")
    except PlanningError:
        return None


def stand_up(ctx: SkillContext, name: str, square_xy: Sequence[float]) -> ArmPlan:
    """The right arm stands the cuboid it holds upright on its square, lets go slowly and backs
    off up."""
    R_WO = upright_part(ctx.model.held_pose("right", ctx.q).rotation())
    goal = standing_goal(R_WO, square_xy, ctx.model.object(name).shape.size[2])
    return place(ctx, "right", goal, gentle_release=True)


def upright_part(R_WO: RotationMatrix) -> RotationMatrix:
    """The exactly upright orientation nearest a nearly upright `R_WO` (same end up, same
    yaw): a measured tilt of a few degrees is not carried into the placement."""
    R = R_WO.matrix()
    yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    flip = RotationMatrix() if R[2, 2] > 0 else RotationMatrix.MakeXRotation(np.pi)
    return RotationMatrix.MakeZRotation(yaw) @ flip

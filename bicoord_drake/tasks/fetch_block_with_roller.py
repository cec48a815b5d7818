"""fetch_block_with_roller: push a cube out from under a low shelf with a wooden roller, then
set it on the shelf.

Measurements of the expert in physics: benchmarks/bench_task_fetch_block_with_roller.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from functools import partial

import numpy as np
from pydrake.all import AngleAxis, RigidTransform, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import CylinderShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.models.shelf import ShelfDims, shelf
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    GraspParams,
    arm_base,
    grasp_candidates,
    turned,
    turned_onto,
)
from bicoord_drake.planning.skills import (
    ArmPlan,
    SkillContext,
    combine,
    hold,
    hold_still,
    merge,
    move_tcp,
    pick,
    place,
    retreat,
    slowed_after,
    split_at,
    track,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    beyond,
    on_a_face,
    on_table,
    released,
    rests_on,
    settled,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

SHELF, CUBE, ROLLER = "shelf", "cube", "roller"
#: The shelf (see the class doc): its footprint centred at SHELF_XY, the tunnel along x.
SHELF_DIMS = ShelfDims()
SHELF_XY = (-0.075, 0.0)
#: The tunnel's exit (its -x end) and the line the pushed cube's centre must cross.
EXIT_X = SHELF_XY[0] - SHELF_DIMS.length / 2
OUT_X = -0.15
#: The cube: 5 cm, light, its centre anywhere in these ranges (under the shelf).
CUBE_EDGE, CUBE_MASS = 0.05, 0.05
CUBE_X, CUBE_Y, CUBE_YAW = (-0.125, -0.025), (-0.01, 0.01), (-0.15, 0.15)
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: The roller: a wooden dowel lying along x in front of the shelf (length, diameter, m).
ROLLER_LENGTH, ROLLER_DIAMETER = (0.34, 0.38), (0.032, 0.036)
ROLLER_DENSITY = 450.0  # kg/m^3, light wood: 0.12-0.17 kg
ROLLER_COLOR = (0.84, 0.67, 0.45, 1.0)
ROLLER_X, ROLLER_Y, ROLLER_YAW = (0.13, 0.17), (-0.21, -0.17), (-0.15, 0.15)
#: Stage 2: the cube's centre within this xy distance (m) of the top plate's centre.
XY_TOL = 0.02
#: Expert: the right hand grips the roller this far (m) behind its middle (toward +x: the
#: front part reaches through the tunnel, the hand stays outside), so at most GRIP_FROM_TIP
#: from its pushing tip (TASKS.md section 11: at most 0.20 m; the longest roller's tip is
#: 0.19 m from its middle); its pads this far above the roller's bottom at least; the roller
#: is lifted this high after the grasp.
GRIP_FROM_TIP = 0.20
GRIP_BACK = GRIP_FROM_TIP - ROLLER_LENGTH[1] / 2
#: Where no upright grasp leaves a push that plans (the hand, GRIP_FROM_TIP behind the tip,
#: would touch the top plate's edge at the push's end: the Franka Hand, 2-5 mm), the grasps
#: tilted about their finger axis by these angles (rad), the hand leaning back toward +x away
#: from the shelf, are tried in turn.
GRIP_PITCHES = (math.radians(15), math.radians(30))
TIP_CLEARANCE = 0.007
LIFT = 0.08
#: The push: the roller's axis this high above the table (below the cube's middle: the
#: table's friction at the cube's bottom does not tip it), its tip from START_X (outside the
#: tunnel's +x mouth) to END_X (the cube's centre then 2.5 cm further, out of the exit),
#: lowered onto the line from APPROACH above; slower than the other moves.
PUSH_Z = 0.024
START_X, END_X = 0.035, -0.168
APPROACH = 0.04
#: A cube pushed out too turned to be picked is pushed on by NUDGE (m), up to NUDGES times.
NUDGE, NUDGES = 0.02, 2
#: Before drawing the roller back, its tip is raised this much (m) off the pushing line.
RAISE = 0.008
PUSH_SPEED = 0.35
#: The left's way to the exit is timed to end this many seconds before the push as planned
#: ahead from the planned grasp (the real push, planned from the measured grasp, is up to
#: ~0.7 s shorter); the rest is slowed to end with the real push.
PUSH_MARGIN = 0.8
#: Seconds both arms hold still at the end (the cube must be seen at rest 0.3 s).
SETTLE = 0.53


@register_task
class FetchBlockWithRoller(Task):
    """Push the cube out from under the shelf with the roller, then put it on the shelf.

    Description: a low grey shelf stands on the table: two side walls under a flat top
    plate, forming a tunnel along x. A 5 cm cube sits inside the tunnel, out of any gripper's
    reach; a wooden roller (a dowel about 36 cm long) lies in front of the shelf on the right.
    The right arm grasps the roller behind its middle, lays it level along the tunnel's axis
    and pushes the cube with the roller's flat end, slowly, out of the tunnel's left end.
    Meanwhile the left arm comes to the pregrasp above where the cube will come out (its
    way there timed to end as the push does) and takes the cube from there, with the grasp
    its hand is already turned for. Then both arms work at once: the right draws the roller
    back until its tip clears the shelf and keeps it in hand there, while the left picks the
    cube and sets it on the middle of the top plate.

    Coordination: the task forces distance in stage 1 (the cube comes out at the tunnel's
    left end, the roller is pushed from the right end, the right hand ~19 cm behind the
    roller's tip) and a hand-off in time: the left cannot grasp before the cube is out,
    nor descend to it while the roller's tip is still within the arms' clearance.

    Layout: the reference's walls (15x5x6 cm at y = +-0.05) under a plate ~9 cm high leave
    a 5 cm tunnel for a 5 cm cube and a gap between walls and plate. Here the walls are
    15 cm long (x in [-0.15, 0]), 2 cm thick and 6.5 cm high with their inner faces 9 cm
    apart (centres at y = +-0.055), under a 15x20x2 cm plate whose top is 8.5 cm above the
    table: the cube has 2 cm of room each side and 1.5 cm above, too little for any finger or
    wrist, and a top grasp is blocked by the plate. The roller lies along x (not across) at
    x = 0.15, in front of the shelf, so the right hand can grasp it where it will push from.

    Randomization: the cube's centre at x in [-0.125, -0.025] (under the shelf, as in the
    reference), y in [-0.01, 0.01], yaw +-0.15 rad, and its colour; the roller's length
    34-38 cm and diameter 3.2-3.6 cm, its centre at x in [0.13, 0.17], y in [-0.21, -0.17],
    turned +-0.15 rad about the vertical from lying along x.

    Stages: (1) the cube's centre past x = -0.15 (out of the tunnel's left end), lying on a
    face on the table (transient); (2) the cube resting on the top plate, its centre within
    2 cm of the plate's centre, lying on a face, released (each gripper open or closed on the
    roller, which the right keeps in hand; no robot body touching the cube), at rest for 0.3 s
    (persistent).

    Success: stage 2 holds when the rollout ends: the cube sits released and still on the
    middle of the shelf.
    """

    name = "fetch_block_with_roller"
    step_limit = 450
    supported_robots = ("aloha_viperx", "franka_pair")
    expert_speed = 0.7
    instructions_seen = (
        "Push the block out from under the shelf with the roller and put it on top of the shelf.",
        "Use the wooden roller to get the cube out of the shelf, then set it on the shelf.",
        "Fetch the cube from under the shelf with the stick and place it on the shelf top.",
        "Slide the block out of the tunnel with the roller, then put it on top.",
        "Poke the cube out from below the shelf with the roller and lift it onto the shelf.",
        "Get the block from under the low shelf using the roller and place it on the shelf.",
        "With the roller, push the cube out the far side of the shelf, then set it on top.",
    )
    instructions_unseen = (
        "The cube is stuck under the shelf: push it out with the dowel and put it on the shelf.",
        "Use the stick as a tool to retrieve the block, then place it in the middle of the shelf.",
        "One hand pushes the block out with the roller, the other puts it on the shelf.",
        "Retrieve the cube from beneath the shelf with the wooden rod and set it on the top.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        cube_xy = [float(rng.uniform(*CUBE_X)), float(rng.uniform(*CUBE_Y))]
        cube_yaw = float(rng.uniform(*CUBE_YAW))
        color = str(rng.choice(sorted(COLORS)))
        length = float(rng.uniform(*ROLLER_LENGTH))
        diameter = float(rng.uniform(*ROLLER_DIAMETER))
        roller_xy = [float(rng.uniform(*ROLLER_X)), float(rng.uniform(*ROLLER_Y))]
        roller_yaw = float(rng.uniform(*ROLLER_YAW))
        return Scene(
            name=self.name,
            seed=seed,
            objects=(
                shelf(SHELF, SHELF_XY, TABLE_TOP, SHELF_DIMS),
                cube(
                    CUBE,
                    *cube_xy,
                    size=CUBE_EDGE,
                    color=COLORS[color],
                    mass=CUBE_MASS,
                    yaw=cube_yaw,
                ),
                roller(length, diameter, roller_xy, roller_yaw),
            ),
            draws={
                "cube_xy": cube_xy,
                "cube_yaw": cube_yaw,
                "color": color,
                "roller_length": length,
                "roller_diameter": diameter,
                "roller_xy": roller_xy,
                "roller_yaw": roller_yaw,
            },
        )

    def may_leave_table(self, scene: Scene) -> dict[str, None]:
        # Success is the cube on the shelf: a roller a policy drops once the cube is out does
        # not end its rollout early.
        return {ROLLER: None}

    def object_count(self, scene: Scene) -> int:
        return len(scene.free_objects) + 1  # the cube, the roller and the shelf

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        pushed_out = all_of(beyond(CUBE, OUT_X, "x"), on_table(CUBE), on_a_face(CUBE))
        on_shelf = all_of(
            rests_on(CUBE, SHELF, xy_tol=XY_TOL),
            on_a_face(CUBE),
            released(CUBE, tools=[ROLLER]),  # the right keeps the roller in hand
            settled([CUBE]),
        )
        return [
            Stage(
                "push the block out",
                "wait above the exit, ready",
                "grasp the roller, push the cube out from under the shelf",
                0.5,
                pushed_out,
                "transient",
            ),
            Stage(
                "put it on the shelf",
                "pick the cube, place it on the middle of the top plate",
                "draw the roller back until its tip clears the shelf, keep holding it",
                0.5,
                on_shelf,
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)

        run = partial(follow, ctx, view)

        # ---- stage 1: right grasps the roller and pushes the cube out; meanwhile the left
        # comes to the pregrasp above where the cube comes out, timed to arrive as it does
        right, push_steps = _pick_for_push(ctx)
        left = move_tcp(ctx, "left", exit_pregrasp(ctx), label="above the exit")
        left = left.stretched(right.num_steps + push_steps - ctx.steps(PUSH_MARGIN))
        left, rest = split_at(left, right.num_steps - 1)
        ctx.q = ctx.with_arm("left", left.q[-1])
        yield from run(merge(ctx, left, right))
        # right lays the roller along the tunnel and pushes the cube out; the left comes on
        cube_y = float(ctx.model.object_pose(CUBE).translation()[1])
        tool = RollerTool.from_grasp(ctx)
        start = np.array([START_X, cube_y, TABLE_TOP + PUSH_Z])
        end = np.array([END_X, cube_y, TABLE_TOP + PUSH_Z])
        push = push_through(ctx, tool, start, end)
        rest = slowed_after(ctx, rest, 0, push.num_steps)
        ctx.q = ctx.with_arm("left", rest.q[-1])
        # the shelf is left out of this check of the arms against each other: each plan was
        # checked against it when made, and merge's denser substeps found the right's hand
        # 0.08 mm into it between two samples of the push on seed 4 (no timing helps that)
        yield from run(merge(ctx, rest, push, stretch=False, ignore=[CUBE, SHELF]))
        # ---- stage 2: right levels the roller off the pushing line (alone, as a track: its
        # hand may graze the table there), then draws it back out and keeps it in hand while
        # left picks the cube and sets it on the plate (the arm leaving is planned first).
        # Past the walls nothing keeps the cube square: turned, it can leave no room for a
        # finger by the shelf, and then the roller pushes it on before this is planned again.
        for nudge in range(NUDGES + 1):
            yield from run(combine(hold(ctx, "left", 0), level_roller(ctx)))
            try:
                with ctx.transaction():
                    left, right = _fetch_and_clear(ctx)
                break
            except PlanningError as err:
                if err.reason != "pick_failed" or nudge == NUDGES:
                    raise
            # one arm moves, its track checked against the other: no merge (the measured roller
            # may start touching the table, which only a track allows)
            yield from run(combine(hold(ctx, "left", 0), push_on(ctx, NUDGE)))
        yield from run(merge(ctx, left, right, ignore=[CUBE]))
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


def _fetch_and_clear(ctx: SkillContext) -> tuple[ArmPlan, ArmPlan]:
    """Stage 2's plans: the right draws the roller back until its tip clears the shelf and
    keeps it in hand there (TASKS.md section 11: the reference keeps the roller to the end);
    the left picks the cube and sets it on the middle of the plate."""
    right = withdraw(ctx, START_X)
    top = TABLE_TOP + SHELF_DIMS.top + CUBE_EDGE / 2
    goal = RigidTransform([SHELF_XY[0], SHELF_XY[1], top + 0.001])
    left = pick(ctx, "left", CUBE, grasps=nearest_first(ctx, "left", cube_grasps(ctx))).then(
        place(ctx, "left", goal, gentle_release=True),
        retreat(ctx, "left"),
    )
    return left, right


# -------------------------------------------------------------------- objects
def roller(length: float, diameter: float, xy, yaw: float) -> SceneObject:
    """The wooden roller lying on the table, its axis along x turned by `yaw`."""
    radius = diameter / 2
    return SceneObject(
        name=ROLLER,
        shape=CylinderShape(radius=radius, length=length),
        color=ROLLER_COLOR,
        mass=ROLLER_DENSITY * math.pi * radius**2 * length,
        pose=Pose(xyz=(xy[0], xy[1], TABLE_TOP + radius), rpy=(0.0, math.pi / 2, yaw)),
    )


# -------------------------------------------------------------------- expert helpers
def roller_grasps(ctx: SkillContext) -> list[Grasp]:
    """Top grasps across the lying roller, moved GRIP_BACK behind its middle (toward +x)."""
    obj = ctx.model.object(ROLLER)
    X_WO = ctx.model.object_pose(ROLLER)
    grasps = grasp_candidates(
        obj,
        ctx.model.embodiment.arm.gripper,
        X_WO=X_WO,
        base=arm_base(ctx.model.embodiment, "right"),
        kinds=["top"],
        params=GraspParams(tip_clearance=TIP_CLEARANCE),
    )
    axis = X_WO.rotation().col(2)
    shift = GRIP_BACK * math.copysign(1.0, axis[0]) * axis
    return [_shifted(g, X_WO, shift) for g in grasps]


def leaning_back(g: Grasp, X_WO: RigidTransform, angle: float) -> Grasp:
    """`g` turned by `angle` about its finger axis through the TCP (``grasps.turned``), in the
    sense that leans the hand back toward +x: its approach then points toward -x, the shelf."""
    R = g.X_WG.rotation().matrix()  # a copy: .col() of a temporary is a view of freed memory
    turn = AngleAxis(angle, R[:, 1]).rotation()
    if (turn @ R)[0, 0] > 0:
        turn = turn.T
    return turned(g, X_WO, RotationMatrix(turn))


def _pick_for_push(ctx: SkillContext) -> tuple[ArmPlan, int]:
    """The right's pick of the roller and the control steps of the push planned from it: the
    upright grasps first (``roller_grasps``), then each tilted by GRIP_PITCHES, until the push
    from the grasp plans. Raises the upright grasps' error when none does."""
    upright = roller_grasps(ctx)
    first: PlanningError | None = None
    X_WO = ctx.model.object_pose(ROLLER)
    tilted = [[leaning_back(g, X_WO, angle) for g in upright] for angle in GRIP_PITCHES]
    for grasps in (upright, *tilted):
        try:
            with ctx.transaction():
                right = pick(ctx, "right", ROLLER, grasps=grasps, lift=LIFT)
                return right, _push_steps(ctx)
        except PlanningError as err:
            first = first or err
    assert first is not None
    raise first


def _shifted(g: Grasp, X_WO: RigidTransform, shift: np.ndarray) -> Grasp:
    X_WG = RigidTransform(g.X_WG.rotation(), g.X_WG.translation() + shift)
    X_WPre = RigidTransform(g.X_WPre.rotation(), g.X_WPre.translation() + shift)
    return replace(g, X_WG=X_WG, X_WPre=X_WPre, X_OG=X_WO.inverse() @ X_WG)


def cube_grasps(ctx: SkillContext) -> list[Grasp]:
    """Top grasps of the pushed-out cube with the fingers on the side faces nearest to across
    y: a finger across x would come down by the shelf's edge or the roller's tip."""
    grasps = grasp_candidates(
        ctx.model.object(CUBE),
        ctx.model.embodiment.arm.gripper,
        X_WO=ctx.model.object_pose(CUBE),
        base=arm_base(ctx.model.embodiment, "left"),
        kinds=["top"],
    )
    if not grasps:
        raise PlanningError("no_grasp", "no top grasp of the cube")
    best = max(abs(g.finger_axis[1]) for g in grasps)
    return [g for g in grasps if abs(g.finger_axis[1]) > best - 1e-6]


def exit_pregrasp(ctx: SkillContext) -> RigidTransform:
    """The left's pregrasp of the cube where the push will leave it (its centre half an edge
    beyond the roller's last tip position, END_X): the grasp it will take, planned for that
    pose (the cube is put back where it is)."""
    X_now = ctx.model.object_pose(CUBE)
    p = X_now.translation()
    X_out = RigidTransform(X_now.rotation(), [END_X - CUBE_EDGE / 2, p[1], p[2]])
    ctx.model.set_object_pose(CUBE, X_out)
    try:
        return cube_grasps(ctx)[0].X_WPre
    finally:
        ctx.model.set_object_pose(CUBE, X_now)


def _push_steps(ctx: SkillContext) -> int:
    """Control steps of the push as planned from the grasp just planned (the real push is
    planned once the grasp is measured); the tracked state and the checker's padding are
    left as they were."""
    q, opening = ctx.q.copy(), dict(ctx.opening)
    with ctx.model.keeping_padding():
        try:
            cube_y = float(ctx.model.object_pose(CUBE).translation()[1])
            tool = RollerTool.from_grasp(ctx)
            start = np.array([START_X, cube_y, TABLE_TOP + PUSH_Z])
            end = np.array([END_X, cube_y, TABLE_TOP + PUSH_Z])
            return push_through(ctx, tool, start, end).num_steps
        finally:
            ctx.q, ctx.opening = q, opening


def nearest_first(ctx: SkillContext, side: str, grasps: list[Grasp]) -> list[Grasp]:
    """`grasps` ordered by how far the hand of `side` must turn to take them (the left waits
    above the exit turned for the grasp it expected; the pushed cube may have turned so that
    the other finger direction comes first, which would turn the wrist over in place)."""
    R_now = ctx.model.tcp_pose(ctx.q, side).rotation()

    def turn(g: Grasp) -> float:
        return float(AngleAxis((R_now.inverse() @ g.X_WG.rotation()).ToQuaternion()).angle())

    return sorted(grasps, key=turn)


class RollerTool:
    """The held roller laid level along -x: the TCP pose that puts its tip (the end of its
    axis toward -x) at a point, the grasp as measured after the pick."""

    def __init__(self, R_WO: RotationMatrix, p_OQ: np.ndarray, X_OT: RigidTransform) -> None:
        self.R_WO, self.p_OQ, self.X_OT = R_WO, p_OQ, X_OT

    @classmethod
    def from_grasp(cls, ctx: SkillContext) -> RollerTool:
        X_WT = ctx.model.tcp_pose(ctx.q, "right")
        X_WO = ctx.model.held_pose("right", ctx.q)
        shape = ctx.model.object(ROLLER).shape
        axis = X_WO.rotation().col(2)
        sign = -1.0 if axis[0] > 0 else 1.0  # the end that points toward -x
        p_OQ = np.array([0.0, 0.0, sign * shape.length / 2])
        R_level = turned_onto(X_WO.rotation(), sign * axis, np.array([-1.0, 0.0, 0.0]))
        return cls(R_level, p_OQ, X_WO.inverse() @ X_WT)

    def tcp_at(self, tip: np.ndarray) -> RigidTransform:
        X_WO = RigidTransform(self.R_WO, np.asarray(tip) - self.R_WO @ self.p_OQ)
        return X_WO @ self.X_OT

    def line(self, a: np.ndarray, b: np.ndarray) -> Callable[[float], RigidTransform]:
        return lambda s: self.tcp_at(a + s * (b - a))


@contextmanager
def _slow(ctx: SkillContext, speed: float):
    """Plan Cartesian tracks at `speed` instead of the context's speed."""
    saved = ctx.speed
    ctx.speed = speed
    try:
        yield
    finally:
        ctx.speed = saved


def push_through(
    ctx: SkillContext, tool: RollerTool, start: np.ndarray, end: np.ndarray
) -> ArmPlan:
    """The roller level along the tunnel, its tip onto `start` from APPROACH above (outside
    the tunnel), then straight along to `end` in contact with the cube (only the cube is
    left out of the collision checks: the roller and the hand are checked against the
    shelf and the table all the way)."""
    up = np.array([0.0, 0.0, APPROACH])
    above = move_tcp(ctx, "right", tool.tcp_at(start + up), label="roller over the mouth")
    down = track(ctx, "right", tool.line(start + up, start), APPROACH, 0.0, label="roller down")
    with _slow(ctx, PUSH_SPEED):
        dist = float(np.linalg.norm(end - start))
        along = track(ctx, "right", tool.line(start, end), dist, 0.0, label="push", ignore=[CUBE])
    plan = above.then(down, along)
    plan.label = "push the cube out with the roller"
    return plan


def push_on(ctx: SkillContext, distance: float) -> ArmPlan:
    """Push the cube `distance` (m) further along -x with the roller: the grasp re-measured,
    the roller levelled again with its tip on the pushing line, then along it, slowly."""
    X_now = ctx.model.tcp_pose(ctx.q, "right")
    tool = RollerTool.from_grasp(ctx)
    tip = ctx.model.held_pose("right", ctx.q) @ tool.p_OQ
    start = np.array([tip[0], tip[1], TABLE_TOP + PUSH_Z])
    end = start - [distance, 0.0, 0.0]
    level = track(
        ctx,
        "right",
        _between(X_now, tool.tcp_at(start)),
        float(np.linalg.norm(start - tip)),
        0.1,
        label="level the roller",
        ignore=[CUBE],
    )
    with _slow(ctx, PUSH_SPEED):
        on = track(
            ctx, "right", tool.line(start, end), distance, 0.0, label="push on", ignore=[CUBE]
        )
    return level.then(on)


def level_roller(ctx: SkillContext) -> ArmPlan:
    """Level the roller again from the re-measured grasp (it turns a few degrees in the hand
    while pushing) and raise its tip by RAISE off the pushing line. A track: at the end of
    the push the hand may graze the table, which only a track allows."""
    X_now = ctx.model.tcp_pose(ctx.q, "right")
    tool = RollerTool.from_grasp(ctx)
    tip = ctx.model.held_pose("right", ctx.q) @ tool.p_OQ + np.array([0.0, 0.0, RAISE])
    return track(
        ctx,
        "right",
        _between(X_now, tool.tcp_at(tip)),
        RAISE,
        0.1,
        label="level the roller",
        ignore=[CUBE],
    )


def withdraw(ctx: SkillContext, start_x: float) -> ArmPlan:
    """Draw the levelled roller (:func:`level_roller`) straight back out of the tunnel to its
    tip at `start_x`, then lift it clear."""
    tool = RollerTool.from_grasp(ctx)
    tip = ctx.model.held_pose("right", ctx.q) @ tool.p_OQ
    out = np.array([start_x, tip[1], tip[2]])
    dist = float(np.linalg.norm(out - tip))
    back = track(ctx, "right", tool.line(tip, out), dist, 0.0, label="draw back", ignore=[CUBE])
    up = out + np.array([0.0, 0.0, APPROACH])
    rise = track(ctx, "right", tool.line(out, up), APPROACH, 0.0, label="roller up")
    return back.then(rise)


def _between(X_a: RigidTransform, X_b: RigidTransform) -> Callable[[float], RigidTransform]:
    """Poses from `X_a` to `X_b`: the position along the line, the rotation about one axis."""
    R_ab = X_a.rotation().inverse() @ X_b.rotation()
    turn = AngleAxis(R_ab.ToQuaternion())
    p_a, p_b = X_a.translation(), X_b.translation()

    def pose_at(s: float) -> RigidTransform:
        R = X_a.rotation() @ RotationMatrix(AngleAxis(s * turn.angle(), turn.axis()))
        return RigidTransform(R, p_a + s * (p_b - p_a))

    return pose_at

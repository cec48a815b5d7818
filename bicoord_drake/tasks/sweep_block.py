"""sweep_block: sweep a cube off a pedestal into a dustpan with a brush, empty it into a bin.

Measurements of the expert in physics: benchmarks/bench_task_sweep_block.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from pydrake.all import RigidTransform, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BinShape, BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.models.tools import (
    BrushDims,
    DustpanDims,
    dustpan,
    dustpan_cavity,
    hand_brush,
)
from bicoord_drake.planning.grasps import Grasp, gripper_frame
from bicoord_drake.planning.skills import (
    ArmPlan,
    SkillContext,
    hold_still,
    merge,
    move_tcp,
    pick,
    pour,
    retreat,
    slowed_after,
    split_at,
    track,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    held_by,
    in_pan,
    inside,
    lifted,
    settled,
    untouched,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task
from bicoord_drake.tasks.turn_taking import hold_until_still

PEDESTAL, CUBE, PAN, BRUSH, BIN = "pedestal", "cube", "dustpan", "brush", "bin"
#: The pedestal: a fixed white block, 8 cm (x) by 10 cm (y), 10 cm tall, its centre at
#: x = PEDESTAL_X and y drawn from PEDESTAL_Y (the reference's [0, 0.1] shifted 5 cm toward
#: the robot: see the class doc).
PEDESTAL_SIZE = (0.08, 0.10, 0.10)
PEDESTAL_X, PEDESTAL_Y = -0.05, (-0.05, 0.05)
PEDESTAL_TOP = TABLE_TOP + PEDESTAL_SIZE[2]
#: Its left face: the edge the dustpan is held against.
EDGE_X = PEDESTAL_X - PEDESTAL_SIZE[0] / 2
PEDESTAL_COLOR = (0.93, 0.93, 0.91, 1.0)
#: The cube: 4 cm, its centre this far (m) from the pedestal's top centre in x and y, turned
#: by up to CUBE_YAW.
CUBE_EDGE, CUBE_MASS = 0.04, 0.04
CUBE_OFFSET, CUBE_YAW = (-0.01, 0.01), (-0.2, 0.2)
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: The dustpan (models/tools.py): plastic, light, its mouth toward +x (the pedestal), its
#: centre drawn from these ranges, turned by up to TOOL_YAW. Its friction is the default
#: 0.9 (a slicker pan slips in the fingers); the cube slides out when tipped past ~42 deg.
PAN_DIMS = DustpanDims()
PAN_SHAPE = dustpan(PAN_DIMS)
PAN_CAVITY = dustpan_cavity(PAN_DIMS)
PAN_MASS = 0.05
PAN_X, PAN_Y = (-0.3, -0.2), (-0.22, -0.17)
PAN_COLORS = {
    "blue": (0.15, 0.4, 0.8, 1.0),
    "green": (0.2, 0.65, 0.35, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
    "grey": (0.45, 0.47, 0.5, 1.0),
}
#: The brush: bristles (dark) under a wooden back, the handle toward +x; its head's centre
#: drawn from these ranges.
BRUSH_DIMS = BrushDims()
BRUSH_SHAPE = hand_brush(BRUSH_DIMS)
BRUSH_MASS = 0.07
BRUSH_X, BRUSH_Y = (0.2, 0.25), (-0.2, -0.13)
BRUSH_COLORS = {
    "beech": (0.78, 0.6, 0.4, 1.0),
    "walnut": (0.5, 0.33, 0.2, 1.0),
    "red": (0.75, 0.2, 0.15, 1.0),
}
TOOL_YAW = (-0.15, 0.15)
#: The bin: a fixed open box at the table's left end, beyond the dustpan's handle.
BIN_SHAPE = BinShape(size=(0.14, 0.14, 0.07), wall=0.006)
BIN_XY = (-0.44, -0.04)
BIN_COLOR = (0.3, 0.3, 0.32, 1.0)
#: Grasps: the dustpan's handle this far (m) behind the back wall, the brush's handle this far
#: in front of the head's back; fingertips at least TIP_CLEARANCE above the support.
PAN_GRIP, BRUSH_GRIP = 0.018, 0.06
TIP_CLEARANCE = 0.005
#: Expert: lift after the picks (m).
LIFT = 0.06
#: The dustpan held at the pedestal: its front edge GAP (m) from the pedestal's left face, its
#: floor's top DROP below the pedestal's top.
GAP, DROP = 0.006, 0.006
#: The sweep: bristles this high above the pedestal's top, lowered from APPROACH above onto
#: the start (the bristles START_GAP behind the cube), along -x until the bristles' front is
#: SWEEP_PAST beyond the pedestal's edge (over the pan); slower than the other moves. (With
#: 2.5 cm a cube that tipped over the edge into a pan sagging in a short-padded grip, the
#: Franka Hand's, lay at the pan's lip, tumbled over it when tipped out and bounced off the
#: bin's floor; 4.5 cm pushes it 2 cm further in.)
BRISTLE_GAP, APPROACH, START_GAP, SWEEP_PAST = 0.003, 0.04, 0.012, 0.045
SWEEP_SPEED = 0.35
#: After the sweep the brush goes up APPROACH and back toward +x by BACK_OFF (m), the pan held
#: still meanwhile and until the cube is at rest in it (a cube that tipped over the edge can
#: lean on the bristles: backing the pan away and up at once flipped it out over the lip).
BACK_OFF = 0.04
#: While the brush sweeps over the held dustpan (between its side walls, ~1.6 cm from each),
#: the clearance between the arms' bodies and held tools is this (m) instead of 3 cm.
TOOL_CLEARANCE = 0.004
#: Emptying: the dustpan carried beside the bin, its mouth turned toward it (-x), its front
#: edge LIP_IN short of the bin's centre and its floor RAISE above the rim, tipped by
#: TIP_ANGLE about that edge.
LIP_IN, RAISE, TIP_ANGLE = 0.01, 0.04, math.radians(65)
#: The right's way home is timed to end this many seconds before the tip as planned ahead
#: (the real tip, planned from the measured grasp, may come out shorter); the rest is slowed
#: to end with the real tip. The tipped pan is held TIP_HOLD (s).
TIP_MARGIN, TIP_HOLD = 0.4, 0.8
#: Seconds both arms hold still at the end (the cube must be seen at rest 0.3 s).
SETTLE = 0.67


@register_task
class SweepBlock(Task):
    """Sweep the cube off the pedestal into the dustpan with the brush, then empty the pan
    into the bin.

    Description: a red (or other colour) 4 cm cube sits on a white pedestal 10 cm tall in the
    middle of the table. A plastic dustpan - a flat pan with low side walls, a back wall and
    a short handle - lies on the left, its mouth toward the pedestal; a hand brush - dark
    bristles under a wooden back and handle - lies on the right; a bin stands at the table's
    left end. Both arms pick their tool at once (the left the dustpan by its handle, the right
    the brush by its handle) and bring it to the pedestal together: the left holds the pan
    level with its front edge against the pedestal's left face, its floor just below the
    pedestal's top, while the right lowers the brush behind the cube and sweeps it across
    the top, off the edge, into the pan. Then the right lifts the brush off the pan (the pan
    held still until the cube rests in it) and goes back while the left carries the pan to
    the bin, turning it half around on the way so its mouth faces the bin, and tips it
    forward about its front edge (held over the bin) until the cube slides out into the bin;
    the right's way back takes as long as the carry and the tip (it ends as the pan is
    tilted back).

    Coordination: both arms work throughout (each holds its tool from its pick on), but the
    layout keeps them apart in stages 1 and 3: the tools lie at the table's two ends (the
    picks are farther apart than the arms' home), and the bin stands at the left end, where
    only the left can empty the pan (the right has nothing to do there: the task has it
    hold still). They come close only at the pedestal (stage 2).

    Layout: the reference's bin stands on the floor beside the table on the left, out of
    reach of our ViperX arms (0.75 m below their bases); here it is a low bin (14x14x7 cm)
    on the table's left end at (-0.44, -0.04), beyond the dustpan's handle. The pedestal is
    8x10 cm and 10 cm tall at x = -0.05 as in the reference, but its y is drawn from
    [-0.05, 0.05] instead of [0, 0.1]: with the cube beyond y = 0.06 the right arm, sweeping
    it off the pedestal's left side, is past its reach. The dustpan starts at the spec's x
    and y in [-0.22, -0.17], clear of the bin. The dustpan is held with its front edge
    6 mm from the pedestal's face (planning keeps a held object that far from fixtures) and
    its floor 6 mm below the pedestal's top: the cube drops onto it.

    Randomization: the pedestal's y in [-0.05, 0.05]; the cube's offset from the pedestal's top
    centre +-1 cm in x and y, its yaw +-0.2 rad and colour; the dustpan's centre at x in
    [-0.3, -0.2], y in [-0.22, -0.17] and its colour; the brush's head at x in [0.2, 0.25],
    y in [-0.2, -0.13] and its wood; both tools turned +-0.15 rad.

    Stages: (1) both tools held: the dustpan by a closed left gripper, the brush by a closed
    right gripper, each raised 2 cm (transient); (2) the cube in the dustpan: its whole solid
    within the pan's side walls, back wall and front edge, lying on the pan's floor, the pan
    held by the left hand within 30 degrees of level (transient); (3) the cube in the bin:
    inside the bin's real cavity (within its inner walls, on its floor, below the rim), no
    finger touching it, at rest for 0.3 s (persistent).

    Success: stage 3 holds when the rollout ends: the cube lies still in the bin.
    """

    name = "sweep_block"
    step_limit = 500
    supported_robots = ("aloha_viperx", "franka_pair")
    expert_speed = 0.5
    instructions_seen = (
        "Sweep the block into the dustpan with the brush and empty it into the bin.",
        "Hold the dustpan by the pedestal, brush the cube into it, then tip it into the bin.",
        "Use the brush to sweep the cube off the pedestal into the dustpan, then dump it.",
        "Pick up the dustpan and the brush, sweep the block in and throw it in the bin.",
        "Brush the cube from the stand into the dustpan and pour it into the trash bin.",
        "Left hand holds the dustpan, right hand sweeps the block in; then empty the pan.",
        "Clean the pedestal: sweep the cube into the dustpan and empty it over the bin.",
    )
    instructions_unseen = (
        "Get the block off the pedestal with the brush and dustpan and put it in the bin.",
        "Sweep up the cube with the hand brush and dustpan and tip it into the bin.",
        "Take the dustpan and brush, collect the block from the stand, dispose of it in the bin.",
        "One hand holds the pan at the edge while the other brushes the cube in; then bin it.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        ped_y = float(rng.uniform(*PEDESTAL_Y))
        offset = [float(rng.uniform(*CUBE_OFFSET)), float(rng.uniform(*CUBE_OFFSET))]
        cube_yaw = float(rng.uniform(*CUBE_YAW))
        color = str(rng.choice(sorted(COLORS)))
        pan_xy = [float(rng.uniform(*PAN_X)), float(rng.uniform(*PAN_Y))]
        pan_yaw = float(rng.uniform(*TOOL_YAW))
        pan_color = str(rng.choice(sorted(PAN_COLORS)))
        brush_xy = [float(rng.uniform(*BRUSH_X)), float(rng.uniform(*BRUSH_Y))]
        brush_yaw = float(rng.uniform(*TOOL_YAW))
        wood = str(rng.choice(sorted(BRUSH_COLORS)))
        cube_obj = cube(
            CUBE,
            PEDESTAL_X + offset[0],
            ped_y + offset[1],
            size=CUBE_EDGE,
            color=COLORS[color],
            mass=CUBE_MASS,
            yaw=cube_yaw,
        )
        cube_obj = cube_obj.model_copy(
            update={
                "pose": Pose(
                    xyz=(*cube_obj.pose.xyz[:2], PEDESTAL_TOP + CUBE_EDGE / 2),
                    rpy=cube_obj.pose.rpy,
                )
            }
        )
        return Scene(
            name=self.name,
            seed=seed,
            objects=(
                pedestal(ped_y),
                cube_obj,
                SceneObject(
                    name=PAN,
                    shape=PAN_SHAPE,
                    color=PAN_COLORS[pan_color],
                    mass=PAN_MASS,
                    pose=Pose(xyz=(*pan_xy, TABLE_TOP), rpy=(0.0, 0.0, pan_yaw)),
                ),
                SceneObject(
                    name=BRUSH,
                    shape=BRUSH_SHAPE,
                    color=BRUSH_COLORS[wood],
                    mass=BRUSH_MASS,
                    pose=Pose(xyz=(*brush_xy, TABLE_TOP), rpy=(0.0, 0.0, brush_yaw)),
                ),
                SceneObject(
                    name=BIN,
                    shape=BIN_SHAPE,
                    color=BIN_COLOR,
                    mass=1.0,
                    fixed=True,
                    pose=Pose(xyz=(*BIN_XY, TABLE_TOP)),
                ),
            ),
            draws={
                "pedestal_y": ped_y,
                "cube_offset": offset,
                "cube_yaw": cube_yaw,
                "color": color,
                "pan_xy": pan_xy,
                "pan_yaw": pan_yaw,
                "pan_color": pan_color,
                "brush_xy": brush_xy,
                "brush_yaw": brush_yaw,
                "brush_wood": wood,
            },
        )

    def object_count(self, scene: Scene) -> int:
        return len(scene.free_objects) + 2  # the cube, two tools, the pedestal and the bin

    def may_leave_table(self, scene: Scene) -> dict[str, None]:
        # Success is the cube in the bin (on the table): once the cube is swept in and tipped
        # out, neither tool matters, so a policy dropping one does not end its rollout early.
        return {BRUSH: None, PAN: None}

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        tools_held = all_of(
            held_by(PAN, "left"),
            held_by(BRUSH, "right"),
            lifted(PAN, 0.02),
            lifted(BRUSH, 0.02),
        )
        in_dustpan = all_of(in_pan(CUBE, PAN, PAN_CAVITY), held_by(PAN, "left"))
        in_bin = all_of(inside(CUBE, BIN), untouched(CUBE), settled([CUBE]))
        return [
            Stage(
                "take the tools",
                "pick the dustpan by its handle",
                "pick the brush by its handle",
                0.0,
                tools_held,
                "transient",
            ),
            Stage(
                "sweep the cube in",
                "hold the dustpan against the pedestal's edge",
                "sweep the cube off the pedestal into the dustpan",
                0.0,
                in_dustpan,
                "transient",
            ),
            Stage(
                "empty the dustpan",
                "carry the dustpan over the bin and tip it",
                "lift the brush away and hold still",
                1.0,
                in_bin,
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)

        run = partial(follow, ctx, view)

        # ---- stage 1: both arms pick their tool at once
        left = pick(ctx, "left", PAN, grasps=handle_grasps(ctx, PAN), lift=LIFT)
        right = pick(ctx, "right", BRUSH, grasps=handle_grasps(ctx, BRUSH), lift=LIFT)
        yield from run(merge(ctx, left, right))
        # ---- stage 2: the pan to the pedestal's edge, the brush above the start, together
        cube_xy = ctx.model.object_pose(CUBE).translation()[:2]
        left = move_tcp(ctx, "left", held_tcp(ctx, "left", pan_at_edge(cube_xy[1])), label="pan")
        start = sweep_start(ctx, cube_xy)
        above = RigidTransform(start.rotation(), start.translation() + [0.0, 0.0, APPROACH])
        right = move_tcp(ctx, "right", held_tcp(ctx, "right", above), label="brush above")
        yield from run(merge(ctx, left, right))
        with ctx.tuned(clearance=TOOL_CLEARANCE):
            yield from run(merge(ctx, None, sweep(ctx, start), ignore=[CUBE]))
        # ---- stage 3: the right lifts the brush away, the left empties the pan into the bin
        # (the cube rides in the pan: the planning model, which does not carry it, leaves it
        # out; the pan itself is checked)
        # First the brush comes off the pan while the pan holds still, until the cube rests
        # in it. The right's way home is then slowed to end with the left's last action, the
        # tip (planned ahead from the planned carry; the real tip is planned once the carry is
        # done, and the rest of the way home is timed to it).
        with ctx.model.ignoring([CUBE]):
            yield from run(merge(ctx, None, brush_up(ctx), ignore=[CUBE]))
            yield from hold_until_still(ctx, view, [CUBE])
            right = retreat(ctx, "right")
            left = to_bin(ctx)
            tip_steps = _tip_steps(ctx)
            right = slowed_after(ctx, right, 0, left.num_steps + tip_steps - ctx.steps(TIP_MARGIN))
            right, rest = split_at(right, left.num_steps - 1)
            ctx.q = ctx.with_arm("right", right.q[-1])
            yield from run(merge(ctx, left, right, stretch=False, ignore=[CUBE]))
            pan = tip(ctx)
            rest = slowed_after(ctx, rest, 0, pan.num_steps)
            ctx.q = ctx.with_arm("right", rest.q[-1])
            yield from run(merge(ctx, pan, rest, stretch=False, ignore=[CUBE]))
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- objects
def pedestal(y: float) -> SceneObject:
    """The fixed white pedestal at (PEDESTAL_X, y)."""
    return SceneObject(
        name=PEDESTAL,
        shape=BoxShape(size=PEDESTAL_SIZE, rounding=0.002),
        color=PEDESTAL_COLOR,
        mass=1.0,
        fixed=True,
        pose=Pose(xyz=(PEDESTAL_X, y, TABLE_TOP + PEDESTAL_SIZE[2] / 2)),
    )


# -------------------------------------------------------------------- expert helpers
def handle_grasps(ctx: SkillContext, name: str) -> list[Grasp]:
    """Top grasps of a tool's handle across its width (both finger directions), the pads'
    top flush with the handle's top or lower, the fingertips TIP_CLEARANCE above the table."""
    g = ctx.model.embodiment.arm.gripper
    X_WO = ctx.model.object_pose(name)
    if name == PAN:
        d = PAN_DIMS
        x = -d.length / 2 - PAN_GRIP
        top = d.floor + d.back_height
    else:
        d = BRUSH_DIMS
        x = d.back_depth / 2 + BRUSH_GRIP
        top = d.top
    z = max(top - g.pad_length / 2, TIP_CLEARANCE + g.pad_length / 2)
    p = X_WO @ np.array([x, 0.0, z])
    R = X_WO.rotation().matrix()
    down = np.array([0.0, 0.0, -1.0])
    out = []
    for sign in (1.0, -1.0):
        X_WG = gripper_frame(down, sign * R[:, 1], p)
        X_WPre = RigidTransform(X_WG.rotation(), p + [0.0, 0.0, 0.08])
        width = d.handle_width
        out.append(Grasp("handle", X_WG, X_WPre, X_WO.inverse() @ X_WG, width, 1.0))
    return out


def held_tcp(ctx: SkillContext, side: str, X_WO: RigidTransform) -> RigidTransform:
    """The TCP pose that puts the object `side` holds at `X_WO` (the grasp as measured)."""
    X_OT = ctx.model.held_pose(side, ctx.q).inverse() @ ctx.model.tcp_pose(ctx.q, side)
    return X_WO @ X_OT


def pan_at_edge(y: float) -> RigidTransform:
    """The dustpan level, its mouth toward the pedestal, front edge GAP from its left face,
    floor top DROP below its top, centred on `y`."""
    x = EDGE_X - GAP - PAN_DIMS.length / 2
    z = PEDESTAL_TOP - DROP - PAN_DIMS.floor
    return RigidTransform([x, y, z])


def sweep_start(ctx: SkillContext, cube_xy: np.ndarray) -> RigidTransform:
    """The brush's pose at the start of the sweep: level, its head across x behind the cube
    (toward +x), the bristles BRISTLE_GAP above the pedestal's top."""
    yaw = float(ctx.model.object_pose(CUBE).rotation().ToRollPitchYaw().yaw_angle())
    reach = CUBE_EDGE / 2 * (abs(math.cos(yaw)) + abs(math.sin(yaw)))
    x = cube_xy[0] + reach + START_GAP + BRUSH_DIMS.bristle_depth / 2
    return RigidTransform([x, cube_xy[1], PEDESTAL_TOP + BRISTLE_GAP])


def sweep(ctx: SkillContext, start: RigidTransform) -> ArmPlan:
    """Lower the brush onto the start, then sweep it straight along -x until its bristles'
    front is SWEEP_PAST beyond the pedestal's edge (the cube is pushed off into the pan).
    Only the cube is left out of the collision checks."""
    p0 = start.translation()
    p_up = p0 + [0.0, 0.0, APPROACH]
    x_end = EDGE_X - SWEEP_PAST + BRUSH_DIMS.bristle_depth / 2
    p1 = np.array([x_end, p0[1], p0[2]])
    R = start.rotation()

    def line(a, b):
        return lambda s: held_tcp(ctx, "right", RigidTransform(R, a + s * (b - a)))

    with ctx.tuned(clearance=TOOL_CLEARANCE):
        down = track(ctx, "right", line(p_up, p0), APPROACH, 0.0, label="brush down")
        with ctx.tuned(speed=SWEEP_SPEED):
            dist = float(p0[0] - p1[0])
            along = track(ctx, "right", line(p0, p1), dist, 0.0, label="sweep", ignore=[CUBE])
    plan = down.then(along)
    plan.label = "sweep the cube into the pan"
    return plan


def brush_up(ctx: SkillContext) -> ArmPlan:
    """Lift the brush straight up off the pan, APPROACH."""
    X = ctx.model.tcp_pose(ctx.q, "right")
    up = RigidTransform(X.rotation(), X.translation() + [BACK_OFF, 0.0, APPROACH])
    a, b = X.translation(), up.translation()
    with ctx.tuned(clearance=TOOL_CLEARANCE):
        return track(
            ctx,
            "right",
            lambda s: RigidTransform(X.rotation(), a + s * (b - a)),
            math.hypot(BACK_OFF, APPROACH),
            0.0,
            label="brush up",
            ignore=[CUBE],
        )


def pan_over_bin() -> RigidTransform:
    """The dustpan level by the bin, its mouth toward -x (a half turn from the sweep: the
    handle toward the middle of the table), its front edge over the bin LIP_IN short of the
    bin's centre, its floor RAISE above the rim."""
    x = BIN_XY[0] + LIP_IN + PAN_DIMS.length / 2
    z = TABLE_TOP + BIN_SHAPE.size[2] + RAISE
    return RigidTransform(RotationMatrix.MakeZRotation(math.pi), [x, BIN_XY[1], z])


def to_bin(ctx: SkillContext) -> ArmPlan:
    """Carry the dustpan (with the cube) from the pedestal over the bin: first straight back
    from the pedestal and up, then over the bin."""
    X = ctx.model.tcp_pose(ctx.q, "left")
    back = RigidTransform(X.rotation(), X.translation() + [-0.03, 0.0, 0.05])
    away = move_tcp(ctx, "left", back, label="pan back", straight=True, ignore=[CUBE])
    over = move_tcp(
        ctx, "left", held_tcp(ctx, "left", pan_over_bin()), label="pan over bin", ignore=[CUBE]
    )
    return away.then(over)


def tip(ctx: SkillContext) -> ArmPlan:
    """Tip the dustpan forward about its front edge by TIP_ANGLE, hold, and tilt it back."""
    X_WO = ctx.model.held_pose("left", ctx.q)
    lip = X_WO @ np.array([PAN_DIMS.length / 2, 0.0, PAN_DIMS.floor])
    mouth = X_WO.rotation().col(0)
    return pour(
        ctx,
        "left",
        TIP_ANGLE,
        direction=[float(mouth[0]), float(mouth[1]), 0.0],
        pivot=lip,
        hold_time=TIP_HOLD,
        ignore=[CUBE],
    )


def _tip_steps(ctx: SkillContext) -> int:
    """Control steps of the tip as planned from the state planned so far (the real tip is
    planned once the pan is over the bin); the tracked state and the checker's padding are
    left as they were."""
    q, opening = ctx.q.copy(), dict(ctx.opening)
    with ctx.model.keeping_padding():
        try:
            return tip(ctx).num_steps
        finally:
            ctx.q, ctx.opening = q, opening

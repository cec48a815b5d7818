"""extract_bottom_block_to_top: pull the bottom cube out of a three-cube stack while the other
arm holds the two above it up, then put the pulled cube on top."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from functools import partial

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BoxShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.planning.clearance import hands_gap, roomy_first
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import Grasp, GraspParams, box_grasps, stack_target
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    SkillContext,
    carry_above,
    first_step_in_zone,
    grip,
    hold_still,
    leave_as_arrives,
    merge,
    move_tcp,
    pick,
    place,
    pull,
    retreat,
    slowed_after,
    track,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    at_rest,
    clear_of,
    hands_free,
    held_by,
    lifted,
    on_top_of,
    settled,
    stacked,
    untouched,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

PLATFORM = "platform"
BLOCKS = ("bottom_cube", "middle_cube", "top_cube")  # as stacked at the start
PLATFORM_SIZE = (0.08, 0.08, 0.06)
PLATFORM_TOP = TABLE_TOP + PLATFORM_SIZE[2]
#: Where the platform's centre lies (the reference's ranges).
PLATFORM_X = (-0.05, 0.0)
PLATFORM_Y = (-0.05, 0.10)
EDGE = (0.04, 0.06)
DENSITY = 600.0  # kg/m^3 (painted wood): 0.04-0.13 kg
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: How far (m) the lifter raises the middle cube, and the extractor pulls the bottom one out.
LIFT = 0.02
PULL = 0.10
#: The middle cube counts as held up from this rise (m) above where it started.
HELD_UP = 0.01
#: Seconds between the end of the lifter's lift and the start of the pull.
PULL_LAG = 0.13
#: The lifter lowers the middle cube until it is LOWER_GAP (m) above the platform; before it
#: grasps, it checks that it can track that lowering LOWER_MARGIN (m) further (the cube slips
#: a little in the grasp).
LOWER_GAP = 0.002
LOWER_MARGIN = 0.003
#: Most seconds one arm's approach may be delayed so that the two approaches do not meet,
#: tried in multiples of DELAY_STRIDE (s).
MAX_DELAY, DELAY_STRIDE = 4.0, 0.2
#: The lifter's first choice of approach (its jaws then close along x).
FRONT = np.array([0.0, 1.0, 0.0])
#: Clearance (m) between the arms while both hold the stack (their fingers pass 2-4 cm apart).
CLOSE_CLEARANCE = 0.01
#: Where the lifter's empty hand steps back from the stack while the pulled cube is set on
#: top (out of the way, not all the way home), best first: (m back along its approach axis,
#: toward its own side, up).
STEP_BACK = ((0.08, 0.0, 0.0), (0.06, 0.06, 0.0), (0.08, 0.0, 0.06))
#: Height (m) of the carried cube's bottom above the two-cube stack before it is set on top.
ABOVE_STACK = 0.05
#: Seconds both arms hold still at the end: the stack must be seen at rest for 0.3 s.
SETTLE = 0.53


@register_task
class ExtractBottomBlockToTop(Task):
    """Pull the bottom cube out from under the stack and put it on top.

    Description: a static platform (8x8x6 cm) carries a stack of three equal cubes. The lifter
    arm side-grasps the middle cube from the front (approach +y, jaws closing along x) and lifts
    it 2 cm, the top cube riding on it; at the same time the extractor arm side-grasps the
    bottom cube from its own side (approach along x toward the centre line, jaws closing along
    y, TCP low over the platform top) and pulls it 10 cm straight out toward its side (skill
    ``pull``), under the lifter's fingers. The pull is timed from both plans: it starts
    0.13 s after the lifter's lift ends, or as soon as the extractor's own grasp is
    closed if that is later; where the two approaches would meet, one arm's whole plan starts
    a few steps later and the wait is recomputed. Then the lifter lowers the middle cube (with
    the top one) onto the platform, lets go slowly and backs off (at a pace that ends with the
    extractor's carry) while the extractor raises the pulled cube beside the platform and
    carries it over the stack - entering the space above the stack only once the lowering is
    done; finally the lifter steps further back out of the way (not all the way home; home if
    no step back is reachable) as the extractor sets the cube on top, its step timed to end
    with the placing, and the extractor lets go.

    Randomization: the platform's centre x in [-0.05, 0], y in [-0.05, 0.10] (the reference's
    layout); the cube edge in [4, 6] cm (all three equal); which arm extracts (the other lifts);
    three distinct colours.

    Stages: (1) the bottom cube held by the extractor clear of the platform (no part of it over
    the platform's top) while the middle cube is held up by the lifter at least 1 cm above where
    it started with the top cube resting on it (transient, 0); (2) a two-cube stack on the
    platform - the middle cube on the platform, the top cube on it, both untouched and at rest
    (0.5); (3) the old bottom cube on top of that stack, released and settled (0.5).

    Success: platform, middle, top and old bottom cube stacked in that order (each centre within
    2 cm in xy of the one below, bottom within 1 cm of its top, every cube lying on a face),
    both grippers open, no finger touching any cube, every cube at rest for 0.3 s.
    """

    name = "extract_bottom_block_to_top"
    step_limit = 400
    supported_robots = ("aloha_viperx", "franka_pair")
    instructions_seen = (
        "Pull the bottom block out of the stack and put it on top.",
        "Lift the upper blocks a little, slide out the bottom one and stack it on top.",
        "Take the lowest cube out from under the tower and place it at the top.",
        "Hold up the top two cubes, pull out the bottom cube, then put it on the stack.",
        "Move the bottom block of the tower to the top without knocking it over.",
        "Extract the bottom cube while the other hand lifts the rest, then stack it on top.",
        "Use both hands to pull out the block at the bottom and set it on top of the others.",
    )
    instructions_unseen = (
        "Swap the bottom cube to the top of the pile using both arms.",
        "One arm raises the upper cubes while the other slides the bottom one out; put it on top.",
        "Rebuild the tower so the cube that was at the bottom ends up on top.",
        "Slide the lowest block out from beneath the others and stack it on the top.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        x, y = float(rng.uniform(*PLATFORM_X)), float(rng.uniform(*PLATFORM_Y))
        edge = float(rng.uniform(*EDGE))
        extractor = str(rng.choice(SIDES))
        color_names = [str(c) for c in rng.choice(sorted(COLORS), size=3, replace=False)]
        objects = [_platform(x, y)]
        for k, (name, color) in enumerate(zip(BLOCKS, color_names, strict=True)):
            block = cube(name, x, y, size=edge, color=COLORS[color], mass=DENSITY * edge**3)
            z = PLATFORM_TOP + edge * (k + 0.5)
            objects.append(block.model_copy(update={"pose": Pose(xyz=(x, y, z))}))
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "platform_xy": [x, y],
                "edge": edge,
                "extractor": extractor,
                "colors": color_names,
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 4  # three cubes and the platform

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        bottom, middle, top = BLOCKS
        ext, lifter = _roles(scene)
        arms = {ext: "pull the bottom cube out 10 cm", lifter: "lift the middle cube 2 cm"}
        lower = {ext: "raise the extracted cube", lifter: "set the middle cube on the platform"}
        last = {ext: "place the extracted cube on top", lifter: "retreat"}
        return [
            Stage(
                "extract the bottom cube",
                arms["left"],
                arms["right"],
                0.0,
                all_of(
                    clear_of(bottom, PLATFORM),
                    held_by(bottom, ext),
                    held_by(middle, lifter),
                    lifted(middle, HELD_UP),
                    on_top_of(top, middle),
                ),
                "transient",
            ),
            Stage(
                "lower the rest",
                lower["left"],
                lower["right"],
                0.5,
                all_of(
                    stacked([PLATFORM, middle, top]),
                    untouched(middle),
                    untouched(top),
                    at_rest(middle),
                    at_rest(top),
                ),
                "persistent",
            ),
            Stage(
                "put it on top",
                last["left"],
                last["right"],
                0.5,
                all_of(
                    stacked([PLATFORM, middle, top, bottom]), hands_free(BLOCKS), settled(BLOCKS)
                ),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        bottom, middle, top = BLOCKS
        ext, lifter = _roles(scene)
        ctx = self.skill_context(view)

        run = partial(follow, ctx, view)

        # ---- stage 1: lift the middle cube, pull the bottom one out as soon as it is up
        yield from run(_extract(ctx, scene, ext, lifter))
        # ---- stage 2: lower the rest onto the platform; raise the pulled cube over it
        with _close(ctx):
            lowering = _lower_and_raise(ctx, scene, ext, lifter)
        yield from run(lowering)
        # ---- stage 3: the lifter retreats, the extractor sets the cube on top
        # (it leaves as the cube arrives; its way home ends with the placing)
        X_top = ctx.model.object_pose(top)
        goal = stack_target(X_top, _shape(scene), _shape(scene))
        leaving = _step_back(ctx, lifter)
        placing = place(ctx, ext, goal, approach_height=ABOVE_STACK, gentle_release=True)
        zone = scene.draws["edge"] + 0.02
        yield from run(leave_as_arrives(ctx, leaving, placing, X_top.translation()[:2], zone))
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- expert steps
def _extract(ctx: SkillContext, scene: Scene, ext: str, lifter: str) -> Motion:
    """Both arms grasp at once; the lifter lifts the middle cube LIFT; the extractor's pull
    starts PULL_LAG seconds after the lift is complete (or when its own grasp is, if later)."""
    bottom, middle, top = BLOCKS
    lift_plan = _lift(ctx, scene, ext, lifter)
    # the top cube now rests on the held middle one: left out of the checks (it is above both)
    with _close(ctx), ctx.model.ignoring([top]):
        takes = _grasps(ctx, scene, bottom, ext, _inward(ext))
        take = pick(ctx, ext, bottom, lift=0.0, grasps=takes)
        away = np.array([1.0 if ext == "right" else -1.0, 0.0, 0.0])
        out = pull(ctx, ext, away, PULL, ignore=[PLATFORM])
    return _pull_after_lift(ctx, ext, take, out, lift_plan, ignore=[top])


def _lift(ctx: SkillContext, scene: Scene, ext: str, lifter: str) -> ArmPlan:
    """The lifter grasps the middle cube (the first of its grasps that plans) and lifts it
    LIFT, the top cube riding on it. Where the arm, so holding it, could not then track it
    straight down onto the platform (the lowering of stage 2, LOWER_MARGIN further; a wrist at
    its joint limit: franka seeds 6, 16, 23, 29), the next grasp - the same faces with the hand
    turned over is often the one whose wrist has room."""
    bottom, middle, top = BLOCKS
    X_top = ctx.model.object_pose(top)
    drop = LIFT + scene.draws["edge"] - LOWER_GAP + LOWER_MARGIN

    def lift_checked() -> ArmPlan:
        up = _vertical(ctx, lifter, LIFT, ignore=[top, bottom], label="lift the middle cube")
        # the top cube rides on the middle one
        ctx.model.set_object_pose(
            top, RigidTransform(X_top.rotation(), X_top.translation() + [0, 0, LIFT])
        )
        _check_lowering(ctx, lifter, drop)
        return up

    grasps = _lifter_grasps(ctx, scene, ext, lifter)
    return pick(ctx, lifter, middle, lift=0.0, grasps=grasps, then=lift_checked)


def _check_lowering(ctx: SkillContext, lifter: str, drop: float) -> None:
    """Raise the PlanningError of the lifter's straight lowering by `drop` (m) from where it
    is (planned, then undone; the bottom cube, still under it, is left out: it will have been
    pulled out)."""
    bottom, middle, top = BLOCKS
    q = ctx.q.copy()
    try:
        with _close(ctx):
            _vertical(ctx, lifter, -drop, ignore=[top, bottom, PLATFORM], label="lower the stack")
    finally:
        ctx.q = q


def _pull_after_lift(
    ctx: SkillContext, ext: str, take: ArmPlan, out: ArmPlan, lift_plan: ArmPlan, ignore
) -> Motion:
    """Both arms at once: the extractor's grasp `take`, a wait, its pull `out` starting
    PULL_LAG seconds after the lifter's `lift_plan` ends (at once if its grasp ends later).
    Where the two approaches would meet, one arm's whole plan starts a few steps later (the
    least delay that clears them) and the wait is planned anew from the delayed timing."""
    reasons = []
    for delay in range(0, ctx.steps(MAX_DELAY) + 1, ctx.steps(DELAY_STRIDE)):
        for late in ("ext", "lifter") if delay else ("ext",):
            d_ext, d_lift = (delay, 0) if late == "ext" else (0, delay)
            first = take.delayed(d_ext)
            wait = max(0, lift_plan.num_steps + d_lift + ctx.steps(PULL_LAG) - first.num_steps)
            plan = first.then(_still(first, wait), out) if wait else first.then(out)
            try:
                with _close(ctx):
                    return _together(ctx, ext, plan, lift_plan.delayed(d_lift), ignore=ignore)
            except PlanningError as err:
                reasons.append(err.reason)
    raise PlanningError(
        "arm_conflict", f"the grasps of the stack meet at every delay ({reasons[-1]})"
    )


def _still(plan: ArmPlan, steps: int) -> ArmPlan:
    """Hold the last sample of `plan` for `steps` more samples."""
    return ArmPlan(
        plan.side,
        np.repeat(plan.q[-1:], steps + 1, 0),
        np.repeat(plan.opening[-1:], steps + 1),
        label="wait for the lift",
    )


def _lower_and_raise(ctx: SkillContext, scene: Scene, ext: str, lifter: str) -> Motion:
    """The lifter lowers the middle cube (the top riding on it) onto the platform, lets go
    slowly and backs off; the extractor raises the pulled cube and carries it over the stack,
    entering the space above the stack only once the lowering is done."""
    bottom, middle, top = BLOCKS
    edge = scene.draws["edge"]
    X_mid = ctx.model.object_pose(middle)
    X_top = ctx.model.object_pose(top)
    drop = X_mid.translation()[2] - (PLATFORM_TOP + edge / 2 + LOWER_GAP)
    down = _vertical(ctx, lifter, -drop, ignore=[top, PLATFORM], label="lower the stack")
    lowered = RigidTransform(X_top.rotation(), X_top.translation() - [0, 0, drop])
    ctx.model.set_object_pose(top, lowered)
    opened = grip(ctx, lifter, 1.0, label="let go", gentle=True)
    X_WO = ctx.model.held_pose(lifter, ctx.q)
    ctx.model.detach(lifter, X_WO=X_WO)
    X = ctx.model.tcp_pose(ctx.q, lifter)
    X_back = RigidTransform(X.rotation(), X.translation() - 0.06 * X.rotation().col(0))
    back = move_tcp(ctx, lifter, X_back, label="back off", ignore=[middle, top], straight=True)
    lifter_plan = down.then(opened, back)
    let_go = down.num_steps + opened.num_steps - 2
    lifter_plan.events.append((let_go, "detach", middle))
    # the extractor: up out beside the platform, then over the stack
    goal = stack_target(lowered, _shape(scene), _shape(scene))
    ext_plan = _carry_over(ctx, ext, goal, ABOVE_STACK)
    xy = lowered.translation()[:2]
    into = first_step_in_zone(ctx, ext_plan, xy, edge + 0.02)
    wait = max(0, down.num_steps + 1 - into)
    # where the arms would still meet, the extractor waits longer (never less); the lifter
    # backs off from the stack it let go at a pace that ends with the extractor's carry (at
    # its own pace if that meets the extractor)
    for extra in range(0, ctx.steps(MAX_DELAY) + 1, ctx.steps(DELAY_STRIDE)):
        carry = ext_plan.delayed(wait + extra)
        for backing in (slowed_after(ctx, lifter_plan, let_go, carry.num_steps), lifter_plan):
            try:
                return _together(ctx, ext, carry, backing, ignore=[top])
            except PlanningError as err:
                reason = err.reason
    raise PlanningError("arm_conflict", f"lowering and raising meet at every delay ({reason})")


def _step_back(ctx: SkillContext, side: str) -> ArmPlan:
    """`side`'s empty hand further back from the stack, out of the way of the cube set on
    top: the first of STEP_BACK (m back along its approach axis, toward its own side, up)
    it can reach, else home."""
    X = ctx.model.tcp_pose(ctx.q, side)
    sign = 1.0 if side == "right" else -1.0
    for back, aside, up in STEP_BACK:
        away = X.translation() - back * X.rotation().col(0) + [sign * aside, 0.0, up]
        try:
            return move_tcp(ctx, side, RigidTransform(X.rotation(), away), label="step back")
        except PlanningError:
            continue
    return retreat(ctx, side)


def _carry_over(ctx: SkillContext, side: str, goal: RigidTransform, height: float) -> ArmPlan:
    """Straight up beside the platform until the held cube's bottom is `height` above the
    goal's, then across to straight above the goal; where the arm cannot keep its hand's
    orientation on the way up (a wrist at its joint limit), one planned carry instead."""
    X_WO = ctx.model.held_pose(side, ctx.q)
    rise = goal.translation()[2] + height - X_WO.translation()[2]
    if rise <= 0.005:
        return carry_above(ctx, side, goal, height=height)
    try:
        up = _vertical(ctx, side, rise, ignore=[PLATFORM], label="raise")
    except PlanningError as err:
        if err.reason != "ik_unreachable":
            raise
        return carry_above(ctx, side, goal, height=height)
    return up.then(carry_above(ctx, side, goal, height=height))


def _vertical(ctx: SkillContext, side: str, dz: float, *, ignore, label: str) -> ArmPlan:
    """The TCP straight up (dz > 0) or down by |dz|, orientation kept, exactly on the line."""
    X = ctx.model.tcp_pose(ctx.q, side)
    p0 = X.translation()

    def pose_at(s: float) -> RigidTransform:
        return RigidTransform(X.rotation(), p0 + [0.0, 0.0, s * dz])

    return track(ctx, side, pose_at, abs(dz), 0.0, label=label, ignore=ignore)


def _together(ctx: SkillContext, ext: str, ext_plan: ArmPlan, lifter_plan: ArmPlan, ignore):
    """Both plans at their own pace, no delay added (the timing between them is planned)."""
    plans = {ext: ext_plan, (other_side(ext)): lifter_plan}
    ctx.model.set_padding(ctx.clearance, 0.0)
    return merge(ctx, plans["left"], plans["right"], stretch=False, max_delay=0, ignore=ignore)


@contextmanager
def _close(ctx: SkillContext) -> Iterator[None]:
    """Within the block the arms may come CLOSE_CLEARANCE apart (both hands on one stack);
    the checker's padding is set to that (no environment margin) for the merged motions."""
    with ctx.tuned(clearance=CLOSE_CLEARANCE):
        ctx.model.set_padding(CLOSE_CLEARANCE, 0.0)
        yield


def _grasps(ctx: SkillContext, scene: Scene, name: str, side: str, want: np.ndarray) -> list[Grasp]:
    """Side grasps of cube `name` by `side` approaching along `want`, the TCP low over the
    platform top, best first."""
    params = GraspParams(support_z=PLATFORM_TOP, side_clearance=0.0)
    X_WO = ctx.model.object_pose(name)
    grasps = box_grasps(
        X_WO,
        scene.object(name).shape,
        ctx.model.embodiment.arm.gripper,
        base=np.array(ctx.model.embodiment.base_pose(side).xyz),
        kinds=("side",),
        params=params,
    )
    chosen = [g for g in grasps if g.approach @ want > 0.99]
    if not chosen:
        raise PlanningError("no_grasp", f"no side grasp of {name} for the {side} arm")
    return chosen


def _inward(side: str) -> np.ndarray:
    """The approach from `side`'s own side toward the centre line."""
    return np.array([-1.0 if side == "right" else 1.0, 0.0, 0.0])


def _lifter_grasps(ctx: SkillContext, scene: Scene, ext: str, lifter: str) -> list[Grasp]:
    """The lifter's side grasps of the middle cube, best first: from the front (approach +y,
    jaws along x), then from its own side (jaws along y). Those whose hand, raised LIFT, comes
    closer than the arms' clearance to the extractor's hand at every one of its grasps of the
    bottom cube are moved behind (a hand wide along its finger axis, held from the front,
    reaches over the extractor's; only the fingers may pass CLOSE_CLEARANCE apart)."""
    bottom, middle, _ = BLOCKS
    takes = _grasps(ctx, scene, bottom, ext, _inward(ext))
    grasps = _grasps(ctx, scene, middle, lifter, FRONT)
    grasps += _grasps(ctx, scene, middle, lifter, _inward(lifter))
    boxes = ctx.model.hand_boxes
    margins = [
        max(hands_gap(boxes, _raised(g.X_WG, LIFT), t.X_WG) for t in takes) - ctx.clearance
        for g in grasps
    ]
    return roomy_first(grasps, margins)


def _raised(X: RigidTransform, dz: float) -> RigidTransform:
    return RigidTransform(X.rotation(), X.translation() + [0.0, 0.0, dz])


def _roles(scene: Scene) -> tuple[str, str]:
    """(extractor, lifter)."""
    ext = scene.draws["extractor"]
    return ext, (other_side(ext))


def _shape(scene: Scene) -> BoxShape:
    return scene.object(BLOCKS[0]).shape


def _platform(x: float, y: float) -> SceneObject:
    return SceneObject(
        name=PLATFORM,
        shape=BoxShape(size=PLATFORM_SIZE),
        color=(0.62, 0.5, 0.38, 1.0),
        fixed=True,
        pose=Pose(xyz=(x, y, TABLE_TOP + PLATFORM_SIZE[2] / 2)),
    )

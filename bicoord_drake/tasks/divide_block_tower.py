"""divide_block_tower: take a four-cube tower of two colours apart, two by two, into one
two-cube tower per colour on that colour's sign."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import partial

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.embodiment import other_side
from bicoord_drake.models.geometry import Pose, Primitive
from bicoord_drake.models.objects import BoxShape, CompoundShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, cube
from bicoord_drake.planning.clearance import side_pitch
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    GraspParams,
    arm_base,
    grasp_candidates,
    pitched,
    stack_target,
    table_target,
)
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    SkillContext,
    hold_still,
    merge,
    move,
    move_tcp,
    pick,
    place,
    retreat,
    slowed_after,
    solve_tcp,
    tcp_deviation,
)
from bicoord_drake.planning.skills.core import combine
from bicoord_drake.planning.skills.pick_place import MAX_LINE_DEVIATION
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    Predicate,
    all_of,
    any_of,
    at_rest,
    fraction_true,
    hands_free,
    latched,
    lifted,
    near_start,
    on_a_face,
    on_table,
    on_top_of,
    settled,
    stacked,
    untouched,
    weighted,
    within_square,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

#: The cubes, bottom of the tower first; their edges (m) and density (painted wood).
CUBES = tuple(f"cube_{k}" for k in range(4))
EDGE = (0.04, 0.05)
DENSITY = 600.0  # kg/m^3: 38-75 g
#: The static black base the tower stands on: size (m) and where its centre is drawn.
BASE_SIZE = (0.08, 0.08, 0.06)
BASE_X = (-0.05, 0.0)
BASE_Y = (0.05, 0.10)
#: Each cube's centre is off the base's vertical axis by at most this (m), turned by at most
#: CUBE_YAW (rad): a hand-stacked tower.
CUBE_JITTER = 0.003
CUBE_YAW = 0.1
#: The signs: a 10 cm square outlined by SIGN_LINE (m) bars; colour A's on the left, B's on the
#: right, centres drawn in these ranges.
SIGN = 0.10
SIGN_LINE = 0.008
SIGN_X = {"left": (-0.2, -0.15), "right": (0.10, 0.15)}
SIGN_Y = (-0.1, -0.05)
#: A cube counts as on a sign with its centre within this (m) of the sign's centre along both of
#: the sign's axes (a 5 cm cube then still lies mostly inside the outline).
ON_SIGN_TOL = 0.03
#: A cube is taken off the tower once lifted this much (m) above where it started; the cubes
#: left on the tower must stay within IN_PLACE_TOL (m) of where they started.
TAKEN_LIFT = 0.03
IN_PLACE_TOL = 0.01
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: The six towers, bottom first: where the two cubes of colour A stand.
ORDERS = tuple(
    tuple("A" if k in pair else "B" for k in range(4))
    for pair in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
)
#: The arm that handles each colour (and the side of its sign).
ARM = {"A": "left", "B": "right"}

# ---- expert
#: Each arm side-grasps tower cubes from its own side: the approach within ~35 deg of
#: +x (left) or -x (right).
APPROACH = {"left": np.array([1.0, 0.0, 0.0]), "right": np.array([-1.0, 0.0, 0.0])}
APPROACH_COS = 0.8
#: Lift (m) after a side grasp, before carrying the cube to its sign.
LIFT = 0.06
#: After the lift, the cube is drawn back (m) to its arm's side of the tower, rising.
PULL = 0.08
RISE = 0.04
#: Clearance (m) between the arms while two plans are merged at the tower: the arm taking the
#: lower cube closes on it only once the other's fingers have risen this far clear of its own,
#: i.e. once the cube above has been lifted off it.
ARM_GAP = 0.03
#: Height (m) of the side grasps' TCP above the cube's bottom: the gripper body (5 cm tall about
#: the TCP) then clears the table when the cube is set on a sign; a 4 cm cube's pads reach its
#: top face.
SIDE_TCP = 0.029
#: The hand stays this far (m) above the cube's bottom at a side grasp (the ViperX's gripper,
#: 5 cm tall, at SIDE_TCP); a taller hand pitches its approach down until it does
#: (:func:`~bicoord_drake.planning.clearance.side_pitch`).
SIDE_FLOOR = 0.004
#: The lower cube's arm moves its fingers in only once the upper cube has risen this much (m).
CLEAR_RISE = 0.025
#: Most seconds the lower cube's arm is held back beyond that, to keep ARM_GAP, tried in
#: multiples of DELAY_STRIDE (s).
MAX_DELAY, DELAY_STRIDE = 6.0, 0.2
#: How far short (m) of its pregrasp an arm that comes to the tower ahead of its turn stops;
#: it covers the rest as the cube above its own rises, arriving just in time.
STANDOFF = 0.06
#: Seconds both arms hold still at the end: the towers must be seen at rest for 0.3 s.
SETTLE = 0.53


@register_task
class DivideBlockTower(Task):
    """Divide a four-cube tower of two colours into one two-cube tower per colour.

    Description: a static black base (8x8x6 cm) stands at the back of the table with four cubes
    (4-5 cm edges) stacked on it, two of colour A and two of colour B in a random order; a 10 cm
    square sign outlined in colour A lies on the left and one outlined in colour B on the right,
    both near the robot. The cubes are taken off the tower two at a time, top first, and each is
    put on the sign of its colour, the second on the first, so that each sign ends with a
    two-cube tower of its colour. The left arm handles colour A and the right arm colour B, each
    side-grasping the tower's cubes from its own side (jaws horizontal; a hand too tall to clear
    the table so when it sets a cube on a sign pitches its approach down, by the least angle
    that does, e.g. 12.5 deg for the Franka Hand, 0 for the ViperX). Of the two cubes taken
    at once, the upper one's arm lifts it and pulls it out to its own side; the other arm waits
    beside the cube below and slides its fingers in as soon as the upper cube has risen 2.5 cm
    off it (no earlier, so it never lifts a cube with another on it), then lifts it; each arm
    sets its cube on its sign and goes home. The lower cube's arm arrives beside its cube just
    in time (its approach is slowed to end as the upper cube comes free, instead of waiting at
    home), and the arm done first takes its way home at a pace that ends with the other's. When
    the top two cubes differ in colour, both arms take one at once, sort them onto the signs,
    then take and stack the last two the same way. When they share a colour, that colour's arm
    takes the top cube to its sign alone and comes straight back beside the second (where that
    way is no longer than going home and back; the other arm comes to the tower meanwhile and
    stops 6 cm short of the cube it takes next, covering the rest as the cube above it rises),
    then it takes the second while the other arm takes the third and comes back for the bottom
    cube (straight, on the same condition), which it takes alone: turn-taking forced by the
    tower and the colours - the bottom cube comes free only after the third, and only its
    colour's arm, whose cubes these both are, may take it; the other arm has no cube left and
    goes home. A cube is never handed over: the arm of its colour reaches every level of the
    tower from its own side (measured for the whole base range and both cube sizes), so the
    spec's handover (when R picks an A cube) never arises. After every take the expert checks
    that the cubes left on the tower moved less than 1 cm (else the episode is dropped:
    ``tower_disturbed``).

    Randomization: the two colours (from six); which two of the four levels hold colour A
    (six towers); each cube's edge in [4, 5] cm, its centre within 3 mm of the base's axis and
    its yaw within +-0.1 rad; the base's centre at x in [-0.05, 0], y in [0.05, 0.10]; the
    sign centres at x in [-0.2, -0.15] (A, left) and [0.10, 0.15] (B, right), y in
    [-0.1, -0.05] (the reference layout, which our arms reach).

    Stages: (1) the top two cubes taken off the tower - each lifted 3 cm above where it
    started at some point (or already on a sign) - while the two below stay within 1 cm of
    where they started; (2) the top two cubes sorted: 0.125 for each one resting on its
    colour's sign (centre within 3 cm of the sign's centre, on the table or on a cube, on a
    face), untouched and at rest; (3) the last two cubes taken; (4) the stacks by colour:
    0.125 for each of the last two cubes on its colour's sign, untouched and at rest, and 0.25
    for each sign holding a two-cube tower of its colour, released and settled.

    Success: each sign holds a tower of the two cubes of its colour (the lower on the table
    within 3 cm of the sign's centre, the upper on it, centres within 2 cm, each on a face),
    both grippers open, no finger touching a cube, every cube at rest for 0.3 s.
    """

    name = "divide_block_tower"
    step_limit = 1000
    supported_robots = ("aloha_viperx", "franka_pair")
    instructions_seen = (
        "Split the tower into two towers by colour, each on the sign of its colour.",
        "Take the blocks off the tower and stack each colour on its own coloured sign.",
        "Divide the block tower: sort the cubes by colour onto the matching signs.",
        "Unstack the four cubes two at a time and rebuild them as one tower per colour on the "
        "signs.",
        "Move the cubes from the black base onto the signs, stacking cubes of the same colour.",
        "Sort the stacked blocks by colour, building a two-block tower on each coloured sign.",
        "Take the tower apart and put every cube on the outline of its own colour.",
    )
    instructions_unseen = (
        "Separate the tall tower into two small ones, matching each block to the sign's colour.",
        "Pull the cubes off the pile and stack them by colour on the two outlined squares.",
        "Rebuild the four-block tower as two towers, one on each sign of the same colour.",
        "Using both hands, dismantle the tower and group the cubes by colour on their signs.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        color_names = [str(c) for c in rng.choice(sorted(COLORS), size=2, replace=False)]
        colors = dict(zip("AB", color_names, strict=True))
        order = list(ORDERS[int(rng.integers(len(ORDERS)))])
        edges = [float(rng.uniform(*EDGE)) for _ in CUBES]
        base_xy = [float(rng.uniform(*BASE_X)), float(rng.uniform(*BASE_Y))]
        offsets = [_disc(rng, CUBE_JITTER) for _ in CUBES]
        yaws = [float(rng.uniform(-CUBE_YAW, CUBE_YAW)) for _ in CUBES]
        signs = {s: [float(rng.uniform(*SIGN_X[s])), float(rng.uniform(*SIGN_Y))] for s in SIGN_X}
        objects = [_base(base_xy)]
        objects += [_sign(f"sign_{k.lower()}", signs[ARM[k]], COLORS[colors[k]]) for k in "AB"]
        z = TABLE_TOP + BASE_SIZE[2]
        for name, edge, offset, yaw, k in zip(CUBES, edges, offsets, yaws, order, strict=True):
            block = cube(
                name,
                base_xy[0] + offset[0],
                base_xy[1] + offset[1],
                size=edge,
                color=COLORS[colors[k]],
                mass=DENSITY * edge**3,
                yaw=yaw,
            )
            objects.append(block.model_copy(update={"pose": _lifted(block.pose, z - TABLE_TOP)}))
            z += edge
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "colors": color_names,
                "order": order,
                "edges": edges,
                "base_xy": base_xy,
                "offsets": offsets,
                "yaws": yaws,
                "sign_a_xy": signs["left"],
                "sign_b_xy": signs["right"],
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 6  # four cubes and two signs

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        order = scene.draws["order"]
        c0, c1, c2, c3 = CUBES

        def on_sign(name: str) -> Predicate:
            return all_of(_rests_on_sign(scene, name), untouched(name), at_rest(name))

        def taken(name: str) -> Predicate:
            return any_of(latched(lifted(name, TAKEN_LIFT)), _rests_on_any_sign(scene, name))

        towers = [_tower(scene, k) for k in "AB"]
        first, last = _roles(order)
        return [
            Stage(
                "take the top two cubes",
                first["left"],
                first["right"],
                0.0,
                all_of(taken(c3), taken(c2), near_start(c1, IN_PLACE_TOL), near_start(c0)),
                "transient",
            ),
            Stage(
                "sort them",
                "place its cube on its colour's sign",
                "place its cube on its colour's sign",
                0.25,
                fraction_true([on_sign(c3), on_sign(c2)]),
                "persistent",
            ),
            Stage(
                "take the last two cubes",
                last["left"],
                last["right"],
                0.0,
                all_of(taken(c1), taken(c0)),
                "transient",
            ),
            Stage(
                "stack by colour",
                "stack its cube on its colour's sign",
                "stack its cube on its colour's sign",
                0.75,
                weighted([on_sign(c1), on_sign(c0), *towers], [1, 1, 2, 2]),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        on_tower = list(CUBES)
        signs = {ARM[k]: scene.draws[f"sign_{k.lower()}_xy"] for k in "AB"}
        placed: dict[str, list[str]] = {"left": [], "right": []}

        def run(motion: Motion) -> Iterator[np.ndarray]:
            yield from follow(ctx, view, motion)
            _check_tower(view, scene, on_tower)

        def goal(side: str, name: str) -> RigidTransform:
            """Where `side` sets `name`: on its sign, or on the cube already there."""
            shape = scene.object(name).shape
            if not placed[side]:
                return table_target(signs[side], shape)
            below = placed[side][-1]
            return stack_target(ctx.model.object_pose(below), scene.object(below).shape, shape)

        approached: dict[str, Grasp] = {}  # cube -> the grasp whose pregrasp an arm came to

        def take(side: str, name: str, pull: bool = True) -> ArmPlan:
            """`side` side-grasps `name` (first by the grasp it came beside it for, so the
            wrist does not turn over at the pregrasp), lifts it and (with `pull`) pulls it out
            to its own side of the tower."""
            grasps = _side_grasps(ctx, side, name)
            if name in approached:
                grasps = [approached.pop(name), *grasps]
            plan = pick(ctx, side, name, lift=LIFT, grasps=grasps)
            on_tower.remove(name)
            return plan.then(_pull_out(ctx, side)) if pull else plan

        def put(side: str, name: str, chained: bool) -> ArmPlan:
            """`side` sets the `name` it holds on its sign (on the cube there, if any), then
            (`chained`) comes straight beside the cube it takes next, if any, else goes home."""
            target = goal(side, name)
            try:  # the cube turned as it is held: the hand keeps pointing across the table
                yaw = _yaw(ctx.model.held_pose(side, ctx.q)) - _yaw(target)
                plan = place(ctx, side, target, gentle_release=bool(placed[side]), yaws=[yaw])
            except PlanningError:
                plan = place(ctx, side, target, gentle_release=bool(placed[side]))
            placed[side].append(name)
            k = nexts[side].get(name)
            if chained and k is not None:
                q, opening = ctx.q.copy(), dict(ctx.opening)
                after = _approach(ctx, side, CUBES[k], above=CUBES[k + 1], chosen=approached)
                # only where that is no longer than going home and coming back from there
                direct = ctx.q.copy()
                ctx.q, ctx.opening = q.copy(), dict(opening)
                try:
                    home = retreat(ctx, side)
                    back = _approach(ctx, side, CUBES[k], above=CUBES[k + 1])
                    via_home = home.num_steps + back.num_steps
                except PlanningError:
                    via_home = None
                ctx.q = direct
                if via_home is None or after.num_steps <= via_home:
                    return plan.then(after)
                ctx.q, ctx.opening = q, opening
                approached.pop(CUBES[k])
            return plan.then(retreat(ctx, side))

        order = scene.draws["order"]
        steps = _steps(order)
        nexts = _next_takes(steps)

        def plan_step(step: Step, chained: bool) -> Motion:
            put_ = partial(put, chained=chained)
            upper, arm_u, arm_o = CUBES[step.upper], step.upper_arm, step.other_arm
            if step.lower is not None:
                # The lower cube's arm comes beside it (planned with the upper cube still on
                # it), then slides in as the upper cube rises and takes it. Each arm's next
                # move is planned where the other will be meanwhile: the upper arm pulls its
                # cube out to its side while the lower one lifts its own.
                lower = CUBES[step.lower]
                come = _approach(ctx, arm_o, lower, above=upper, chosen=approached)
                up = take(arm_u, upper)
                low = take(arm_o, lower, pull=False)
                up = up.then(put_(arm_u, upper))
                low = low.then(put_(arm_o, lower))
                return _take_below(ctx, up, come, low, (upper, lower))
            else:
                plans = {arm_u: take(arm_u, upper)}
                plans[arm_u] = plans[arm_u].then(put_(arm_u, upper))
                if step.other == "prepare":  # come beside the cube it takes next
                    k = _next_lower(order, step.upper)
                    plans[arm_o] = _approach(
                        ctx, arm_o, CUBES[k], CUBES[k + 1], approached, standoff=STANDOFF
                    )
                with ctx.model.padded(ARM_GAP, 0.0):
                    return merge(ctx, plans.get("left"), plans.get("right"))

        for step in steps:
            # Each arm goes from its sign straight to the cube it takes next; if the arms then
            # meet at every timing, they go home between the steps instead.
            kept = (list(on_tower), {k: list(v) for k, v in placed.items()}, dict(approached))
            try:
                with ctx.transaction():
                    motion = plan_step(step, chained=True)
            except PlanningError:
                on_tower[:] = kept[0]
                placed.update(kept[1])
                approached.clear()
                approached.update(kept[2])
                motion = plan_step(step, chained=False)
            yield from run(motion)
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- the plan per tower
@dataclass(frozen=True)
class Step:
    """One merged step of the expert: `upper_arm` takes the cube at level `upper` to its sign;
    with `lower`, the other arm takes the cube below it as it comes free, else the other arm
    does `other` ('prepare': comes beside the cube it takes next; 'hold'). Each arm goes home
    after setting its cube down."""

    upper: int
    upper_arm: str
    lower: int | None = None
    other: str = "hold"

    @property
    def lower_arm(self) -> str:
        return other_side(self.upper_arm)

    @property
    def other_arm(self) -> str:
        return other_side(self.upper_arm)


def _steps(order: list[str]) -> list[Step]:
    """The expert's steps for a tower (colours bottom first): two two-arm steps when the top
    two differ in colour; else a one-arm step, a two-arm step and a one-arm step."""
    arms = [ARM[k] for k in order]
    if arms[3] != arms[2]:
        return [Step(3, arms[3], 2), Step(1, arms[1], 0)]
    return [Step(3, arms[3], other="prepare"), Step(2, arms[2], 1), Step(0, arms[0])]


def _next_takes(steps: list[Step]) -> dict[str, dict[str, int]]:
    """Per arm, for each cube it takes, the level of the next cube it takes - if it takes that
    one as the upper cube of a step whose other arm is not still to come (a one-arm step, or
    one whose lower cube's arm came beside it in the step before). The arm then comes
    straight from its sign to that cube and starts at once; otherwise the other arm, coming
    from home to wait for the cube above its own to rise, sets the pace anyway."""
    taken: dict[str, list[tuple[int, bool]]] = {"left": [], "right": []}
    for j, step in enumerate(steps):
        prepared = j > 0 and steps[j - 1].other == "prepare"
        taken[step.upper_arm].append((step.upper, step.lower is None or prepared))
        if step.lower is not None:
            taken[step.lower_arm].append((step.lower, False))
    return {
        side: {CUBES[a]: b for (a, _), (b, now) in zip(takes, takes[1:], strict=False) if now}
        for side, takes in taken.items()
    }


def _next_lower(order: list[str], level: int) -> int:
    """The highest level below `level` whose cube is not of `level`'s colour."""
    return max(k for k in range(level) if order[k] != order[level])


def _roles(order: list[str]) -> tuple[dict[str, str], dict[str, str]]:
    """What each arm does in the two take stages (the annotations' sub-goals per arm)."""
    top, below = ARM[order[3]], other_side(ARM[order[3]])
    if ARM[order[2]] != top:
        first = {
            top: "side-grasp the top cube, lift it off",
            below: "side-grasp the cube below as it comes free, lift it",
        }
        upper = ARM[order[1]]
        last = {
            upper: "side-grasp the upper cube, lift it off",
            other_side(upper): "side-grasp the bottom cube as it comes free, lift it",
        }
        return first, last
    first = {
        top: "take the top cube to its sign, then side-grasp the next one and lift it",
        below: "come beside the cube under them and wait",
    }
    last = {
        top: "stack its cube on its sign, retreat",
        below: "side-grasp the cube under them as it comes free, then the bottom cube",
    }
    return first, last


# -------------------------------------------------------------------- expert helpers
def _side_grasps(ctx: SkillContext, side: str, name: str) -> list[Grasp]:
    """Side grasps of a cube from `side`'s own side of the tower (jaws horizontal), the TCP
    SIDE_TCP above the cube's bottom (so the gripper clears the table when it is set down;
    pitched down where the hand is too tall for that, see SIDE_FLOOR), best first."""
    X_WO = ctx.model.object_pose(name)
    shape = ctx.model.object(name).shape
    params = GraspParams(
        support_z=X_WO.translation()[2] - shape.size[2] / 2, side_clearance=SIDE_TCP
    )
    grasps = grasp_candidates(
        ctx.model.object(name),
        ctx.model.embodiment.arm.gripper,
        X_WO=X_WO,
        base=arm_base(ctx.model.embodiment, side),
        kinds=["side"],
        params=params,
    )
    mine = [g for g in grasps if g.approach @ APPROACH[side] >= APPROACH_COS]
    if not mine:
        raise PlanningError("no_grasp", f"no side grasp of {name!r} from the {side}")
    # a hand taller than twice SIDE_TCP - SIDE_FLOOR: the approach pitched down, by the least
    # angle that keeps it SIDE_FLOOR above the table when the cube is set on its sign
    pitch = side_pitch(ctx.model.hand_boxes, SIDE_TCP, SIDE_FLOOR)
    if pitch is None:
        raise PlanningError("no_grasp", f"no side grasp of {name!r} keeps the hand off the table")
    return [pitched(g, X_WO, pitch) for g in mine]


def _approach(
    ctx: SkillContext,
    side: str,
    name: str,
    above: str,
    chosen: dict[str, Grasp] | None = None,
    standoff: float = 0.0,
) -> ArmPlan:
    """`side` comes to the pregrasp of its first reachable side grasp of `name` and waits
    there, clear of the cube `above` it (a later :func:`pick` of `name` starts from it; its
    grasp is checked as if `above` were gone, as it will be). The grasp goes into `chosen`
    under `name` (one already there is tried first). With `standoff` (m) it stops that much
    short of the pregrasp along the grasp's approach (where it can; else at the pregrasp): a
    later call covers the rest, straight where it can."""
    reasons = []
    grasps = _side_grasps(ctx, side, name)
    if chosen is not None and name in chosen:  # the grasp it came toward before, first
        grasps = [chosen[name], *grasps]
    for grasp in grasps:
        try:
            q_pre = solve_tcp(ctx, side, TcpTarget(grasp.X_WPre))
            q_grasp = solve_tcp(
                ctx, side, TcpTarget(grasp.X_WG), seed_arm=q_pre, ignore=[name, above]
            )
            # the pick's descent from here must be straight (not a wrist turning over)
            if tcp_deviation(ctx, side, q_pre, q_grasp) > MAX_LINE_DEVIATION:
                reasons.append("not_straight")
                continue
            q_goal = q_pre
            if standoff > 0.0:
                q_goal = _standoff(ctx, side, grasp, q_pre, standoff)
            near = np.linalg.norm(
                ctx.model.tcp_pose(ctx.q, side).translation() - grasp.X_WPre.translation()
            )
            plan = None
            if near <= STANDOFF + 0.01:  # from its standoff: straight in
                try:
                    plan = move(ctx, side, q_goal, label=f"approach {name}", straight=True)
                except PlanningError:
                    plan = None
            if plan is None:
                plan = move(ctx, side, q_goal, label=f"approach {name}", replan_grazing=True)
            if chosen is not None:
                chosen[name] = grasp
            return plan
        except PlanningError as err:
            reasons.append(err.reason)
    raise PlanningError("approach_failed", f"{side} cannot come beside {name!r} ({reasons})")


def _standoff(
    ctx: SkillContext, side: str, grasp: Grasp, q_pre: np.ndarray, standoff: float
) -> np.ndarray:
    """`side`'s joints `standoff` (m) short of `grasp`'s pregrasp along its approach, if the
    straight move from there to `q_pre` is free with the other arm where it is now; else
    `q_pre`."""
    X = grasp.X_WPre
    p = X.translation() - standoff * np.asarray(grasp.approach, dtype=float)
    try:
        q = solve_tcp(ctx, side, TcpTarget(RigidTransform(X.rotation(), p)))
    except PlanningError:
        return q_pre
    if ctx.edge_free(ctx.with_arm(side, q), ctx.with_arm(side, q_pre)):
        return q
    return q_pre


def _take_below(
    ctx: SkillContext,
    upper_plan: ArmPlan,
    come: ArmPlan,
    take: ArmPlan,
    names: tuple[str, str],
) -> Motion:
    """Both take plans at once (the lower cube's arm comes beside its cube, `come`, then takes
    and puts it, `take`). The lower arm's fingers move in from the pregrasp only once the upper
    cube has risen CLEAR_RISE off it, and later still if the arms would come closer than
    ARM_GAP (`names`: the two cubes, which change hands). It arrives just in time: its way to
    the pregrasp is slowed to end then (held back at its start only if it has no way to go).
    The arm that sets its cube down first takes its way home at a pace that ends with the
    other's (:func:`slowed_after`, from where it let go)."""
    lower_plan = come.then(take)
    clear = _risen(ctx, upper_plan, CLEAR_RISE)
    enter = _entering(ctx, lower_plan)
    start = max(0, clear - enter)
    for together in (True, False):
        for delay in range(start, start + ctx.steps(MAX_DELAY) + 1, ctx.steps(DELAY_STRIDE)):
            plans = {upper_plan.side: upper_plan, come.side: _arrive_late(come, delay).then(take)}
            if together:
                plans = _end_together(ctx, plans)
            motion = combine(plans["left"], plans["right"])
            if ctx.checked(motion, ARM_GAP, 0.0, ignore=names):
                motion.info["lower_delay"] = delay
                return motion
    raise PlanningError(
        "arm_conflict",
        f"the arms taking {names} meet at every delay up to {MAX_DELAY:g} s past the rise",
    )


def _arrive_late(come: ArmPlan, delay: int) -> ArmPlan:
    """`come` taking `delay` control steps longer: slowed if it moves, else held at its start."""
    if delay <= 0:
        return come
    if come.num_steps > 1 and np.any(come.q != come.q[0]):
        return come.stretched(come.num_steps + delay)
    return come.delayed(delay)


def _end_together(ctx: SkillContext, plans: dict[str, ArmPlan]) -> dict[str, ArmPlan]:
    """The shorter plan's way back, from where its gripper is open after it last let go,
    slowed to end with the other."""
    n = max(p.num_steps for p in plans.values())
    out = {}
    for side, plan in plans.items():
        let_go = [i for i, kind, _ in plan.events if kind == "detach"]
        if not let_go:
            out[side] = plan
            continue
        i = max(let_go)
        opened = i + int(np.argmax(plan.opening[i:] >= plan.opening[i:].max()))
        out[side] = slowed_after(ctx, plan, opened, n)
    return out


def _tcp_track(ctx: SkillContext, plan: ArmPlan) -> np.ndarray:
    """(N, 3) TCP positions of `plan`'s arm along it (the other arm as it is now)."""
    q = ctx.q.copy()
    out = []
    for q_arm in plan.q:
        q[ctx.model.side_slice(plan.side)] = q_arm
        out.append(ctx.model.tcp_pose(q, plan.side).translation())
    return np.array(out)


def _closed_at(plan: ArmPlan) -> int:
    """The first sample at which `plan`'s gripper is commanded shut."""
    shut = np.flatnonzero(plan.opening <= 1e-6)
    if not len(shut):
        raise PlanningError("no_grasp", f"{plan.label!r} never closes its gripper")
    return int(shut[0])


def _risen(ctx: SkillContext, plan: ArmPlan, height: float) -> int:
    """The first sample after `plan`'s grasp at which its TCP has risen `height` (m)."""
    z = _tcp_track(ctx, plan)[:, 2]
    i = _closed_at(plan)
    up = np.flatnonzero(z[i:] >= z[i] + height)
    if not len(up):
        raise PlanningError("no_lift", f"{plan.label!r} never lifts {height} m")
    return i + int(up[0])


def _entering(ctx: SkillContext, plan: ArmPlan) -> int:
    """The sample at which `plan`'s fingers start moving in from the pregrasp (its TCP last
    leaves a ball of PREGRASP - 1 cm around the grasp point before the grasp)."""
    p = _tcp_track(ctx, plan)
    i = _closed_at(plan)
    far = np.linalg.norm(p[: i + 1] - p[i], axis=1) > GraspParams().pregrasp_distance - 0.01
    return int(np.flatnonzero(far)[-1]) if far.any() else 0


def _yaw(X: RigidTransform) -> float:
    R = X.rotation().matrix()
    return float(np.arctan2(R[1, 0], R[0, 0]))


def _pull_out(ctx: SkillContext, side: str) -> ArmPlan:
    """The held cube drawn straight back PULL (m) along the grasp's approach and up RISE (m),
    to `side`'s own side of the tower, clear of the other arm working there."""
    X = ctx.model.tcp_pose(ctx.q, side)
    away = X.translation() - PULL * X.rotation().col(0) + [0.0, 0.0, RISE]
    X_out = RigidTransform(X.rotation(), away)
    try:
        return move_tcp(ctx, side, X_out, label="pull out", straight=True)
    except PlanningError:  # the straight joint move sweeps off the line: a planned path
        return move_tcp(ctx, side, X_out, label="pull out")


def _check_tower(view: WorldView, scene: Scene, names: list[str]) -> None:
    """Raise unless every cube still on the tower is within IN_PLACE_TOL of where it
    started (taking a cube must not topple the rest)."""
    for name in names:
        moved = np.linalg.norm(view.object_pose(name)[:3] - np.array(scene.object(name).pose.xyz))
        if moved > IN_PLACE_TOL:
            raise PlanningError(
                "tower_disturbed", f"{name} moved {moved * 100:.1f} cm while still on the tower"
            )


# -------------------------------------------------------------------- stage helpers
def _sign_xy(scene: Scene, k: str) -> list[float]:
    return scene.draws[f"sign_{k.lower()}_xy"]


def _rests(name: str) -> Predicate:
    """`name` lies on the table or on another cube, on a face."""
    others = [on_top_of(name, o) for o in CUBES if o != name]
    return all_of(any_of(on_table(name), *others), on_a_face(name))


def _rests_on_sign(scene: Scene, name: str) -> Predicate:
    """`name` rests on the sign of its own colour (see ON_SIGN_TOL)."""
    k = scene.draws["order"][CUBES.index(name)]
    return all_of(within_square(name, _sign_xy(scene, k), ON_SIGN_TOL), _rests(name))


def _rests_on_any_sign(scene: Scene, name: str) -> Predicate:
    squares = [within_square(name, _sign_xy(scene, k), ON_SIGN_TOL) for k in "AB"]
    return all_of(any_of(*squares), _rests(name))


def _tower(scene: Scene, k: str) -> Predicate:
    """The two cubes of colour `k` stacked on their sign (either on top), released and
    settled."""
    a, b = [c for c, kk in zip(CUBES, scene.draws["order"], strict=True) if kk == k]
    square = [within_square(c, _sign_xy(scene, k), ON_SIGN_TOL) for c in (a, b)]
    return all_of(
        any_of(stacked([a, b]), stacked([b, a])),
        *square,
        hands_free([a, b]),
        settled([a, b]),
    )


# -------------------------------------------------------------------- scene helpers
def _disc(rng: np.random.Generator, radius: float) -> list[float]:
    r, a = radius * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
    return [float(r * np.cos(a)), float(r * np.sin(a))]


def _lifted(pose: Pose, dz: float) -> Pose:
    return Pose(xyz=(pose.xyz[0], pose.xyz[1], pose.xyz[2] + dz), rpy=pose.rpy)


def _base(xy: list[float]) -> SceneObject:
    """The static black base the tower stands on."""
    return SceneObject(
        name="base",
        shape=BoxShape(size=BASE_SIZE),
        color=(0.08, 0.08, 0.09, 1.0),
        fixed=True,
        pose=Pose(xyz=(xy[0], xy[1], TABLE_TOP + BASE_SIZE[2] / 2)),
    )


def _sign(name: str, xy: list[float], color) -> SceneObject:
    """A 10 cm square outlined in `color`, flat on the table: seen, never collided with."""
    h, w, t = SIGN / 2, SIGN_LINE, 0.001
    bars = [((SIGN, w, t), (0.0, s * (h - w / 2))) for s in (1, -1)]
    bars += [((w, SIGN - 2 * w, t), (s * (h - w / 2), 0.0)) for s in (1, -1)]
    return SceneObject(
        name=name,
        shape=CompoundShape(
            parts=tuple(
                Primitive(kind="box", size=size, pose=Pose(xyz=(p[0], p[1], 0.0)))
                for size, p in bars
            )
        ),
        color=color,
        fixed=True,
        collide=False,
        pose=Pose(xyz=(xy[0], xy[1], TABLE_TOP + 0.0005)),
    )

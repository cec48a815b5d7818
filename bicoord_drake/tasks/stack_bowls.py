"""stack_bowls: the two arms take turns nesting four bowls into one stack at the stack spot."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from pydrake.all import RigidTransform, RotationMatrix

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import BowlShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene, flat_marker
from bicoord_drake.planning.grasps import GraspParams, arm_base, bowl_rim_grasps, turned_onto
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    SkillContext,
    arrive_as_leaves,
    hold_still,
    leave_as_arrives,
    merge,
    pick,
    place,
    retreat,
    wait_beside,
)
from bicoord_drake.planning.skills.pick_place import wall_close_opening
from bicoord_drake.stages import Stage, WorldState
from bicoord_drake.stages.predicates import (
    Predicate,
    all_of,
    bottom_z,
    hands_free,
    lifted,
    settled,
    tilt,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

#: The bowl: 11.6 cm across the rim, 9 cm at the base, 5 cm deep, 9 mm wall (thicker than the
#: closed jaw, so the pads grip it flat). The steep wall makes a nested bowl sit
#: WALL / sin(lean) ~ 3.6 cm above the one below it.
BOWL = BowlShape(radius=0.058, base_radius=0.045, height=0.05, wall=0.009)
BOWL_MASS = 0.1  # kg
BOWLS = tuple(f"bowl_{k}" for k in range(1, 5))  # in stacking order
#: Height of a nested bowl's frame above the frame of the bowl it sits in (m, nominal).
NEST_RISE = BOWL.wall / math.sin(math.atan2(BOWL.radius - BOWL.base_radius, BOWL.height))
#: A bowl counts as nested in another: frames within NEST_XY in xy, NEST_DZ[0]..NEST_DZ[1]
#: higher (the spec's "xy within 4 cm, at least 2 cm above"; the upper bound rules out a bowl
#: perched on the rim), both upright within MAX_TILT.
NEST_XY = 0.04
NEST_DZ = (0.02, NEST_RISE + 0.01)
MAX_TILT = math.radians(15)
#: Where the bowls stand: |x| in X_RANGE on their side, y in Y_RANGE, MIN_GAP apart and
#: SPOT_GAP from the stack spot (centre to centre, m).
X_RANGE = (0.09, 0.3)
Y_RANGE = (-0.15, 0.15)
MIN_GAP = 0.13
SPOT_GAP = 0.13
SPOT_XY = (0.0, -0.1)
SPOT_SIZE = 0.12  # side of the grey square marking the stack spot
#: The bottom bowl counts as at the spot within this distance (m) of its centre.
SPOT_TOL = 0.04
COLORS = {
    "white": (0.92, 0.92, 0.9, 1.0),
    "blue": (0.25, 0.4, 0.8, 1.0),
    "green": (0.3, 0.65, 0.35, 1.0),
    "yellow": (0.9, 0.78, 0.25, 1.0),
    "pink": (0.9, 0.5, 0.6, 1.0),
    "orange": (0.95, 0.55, 0.15, 1.0),
}
#: Rim grasps down the wall's slant, pads flat on it (the bowl stays upright in the grip); the
#: pad top 5 mm above the rim, so the fingertips end 3 cm below it - above the rim of the bowl
#: below when the held bowl is nested (NEST_RISE ~ 3.6 cm).
GRASP = GraspParams(rim_lean=True, rim_depth=-0.005)
#: The first bowl is let go this far above the table: a bowl hangs tilted in a rim grasp, its
#: fingertips below its base.
SPOT_DROP = 0.004
#: A nested bowl is let go this far above its nested height; it settles the rest.
NEST_DROP = 0.004
#: A nested bowl is let go gently (a fast opening pushes it aside).
NEST = {"gentle_release": True}
#: Where an arm holding the next bowl waits: TCP at |x| (within 0.18 m of the spot, TASKS.md
#: section 17), y past the spot, z above the table.
WAIT_AT = (0.18, 0.14, 0.18)
#: While one arm leaves the stack and the other brings the next bowl, the bringing arm's TCP
#: comes within CLEAR_RADIUS (xy, m) of the spot only CLEAR_LAG (s) after the leaving arm's TCP
#: has gone out of it (merge's collision check leaves out a bowl that is let go within the
#: motion, so it cannot see the carried bowl hit the leaving gripper).
CLEAR_RADIUS = 0.15
CLEAR_LAG = 0.2
#: Seconds both arms hold still at the end: the stack must be seen at rest for 0.3 s.
SETTLE = 0.53


@register_task
class StackBowls(Task):
    """Nest four bowls into one stack on the grey square, the arms taking turns.

    Description: four identical bowls of four colours stand on the table, two on each side; a
    grey square marks the stack spot near the robot. Both arms pick a bowl at once, each on its
    own side; the first arm sets its bowl on the spot while the other carries its bowl to a
    waiting point beside it; then the second arm nests its bowl in the first while the first
    arm picks its second bowl; the first arm nests that one while the second picks its last
    bowl; the second nests the last bowl while the first retreats (out of the spot's zone at
    its own pace, then timed to arrive home as the nest ends). Which arm goes first is drawn
    per seed.

    Randomization: which arm goes first; bowl positions |x| in [0.09, 0.3] on their side, y in
    [-0.15, 0.15], at least 13 cm apart and 13 cm from the spot (the reference's layout); the
    spot at (0, -0.1); four distinct colours. On each side the bowl nearer the spot is picked
    first.

    Stages: (1) the first two bowls both lifted; (2) a bowl on the table at the spot, upright,
    untouched, at rest; (3)-(5) a nested stack of 2, 3 and 4 bowls at the spot, untouched and
    at rest (the last also: both grippers open, the stack settled for 0.3 s). Each of (3)-(5)
    scores 1/3: the score is (n - 1)/3 for the tallest stack n.

    Success: four bowls nested at the spot - the bottom one on the table within 4 cm of the
    spot's centre, each next one nested in the one below (frames within 4 cm in xy, 2 to 4.6 cm
    higher), all within 15 deg of upright, both grippers open, no finger touching a bowl, every
    bowl at rest for 0.3 s.
    """

    name = "stack_bowls"
    step_limit = 900
    supported_robots = ("aloha_viperx", "franka_pair")
    ci_seed = 0
    instructions_seen = (
        "Stack the four bowls inside each other on the grey square.",
        "Nest all the bowls into one stack on the grey mark.",
        "Put the bowls one into another on the grey square, taking turns with both hands.",
        "Make a single stack of the four bowls on the grey spot.",
        "Place one bowl on the grey square and nest the other three in it.",
        "Use both arms to stack every bowl on the grey target.",
        "Collect the bowls into one nested pile on the grey square.",
    )
    instructions_unseen = (
        "Gather the four bowls into a single nested stack on the marked spot.",
        "Set a bowl on the grey patch and drop the rest inside it, one after another.",
        "Pile the bowls inside one another on the grey marker, alternating hands.",
        "Build one tower of nested bowls on the grey square.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        first = str(rng.choice(SIDES))
        other = other_side(first)
        xy = _positions(rng)
        color_names = [str(c) for c in rng.choice(sorted(COLORS), size=4, replace=False)]
        # stacking order: first arm's near bowl, other's near, first's far, other's far
        order = [(first, 0), (other, 0), (first, 1), (other, 1)]
        placed = {name: xy[side][k] for name, (side, k) in zip(BOWLS, order, strict=True)}
        objects = [flat_marker("stack_spot", SPOT_XY, SPOT_SIZE)]
        for name, color in zip(BOWLS, color_names, strict=True):
            objects.append(
                SceneObject(
                    name=name,
                    shape=BOWL,
                    color=COLORS[color],
                    mass=BOWL_MASS,
                    pose=Pose(xyz=(*placed[name], TABLE_TOP)),
                    # Rigid (the pads stay compliant): nested compliant bowls made this the
                    # slowest task to simulate (bench_expert_physics.md, "Rigid-hydroelastic
                    # bowls and pots").
                    rigid_hydroelastic=True,
                )
            )
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                "first_side": first,
                **{f"{n}_xy": placed[n] for n in BOWLS},
                "spot_xy": list(SPOT_XY),
                "colors": color_names,
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 5  # four bowls and the spot

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        first = scene.draws["first_side"]
        second = other_side(first)

        def arms(f: str, s: str) -> dict[str, str]:
            return {first: f, second: s}

        a = [
            arms("pick a bowl", "pick a bowl"),
            arms("set it on the grey square", "hold the bowl, wait"),
            arms("pick the next bowl", "nest the bowl in it"),
            arms("nest the bowl in the stack", "pick the last bowl"),
            arms("retreat", "nest the last bowl in the stack"),
        ]
        return [
            Stage(
                "pick two bowls",
                a[0]["left"],
                a[0]["right"],
                0.0,
                all_of(lifted(BOWLS[0], 0.05), lifted(BOWLS[1], 0.05)),
                "transient",
            ),
            Stage("set the first bowl", a[1]["left"], a[1]["right"], 0.0, stack_of(1), "transient"),
            Stage(
                "nest the second bowl",
                a[2]["left"],
                a[2]["right"],
                1 / 3,
                stack_of(2),
                "persistent",
            ),
            Stage(
                "nest the third bowl", a[3]["left"], a[3]["right"], 1 / 3, stack_of(3), "persistent"
            ),
            Stage(
                "nest the fourth bowl",
                a[4]["left"],
                a[4]["right"],
                1 / 3,
                all_of(stack_of(4), hands_free(BOWLS), settled(BOWLS)),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        first = scene.draws["first_side"]
        second = other_side(first)
        b1, b2, b3, b4 = BOWLS
        ctx = self.skill_context(view)

        run = partial(follow, ctx, view)

        def both(plans: dict[str, ArmPlan]) -> Motion:
            return merge(ctx, plans["left"], plans["right"])

        def swap(leaver: ArmPlan, placer: ArmPlan) -> Motion:
            return _leave_then_enter(ctx, leaver, placer)

        # ---- stage 1: both arms pick the bowl nearer the spot on their side
        plans = {first: _pick(ctx, first, b1)}
        plans[second] = _pick(ctx, second, b2)
        yield from run(both(plans))
        # ---- stage 2: the first arm sets its bowl on the spot; the other carries its bowl to
        # a waiting point beside the spot (planned first: it must not block the placement)
        plans = {second: wait_beside(ctx, second, SPOT_XY, WAIT_AT)}
        plans[first] = place(ctx, first, _spot_goal(), gentle_release=True)
        yield from run(both(plans))
        # ---- stage 3: the first arm leaves to pick its second bowl; the other nests its bowl
        leaver = _pick(ctx, first, b3)
        yield from run(swap(leaver, place(ctx, second, _nest_goal(ctx, b1), **NEST)))
        # ---- stage 4: the second arm leaves to pick its last bowl; the first nests its bowl
        leaver = _pick(ctx, second, b4)
        yield from run(swap(leaver, place(ctx, first, _nest_goal(ctx, b2), **NEST)))
        # ---- stage 5: the first arm retreats while the second nests the last bowl; its way
        # home, once out of the spot's zone, is timed to end with the nest (leave_as_arrives)
        leaver = retreat(ctx, first)
        placer = place(ctx, second, _nest_goal(ctx, b3), **NEST)
        yield from run(leave_as_arrives(ctx, leaver, placer, SPOT_XY, CLEAR_RADIUS, lag=CLEAR_LAG))
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


# -------------------------------------------------------------------- predicates
def nested(state: WorldState, upper: str, lower: str) -> bool:
    """`upper` sits inside `lower`: frames within NEST_XY in xy, NEST_DZ higher, both upright."""
    d = state.position(upper) - state.position(lower)
    return bool(
        np.linalg.norm(d[:2]) <= NEST_XY
        and NEST_DZ[0] <= d[2] <= NEST_DZ[1]
        and _upright(state, upper)
        and _upright(state, lower)
    )


def tallest_stack(state: WorldState, spot_xy=SPOT_XY) -> list[str]:
    """The tallest chain of nested bowls at the spot, bottom first: the bottom one upright on
    the table within SPOT_TOL of the spot, each next one nested in the one below."""
    best: list[str] = []
    for base in BOWLS:
        p = state.position(base)
        if not (
            np.hypot(p[0] - spot_xy[0], p[1] - spot_xy[1]) <= SPOT_TOL
            and abs(bottom_z(state, base) - TABLE_TOP) <= 0.01
            and _upright(state, base)
        ):
            continue
        chain = [base]
        while True:
            nxt = [b for b in BOWLS if b not in chain and nested(state, b, chain[-1])]
            if not nxt:
                break
            chain.append(nxt[0])
        if len(chain) > len(best):
            best = chain
    return best


def stack_of(n: int, linear_tol: float = 0.01, angular_tol: float = 0.1) -> Predicate:
    """A nested stack of at least `n` bowls at the spot whose bottom `n` bowls are let go (no
    finger touches them) and at rest."""

    def check(s: WorldState) -> bool:
        chain = tallest_stack(s)[:n]
        if len(chain) < n:
            return False
        for b in chain:
            v = s.velocity(b)
            if s.touching(b) or np.linalg.norm(v[:3]) > linear_tol:
                return False
            if np.linalg.norm(v[3:]) > angular_tol:
                return False
        return True

    return Predicate(check, f"stack_of({n})")


def _upright(state: WorldState, name: str) -> bool:
    return tilt(state, name, "z") <= MAX_TILT


# -------------------------------------------------------------------- expert helpers
def _pick(ctx: SkillContext, side: str, name: str) -> ArmPlan:
    """Pick bowl `name` by the rim with `side`, fingertips kept high (see GRASP), the pads
    pressed at most half their thickness into the wall (`wall_close_opening`: closed fully, the
    Franka Hand's pads were driven 1.7 mm into the 9 mm wall as a nested bowl landed, past the
    middle of its 3 mm pads, and held it; opening dragged the stack 3.5 cm and backing off
    lifted the bowl out: franka seeds 3, 11, 25, 26, 29)."""
    grasps = bowl_rim_grasps(
        ctx.model.object_pose(name),
        BOWL,
        ctx.model.embodiment.arm.gripper,
        base=arm_base(ctx.model.embodiment, side),
        params=GRASP,
    )
    return pick(ctx, side, name, grasps=grasps, close_opening=wall_close_opening(ctx, BOWL.wall))


def _spot_goal() -> RigidTransform:
    return RigidTransform([SPOT_XY[0], SPOT_XY[1], TABLE_TOP + SPOT_DROP])


def _nest_goal(ctx: SkillContext, lower: str) -> RigidTransform:
    """The pose a bowl is let go at to nest in `lower` (measured at the last sync): on
    `lower`'s axis, NEST_RISE + NEST_DROP above it, tilted as `lower` is (a bowl nested a few
    degrees off vertical takes the next one only along its own axis), no yaw."""
    X = ctx.model.object_pose(lower)
    axis = X.rotation().matrix()[:, 2]
    R = turned_onto(RotationMatrix(), np.array([0.0, 0.0, 1.0]), axis)
    return RigidTransform(R, X.translation() + (NEST_RISE + NEST_DROP) * axis)


def _leave_then_enter(ctx: SkillContext, leaver: ArmPlan, placer: ArmPlan) -> Motion:
    """Both plans at once, each at its own pace, the placer held back until the leaver's TCP
    is out of CLEAR_RADIUS around the spot (for CLEAR_LAG seconds) before the placer's comes in."""
    return arrive_as_leaves(ctx, leaver, placer, SPOT_XY, CLEAR_RADIUS, lag=CLEAR_LAG)


def _positions(rng: np.random.Generator) -> dict[str, list[list[float]]]:
    """Two bowl centres per side, MIN_GAP apart and SPOT_GAP from the spot, the one nearer
    the spot first (rejection sampling from `rng`)."""
    spot = np.array(SPOT_XY)
    for _ in range(1000):
        xy = {
            side: [
                [sign * float(rng.uniform(*X_RANGE)), float(rng.uniform(*Y_RANGE))]
                for _ in range(2)
            ]
            for side, sign in (("left", -1.0), ("right", 1.0))
        }
        points = np.array(xy["left"] + xy["right"])
        gaps = [np.linalg.norm(a - b) for i, a in enumerate(points) for b in points[i + 1 :]]
        if min(gaps) >= MIN_GAP and min(np.linalg.norm(points - spot, axis=1)) >= SPOT_GAP:
            return {
                side: sorted(v, key=lambda q: float(np.linalg.norm(np.array(q) - spot)))
                for side, v in xy.items()
            }
    raise RuntimeError("no bowl layout found in 1000 draws")  # pragma: no cover

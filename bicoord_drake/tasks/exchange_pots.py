"""exchange_pots: both hands move two pots by their handles so that they swap places.

The expert holds each pot by its two lug handles (one hand each, closing and opening on the
same control steps) and turns it about the vertical while carrying it (a round pot is the same
pot turned; only its handles move), so that each wrist stays on one IK branch and the hands
keep clear of the other pot:

- pot 1 is parked turned -30 degrees, so that at the regrasp its left handle faces away from
  pot 2 (which then stands 40 cm to its left) and the left gripper fits between the pots;
- pot 2 is picked with the left wrist on its positive-angle branch (``pick_together(...,
  wrist=)``): the carry ends with the left hand close in front of its own base, which only that
  branch reaches (on the other one the wrist runs into its -1.87 rad limit and the IK flips
  branch mid-carry), and it is turned +30 degrees on the way, the right hand's wrist clear of
  the parked pot 1;
- pot 1 is turned back by +30 degrees on its way to pot 2's spot.

The pots are 8.5-10 cm tall (the spec gives no size): on a shorter pot the handle sits so low
that the gripper's side plates, which stand vertical for a grasp of a horizontal handle, touch
the table. A hand longer along its finger axis than the handle is high (the Franka Hand's
0.2 m housing) closes across the handle's width instead, its approach pitched down
(``bimanual.handle_pairs`` chooses by the hand's boxes). The turns above are tried first;
where a carry, its lowering or the release has no plan, :func:`_set_down` tries the other
turns (FALLBACK_TURNS) and then the low height, and the release backs off less
(:func:`_release`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
from pydrake.all import RigidTransform, RotationMatrix

from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import PotShape, SceneObject
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.skills import (
    Motion,
    SkillContext,
    carry_together,
    hold_still,
    merge,
    pick_together,
    release_together,
    retreat,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    hands_free,
    held_by,
    lifted,
    on_table,
    settled,
    upright,
    within_xy,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

POT_1, POT_2 = "pot_1", "pot_2"
POTS = (POT_1, POT_2)
#: Where the pots stand (the reference's spots) and the jitter (m) drawn around each.
HOME = {POT_1: (-0.15, -0.17), POT_2: (0.15, 0.05)}
JITTER = 0.03
#: Pot 1 is parked this far toward +x before pot 2 takes its spot (m).
PARK_DX = 0.40
#: Pot sizes (m) and mass (kg).
RADIUS = (0.055, 0.065)
HEIGHT = (0.085, 0.10)
POT_MASS = 0.3
COLORS = {
    "steel": (0.72, 0.74, 0.78, 1.0),
    "copper": (0.78, 0.45, 0.28, 1.0),
    "red enamel": (0.75, 0.15, 0.12, 1.0),
    "blue enamel": (0.18, 0.3, 0.65, 1.0),
    "black": (0.15, 0.15, 0.16, 1.0),
    "cream": (0.92, 0.88, 0.76, 1.0),
}
#: Stage thresholds: a lift (m), pot 2's carry height (m), the goal tolerance (m), the tilt.
LIFT_HEIGHT = 0.03
CARRY_HEIGHT = 0.18
GOAL_TOL = 0.05
MAX_TILT = math.radians(15)
#: Expert: lifts (m), the release ramp (s), the final hold.
LIFT = 0.05
RAISE = 0.20
PARK_TURN = math.radians(-30)
CARRY_TURN = math.radians(30)
BACK_OFF, SHORT_BACK_OFF = 0.06, 0.03
FALLBACK_TURNS = tuple(math.radians(a) for a in (0, -30, 60, -60, 90, -90))
SETTLE = 0.53


@register_task
class ExchangePots(Task):
    """Swap two pots, each carried by both hands holding its two handles.

    Description: two pots (round walls, two lug handles each) stand on the table, pot 1 near
    the robot on the left, pot 2 further out on the right. Both hands hold each pot by its two
    handles (horizontal grasps from outside, closing on the same step): they lift pot 1 and
    park it 40 cm toward +x, lift pot 2, carry it raised 20 cm to pot 1's old spot and set it
    down, then take pot 1 again and move it, low over the table, to pot 2's old spot. The
    expert turns each pot about the vertical while carrying it (see the module docstring).

    Randomization: each pot within 3 cm (x and y) of its reference spot, (-0.15, -0.17) and
    (0.15, 0.05); radius 5.5-6.5 cm and height 8.5-10 cm per pot; the colours.

    Stages: (1) pot 1 held by both hands, lifted 3 cm (transient); (2) pot 1 parked: within
    5 cm of its spot 40 cm toward +x, upright on the table, both grippers open and off it
    (transient); (3) pot 2 held by both hands, raised 18 cm (transient); (4) pot 2 upright on
    the table within 5 cm of pot 1's original spot, released (persistent); (5) pot 1 held by
    both hands again (transient); (6) pot 1 upright on the table within 5 cm of pot 2's original
    spot, both pots released and at rest for 0.3 s (persistent).

    Success: stages 4 and 6 hold when the rollout ends: the pots have swapped places, upright,
    released and still.
    """

    name = "exchange_pots"
    step_limit = 900
    supported_robots = ("aloha_viperx", "franka_pair")
    expert_speed = 0.8
    instructions_seen = (
        "Swap the two pots using both hands on their handles.",
        "Exchange the positions of the two pots, carrying each by both handles.",
        "Move the near pot aside, bring the far pot to its place, then put the near pot where "
        "the far one was.",
        "Use both grippers on the handles to make the two pots trade places.",
        "Lift each pot by its two handles and switch where they stand.",
        "Carry the pots with two hands so that each ends up at the other's spot.",
        "Swap the pots: hold every pot by both of its handles.",
    )
    instructions_unseen = (
        "Make the two cooking pots change places, handling each with both arms.",
        "Trade the places of the pots, gripping them by the side handles.",
        "Park the first pot, move the second into its spot, then set the first where the "
        "second stood.",
        "Exchange the two pots on the table using two-handed carries.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        draws: dict = {}
        objects = []
        names = sorted(COLORS)
        colors = [str(c) for c in rng.choice(names, size=2, replace=False)]
        for name, color in zip(POTS, colors, strict=True):
            x, y = (float(v + rng.uniform(-JITTER, JITTER)) for v in HOME[name])
            radius, height = float(rng.uniform(*RADIUS)), float(rng.uniform(*HEIGHT))
            shape = PotShape(radius=radius, height=height)
            objects.append(
                SceneObject(
                    name=name,
                    shape=shape,
                    color=COLORS[color],
                    mass=POT_MASS,
                    pose=Pose(xyz=(x, y, TABLE_TOP)),
                )
            )
            draws |= {f"{name}_xy": [x, y], f"{name}_radius": radius, f"{name}_height": height}
            draws[f"{name}_color"] = color
        return Scene(name=self.name, seed=seed, objects=tuple(objects), draws=draws)

    @staticmethod
    def spots(scene: Scene) -> dict[str, tuple[float, float]]:
        """Pot 1's parking spot and the two original spots (table-centred x, y)."""
        x1, y1 = scene.draws[f"{POT_1}_xy"]
        x2, y2 = scene.draws[f"{POT_2}_xy"]
        return {"park": (x1 + PARK_DX, y1), POT_1: (x1, y1), POT_2: (x2, y2)}

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        spots = self.spots(scene)

        def standing(pot: str, xy) -> object:
            return all_of(
                within_xy(pot, xy, GOAL_TOL), on_table(pot), upright(pot, max_tilt=MAX_TILT)
            )

        return [
            Stage(
                "lift pot 1",
                "grasp its left handle, lift",
                "grasp its right handle, lift",
                0.0,
                all_of(held_by(POT_1, "both"), lifted(POT_1, LIFT_HEIGHT)),
                "transient",
            ),
            Stage(
                "park pot 1",
                "carry it 40 cm to the right, set it down, let go",
                "carry it 40 cm to the right, set it down, let go",
                0.0,
                all_of(standing(POT_1, spots["park"]), hands_free([POT_1])),
                "transient",
            ),
            Stage(
                "lift pot 2",
                "grasp its left handle, raise it",
                "grasp its right handle, raise it",
                0.0,
                all_of(held_by(POT_2, "both"), lifted(POT_2, CARRY_HEIGHT)),
                "transient",
            ),
            Stage(
                "carry pot 2 to pot 1's spot",
                "carry it, set it down, let go",
                "carry it, set it down, let go",
                0.5,
                all_of(standing(POT_2, spots[POT_1]), hands_free([POT_2])),
                "persistent",
            ),
            Stage(
                "regrasp pot 1",
                "grasp its left handle",
                "grasp its right handle",
                0.0,
                held_by(POT_1, "both"),
                "transient",
            ),
            Stage(
                "move pot 1 to pot 2's spot",
                "carry it low, set it down, let go",
                "carry it low, set it down, let go",
                0.5,
                all_of(
                    standing(POT_1, spots[POT_2]),
                    hands_free(list(POTS)),
                    settled(list(POTS)),
                ),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        ctx = self.skill_context(view)
        for motion in plan_stages(ctx, self.spots(scene)):
            yield from follow(ctx, view, motion)


def _set_down(
    ctx: SkillContext, pot: str, xy, *, raise_by: float, label: str, turn: float = 0.0
) -> Motion:
    """Carry the pot both hands hold to `raise_by` above `xy`, turning it `turn` (rad) about
    the vertical on the way, lower it there, let go together and back off."""
    X = ctx.model.held_pose("left", ctx.q)
    errors = []
    tries = [(turn, raise_by)] + [(t, h) for h in (raise_by, LIFT) for t in FALLBACK_TURNS]
    for t, h in dict.fromkeys(tries):
        R = RotationMatrix.MakeZRotation(t) @ X.rotation()
        over = RigidTransform(R, [xy[0], xy[1], TABLE_TOP + h])
        down = RigidTransform(R, [xy[0], xy[1], TABLE_TOP + 0.002])
        try:
            with ctx.transaction():
                carry = carry_together(ctx, over, label=label)
                lower = carry_together(ctx, down, label=f"set {pot} down", ignore=[pot])
                release = _release(ctx)
        except PlanningError as err:
            errors.append(err)
            continue
        return carry.then(lower).then(release)
    raise errors[0]


def _release(ctx: SkillContext) -> Motion:
    """Both hands let go of the pot they hold and back off BACK_OFF (m) along their approach,
    or SHORT_BACK_OFF where an arm near the end of its reach cannot back off that far."""
    try:
        return release_together(ctx, gentle=True, back=BACK_OFF)
    except PlanningError:
        return release_together(ctx, gentle=True, back=SHORT_BACK_OFF)


def _put_back(ctx: SkillContext, pot: str) -> Motion:
    """Lower the pot both hands hold straight down onto the table, let go together and take
    the arms home, one after the other."""
    X = ctx.model.held_pose("left", ctx.q)
    down = RigidTransform(X.rotation(), [*X.translation()[:2], TABLE_TOP + 0.002])
    lower = carry_together(ctx, down, label=f"put {pot} back", ignore=[pot])
    release = _release(ctx)
    left_home = merge(ctx, retreat(ctx, "left"), None)
    right_home = merge(ctx, None, retreat(ctx, "right"))
    return lower.then(release).then(left_home).then(right_home)


def plan_stages(ctx: SkillContext, spots: dict) -> Iterator[Motion]:
    """The expert's motions, one per sub-goal, planned from `ctx` (which the caller syncs to the
    measured state after each)."""
    # ---- stages 1-2: both hands lift pot 1 by its handles and park it 40 cm toward +x
    yield pick_together(ctx, POT_1, lift=LIFT)
    yield _set_down(ctx, POT_1, spots["park"], raise_by=LIFT, label="park pot 1", turn=PARK_TURN)
    # ---- stages 3-4: lift pot 2 20 cm, carry it to pot 1's spot, set it down
    yield pick_together(ctx, POT_2, lift=RAISE, wrist={"left": 1.0})
    yield _set_down(ctx, POT_2, spots[POT_1], raise_by=RAISE, label="carry pot 2", turn=CARRY_TURN)
    # ---- stages 5-6: take pot 1 again and move it low to pot 2's spot
    yield pick_together(ctx, POT_1, lift=LIFT)
    move = partial(_set_down, ctx, POT_1, spots[POT_2], raise_by=LIFT, label="move pot 1")
    try:
        last = move(turn=-PARK_TURN)
    except PlanningError:
        # the arms took the handles in joints that cannot carry the pot there (a 7-joint arm
        # can close on them with joints at their limits): put it back, go home, take it again
        yield _put_back(ctx, POT_1)
        yield pick_together(ctx, POT_1, lift=LIFT)
        last = move(turn=-PARK_TURN)
    yield last
    away = merge(ctx, retreat(ctx, "left"), retreat(ctx, "right"))
    yield away.then(hold_still(ctx, SETTLE))

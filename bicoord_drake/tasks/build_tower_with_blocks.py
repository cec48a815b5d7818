"""build_tower_with_blocks: stack three cubes of three sizes into a tower, largest at the bottom."""

from __future__ import annotations

from collections.abc import Iterator
from functools import partial

import numpy as np

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.objects import BoxShape
from bicoord_drake.models.scene import Scene, cube, flat_marker
from bicoord_drake.planning.grasps import stack_target, table_target
from bicoord_drake.planning.skills import (
    ArmPlan,
    Motion,
    carry_above,
    hold_still,
    leave_as_arrives,
    merge,
    pick,
    place,
    retreat,
    wait_beside,
)
from bicoord_drake.stages import Stage
from bicoord_drake.stages.predicates import (
    all_of,
    at_rest,
    hands_free,
    lifted,
    on_table,
    settled,
    stacked,
    untouched,
    within_xy,
)
from bicoord_drake.tasks.base import Task, WorldView, follow
from bicoord_drake.tasks.registry import register_task

#: Edge ranges (m) of the three cubes, bottom of the tower first.
SIZES = {"large": (0.052, 0.06), "middle": (0.04, 0.048), "small": (0.03, 0.038)}
BLOCKS = tuple(f"{k}_cube" for k in SIZES)
DENSITY = 600.0  # kg/m^3 (painted wood): 0.06-0.13 kg, 0.04-0.11 kg, 0.016-0.033 kg
#: Where the cubes lie: |x| in X_RANGE on their side, y in Y_RANGE, yaw within +-YAW.
X_RANGE = (0.10, 0.25)
Y_RANGE = (-0.10, 0.15)
YAW = 0.75
#: Free space between cubes, and from the tower spot (centre to centre, m).
MIN_GAP = 0.13
SPOT_GAP = 0.12
SPOT_Y = (-0.15, -0.10)
SPOT_SIZE = 0.08  # side of the grey square marking the tower spot
#: The large cube counts as at the spot within this distance (m) of its centre.
SPOT_TOL = 0.025
COLORS = {
    "red": (0.85, 0.2, 0.2, 1.0),
    "green": (0.2, 0.6, 0.25, 1.0),
    "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.9, 0.75, 0.15, 1.0),
    "purple": (0.6, 0.3, 0.75, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
}
#: Where the arm holding the small cube waits: TCP at |x|, y past the spot, z above the table.
WAIT_AT = (0.2, 0.06, 0.16)
#: Radius (m, xy) of the zone around the tower spot one hand at a time works in.
SPOT_ZONE = 0.05
#: Seconds both arms hold still at the end: the tower must be seen at rest for 0.3 s.
SETTLE = 0.53


@register_task
class BuildTowerWithBlocks(Task):
    """Build a three-cube tower at the grey square: large at the bottom, small on top.

    Description: three cubes of three sizes (5.2-6, 4-4.8 and 3-3.8 cm edges) lie on the
    table; a grey square marks the tower spot near the robot. The arm on the large cube's side
    picks it and places it on the spot while the other arm, clear of the spot, picks the cube
    on its own side and carries it to a waiting point beside the spot. If that is the middle
    cube, it is carried above the large cube while the first arm picks the small one, set on
    the large cube while the small one is carried beside the spot, and its arm leaves as the
    small one arrives on top. If it is the small cube, its arm holds it beside the spot while
    the first arm picks the middle cube and stacks it (turn-taking forced by the tower: the
    small cube can only go on the middle one, and the spot takes one hand at a time), then
    stacks it as the first arm leaves. A leaving arm's way home is timed to end with the other
    arm's stacking. Which arm does what follows from where the cubes lie.

    Randomization: the three edges; which side (sign of x) the large cube lies on, and which
    side the middle cube lies on - the small cube always lies on the other side from the
    middle one, so each arm has one of them to pick (the reference's "never all on one side");
    positions |x| in [0.10, 0.25] (the reference's [0, 0.25], kept 10 cm clear of the centre
    line and 12 cm from the spot so that no cube lies on the tower spot), y in [-0.10, 0.15],
    at least 13 cm apart; yaws within +-0.75 rad; the tower spot at x = 0, y in [-0.15, -0.10];
    three distinct colours.

    Stages: (1) the large cube lifted; (2) the large cube on the table at the spot, untouched;
    (3) the middle and small cubes both lifted; (4) the middle cube resting on the large one at
    the spot, untouched, at rest, while the other arm may still hold the small cube; (5) the
    small cube on the middle one, the tower released and settled.

    Success: a tower at the spot - the large cube on the table within 2.5 cm of the spot's
    centre, the middle cube on it and the small cube on the middle one (each centre within
    2 cm in xy of the one below, bottom within 1 cm of its top, every cube lying on a face),
    both grippers open, no finger touching any cube, every cube at rest for 0.3 s.
    """

    name = "build_tower_with_blocks"
    step_limit = 800
    supported_robots = ("aloha_viperx", "franka_pair")
    instructions_seen = (
        "Build a tower of the three cubes on the grey square, largest at the bottom.",
        "Stack the blocks on the grey mark: big one first, then the middle one, then the small "
        "one.",
        "Put the large cube on the grey square and stack the two smaller cubes on top of it.",
        "Make a three-block tower on the grey spot with the smallest block on top.",
        "Pile the cubes on the grey square from biggest to smallest.",
        "Place the biggest block on the grey square, then the medium block on it, then the "
        "smallest.",
        "Use both hands to stack the three cubes by size on the grey target.",
    )
    instructions_unseen = (
        "Assemble a tower from the three blocks, big to small, on the grey patch.",
        "Set the large block on the marked spot and build the other two on top in order of size.",
        "Stack all three cubes into one tower on the grey square, the little one at the top.",
        "Build a block tower on the grey marker: the widest cube below, the narrowest above.",
    )

    # ---------------------------------------------------------------- scene
    def sample_scene(self, seed: int) -> Scene:
        rng = np.random.default_rng(seed)
        edges = {k: float(rng.uniform(*r)) for k, r in SIZES.items()}
        large_side = str(rng.choice(SIDES))
        middle_side = str(rng.choice(SIDES))
        sides = {
            "large": large_side,
            "middle": middle_side,
            "small": other_side(middle_side),
        }
        spot = [0.0, float(rng.uniform(*SPOT_Y))]
        xy = _positions(rng, sides, spot)
        yaws = {k: float(rng.uniform(-YAW, YAW)) for k in SIZES}
        color_names = [str(c) for c in rng.choice(sorted(COLORS), size=3, replace=False)]
        objects = [flat_marker("tower_spot", spot, SPOT_SIZE)]
        for (k, edge), color in zip(edges.items(), color_names, strict=True):
            objects.append(
                cube(
                    f"{k}_cube",
                    *xy[k],
                    size=edge,
                    color=COLORS[color],
                    mass=DENSITY * edge**3,
                    yaw=yaws[k],
                )
            )
        return Scene(
            name=self.name,
            seed=seed,
            objects=tuple(objects),
            draws={
                **{f"{k}_edge": edges[k] for k in SIZES},
                **{f"{k}_side": sides[k] for k in SIZES},
                **{f"{k}_xy": xy[k] for k in SIZES},
                **{f"{k}_yaw": yaws[k] for k in SIZES},
                "spot_xy": spot,
                "colors": color_names,
            },
        )

    def object_count(self, scene: Scene) -> int:
        return 4  # three cubes and the spot

    # ---------------------------------------------------------------- stages
    def stages(self, scene: Scene) -> list[Stage]:
        spot = scene.draws["spot_xy"]
        large, middle, small = BLOCKS
        at_spot = within_xy(large, spot, SPOT_TOL)
        sides = _sides(scene)
        mid_arm, small_arm = sides["middle"], sides["small"]
        first = {"left": "stay clear", "right": "stay clear"}
        first[sides["large"]] = None
        return [
            Stage(
                "pick the large cube",
                first["left"] or "pick the large cube",
                first["right"] or "pick the large cube",
                0.0,
                lifted(large, 0.05),
                "transient",
            ),
            Stage(
                "place it at the spot",
                first["left"] or "place it on the grey square",
                first["right"] or "place it on the grey square",
                0.0,
                all_of(at_spot, on_table(large), untouched(large), at_rest(large)),
                "transient",
            ),
            Stage(
                "pick the other two",
                f"pick the {'middle' if mid_arm == 'left' else 'small'} cube",
                f"pick the {'middle' if mid_arm == 'right' else 'small'} cube",
                0.0,
                all_of(lifted(middle, 0.05), lifted(small, 0.05)),
                "transient",
            ),
            Stage(
                "stack the middle cube",
                "stack it on the large cube" if mid_arm == "left" else "hold, wait",
                "stack it on the large cube" if mid_arm == "right" else "hold, wait",
                0.5,
                all_of(
                    at_spot,
                    stacked([large, middle]),
                    untouched(large),
                    untouched(middle),
                    at_rest(large),
                    at_rest(middle),
                ),
                "persistent",
            ),
            Stage(
                "stack the small cube",
                "stack it on the middle cube" if small_arm == "left" else "retreat",
                "stack it on the middle cube" if small_arm == "right" else "retreat",
                0.5,
                all_of(at_spot, stacked(BLOCKS), hands_free(BLOCKS), settled(BLOCKS)),
                "persistent",
            ),
        ]

    # ---------------------------------------------------------------- expert
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        large, middle, small = BLOCKS
        sides = _sides(scene)
        first = sides["large"]
        other = other_side(first)
        own = middle if sides["middle"] == other else small  # the other arm's one cube
        spot = scene.draws["spot_xy"]
        ctx = self.skill_context(view)

        run = partial(follow, ctx, view)

        def on(name: str, support: str):
            X_WS = ctx.model.object_pose(support)  # measured at the last sync
            return stack_target(X_WS, _shape(scene, support), _shape(scene, name))

        def both(plans: dict[str, ArmPlan]) -> Motion:
            return merge(ctx, plans.get("left"), plans.get("right"))

        # ---- stage 1: the arm on the large cube's side picks it while the other arm picks the
        # cube on its own side (it is needed in stage 3 and lies away from the large one)
        plans = {first: pick(ctx, first, large)}
        plans[other] = pick(ctx, other, own)
        yield from run(both(plans))
        # ---- stage 2: the large cube goes on the spot while the other arm carries its cube
        # to its waiting point beside the spot (planned first: it stays clear of the spot)
        plans = {other: wait_beside(ctx, other, spot, WAIT_AT)}
        plans[first] = place(ctx, first, table_target(spot, _shape(scene, large)))
        yield from run(both(plans))
        if own == middle:
            # ---- stage 3: the first arm picks the small cube while the other carries the
            # middle cube above the large one (it still holds it, so both count as lifted;
            # the pick is planned first: it leaves the spot)
            plans = {first: pick(ctx, first, small)}
            plans[other] = carry_above(ctx, other, on(middle, large))
            yield from run(both(plans))
            # ---- stage 4: the middle cube goes on the large one while the small cube is
            # carried to its waiting point on the first arm's side
            plans = {first: wait_beside(ctx, first, spot, WAIT_AT)}
            plans[other] = place(ctx, other, on(middle, large), gentle_release=True)
            yield from run(both(plans))
            stacker, leaver = first, other
        else:
            # ---- stages 3-4: the first arm picks the middle cube and stacks it while the
            # other holds the small cube at its waiting point: the spot takes one hand at a
            # time (turn-taking forced by the tower: the small cube goes on the middle one)
            yield from run(both({first: pick(ctx, first, middle)}))
            plans = {first: place(ctx, first, on(middle, large), gentle_release=True)}
            yield from run(both(plans))
            stacker, leaver = other, first
        # ---- stage 5: the arm that stacked the middle cube leaves as the small cube arrives
        # (the leaver's way home is timed to end with the stacking: it is out of the spot's
        # zone at its own pace, then slows down)
        leaving = retreat(ctx, leaver)
        stacking = place(ctx, stacker, on(small, middle), gentle_release=True)
        yield from run(leave_as_arrives(ctx, leaving, stacking, spot, SPOT_ZONE))
        final = hold_still(ctx, SETTLE)
        yield from final.actions()


def _sides(scene: Scene) -> dict[str, str]:
    """The side each cube lies on: 'large', 'middle', 'small' -> 'left' or 'right'."""
    return {k: scene.draws[f"{k}_side"] for k in SIZES}


def _shape(scene: Scene, name: str) -> BoxShape:
    return scene.object(name).shape


def _positions(
    rng: np.random.Generator, sides: dict[str, str], spot: list[float]
) -> dict[str, list[float]]:
    """Cube centres on their sides, at least MIN_GAP apart and SPOT_GAP from the spot
    (rejection sampling from `rng`)."""
    for _ in range(1000):
        xy = {
            k: [
                float((1 if side == "right" else -1) * rng.uniform(*X_RANGE)),
                float(rng.uniform(*Y_RANGE)),
            ]
            for k, side in sides.items()
        }
        points = np.array(list(xy.values()))
        gaps = [np.linalg.norm(a - b) for i, a in enumerate(points) for b in points[i + 1 :]]
        if min(gaps) >= MIN_GAP and min(np.linalg.norm(points - spot, axis=1)) >= SPOT_GAP:
            return xy
    raise RuntimeError("no cube layout found in 1000 draws")  # pragma: no cover

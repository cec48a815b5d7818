"""Getting back on track after a drop or a knock: what an expert does at a plan boundary when
an object it carried or set down is not where its plan put it (issue #54's recovery
demonstrations).

:func:`~bicoord_drake.tasks.base.follow` calls :func:`recover_drops` after every motion, with
the objects the motion was planned to leave in a hand or set down by :func:`~bicoord_drake.
planning.skills.place` (:func:`carried_by`). From the measured world it finds

- a *lost grasp*: an object the plan still has in a hand lies farther than
  ``GRASP_LOST_DISTANCE`` from it (it slipped out or was dropped): the hand picks it up again
  where it lies (:func:`~bicoord_drake.planning.skills.pick`), and the expert plans on from
  there, the object held with its new grasp;
- a *missed placement*: an object the motion set down with ``place`` rests farther from the
  pose the plan set it down at than :func:`missed_distance` (2 cm on the table top; elsewhere
  4 cm plus the object's own reach: an object let go in a holder may tip that far and still be
  where it was put): it fell on the way. A free hand picks it up and the placement is done
  again, with the same goal and settings (``SkillContext.placements``). An object let fall
  into a container (``drop_into``) has no placement to compare with;
- a *knock*: an object an earlier motion set down on the table top (``SkillContext.settled``)
  and that no motion has handled since lies more than :data:`KNOCKED_DISTANCE` from where it
  came to rest: it is picked up and placed again as a missed placement, before what the
  motion itself set down (on it, perhaps) is checked (:func:`knocked`,
  :func:`recover_knocks`).

Before picking, the expert holds both arms still until the fallen object is at rest
(:data:`REST_SPEED`, at most :data:`REST_WAIT` seconds). Nothing here acts in an undisturbed
episode: a clean placement lands within a few millimetres of its goal, and a clean run never
loses a grasp (it would have failed with ``grasp_lost``). A recovery that cannot be planned
raises the :class:`~bicoord_drake.planning.errors.PlanningError` of its pick or place, whose
reason names the object (the seed then fails).

The world view is told where each recovery ends (``WorldView.note_recovered``), so a
generator can annotate the recovery segment.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

import numpy as np

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.planning.errors import PlanningError

if TYPE_CHECKING:
    from pydrake.all import RigidTransform

    from bicoord_drake.planning.skills import Motion, SkillContext
    from bicoord_drake.planning.skills.pick_place import Placement
    from bicoord_drake.tasks.base import WorldView

LOG = logging.getLogger(__name__)

#: How far (m) from its goal on the table top an object may rest before the expert takes it
#: for fallen on the way: a clean placement on the table lands within a few mm.
MISSED_ON_TABLE = 0.02

#: How far (m), beyond its own reach, a placed object may rest from the pose its placement
#: planned before the expert takes it for fallen: a clean placement lands within a few mm, a
#: drop on the way a hand's width or more away.
MISSED_PLACEMENT = 0.04
#: How far (m) an object the expert set down on the table top may move, with no plan of the
#: robot handling it, before the expert takes it for knocked away from where it came to rest.
KNOCKED_DISTANCE = 0.02
#: Speed (m/s) under which a fallen object counts as at rest, ready to be picked.
REST_SPEED = 0.01
#: Longest wait (s) for a fallen object to come to rest before it is picked anyway.
REST_WAIT = 2.0
#: Lift (m) of a recovery pick: clear of whatever the object fell among.
RECOVERY_LIFT = 0.10

#: How far (m) a hand that starts too close to the scene (what fell landed against its
#: fingers) rises before the recovery's picks are planned.
BACK_OFF = 0.05

#: Runs a motion and brings the context up to date (``follow`` bound to its context and view).
Runner = Callable[["Motion"], Iterator[np.ndarray]]


def carried_by(ctx: SkillContext, motion: Motion) -> tuple[dict[str, str], dict[str, str]]:
    """What `motion` (already planned, so the context is at its end) carries: the objects it
    leaves held (name -> side) and the objects it sets down with a placement recorded since
    the last plan boundary (name -> side of the hand that placed it;
    ``SkillContext.placements``)."""
    held = {h.name: side for side, h in ctx.model.held.items()}
    placed = {}
    for _, side, kind, name in motion.events:
        if kind == "detach" and name in ctx.placements and name not in held:
            placed[name] = side
    return held, placed


def fallen(
    ctx: SkillContext,
    measured: dict[str, RigidTransform],
    held: dict[str, str],
    placed: dict[str, str],
    placements: dict[str, Placement],
) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """From the measured poses: the lost grasps ((side, object), of `held`) and the missed
    placements ((side, object), of `placed`, whose goals `placements` has), as the module
    docstring defines them."""
    lost = [
        (side, name)
        for side, name, _ in ctx.lost_grasps(measured)
        if held.get(name) == side and len(ctx.model.holders(name)) == 1
    ]
    missed = []
    for name, side in placed.items():
        goal = placements[name].X_WO_goal
        if name not in measured:
            continue
        offset = float(np.linalg.norm(measured[name].translation() - goal.translation()))
        LOG.debug("%s set down %.3f m from its goal %s", name, offset, goal.translation())
        shape = ctx.model.object(name).shape
        if offset > MISSED_ON_TABLE and offset > missed_distance(shape, goal):
            missed.append((side, name))
    return lost, missed


def knocked(
    ctx: SkillContext,
    measured: dict[str, RigidTransform],
    motion: Motion,
    placed: dict[str, str],
    placements: dict[str, Placement],
) -> list[tuple[str, str]]:
    """The objects knocked away (``(side that set it down, object)``): set down on the table
    top by an earlier motion (``SkillContext.settled``), not handled by `motion`, and now
    farther than :data:`KNOCKED_DISTANCE` from where they came to rest. Brings
    ``SkillContext.settled`` up to date first: what `motion` picked up or set down leaves it;
    what it set down on the table top (`placed`, whose goals `placements` has) joins it, at
    its measured pose."""
    handled = {name for *_, name in motion.events}
    for name in handled:
        ctx.settled.pop(name, None)
    out = [
        (side, name)
        for name, (side, _, X_rest) in ctx.settled.items()
        if name in measured
        and np.linalg.norm(measured[name].translation() - X_rest.translation()) > KNOCKED_DISTANCE
    ]
    for name, side in placed.items():
        goal = placements[name].X_WO_goal
        if name in measured and _on_table_top(ctx.model.object(name).shape, goal):
            ctx.settled[name] = (side, placements[name], measured[name])
    return out


def _on_table_top(shape, X_WO_goal: RigidTransform) -> bool:
    """Whether a placement's goal stands the object on the table top itself."""
    from bicoord_drake.models.scene import ON_TABLE_TOP_TOLERANCE, TABLE_TOP
    from bicoord_drake.planning.grasps import bottom_offset

    bottom = X_WO_goal.translation()[2] - bottom_offset(shape)
    return abs(bottom - TABLE_TOP) < ON_TABLE_TOP_TOLERANCE


def missed_distance(shape, X_WO_goal: RigidTransform) -> float:
    """How far (m) from its placement's goal an object may rest and still count as set down
    there: :data:`MISSED_ON_TABLE` for a goal on the table top (it lands within a few mm),
    otherwise :data:`MISSED_PLACEMENT` plus the object's :func:`reach` (set into a holder or
    onto another object, it may tip or slide by about that much)."""
    if _on_table_top(shape, X_WO_goal):
        return MISSED_ON_TABLE
    return MISSED_PLACEMENT + reach(shape)


def reach(shape) -> float:
    """How far (m) the shape reaches from its frame's origin (its collision primitives'
    vertices): an object set down in a holder or on a slope may tip or slide by up to
    about that much from where it was let go, and still lie where it was put."""
    points = [p.trimesh().vertices for p in shape.primitives()]
    return float(np.max(np.linalg.norm(np.concatenate(points), axis=1)))


def recover_drops(
    ctx: SkillContext,
    view: WorldView,
    run: Runner,
    lost: list[tuple[str, str]],
    missed: list[tuple[str, str]],
    placements: dict[str, Placement],
) -> Iterator[np.ndarray]:
    """Pick up each lost object again with its hand, and pick up and re-place each missed
    placement (with its own hand, or the other one if that is free and its own is not);
    yields the actions, ending with the context synced to the world. Where the other arm is
    in the way of a pick, it goes home first."""
    names = [name for _, name in lost + missed]
    yield from _let_go(ctx, [side for side, _ in lost])
    yield from _wait_at_rest(ctx, view, names)
    measured = view.object_transforms()
    for name in names:
        X = measured[name]
        LOG.info(
            "step %d: %s fell; at rest at %s, its z axis %s",
            view.steps,
            name,
            np.round(X.translation(), 3).tolist(),
            np.round(X.rotation().matrix()[:, 2], 2).tolist(),
        )
        frame = resting_frame(ctx.model.object(name).shape, X)
        if frame is not None:
            ctx.frames[name] = frame
    for side, name in lost:
        ctx.model.detach(side, X_WO=ctx.modelled(measured)[name])
    ctx.sync(ctx.q, object_poses=measured)
    yield from _backed_off(ctx, run)
    for side, name in lost:
        yield from _pick_up(ctx, run, side, lambda side=side, name=name: _pick(ctx, side, name))
    for side, name in missed:
        hand = _free_hand(ctx, side, name)
        placement = placements[name]

        def again(hand=hand, name=name, placement=placement):
            return _pick(ctx, hand, name).then(placement.redo(ctx, hand))

        yield from _pick_up(ctx, run, hand, again)
    view.note_recovered()


def recover_knocks(
    ctx: SkillContext,
    view: WorldView,
    run: Runner,
    knocks: list[tuple[str, str]],
    missed: list[tuple[str, str]],
    placements: dict[str, Placement],
) -> Iterator[np.ndarray]:
    """Pick up each knocked object (:func:`knocked`) and place it again, then each of the
    motion's `missed` placements (what was set down on a knocked object), as
    :func:`recover_drops` does; `placements` has the missed ones' goals. Where that cannot be
    planned (no free hand, no grasp of it as it lies), the expert carries on without them:
    whether the task is still done is the stage monitor's to say."""
    goals = {**placements, **{name: ctx.settled.pop(name)[1] for _, name in knocks}}
    try:
        yield from recover_drops(ctx, view, run, [], knocks + missed, goals)
    except PlanningError as err:
        LOG.info("%s; the expert carries on without it", err)
        poses = view.object_transforms()
        ctx.sync(ctx.q, object_poses=poses)
        ctx.refresh_grasps(poses)


def resting_frame(shape, X_WB: RigidTransform) -> RigidTransform | None:
    """For a box that fell on another face: the frame, among the box's symmetries (its axes
    permuted and turned where the sides they swap are equal: every face of a cube), whose z
    axis points most nearly up, in the body's frame, so the model can pick it up and set it
    down as if it lay the right way up (where the tasks ask only for where it is, as for
    jigsaw's cells); None for other shapes or where the body's own frame is best."""
    from itertools import permutations, product

    from pydrake.all import RigidTransform, RotationMatrix

    from bicoord_drake.models.shapes import BoxShape

    if not isinstance(shape, BoxShape):
        return None
    size = np.asarray(shape.size, dtype=float)
    R_WB = X_WB.rotation().matrix()
    best, best_up = None, R_WB[2, 2] + 1e-9
    for perm in permutations(range(3)):
        if not np.allclose(size[list(perm)], size, atol=1e-9):
            continue
        for signs in product((1.0, -1.0), repeat=3):
            P = np.zeros((3, 3))
            for j, (i, sgn) in enumerate(zip(perm, signs, strict=True)):
                P[i, j] = sgn  # model axis j is body axis i (times sgn)
            if np.linalg.det(P) < 0:
                continue
            up = float((R_WB @ P)[2, 2])
            if up > best_up:
                best, best_up = P, up
    return None if best is None else RigidTransform(RotationMatrix(best), np.zeros(3))


def _pick(ctx: SkillContext, side: str, name: str):
    """`side` picks fallen `name` up: the task's own way (``SkillContext.picker``) or
    :func:`~bicoord_drake.planning.skills.pick` with generated grasps, the jaw opening on the
    way down."""
    from bicoord_drake.planning.skills import pick

    if ctx.picker is not None:
        plan = ctx.picker(side, name)
    else:
        plan = pick(ctx, side, name, lift=RECOVERY_LIFT, approach_opening=1.0)
    plan.label = f"recover: pick {name} again"
    return plan


def _let_go(ctx: SkillContext, sides: list[str]) -> Iterator[np.ndarray]:
    """Open the hands of `sides` (gently, arms still): a hand whose grasp was lost still
    commands its grip, and would close on what slipped and jammed between its fingers."""
    from bicoord_drake.planning.skills import grip

    for side in sides:
        opened = grip(ctx, side, 1.0, gentle=True, label="recover: let go")
        yield from _alone(ctx, side, opened).actions()


def _backed_off(ctx: SkillContext, run: Runner) -> Iterator[np.ndarray]:
    """Raise straight up by :data:`BACK_OFF` each hand that is closer to the scene (a fallen
    object, the table) than the planning clearance, so the recovery's plans start free: a
    Cartesian track (planned with the other arm where it stands), which may start in a shallow
    contact and leave it; where the contact is deeper, with the touched objects left out of
    the check (the hand moves away from them)."""
    from pydrake.all import RigidTransform

    from bicoord_drake.planning.skills.tracking import track

    with ctx.model.padded(ctx.clearance, ctx.env_clearance):
        pairs = ctx.model.colliding_pairs(ctx.q)
    for side in SIDES:
        arm = f"{side}_arm/"
        # (robot body, what it is too close to): the scene, not an arm
        touched = {b for a, b, _ in pairs if a.startswith(arm) and "_arm/" not in b}
        if not touched:
            continue
        X = ctx.model.tcp_pose(ctx.q, side)

        def up(s: float, X=X) -> RigidTransform:
            return RigidTransform(X.rotation(), X.translation() + [0.0, 0.0, s * BACK_OFF])

        LOG.info("the %s hand starts against %s; it backs off first", side, sorted(touched))
        try:
            with ctx.transaction():
                plan = track(ctx, side, up, BACK_OFF, 0.0, label="recover: back off")
        except PlanningError:
            objects = sorted(touched & {o.name for o in ctx.model.scene.objects})
            plan = track(ctx, side, up, BACK_OFF, 0.0, label="recover: back off", ignore=objects)
        yield from run(_alone(ctx, side, plan))


def _pick_up(ctx: SkillContext, run: Runner, side: str, plan: Callable) -> Iterator[np.ndarray]:
    """Run `plan()` (a plan of `side`) with the other arm still; where it cannot be planned
    (the other arm in the way), the other arm first goes home, then it is planned again."""
    from bicoord_drake.planning.skills import merge, retreat

    try:
        with ctx.transaction():
            motion = merge(ctx, *_arranged(side, plan()))
    except PlanningError as err:
        other = other_side(side)
        home = ctx.model.home[ctx.model.side_slice(other)]
        if np.allclose(ctx.arm_q(other), home):
            raise
        LOG.info("%s; the %s arm stands aside first", err, other)
        yield from run(merge(ctx, *_arranged(other, retreat(ctx, other))))
        motion = merge(ctx, *_arranged(side, plan()))
    yield from run(motion)


def _arranged(side: str, plan, other=None):
    """(left, right): `plan` on its side, `other` on the other (None: that arm holding, for
    :func:`merge`)."""
    return (plan, other) if side == "left" else (other, plan)


def _alone(ctx: SkillContext, side: str, plan) -> Motion:
    """`plan` of `side` with the other arm holding where it stands, unchecked
    (:func:`~bicoord_drake.planning.skills.combine`: for a plan made beside the other arm)."""
    from bicoord_drake.planning.skills import combine, hold

    return combine(*_arranged(side, plan, hold(ctx, other_side(side), 0)))


def _free_hand(ctx: SkillContext, side: str, name: str) -> str:
    """The hand that picks up fallen `name`: `side` unless it holds something and the other
    hand is free."""
    held = ctx.model.held
    if side not in held:
        return side
    other = other_side(side)
    if other not in held:
        return other
    raise PlanningError(
        "recovery_failed", f"both hands hold something; none can pick up fallen {name!r}"
    )


def _wait_at_rest(ctx: SkillContext, view: WorldView, names: list[str]) -> Iterator[np.ndarray]:
    """Both arms hold still (as commanded now) until every object of `names` is at rest, at
    most REST_WAIT seconds."""
    from bicoord_drake.planning.skills import hold_still

    action = hold_still(ctx, ctx.dt).actions()[0]
    steps = max(1, int(np.ceil(REST_WAIT / ctx.dt)))
    before = view.object_poses()
    for _ in range(steps):
        yield action
        now = view.object_poses()
        speeds = [np.linalg.norm(now[n][:3] - before[n][:3]) / ctx.dt for n in names]
        before = now
        if max(speeds) < REST_SPEED:
            return

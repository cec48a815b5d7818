"""Pick and place: grasp an object and lift it, set it down at a pose, steady it, let go.

:func:`pick` tries grasp candidates (generated, or given for a part of a compound object)
until one plans; :func:`place` tries the object's symmetric yaws about the goal;
:func:`drop_into` lets the held object fall into a container from just above its rim;
:func:`carry_above` brings the held object over a goal and stops there (a place in two halves,
so the other arm can work below or finish first);
:func:`stabilize` grasps an object where it stands and keeps still; :func:`release` opens
the gripper where it is and backs off.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, replace

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.planning.clearance import HandRoom, roomy_first
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    GraspParams,
    Place,
    arm_base,
    bottom_offset,
    grasp_candidates,
    place_candidates,
    slid_grasps,
    top_offset,
)
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills.arm import grip, move, move_tcp, solve_tcp, tcp_deviation
from bicoord_drake.planning.skills.core import ArmPlan, SkillContext, hold

#: Grasp candidates tried per pick before giving up.
MAX_GRASP_TRIES = 6
#: Largest TCP deviation (m) from a straight line allowed on the straight joint moves of a
#: pick or place (descend, lift, lower, back off).
MAX_LINE_DEVIATION = 0.02


def pick(
    ctx: SkillContext,
    side: str,
    name: str,
    *,
    lift: float = 0.10,
    kinds: Sequence[str] | None = None,
    grasps: Sequence[Grasp] | None = None,
    approach_opening: float | None = None,
    close_opening: float = 0.0,
    grasp_clearance: float | None = None,
    then: Callable[[], ArmPlan] | None = None,
) -> ArmPlan:
    """Approach, grasp and lift object `name` with `side`; it is attached afterwards.

    `grasps` (best first) replaces the generated candidates, e.g. for one part of a
    compound object. With `approach_opening` the jaw narrows to that opening during the
    approach (so a finger entering a container stays by its wall). The gripper closes to
    the command `close_opening` (default fully closed: the fingers squeeze the object as hard
    as their stiffness and force limit let them). `grasp_clearance` (m) replaces the
    environment clearance the hand keeps at the grasp pose itself (default
    ``ctx.env_clearance``), e.g. a smaller one for an object lying close to a wall. `then`
    plans what must follow the lift from each grasp (the object held); its plan is appended,
    and where it raises a PlanningError everything it and the grasp changed is rolled back
    (:meth:`SkillContext.transaction`) and the next grasp is tried."""
    X_WO = ctx.model.object_pose(name)
    if grasps is None:
        base = arm_base(ctx.model.embodiment, side)
        grasps = grasp_candidates(
            ctx.model.object(name),
            ctx.model.embodiment.arm.gripper,
            X_WO=X_WO,
            base=base,
            kinds=kinds,
            params=hand_params(ctx),
        )
    grasps = roomy_grasps(ctx, side, name, grasps)
    reasons = []
    for grasp in grasps[:MAX_GRASP_TRIES]:
        try:
            q_pre, q_grasp, q_lift = _grasp_keyframes(ctx, side, name, grasp, lift, grasp_clearance)
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        saved = (ctx.q.copy(), dict(ctx.opening))
        try:
            with ctx.transaction() if then is not None else nullcontext():
                approach, descend, close, up = _grasp_moves(
                    ctx, side, name, (q_pre, q_grasp, q_lift), approach_opening, close_opening
                )
                follow = [then()] if then is not None else []
        except PlanningError as err:
            if side in ctx.model.held:
                ctx.model.detach(side, X_WO=X_WO)
            ctx.q, ctx.opening = saved
            reasons.append(err.reason)
            continue
        plan = approach.then(descend, close, up)
        plan.events.append(
            (approach.num_steps + descend.num_steps + close.num_steps - 3, "attach", name)
        )
        if follow:  # after the lift as planned (a zero lift adds no sample to follow on)
            plan = plan.then(*follow)
        plan.label = f"pick {name}"
        return plan
    raise PlanningError(
        "pick_failed",
        f"{side} cannot pick {name!r}: tried "
        f"{min(len(grasps), MAX_GRASP_TRIES)} grasps ({', '.join(reasons)})",
    )


def _grasp_moves(
    ctx: SkillContext,
    side: str,
    name: str,
    keyframes: tuple[np.ndarray, np.ndarray, np.ndarray],
    approach_opening: float | None,
    close_opening: float,
) -> tuple[ArmPlan, ArmPlan, ArmPlan, ArmPlan]:
    """The approach, descent, closing and lift of one grasp through its (pregrasp, grasp,
    lift) joint keyframes; the object is attached at the closing."""
    q_pre, q_grasp, q_lift = keyframes
    approach = move(ctx, side, q_pre, label="approach")
    if approach_opening is not None:  # narrow the jaw on the way, not after
        ramp = np.clip(np.arange(approach.num_steps) / ctx.gripper_steps, 0, 1)
        approach.opening = approach.opening + ramp * (approach_opening - approach.opening)
        ctx.opening[side] = approach_opening
    descend = move(ctx, side, q_grasp, label="descend", ignore=[name], straight=True)
    close = grip(ctx, side, close_opening, label="close")
    ctx.model.attach(name, side, ctx.q)
    up = move(ctx, side, q_lift, label="lift", ignore=[name], straight=True)
    return approach, descend, close, up


def hand_params(ctx: SkillContext, params: GraspParams | None = None) -> GraspParams:
    """`params` with the side clearance raised to what the embodiment's hand needs: a
    horizontal grasp keeps the hand (``ArmSpec.hand_half_height``) the environment clearance
    above the support."""
    params = GraspParams() if params is None else params
    need = round(ctx.model.embodiment.arm.hand_half_height() + ctx.env_clearance, 4)
    return replace(params, side_clearance=max(params.side_clearance, need))


def wall_close_opening(ctx: SkillContext, thickness: float) -> float:
    """The closing command of a grip across a wall `thickness` m thick (a bowl's or a plate's
    rim): the jaw gap is the wall less one pad thickness, so the finger servo presses each
    compliant pad at most half its thickness into the wall. A pad pressed past its middle
    holds a rigid wall: opening then drags the object along, and backing off lifts it (the
    Franka Hand closed fully, its fingers stroking to 0, 3 mm pads). Fully closed (0) where
    that gap is past the fingers' stroke: the ViperX's fingers stop 4 mm from the middle, so
    its command on a 9-12 mm wall stays 0."""
    gripper = ctx.model.embodiment.arm.gripper
    return gripper.opening_for_gap(thickness - gripper.pad_thickness)


def pick_sliding(
    ctx: SkillContext,
    side: str,
    name: str,
    grasps: Sequence[Grasp],
    slides: Sequence[float],
    *,
    prepare: Callable[[], None] = lambda: None,
    **pick_args,
) -> ArmPlan:
    """:func:`pick` with `grasps`; where none of them plans (a wide hand's housing over a wall
    or a neighbour), the same grasps slid along the object by each of `slides` (m, either way,
    :func:`~bicoord_drake.planning.grasps.slid_grasps`) where the pads stay a pad's height
    inside its ends. `prepare` runs before each attempt (e.g. setting the model's fingers)."""
    prepare()
    try:
        with ctx.transaction():
            return pick(ctx, side, name, grasps=grasps, **pick_args)
    except PlanningError as err:
        shape = ctx.model.object(name).shape
        pts = np.concatenate([p.trimesh().vertices for p in shape.primitives()])
        pad = ctx.model.embodiment.arm.gripper.pad_height
        others = slid_grasps(grasps, ctx.model.object_pose(name), pts, slides, pad)
        if not others:
            raise
        prepare()
        try:
            return pick(ctx, side, name, grasps=others, **pick_args)
        except PlanningError as slid_err:
            raise PlanningError(
                "pick_failed", f"{err}; slid along it (SLIDES): {slid_err}"
            ) from slid_err


def roomy_grasps(
    ctx: SkillContext, side: str, name: str, grasps: Sequence[Grasp], ignore: Iterable[str] = ()
) -> list[Grasp]:
    """`grasps` (best first) with those whose hand, at the grasp or the pregrasp, comes
    closer to a neighbour or the other arm than the clearances (:class:`HandRoom`) moved
    behind the others: a wide hand's tries go to grasps with room first."""
    room = HandRoom(ctx.model, side, ctx.q, exclude=[name, *ignore])
    margins = [room.margin((g.X_WG, g.X_WPre), ctx.env_clearance, ctx.clearance) for g in grasps]
    return roomy_first(list(grasps), margins)


def roomy_places(
    ctx: SkillContext, side: str, cands: Sequence[Place], ignore: Iterable[str] = ()
) -> list[Place]:
    """Place candidates (best first) with those whose hand, at the release or above it,
    comes closer to a neighbour or the other arm than the clearances (:class:`HandRoom`; the
    release pose itself needs no environment margin, as its IK) moved behind the others."""
    room = HandRoom(ctx.model, side, ctx.q, exclude=ignore)
    margins = [
        min(
            room.margin((c.X_WG,), 0.0, ctx.clearance),
            room.margin((c.X_WPre,), ctx.env_clearance, ctx.clearance),
        )
        for c in cands
    ]
    return roomy_first(list(cands), margins)


def _grasp_keyframes(
    ctx: SkillContext,
    side: str,
    name: str,
    grasp: Grasp,
    lift: float,
    grasp_clearance: float | None = None,
):
    q_pre = solve_tcp(ctx, side, TcpTarget(grasp.X_WPre))
    q_grasp = solve_tcp(
        ctx,
        side,
        TcpTarget(grasp.X_WG),
        seed_arm=q_pre,
        ignore=[name],
        env_clearance=grasp_clearance,
    )
    X_lift = RigidTransform(grasp.X_WG.rotation(), grasp.X_WG.translation() + [0, 0, lift])
    q_lift = solve_tcp(ctx, side, TcpTarget(X_lift), seed_arm=q_grasp, ignore=[name])
    _check_straight(ctx, side, (q_pre, q_grasp, q_lift), ("descend", "lift"))
    return q_pre, q_grasp, q_lift


def _check_straight(ctx: SkillContext, side: str, qs, labels) -> None:
    """Raise unless each straight joint move between consecutive `qs` keeps the TCP within
    MAX_LINE_DEVIATION of a straight line (an IK branch switch sweeps an arc)."""
    for (a, b), label in zip(zip(qs[:-1], qs[1:], strict=True), labels, strict=True):
        dev = tcp_deviation(ctx, side, a, b)
        if dev > MAX_LINE_DEVIATION:
            raise PlanningError(
                "not_straight", f"{side} {label}: the TCP leaves its line by {dev * 100:.1f} cm"
            )


@dataclass(frozen=True)
class Placement:
    """How :func:`place` set an object down: its goal pose and settings, so the placement can
    be done again (:meth:`redo`) by a hand that picked the object up after it fell."""

    X_WO_goal: RigidTransform
    settings: dict

    def redo(self, ctx: SkillContext, side: str) -> ArmPlan:
        """:func:`place` with this goal and these settings, by `side` (which holds the object)."""
        return place(ctx, side, self.X_WO_goal, **self.settings)


def place(
    ctx: SkillContext,
    side: str,
    X_WO_goal: RigidTransform,
    *,
    approach_height: float = 0.06,
    retreat: float = 0.06,
    ignore: Iterable[str] = (),
    opening: float = 1.0,
    gentle_release: bool = False,
    yaws: Sequence[float] | None = None,
    settle: float = 0.0,
) -> ArmPlan:
    """Carry the held object above `X_WO_goal`, lower it there, release and back off.

    The object's symmetric yaws about the goal (or `yaws`, rad) are tried, most natural
    first. The gripper opens to `opening` (less than 1 inside a container, so the fingers miss
    its walls), with `gentle_release` slowly (:func:`~bicoord_drake.planning.skills.arm.grip`: a
    light object set on a small support, which a fast release can flick off). With `settle` the
    arm holds still that many seconds, gripper closed, between lowering and releasing (the arm's
    servos catch up with the end of the lowering before the fingers let go)."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to place")
    ignore = list(ignore)
    shape = ctx.model.object(held.name).shape
    base = arm_base(ctx.model.embodiment, side)
    reasons = []
    # The model keeps held poses in the gripper link frame; grasps.py works in the TCP frame.
    X_TO = RigidTransform([-ctx.model.embodiment.arm.gripper.tcp_x, 0, 0]) @ held.X_GO
    cands = place_candidates(X_TO, X_WO_goal, shape, base=base, lift=approach_height, yaws=yaws)
    for cand in roomy_places(ctx, side, cands, ignore):
        try:
            q_above = solve_tcp(ctx, side, TcpTarget(cand.X_WPre), ignore=ignore)
            q_place = solve_tcp(
                ctx,
                side,
                TcpTarget(cand.X_WG),
                seed_arm=q_above,
                ignore=ignore + [held.name],
                env_clearance=0.0,
            )
            X_away = RigidTransform(cand.X_WG.rotation(), cand.X_WG.translation() + [0, 0, retreat])
            q_away = solve_tcp(ctx, side, TcpTarget(X_away), seed_arm=q_place, ignore=[held.name])
            _check_straight(ctx, side, (q_above, q_place, q_away), ("lower", "back off"))
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        plan = _place_moves(
            ctx,
            side,
            held.name,
            cand.X_WO,
            q_above,
            q_place,
            q_away,
            ignore,
            opening,
            gentle_release,
            settle,
        )
        ctx.placements[held.name] = Placement(
            X_WO_goal,
            dict(
                approach_height=approach_height,
                retreat=retreat,
                ignore=tuple(ignore),
                opening=opening,
                gentle_release=gentle_release,
                yaws=None if yaws is None else tuple(yaws),
                settle=settle,
            ),
        )
        return plan
    raise PlanningError(
        "place_failed",
        f"{side} cannot place {held.name!r} at "
        f"{np.round(X_WO_goal.translation(), 3)} ({', '.join(reasons)})",
    )


def drop_into(
    ctx: SkillContext,
    side: str,
    container: str,
    *,
    offset_xy: Sequence[float] = (0.0, 0.0),
    fall: float = 0.03,
    lower: float = 0.04,
    retreat: float = 0.05,
    yaws: Sequence[float] = tuple(k * np.pi / 4 for k in range(8)),
    gentle_release: bool = False,
) -> ArmPlan:
    """Carry the held object over the opening of `container`, lower it until its bottom is
    `fall` (m) above the rim (below it if negative: lowered into the container, from `lower`
    above that), let go and back off up: the object falls the last few cm (a bin
    is filled this way; nothing is set down inside it). The drop point is the container's
    centre shifted by `offset_xy` in the world; the object stays upright, turned by each of
    `yaws` about the container's axes (most natural first: the wrist turns least).
    `gentle_release` as :func:`place`."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to drop")
    X_WC = ctx.model.object_pose(container)
    rim = X_WC.translation()[2] + top_offset(ctx.model.object(container).shape)
    shape = ctx.model.object(held.name).shape
    xy = X_WC.translation()[:2] + np.asarray(offset_xy, dtype=float)
    z = rim + fall + bottom_offset(shape) + _bottom_below_frame(shape)
    goal = RigidTransform(X_WC.rotation(), [xy[0], xy[1], z])
    plan = place(
        ctx,
        side,
        goal,
        approach_height=lower,
        retreat=retreat,
        yaws=yaws,
        gentle_release=gentle_release,
    )
    plan.label = f"drop {held.name} into {container}"
    # It lands below where it was let go (and may roll in the container): no placement for
    # a recovery to compare with or to do again (bicoord_drake.tasks.recovery).
    ctx.placements.pop(held.name, None)
    return plan


def _bottom_below_frame(shape) -> float:
    """How far the shape's lowest point lies below its frame beyond ``bottom_offset``
    (a compound whose frame is on its bottom: 0)."""
    lo = min(p.trimesh().bounds[0][2] for p in shape.primitives())
    return max(0.0, -lo - bottom_offset(shape))


def carry_above(
    ctx: SkillContext,
    side: str,
    X_WO_goal: RigidTransform,
    *,
    height: float = 0.06,
    ignore: Iterable[str] = (),
) -> ArmPlan:
    """Carry the held object to `height` (m) straight above `X_WO_goal` and stop there, still
    held; the object's symmetric yaws about the goal are tried, most natural first (as
    :func:`place` does, so a later ``place`` at the same goal starts right above it)."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to carry")
    shape = ctx.model.object(held.name).shape
    base = arm_base(ctx.model.embodiment, side)
    X_TO = RigidTransform([-ctx.model.embodiment.arm.gripper.tcp_x, 0, 0]) @ held.X_GO
    reasons = []
    ignore = list(ignore)
    cands = place_candidates(X_TO, X_WO_goal, shape, base=base, lift=height)
    for cand in roomy_places(ctx, side, cands, ignore):
        try:
            q_above = solve_tcp(ctx, side, TcpTarget(cand.X_WPre), ignore=list(ignore))
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        plan = move(ctx, side, q_above, label=f"carry {held.name} above", ignore=list(ignore))
        plan.label = f"carry {held.name} above {np.round(X_WO_goal.translation(), 3).tolist()}"
        return plan
    raise PlanningError(
        "carry_failed",
        f"{side} cannot hold {held.name!r} {height} m above "
        f"{np.round(X_WO_goal.translation(), 3)} ({', '.join(reasons)})",
    )


def carry_margin(
    ctx: SkillContext,
    side: str,
    X_WO_goal: RigidTransform,
    *,
    height: float = 0.06,
    ignore: Iterable[str] = (),
) -> float:
    """How much room (m, :class:`HandRoom` margin; negative: too little) the hand of `side`
    has with its held object `height` above `X_WO_goal`, at the roomiest of the object's
    symmetric yaws: a cheap way to rank several candidate goals before planning any (no IK)."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to carry")
    shape = ctx.model.object(held.name).shape
    X_TO = RigidTransform([-ctx.model.embodiment.arm.gripper.tcp_x, 0, 0]) @ held.X_GO
    room = HandRoom(ctx.model, side, ctx.q, exclude=ignore)
    cands = place_candidates(X_TO, X_WO_goal, shape, lift=height)
    return max(room.margin((c.X_WPre,), ctx.env_clearance, ctx.clearance) for c in cands)


def _place_moves(
    ctx: SkillContext,
    side,
    name,
    X_WO,
    q_above,
    q_place,
    q_away,
    ignore,
    opening=1.0,
    gentle_release=False,
    settle=0.0,
) -> ArmPlan:
    carry = move(ctx, side, q_above, label="carry", ignore=ignore)
    lower = move(ctx, side, q_place, label="lower", ignore=ignore + [name], straight=True)
    if ctx.steps(settle) > 0:
        lower = lower.then(hold(ctx, side, settle, label="settle"))
    opened = grip(ctx, side, opening, label="release", gentle=gentle_release)
    ctx.model.detach(side, X_WO=X_WO)
    back = move(ctx, side, q_away, label="back off", ignore=ignore + [name], straight=True)
    plan = carry.then(lower, opened, back)
    plan.events.append((carry.num_steps + lower.num_steps - 2, "detach", name))
    plan.label = f"place {name}"
    return plan


def stabilize(
    ctx: SkillContext, side: str, name: str, *, kinds: Sequence[str] | None = None
) -> ArmPlan:
    """Grasp object `name` where it is and keep still with the gripper closed on it.

    The object is attached to `side` (it rides with that gripper in the planning model), so
    the other arm can work around it; a merged motion holds this arm's last sample for as
    long as the other arm needs. :meth:`release` lets go."""
    X_WO = ctx.model.object_pose(name)
    plan = pick(ctx, side, name, lift=0.0, kinds=kinds)
    plan.label = f"stabilize {name}"
    # It still rests on its support: the model keeps it a hair above, so that the other
    # arm's planning does not see the support touching this arm.
    lift = np.array([0.0, 0.0, ctx.env_clearance + 0.001])
    ctx.model.detach(side, X_WO=X_WO)
    ctx.model.attach(name, side, ctx.q, RigidTransform(X_WO.rotation(), X_WO.translation() + lift))
    ctx.stabilized[side] = lift
    return plan


def release(ctx: SkillContext, side: str, *, back: float = 0.06, label: str = "release") -> ArmPlan:
    """Open the gripper where it is, leave the object there and back off `back` (m) along
    the approach axis."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds nothing to release")
    X_WO = ctx.model.held_pose(side, ctx.q)
    lift = ctx.stabilized.pop(side, None)
    if lift is not None:
        X_WO = RigidTransform(X_WO.rotation(), X_WO.translation() - lift)
    opened = grip(ctx, side, 1.0, label="open")
    ctx.model.detach(side, X_WO=X_WO)
    X = ctx.model.tcp_pose(ctx.q, side)
    X_back = RigidTransform(X.rotation(), X.translation() - back * X.rotation().col(0))
    away = move_tcp(ctx, side, X_back, label="back off", ignore=[held.name], straight=True)
    plan = opened.then(away)
    plan.events.append((opened.num_steps - 1, "detach", held.name))
    plan.label = f"{label} {held.name}"
    return plan

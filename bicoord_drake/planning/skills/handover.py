"""Handover: one arm gives what it holds to the other in mid-air.

Both arms move at once and arrive at the meeting at the same control step (a
:func:`~bicoord_drake.planning.timing.rendezvous`); the receiver closes, then the giver opens
and backs off. Where the object is turned at the meeting and how the receiver grasps it are
options: by default the object keeps the giver's orientation (turned by its symmetric yaws)
and the receiver grasps across another axis (:func:`crossing_grasps`); a task with a special
object passes its own ``orientations`` and ``receiver_grasps`` (exchange_mics: a mic handed
over by its head is taken by the handle).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import replace

import numpy as np
from pydrake.all import RigidTransform, RotationMatrix

from bicoord_drake.models.objects import BoxShape
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    arm_base,
    grasp_candidates,
    naturalness,
    symmetric_yaws,
)
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.motion import plan_path
from bicoord_drake.planning.skills.arm import grip, move_tcp
from bicoord_drake.planning.skills.core import Motion, SkillContext
from bicoord_drake.planning.skills.shapes import half_extent
from bicoord_drake.planning.timing import JointLimits, rendezvous, time_path

#: The receiver's grasps of the object at a meeting, best first, given the object's pose there
#: and the giver's TCP pose there. Each grasp's ``X_WG`` and ``X_WPre`` are used as they are.
ReceiverGrasps = Callable[[RigidTransform, RigidTransform], Iterable[Grasp]]

#: Receiver pregrasp: this far back (m) along its approach from the grasp.
PREGRASP_DISTANCE = 0.08


def fingers_cross(X_WG: RigidTransform, X_WTg: RigidTransform) -> bool:
    """Whether a receiver grasp `X_WG` closes its fingers across the giver's (TCP `X_WTg`):
    the finger axes are at least about 72 degrees apart."""
    return abs(X_WG.rotation().matrix()[:, 1] @ X_WTg.rotation().matrix()[:, 1]) <= 0.3


def crossing_grasps(
    ctx: SkillContext,
    name: str,
    receiver: str,
    *,
    kinds: Sequence[str] = ("side", "top"),
    tip_margin: float = 0.003,
) -> ReceiverGrasps:
    """The default receiver grasps of object `name`: generated candidates of `kinds` whose
    fingers cross the giver's and that do not come from the giver's side, pushed in until the
    fingertips stop `tip_margin` (m) short of the far face, with the pregrasp
    PREGRASP_DISTANCE back along the approach."""
    obj = ctx.model.object(name)
    gripper = ctx.model.embodiment.arm.gripper
    base = arm_base(ctx.model.embodiment, receiver)

    def grasps(X_WO: RigidTransform, X_WTg: RigidTransform) -> Iterator[Grasp]:
        Rg = X_WTg.rotation().matrix()
        for grasp in grasp_candidates(obj, gripper, X_WO=X_WO, base=base, kinds=list(kinds)):
            Rr = grasp.X_WG.rotation().matrix()
            if abs(Rr[:, 1] @ Rg[:, 1]) > 0.3 or Rr[:, 0] @ Rg[:, 0] > 0.5:
                continue  # same finger axis, or coming from the giver's side
            a = Rr[:, 0]
            reach = half_extent(obj.shape, X_WO.rotation().matrix(), a)
            tip = (grasp.X_WG.translation() - X_WO.translation()) @ a + gripper.pad_length / 2
            shift = max(0.0, tip - reach + tip_margin)
            X_WG = RigidTransform(grasp.X_WG.rotation(), grasp.X_WG.translation() - shift * a)
            X_pre = RigidTransform(X_WG.rotation(), X_WG.translation() - PREGRASP_DISTANCE * a)
            yield replace(grasp, X_WG=X_WG, X_WPre=X_pre, X_OG=X_WO.inverse() @ X_WG)

    return grasps


def handover(
    ctx: SkillContext,
    giver: str,
    receiver: str,
    *,
    meet: Sequence[float] = (0.0, -0.05, 0.95),
    clearance: float = 0.005,
    retreat: float = 0.06,
    kinds: Sequence[str] = ("side", "top"),
    tip_margin: float = 0.003,
    orientations: Sequence[RotationMatrix] | None = None,
    receiver_grasps: ReceiverGrasps | None = None,
    grip_half_width: float | None = None,
) -> Motion:
    """Hand the object held by `giver` to `receiver` in mid-air at `meet` (the object frame's
    origin there).

    The object's `orientations` at the meeting are tried most natural for the giver first
    (default: as the giver holds it now, turned by the symmetric yaws of a box). The receiver
    takes the first of `receiver_grasps` (default :func:`crossing_grasps` with `kinds` and
    `tip_margin`) for which both arms reach the meeting with at least `clearance` (m) between
    them. Both arms move at once and arrive at the same control step (:func:`meet_motion`); if
    that collides, the giver arrives first (``info["rendezvous"]`` False). Then the receiver
    closes, the giver opens and backs off `retreat` (m). `grip_half_width` is how far the
    giver's fingers are closed (m from the middle; default: the object's half extent across
    them). ``info`` gives the sample indices of the meeting, the receiver's grip and the
    giver's release, and the receiver's grasp. On failure nothing is changed.
    """
    if giver == receiver:
        raise ValueError("giver and receiver must be different arms")
    held = ctx.model.held.get(giver)
    if held is None:
        raise PlanningError("gripper_empty", f"{giver} holds nothing to hand over")
    if receiver in ctx.model.held:
        raise PlanningError("gripper_busy", f"{receiver} already holds something")
    name, gripper = held.name, ctx.model.embodiment.arm.gripper
    obj = ctx.model.object(name)
    if orientations is None:
        R_WO = (ctx.model.gripper_pose(ctx.q, giver) @ held.X_GO).rotation()
        yaws = symmetric_yaws(obj.shape) if isinstance(obj.shape, BoxShape) else [0.0]
        orientations = [RotationMatrix.MakeZRotation(yaw) @ R_WO for yaw in yaws]
    if receiver_grasps is None:
        receiver_grasps = crossing_grasps(ctx, name, receiver, kinds=kinds, tip_margin=tip_margin)
    if grip_half_width is None:
        grip_half_width = half_extent(obj.shape, held.X_GO.rotation(), [0, 1, 0])
    closed = float(np.clip(gripper.opening(grip_half_width), 0, 1))
    with ctx.transaction():
        ctx.model.set_gripper(giver, closed)  # the giver's fingers really are closed on it
        try:
            q_meet, q_pre, grasp = _meeting(
                ctx,
                giver,
                receiver,
                name,
                orientations,
                np.asarray(meet, float),
                clearance,
                receiver_grasps,
            )
            motion = meet_motion(ctx, giver, receiver, q_meet, q_pre, clearance)
        finally:
            ctx.model.set_gripper(giver, ctx.model.embodiment.home_opening)
        return _exchange(ctx, giver, receiver, name, q_meet, motion, retreat, clearance, grasp)


def _exchange(ctx, giver, receiver, name, q_meet, motion, retreat, clearance, grasp) -> Motion:
    """After the meeting: the receiver closes, the giver opens and backs off."""
    X_WO = ctx.model.held_pose(giver, q_meet)
    ctx.q = q_meet.copy()
    close = grip(ctx, receiver, 0.0, label="receive")
    ctx.model.detach(giver, X_WO=X_WO)
    ctx.model.attach(name, receiver, ctx.q, X_WO)
    opened = grip(ctx, giver, 1.0, label="let go")
    X = ctx.model.tcp_pose(ctx.q, giver)
    X_back = RigidTransform(X.rotation(), X.translation() - retreat * X.rotation().col(0))
    back = move_tcp(
        ctx, giver, X_back, label="back off", ignore=[name], straight=True, clearance=clearance
    )
    rest = ctx.sequence([{receiver: close}, {giver: opened}, {giver: back}], motion)
    i_receive = motion.num_steps + close.num_steps - 2
    i_release = i_receive + opened.num_steps - 1
    rest.events += [(i_receive, receiver, "attach", name), (i_release, giver, "detach", name)]
    rest.events.sort()
    rest.label = f"handover {name} {giver}->{receiver}"
    rest.info.update(
        meet_index=motion.num_steps - 1,
        receive_index=i_receive,
        release_index=i_release,
        receiver_grasp=grasp,
    )
    return rest


def _meeting(ctx, giver, receiver, name, orientations, p_meet, clearance, receiver_grasps):
    """Joint angles at the meeting, the receiver's pregrasp joints and its grasp."""
    held = ctx.model.held[giver]
    X_OT = held.X_GO.inverse() @ RigidTransform([ctx.model.embodiment.arm.gripper.tcp_x, 0, 0])
    base = arm_base(ctx.model.embodiment, giver)
    metas = []
    for R in orientations:
        X_WO = RigidTransform(R, p_meet)
        X_WTg = X_WO @ X_OT
        metas.append((naturalness(X_WTg, base), X_WO, X_WTg))
    metas.sort(key=lambda m: -m[0])
    reasons: list[str] = []
    for _, X_WO, X_WTg in metas:
        for grasp in receiver_grasps(X_WO, X_WTg):
            try:
                q_meet = ctx.ik.solve(
                    {giver: TcpTarget(X_WTg), receiver: TcpTarget(grasp.X_WG)},
                    clearance=clearance,
                    env_clearance=ctx.env_clearance,
                    seed=ctx.q,
                    restarts=4,
                )
                q_pre = ctx.ik.solve_single(
                    receiver,
                    TcpTarget(grasp.X_WPre),
                    q_meet[ctx.model.side_slice(giver)],
                    seed=q_meet,
                    clearance=clearance,
                    env_clearance=ctx.env_clearance,
                    restarts=4,
                )
            except PlanningError as err:
                reasons.append(err.reason)
                continue
            ctx.model.set_padding(clearance * 0.8, 0.0)
            if not ctx.edge_free(q_pre, q_meet):
                reasons.append("approach_in_collision")
                continue
            return q_meet, q_pre, grasp
    raise PlanningError(
        "handover_failed",
        f"no meeting of {giver} and {receiver} at {np.round(p_meet, 3)} for {name!r} "
        f"({', '.join(sorted(set(reasons))) or 'no receiver grasp across the giver'})",
    )


def meet_motion(
    ctx: SkillContext,
    giver: str,
    receiver: str,
    q_meet: np.ndarray,
    q_pre: np.ndarray,
    clearance: float,
) -> Motion:
    """Both arms from where they are to the meeting `q_meet` (the receiver through its
    pregrasp `q_pre`), arriving at the same control step. If that collides, or the receiver's
    pregrasp collides with the giver where it is now, the giver arrives first
    (``info["rendezvous"]`` False); if the giver's meeting pose collides with the receiver
    where it is now, the receiver goes to its pregrasp first (:func:`_receiver_first`). The
    context's state is not advanced."""
    start = ctx.q.copy()
    g_goal = start.copy()
    g_goal[ctx.model.side_slice(giver)] = q_meet[ctx.model.side_slice(giver)]
    r_goal = start.copy()
    r_goal[ctx.model.side_slice(receiver)] = q_pre[ctx.model.side_slice(receiver)]
    try:
        g_path = plan_path(ctx.model, start, g_goal, arms=(giver,), env_clearance=0.0)
    except PlanningError as err:
        if err.reason != "goal_in_collision":
            raise
        return _receiver_first(ctx, giver, receiver, q_meet, q_pre, clearance)
    cols = {side: ctx.model.side_slice(side) for side in (giver, receiver)}
    paths = {giver: g_path[:, cols[giver]]}
    try:
        r_path = plan_path(ctx.model, start, r_goal, arms=(receiver,), env_clearance=0.0)
    except PlanningError as err:  # its pregrasp collides with the giver where it is now
        if err.reason != "goal_in_collision":
            raise
    else:
        r_path = np.vstack([r_path, q_meet[None]])
        paths[receiver] = r_path[:, cols[receiver]]
        limits = JointLimits.concat(ctx.arm_limits, ctx.arm_limits)
        traj = rendezvous(paths["left"], paths["right"], limits, ctx.dt)
        motion = ctx.motion_of(traj, "meet")
        if ctx.checked(motion, clearance * 0.8, 0.0):
            motion.info["rendezvous"] = True
            return motion
    # Fallback: the giver arrives first, then the receiver comes in.
    g_plan = ctx.arm_plan(giver, time_path(paths[giver], ctx.arm_limits, ctx.dt), "give")
    r_path = plan_path(
        ctx.model, g_goal, q_pre, arms=(receiver,), clearance=clearance, env_clearance=0.0
    )
    r_path = np.vstack([r_path, q_meet[None]])[:, cols[receiver]]
    r_plan = ctx.arm_plan(receiver, time_path(r_path, ctx.arm_limits, ctx.dt), "receive")
    motion = ctx.sequence([{giver: g_plan}, {receiver: r_plan}], ctx.still(start))
    if not ctx.checked(motion, clearance * 0.8, 0.0):
        raise PlanningError("arm_conflict", f"{giver} and {receiver} collide on the way")
    motion.info["rendezvous"] = False
    return motion


def _receiver_first(
    ctx: SkillContext,
    giver: str,
    receiver: str,
    q_meet: np.ndarray,
    q_pre: np.ndarray,
    clearance: float,
) -> Motion:
    """The receiver moves to its pregrasp `q_pre` first (out of the giver's way), then the
    giver brings the object to the meeting, then the receiver closes in (wide hands whose
    meeting pose collides with the receiver's present one)."""
    cols = {side: ctx.model.side_slice(side) for side in (giver, receiver)}
    start = ctx.q.copy()
    r_goal = start.copy()
    r_goal[cols[receiver]] = q_pre[cols[receiver]]
    g_goal = r_goal.copy()
    g_goal[cols[giver]] = q_meet[cols[giver]]
    kwargs = {"clearance": clearance, "env_clearance": 0.0}
    r_path = plan_path(ctx.model, start, r_goal, arms=(receiver,), **kwargs)
    g_path = plan_path(ctx.model, r_goal, g_goal, arms=(giver,), **kwargs)
    r_in = np.vstack([q_pre[cols[receiver]], q_meet[cols[receiver]]])
    parts = [
        {
            receiver: ctx.arm_plan(
                receiver, time_path(r_path[:, cols[receiver]], ctx.arm_limits, ctx.dt), "pregrasp"
            )
        },
        {
            giver: ctx.arm_plan(
                giver, time_path(g_path[:, cols[giver]], ctx.arm_limits, ctx.dt), "give"
            )
        },
        {receiver: ctx.arm_plan(receiver, time_path(r_in, ctx.arm_limits, ctx.dt), "receive")},
    ]
    motion = ctx.sequence(parts, ctx.still(start))
    if not ctx.checked(motion, clearance * 0.8, 0.0):
        raise PlanningError("arm_conflict", f"{giver} and {receiver} collide on the way")
    motion.info["rendezvous"] = False
    return motion

"""A drawer (a scene object on a slide joint, ``SceneObject.slide``): grasp its handle, slide
it along the joint axis, let go.

The handle is one box primitive of the drawer's shape (a bar, long along its x). The gripper
comes down on it from above with the fingers across the bar (along its y) and closes; the
drawer is not attached to the hand in the planning model (it moves on its joint, not with the
gripper): :func:`slide_drawer` moves the TCP along the joint axis in a straight line, exactly
at every control sample (:func:`~.tracking.track`), and then puts the drawer's obstacle at the
new joint position (``PlanningModel.set_slide``), so later plans see it where it will be.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import arm_base, gripper_frame, naturalness
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills.arm import grip, move, solve_tcp
from bicoord_drake.planning.skills.core import ArmPlan, SkillContext
from bicoord_drake.planning.skills.tracking import track
from bicoord_drake.sim.station import rigid_transform

#: Jaw clearance (m) each side of the handle bar while the fingers come down around it.
HANDLE_MARGIN = 0.008


def handle_opening(ctx: SkillContext, thickness: float, margin: float = HANDLE_MARGIN) -> float:
    """The opening command whose jaw clears a bar `thickness` (m) thick by `margin` a side."""
    g = ctx.model.embodiment.arm.gripper
    half = thickness / 2 + margin
    return float(np.clip((half - g.finger_min) / (g.finger_max - g.finger_min), 0.0, 1.0))


def handle_grasps(
    ctx: SkillContext, side: str, name: str, part: int, above: float = 0.06
) -> list[tuple[RigidTransform, RigidTransform]]:
    """(X_WG, X_WPre) top grasps of the handle bar (part `part` of `name`'s shape), fingers
    across the bar, TCP at the bar's centre: both finger directions, most natural first;
    the pregrasp `above` (m) higher."""
    prim = ctx.model.object(name).shape.primitives()[part]
    X_WH = ctx.model.object_pose(name) @ rigid_transform(prim.pose)
    across = X_WH.rotation().col(1)
    p = X_WH.translation()
    down = np.array([0.0, 0.0, -1.0])
    base = arm_base(ctx.model.embodiment, side)
    out = []
    for sign in (1.0, -1.0):
        X_WG = gripper_frame(down, sign * across, p)
        X_WPre = RigidTransform(X_WG.rotation(), p + [0.0, 0.0, above])
        out.append((X_WG, X_WPre))
    return sorted(out, key=lambda g: -naturalness(g[0], base))


def grasp_handle(ctx: SkillContext, side: str, name: str, part: int) -> ArmPlan:
    """Come down on the drawer's handle bar from above, the jaw narrowed around it, and close
    (the drawer stays on its joint; the fingers hold the bar)."""
    bar = ctx.model.object(name).shape.primitives()[part]
    opening = handle_opening(ctx, bar.size[1])
    home_opening = ctx.model.embodiment.home_opening
    ctx.model.set_gripper(side, opening)  # planned with the jaw as narrow as it will be
    reasons = []
    for X_WG, X_WPre in handle_grasps(ctx, side, name, part):
        saved = (ctx.q.copy(), dict(ctx.opening))
        try:
            q_pre = solve_tcp(ctx, side, TcpTarget(X_WPre))
            q_grasp = solve_tcp(ctx, side, TcpTarget(X_WG), seed_arm=q_pre, ignore=[name])
            approach = move(ctx, side, q_pre, label="over the handle")
            ramp = np.clip(np.arange(approach.num_steps) / ctx.gripper_steps, 0, 1)
            approach.opening = approach.opening + ramp * (opening - approach.opening)
            ctx.opening[side] = opening
            down = move(
                ctx, side, q_grasp, label="down on the handle", ignore=[name], straight=True
            )
            close = grip(ctx, side, 0.0, label="close on the handle")
        except PlanningError as err:
            ctx.q, ctx.opening = saved
            reasons.append(err.reason)
            continue
        plan = approach.then(down, close)
        plan.label = f"grasp the handle of {name}"
        return plan
    ctx.model.set_gripper(side, home_opening)
    raise PlanningError("handle_unreachable", f"{side} cannot grasp {name}'s handle: {reasons}")


def slide_drawer(
    ctx: SkillContext,
    side: str,
    name: str,
    distance: float,
    *,
    carried: Sequence[str] = (),
    label: str | None = None,
) -> ArmPlan:
    """Move the hand holding `name`'s handle `distance` (m) along its slide axis (positive
    opens, negative closes) in a straight line, orientation kept; the drawer and what it
    `carried` (objects lying in it) are left out of the checks, the cabinet and the rest are
    checked. The planning model's drawer is then at its new joint position (clipped to the
    joint's limits), and the carried objects moved with it."""
    slide = ctx.model.object(name).slide
    if slide is None:
        raise ValueError(f"{name!r} is not on a slide joint")
    start = ctx.model.slide_position(name)
    end = float(np.clip(start + distance, slide.lower, slide.upper))
    if abs(end - start) < 1e-4:
        raise PlanningError("slide_at_limit", f"{name} cannot move {distance:+.3f} m from {start}")
    d = ctx.model.scene.slide_axis(name) * (end - start)
    X = ctx.model.tcp_pose(ctx.q, side)
    p0 = X.translation()

    def pose_at(s: float) -> RigidTransform:
        return RigidTransform(X.rotation(), p0 + s * d)

    text = label or f"{'open' if end > start else 'close'} {name}"
    ignore = [name, *carried]
    plan = track(ctx, side, pose_at, abs(end - start), 0.0, label=text, ignore=ignore)
    ctx.model.set_slide(name, end)
    for other in carried:
        X = ctx.model.object_pose(other)
        ctx.model.set_object_pose(other, RigidTransform(X.rotation(), X.translation() + d))
    return plan


def let_go_handle(
    ctx: SkillContext, side: str, name: str, part: int, rise: float = 0.06
) -> ArmPlan:
    """Open the jaw just clear of the handle bar (a wide jaw would hit the drawer's face) and
    rise straight up `rise` (m). The jaw stays that narrow (in the planning model too) until
    a later grip opens it."""
    bar = ctx.model.object(name).shape.primitives()[part]
    release = grip(ctx, side, handle_opening(ctx, bar.size[1]), label="let go of the handle")
    X = ctx.model.tcp_pose(ctx.q, side)
    up = RigidTransform(X.rotation(), X.translation() + [0.0, 0.0, rise])
    q_up = solve_tcp(ctx, side, TcpTarget(up), seed_arm=ctx.arm_q(side), ignore=[name])
    rise_plan = move(ctx, side, q_up, label="up from the handle", ignore=[name], straight=True)
    plan = release.then(rise_plan)
    plan.label = f"let go of {name}"
    return plan

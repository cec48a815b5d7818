"""Tracking and pushing: the TCP follows a Cartesian path exactly at the control samples.

:func:`track` is the shared machinery (IK at every sample, seeded from the previous one, timed
so that every joint keeps up); :func:`push` moves a held tool's tip down onto a line, along it
in contact, and up again. :mod:`~bicoord_drake.planning.skills.pour` tilts with it too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.embodiment import other_side
from bicoord_drake.models.objects import BoxShape, CylinderShape
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills.arm import move_tcp
from bicoord_drake.planning.skills.core import ArmPlan, SkillContext
from bicoord_drake.planning.timing import JointLimits, time_path

#: Cartesian skills (pour, push): TCP speed (m/s) and rotation rate (rad/s) at speed = 1.
TRACK_SPEED = 0.25
TRACK_ROTATION = 1.2
#: Cartesian skills: the largest joint step (rad) between two samples (more means the IK
#: solution jumped to another branch).
TRACK_MAX_STEP = 0.3
#: Cartesian skills: how deep (m) the measured start may be in contact with the environment
#: (a finger or link pressed into the table by the previous push) and still be tracked, as long
#: as the path never presses deeper into what it touches at the start.
START_CONTACT_DEPTH = 0.002


def track(
    ctx: SkillContext,
    side: str,
    pose_at: Callable[[float], RigidTransform],
    distance: float,
    rotation: float,
    *,
    label: str,
    ignore: Iterable[str] = (),
) -> ArmPlan:
    """Follow the TCP path ``pose_at(s)``, s in [0, 1], exactly at the control samples.

    s is timed by a 1-DoF jerk-limited profile for `distance` (m) and `rotation` (rad) at
    TRACK_SPEED / TRACK_ROTATION (scaled like the joint limits), slowed down until every
    joint stays within its velocity limit; IK runs at every sample, seeded from the
    previous one, and every step between samples is collision-checked."""
    ignore = list(ignore)
    other = other_side(side)
    duration = max(
        distance / (TRACK_SPEED * ctx.speed), rotation / (TRACK_ROTATION * ctx.speed), 0.2
    )
    q_other = ctx.arm_q(other)
    with ctx.model.ignoring(ignore):  # once: entering it costs a filter rebuild
        ctx.model.set_padding(ctx.clearance / 2, 0.0)
        start = deepest_contacts(ctx.model.colliding_pairs(ctx.q))
        start_depth = -min(start.values(), default=0.0)
        if start_depth > START_CONTACT_DEPTH:
            raise PlanningError(
                "start_in_collision",
                f"{label}: the {side} arm starts {start_depth * 1e3:.1f} mm deep",
            )
        q_arm = _track_samples(ctx, side, pose_at, duration, q_other, ignore, label)
        ctx.model.set_padding(ctx.clearance / 2, 0.0)
        q = [ctx.with_arm(side, x) for x in q_arm]
        if not _path_free(ctx, q, start):
            raise PlanningError("path_in_collision", f"{label}: the {side} path collides")
    ctx.q = q[-1].copy()
    return ArmPlan(side, q_arm, np.full(len(q_arm), ctx.opening[side]), label=label)


def deepest_contacts(
    pairs: Iterable[tuple[str, str, float]],
) -> dict[tuple[str, str], float]:
    """(body, other) -> the smallest distance of their contacts in `pairs` (two bodies can
    touch at several of their shapes: the deepest one bounds the pair)."""
    out: dict[tuple[str, str], float] = {}
    for a, b, d in pairs:
        out[(a, b)] = min(d, out.get((a, b), np.inf))
    return out


def _path_free(
    ctx: SkillContext, q: Sequence[np.ndarray], start: dict[tuple[str, str], float]
) -> bool:
    """Whether the sampled path `q` is collision-free (current padding), except for the
    contacts `start` ((body, other) -> distance at q[0], checked by the caller to be at most
    START_CONTACT_DEPTH deep): such a pair may stay in contact along the path, never deeper
    than it began."""
    for a, b in zip(q[:-1], q[1:], strict=True):
        if ctx.edge_free(a, b):
            continue
        if not start:
            return False
        n = max(2, int(np.ceil(np.max(np.abs(b - a)) / 0.01)) + 1)
        for s in np.linspace(0, 1, n):
            for body, other, d in ctx.model.colliding_pairs(a + s * (b - a)):
                if d < start.get((body, other), np.inf) - 1e-4:
                    return False
    return True


def path_parameter(duration: float, dt: float) -> np.ndarray:
    """Samples of a path parameter s from 0 to 1 on the control grid: one jerk-limited
    profile whose top speed is 1 / `duration` (acceleration 6x, jerk 60x that rate)."""
    rate = 1.0 / duration
    s_limits = JointLimits(
        np.zeros(1), np.ones(1), np.array([rate]), np.array([6 * rate]), np.array([60 * rate])
    )
    return time_path(np.array([[0.0], [1.0]]), s_limits, dt).q[:, 0]


def _track_samples(
    ctx: SkillContext, side, pose_at, duration, q_other, ignore, label
) -> np.ndarray:
    """(N, n) joint samples of :meth:`_track`, slowed until the joints keep up."""
    for _ in range(4):
        s = path_parameter(duration, ctx.dt)
        q, prev = [ctx.q.copy()], ctx.q.copy()
        for s_k in s[1:]:
            ctx.track_ik.nominal = prev
            prev = ctx.track_ik.solve_single(
                side,
                TcpTarget(pose_at(float(s_k))),
                q_other,
                seed=prev,
                clearance=ctx.clearance,
                env_clearance=0.0,
                ignore=ignore,
                restarts=3,
            )
            q.append(prev)
        q_arm = np.array(q)[:, ctx.model.side_slice(side)]
        if np.max(np.abs(np.diff(q_arm, axis=0))) > TRACK_MAX_STEP:
            raise PlanningError("track_discontinuous", f"{label}: IK switched branches")
        speed = np.max(np.abs(np.diff(q_arm, axis=0)) / ctx.dt / ctx.arm_limits.velocity)
        if speed <= 1.0:
            return q_arm
        duration *= speed * 1.1
    raise PlanningError("track_too_fast", f"{label}: the joints cannot follow the path")


def push(
    ctx: SkillContext,
    side: str,
    start: Sequence[float],
    end: Sequence[float],
    *,
    tip: Sequence[float] | None = None,
    approach: float = 0.05,
    ignore: Iterable[str] = (),
) -> ArmPlan:
    """Push with the held tool: its `tip` (a point in the tool's frame; default the end of
    its long axis that leads in the push direction) goes down onto `start` from `approach`
    (m) above, along the straight line to `end` in contact, and up again. The tool keeps
    its orientation; objects in `ignore` (what is pushed) are not collision-checked."""
    held = ctx.model.held.get(side)
    if held is None:
        raise PlanningError("gripper_empty", f"{side} holds no tool to push with")
    ignore = list(ignore)
    shape = ctx.model.object(held.name).shape
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    X_WT = ctx.model.tcp_pose(ctx.q, side)
    X_WO = ctx.model.held_pose(side, ctx.q)
    if tip is None:
        p_OQ = _tool_tip(shape, X_WO.rotation().matrix(), end - start)
    else:
        p_OQ = np.asarray(tip, dtype=float)
    offset = X_WT.translation() - X_WO @ p_OQ  # TCP minus tip, fixed while pushing
    up = np.array([0.0, 0.0, approach])

    def tcp_at(p: np.ndarray) -> RigidTransform:
        return RigidTransform(X_WT.rotation(), p + offset)

    def line(a: np.ndarray, b: np.ndarray) -> Callable[[float], RigidTransform]:
        return lambda s: tcp_at(a + s * (b - a))

    above = move_tcp(ctx, side, tcp_at(start + up), label="above start", ignore=ignore)
    free = ignore + [held.name]  # the tool itself touches what it pushes
    plans = [above]
    legs = ((start + up, start, "down"), (start, end, "push"), (end, end + up, "up"))
    for a, b, label in legs:
        dist = float(np.linalg.norm(b - a))
        plans.append(track(ctx, side, line(a, b), dist, 0.0, label=label, ignore=free))
    plan = plans[0].then(*plans[1:])
    plan.label = f"push with {held.name}"
    return plan


def _tool_tip(shape, R_WO: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The end of a tool's long axis (in the tool's frame) that points most along the world
    `direction`."""
    if isinstance(shape, BoxShape):
        i = int(np.argmax(shape.size))
        axis, half = np.eye(3)[i], shape.size[i] / 2
    elif isinstance(shape, CylinderShape):
        axis, half = np.array([0.0, 0.0, 1.0]), shape.length / 2
    else:
        raise PlanningError("unsupported_shape", "a push tool must be a box or a cylinder")
    sign = 1.0 if (R_WO @ axis) @ np.asarray(direction, dtype=float) >= 0 else -1.0
    return sign * half * axis

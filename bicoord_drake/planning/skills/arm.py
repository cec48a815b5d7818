"""Arm primitives: joint and TCP moves, gripper opening and closing, lifting, waiting beside a
shared spot and retreating.

Each plans one arm (the other stays where it is), advances the context and returns an
:class:`~bicoord_drake.planning.skills.core.ArmPlan`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.embodiment import other_side
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills.core import ArmPlan, SkillContext, hold
from bicoord_drake.planning.timing import time_path


def move(
    ctx: SkillContext,
    side: str,
    q_goal: np.ndarray,
    *,
    label: str = "move",
    ignore: Iterable[str] = (),
    straight: bool = False,
    clearance: float | None = None,
    env_clearance: float = 0.0,
    replan_grazing: bool = False,
) -> ArmPlan:
    """A collision-checked, timed joint path of one arm (the other stays where it is); not
    while both hands hold one object.

    A `clearance` (m) between the arms, if given, is checked with no environment margin
    (close two-arm work such as a handover). A planned (not `straight`) path keeps
    `env_clearance` (m) from the environment. With `replan_grazing`, a path found with less
    that comes closer than ``ctx.env_clearance`` to the table or a fixed object (a hand
    grazing the table on its way lags behind its command and jams there) is planned again
    keeping that. Not the default: on every move it cost collect_pens two seeds of 0-29
    (24 and 27: the last pen not in) and lengthened fetch_block_with_roller's episodes by
    6-8 % (benchmarks/rate_invariance.md, "The grazing re-plan on every move")."""
    from bicoord_drake.planning.motion import plan_path

    together = ctx.model.held_together
    if together is not None:
        raise PlanningError(
            "held_together",
            f"{label}: both hands hold {together!r}; one arm cannot move alone (carry_together)",
        )
    start = ctx.q.copy()
    goal = ctx.with_arm(side, np.asarray(q_goal, float))
    if clearance is not None:
        ctx.model.set_padding(clearance * 0.8, 0.0)
    if straight:
        with ctx.model.ignoring(ignore):
            if not ctx.edge_free(start, goal):
                raise PlanningError(
                    "path_in_collision", f"{label}: the straight {side} move collides"
                )
        waypoints = np.vstack([start, goal])
    else:
        kwargs = {} if clearance is None else {"clearance": clearance * 0.8}
        waypoints = plan_path(
            ctx.model,
            start,
            goal,
            arms=(side,),
            ignore=ignore,
            env_clearance=env_clearance,
            **kwargs,
        )
    traj = time_path(waypoints[:, ctx.model.side_slice(side)], ctx.arm_limits, ctx.dt)
    if replan_grazing and not straight and env_clearance < ctx.env_clearance:
        if env_gap(ctx, start, side, traj.q) < ctx.env_clearance:
            return move(
                ctx,
                side,
                q_goal,
                label=label,
                ignore=ignore,
                clearance=clearance,
                env_clearance=ctx.env_clearance,
            )
    ctx.q = goal
    return ArmPlan(side, traj.q, np.full(len(traj.q), ctx.opening[side]), label=label)


def env_gap(ctx: SkillContext, start: np.ndarray, side: str, q_arm: np.ndarray) -> float:
    """The least distance (m) of `side`'s arm, at the joint samples `q_arm`, to the table and
    the fixed objects (the other arm as in `start`); ``ctx.env_clearance`` where all are
    farther."""
    fixed = {"table_top"} | {o.name for o in ctx.model.scene.objects if o.fixed and o.collide}
    q = np.array(start, dtype=float)
    gap = ctx.env_clearance
    with ctx.model.padded(0.0, 0.0):
        for sample in q_arm:
            q[ctx.model.side_slice(side)] = sample
            for _, other, d in ctx.model.colliding_pairs(q, ctx.env_clearance):
                if other in fixed:
                    gap = min(gap, d)
    return gap


#: A gentle release lowers the finger servo's squeeze at this many N per second
#: (:func:`gentle_release_time`): 12 control steps at 15 Hz over the ViperX's whole stroke,
#: the slowest opening a task needed (a 16-33 g cube squeezed with 30 N flicked 2.3 cm sideways
#: off a tower when its fingers opened in 4 steps, and stayed within 5 mm over 12:
#: benchmarks/bench_task_build_tower_with_blocks.md).
RELEASE_FORCE_RATE = 150.0


def gentle_release_time(ctx: SkillContext) -> float:
    """Seconds a gentle release lasts: the time its commanded finger would take to travel the
    whole stroke while the finger servo's squeeze falls at RELEASE_FORCE_RATE N/s (the force
    is finger_kp times the command's distance past the contact, so the command moves at
    RELEASE_FORCE_RATE / finger_kp m/s). A partial opening (to a narrow jaw beside a wall) is
    spread over the same time, more slowly still. Derived from the gripper alone."""
    g = ctx.model.embodiment.arm.gripper
    return (g.finger_max - g.finger_min) * g.finger_kp / RELEASE_FORCE_RATE


def grip(
    ctx: SkillContext,
    side: str,
    opening: float,
    *,
    settle: float = 0.2,
    label: str = "grip",
    gentle: bool = False,
) -> ArmPlan:
    """Open or close one gripper (arm still), then hold for `settle` seconds.

    The command moves as fast as the fingers go, or with `gentle` over
    :func:`gentle_release_time` (never faster than the fingers): a squeezed light object
    unloads gently instead of springing off."""
    steps = ctx.gripper_steps
    if gentle:
        steps = max(ctx.steps(gentle_release_time(ctx)), steps)
    start = ctx.opening[side]
    n = steps + ctx.steps(settle)
    ramp = np.clip(np.arange(n + 1) / steps, 0, 1)
    q_arm = ctx.arm_q(side)
    ctx.opening[side] = float(opening)
    return ArmPlan(
        side, np.repeat(q_arm[None], n + 1, 0), start + ramp * (opening - start), label=label
    )


def solve_tcp(
    ctx: SkillContext,
    side: str,
    target: TcpTarget,
    *,
    seed_arm: np.ndarray | None = None,
    ignore: Iterable[str] = (),
    env_clearance: float | None = None,
    clearance: float | None = None,
) -> np.ndarray:
    """The joint angles of `side` reaching `target` with the other arm fixed (IK seeded from
    `seed_arm`, default: where the arm is). A redundant arm (more than six joints) given a
    `seed_arm` - a keyframe continuing from another - also stays near it rather than near the
    nominal pose, so the two keyframes lie on one branch of its self-motion."""
    other = other_side(side)
    seed = ctx.q.copy() if seed_arm is None else ctx.with_arm(side, seed_arm)
    near = seed if seed_arm is not None and ctx.model.redundant else None
    q = ctx.ik.solve_single(
        side,
        target,
        ctx.arm_q(other),
        seed=seed,
        clearance=ctx.clearance if clearance is None else clearance,
        env_clearance=ctx.env_clearance if env_clearance is None else env_clearance,
        ignore=ignore,
        nominal=near,
    )
    return q[ctx.model.side_slice(side)]


def move_tcp(
    ctx: SkillContext,
    side: str,
    X_WT: RigidTransform,
    *,
    label: str = "move_tcp",
    ignore: Iterable[str] = (),
    straight: bool = False,
    free_axis: bool = False,
    clearance: float | None = None,
) -> ArmPlan:
    """Move the TCP of `side` to `X_WT` (see :meth:`move`)."""
    target = TcpTarget(X_WT, free_axis=free_axis)
    q_arm = solve_tcp(ctx, side, target, ignore=ignore, clearance=clearance)
    return move(
        ctx, side, q_arm, label=label, ignore=ignore, straight=straight, clearance=clearance
    )


def tcp_deviation(
    ctx: SkillContext, side: str, q_a: np.ndarray, q_b: np.ndarray, samples: int = 9
) -> float:
    """Largest distance (m) of the TCP from the straight segment between its ends along the
    straight joint move q_a -> q_b of `side`. Two IK solutions on different branches make
    a short Cartesian move (a descent onto a grasp) sweep a wide arc instead."""
    q = ctx.q.copy()
    points = []
    for s in np.linspace(0.0, 1.0, samples):
        q[ctx.model.side_slice(side)] = (1 - s) * np.asarray(q_a) + s * np.asarray(q_b)
        points.append(ctx.model.tcp_pose(q, side).translation())
    a, b = points[0], points[-1]
    d = b - a
    length2 = float(d @ d)
    worst = 0.0
    for p in points[1:-1]:
        t = 0.0 if length2 < 1e-12 else float(np.clip((p - a) @ d / length2, 0.0, 1.0))
        worst = max(worst, float(np.linalg.norm(p - (a + t * d))))
    return worst


def lift(ctx: SkillContext, side: str, height: float) -> ArmPlan:
    """Raise the TCP straight up by `height` (m), keeping its orientation."""
    X = ctx.model.tcp_pose(ctx.q, side)
    X_up = RigidTransform(X.rotation(), X.translation() + [0, 0, height])
    return move_tcp(ctx, side, X_up, label="lift", straight=True)


def wait_beside(
    ctx: SkillContext, side: str, center_xy: Sequence[float], offset: Sequence[float]
) -> ArmPlan:
    """Carry what `side` holds, TCP orientation unchanged, to wait beside a shared spot on its
    own side: `offset` = (x away from `center_xy` toward the arm's side, y from it, z above
    the table top), m. Where that is out of reach, stay where it is."""
    X = ctx.model.tcp_pose(ctx.q, side)
    sign = 1.0 if side == "right" else -1.0
    p = [center_xy[0] + sign * offset[0], center_xy[1] + offset[1], TABLE_TOP + offset[2]]
    try:
        return move_tcp(ctx, side, RigidTransform(X.rotation(), p), label="wait")
    except PlanningError:
        return hold(ctx, side, 0.0, label="wait")


def retreat(ctx: SkillContext, side: str, q_arm: np.ndarray | None = None) -> ArmPlan:
    """Back to `q_arm` (default: home) along a collision-free path."""
    q_arm = ctx.model.home[ctx.model.side_slice(side)] if q_arm is None else q_arm
    return move(ctx, side, q_arm, label="retreat")

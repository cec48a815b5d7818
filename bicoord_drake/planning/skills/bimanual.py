"""Two hands on one object: grasp it together, carry it along a path, let go together.

A long object (a roller, a beam, a pot by its two handles) is held by both grippers at once:

- :func:`two_hand_grasps` chooses the grasps together: one near each end, symmetric about the
  centre (the weight between the hands), the left hand on the end with the smaller x; pairs
  are ranked by how natural both are, and :func:`pick_together` keeps the first pair both arms
  reach at once (one bimanual IK for the pregrasps, one for the grasps).
- :func:`grip_together` closes (or opens) both grippers on the same control steps.
- :func:`track_together` plans the *object's* path, not the arms': at every control sample
  both TCP poses follow from the object pose and the fixed grasps, and one bimanual IK (both
  arms, inter-arm and scene clearances, seeded from and pulled toward the previous sample) is
  solved and checked; one jerk-limited profile of the path parameter times both arms, so the
  grippers keep their relative pose and neither arm is stretched or delayed against the other.
  :func:`carry_together` is the straight-line case (position and rotation).
- :func:`release_together` opens both grippers on the same steps and backs both off at once.

Each returns a :class:`~bicoord_drake.planning.skills.core.Motion` (both arms) and advances the
context (on a planning failure it is left unchanged); the model holds the object with both
hands (``PlanningModel.attach_both``) between :func:`pick_together` and
:func:`release_together`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.all import PiecewiseQuaternionSlerp, RigidTransform, RotationMatrix

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.objects import BoxShape, CylinderShape, PotShape
from bicoord_drake.planning.clearance import hand_floor
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    arm_base,
    grasp_candidates,
    naturalness,
    pot_handle_grasps,
    pot_handle_grasps_across,
)
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.skills.arm import grip, tcp_deviation
from bicoord_drake.planning.skills.core import Motion, SkillContext, combine
from bicoord_drake.planning.skills.shapes import half_extent
from bicoord_drake.planning.skills.tracking import (
    TRACK_MAX_STEP,
    TRACK_ROTATION,
    TRACK_SPEED,
    path_parameter,
)
from bicoord_drake.planning.timing import JointLimits, time_path

#: Grasp pairs tried by :func:`pick_together` before giving up.
MAX_PAIR_TRIES = 4
#: Default grasp inset (m) from each end of the long axis.
END_INSET = 0.04
#: Largest TCP deviation (m) from a straight line on the straight two-arm moves.
MAX_LINE_DEVIATION = 0.02


@dataclass(frozen=True)
class GraspPair:
    """One grasp per hand on the same object; `score` ranks pairs (higher is better)."""

    left: Grasp
    right: Grasp
    score: float

    def of(self, side: str) -> Grasp:
        return self.left if side == "left" else self.right


def long_axis(shape, R_WO: np.ndarray) -> np.ndarray:
    """World direction of the object's long axis (a box's longest side, a cylinder's axis),
    pointing toward +x (from the left hand's end to the right hand's)."""
    R = np.asarray(R_WO.matrix() if hasattr(R_WO, "matrix") else R_WO, dtype=float)
    if isinstance(shape, CylinderShape):
        axis = R[:, 2]
    elif isinstance(shape, BoxShape):
        axis = R[:, int(np.argmax(shape.size))]
    else:
        raise PlanningError(
            "unsupported_shape", f"two-handed grasps need a box or a cylinder, not {shape.kind}"
        )
    return axis if axis[0] >= 0 else -axis


def two_hand_grasps(
    ctx: SkillContext,
    name: str,
    *,
    inset: float = END_INSET,
    kinds: Sequence[str] = ("top",),
    X_WO: RigidTransform | None = None,
) -> list[GraspPair]:
    """Grasp pairs of object `name` (at `X_WO`, default its planning pose), best first: each
    hand `inset` (m) in from its end of the long axis, the two symmetric about the centre;
    grasps whose approach or fingers run along the long axis are left out. A pot
    (:class:`~bicoord_drake.models.objects.PotShape`) is held by its two handles instead
    (:func:`handle_pairs`; `inset` and `kinds` do not apply)."""
    obj = ctx.model.object(name)
    X_WO = ctx.model.object_pose(name) if X_WO is None else X_WO
    if isinstance(obj.shape, PotShape):
        return handle_pairs(ctx, name, X_WO=X_WO)
    R = X_WO.rotation().matrix()
    axis = long_axis(obj.shape, R)
    offset = half_extent(obj.shape, R, axis) - inset
    if offset <= 0:
        raise PlanningError("no_grasp", f"{name} is too short for two hands {inset} m in")
    gripper = ctx.model.embodiment.arm.gripper
    middle = grasp_candidates(obj, gripper, X_WO=X_WO, kinds=list(kinds))
    per_side: dict[str, list[tuple[Grasp, float]]] = {}
    for side, sign in (("left", -1.0), ("right", 1.0)):
        shift = sign * offset * axis
        base = arm_base(ctx.model.embodiment, side)
        out = []
        for g in middle:
            if abs(g.approach @ axis) > 0.5 or abs(g.finger_axis @ axis) > 0.5:
                continue
            X_WG = RigidTransform(g.X_WG.rotation(), g.X_WG.translation() + shift)
            X_pre = RigidTransform(g.X_WPre.rotation(), g.X_WPre.translation() + shift)
            score = naturalness(X_WG, base)
            grasp = Grasp(g.kind, X_WG, X_pre, X_WO.inverse() @ X_WG, g.width, score)
            out.append((grasp, score))
        per_side[side] = out
    pairs = [GraspPair(a, b, sa + sb) for a, sa in per_side["left"] for b, sb in per_side["right"]]
    if not pairs:
        raise PlanningError("no_grasp", f"no two-handed grasp of {name!r} of kinds {list(kinds)}")
    return sorted(pairs, key=lambda p: -p.score)


def handle_pairs(
    ctx: SkillContext, name: str, *, X_WO: RigidTransform | None = None
) -> list[GraspPair]:
    """Grasp pairs of a pot `name` by its two lug handles, best first: the left hand on the
    handle with the smaller world x, the right on the other, each a horizontal grasp from
    outside (:func:`~bicoord_drake.planning.grasps.pot_handle_grasps`)."""
    obj = ctx.model.object(name)
    if not isinstance(obj.shape, PotShape):
        raise PlanningError("unsupported_shape", f"{name!r} is a {obj.shape.kind}, not a pot")
    X_WO = ctx.model.object_pose(name) if X_WO is None else X_WO
    gripper = ctx.model.embodiment.arm.gripper
    x_axis = X_WO.rotation().col(0)
    # the handle at +x of the pot frame is the right hand's if that axis points to world +x
    right_sign = 1.0 if x_axis[0] >= 0 else -1.0
    per_side = {}
    floor = X_WO.translation()[2]
    for side, sign in (("left", -right_sign), ("right", right_sign)):
        base = arm_base(ctx.model.embodiment, side)
        grasps = pot_handle_grasps(X_WO, obj.shape, gripper, base=base, handles=(sign,))
        if not any(hand_floor(ctx.model.hand_boxes, g.X_WG, floor) >= 0 for g in grasps):
            # a hand this long along its finger axis, standing vertical at the handle, would
            # reach below the pot's base: it closes across the handle's width instead
            across = pot_handle_grasps_across(X_WO, obj.shape, gripper, base=base, handles=(sign,))
            grasps = across or grasps
        per_side[side] = grasps
    pairs = [
        GraspPair(a, b, a.score + b.score) for a in per_side["left"] for b in per_side["right"]
    ]
    if not pairs:
        raise PlanningError("no_grasp", f"no two-handed handle grasp of {name!r}")
    return sorted(pairs, key=lambda p: -p.score)


def grip_together(
    ctx: SkillContext,
    opening: float,
    *,
    settle: float = 0.2,
    gentle: bool = False,
    label: str = "grip together",
) -> Motion:
    """Both grippers move to `opening` on the same control steps (arms still), then hold for
    `settle` seconds (see :func:`~bicoord_drake.planning.skills.arm.grip`)."""
    plans = [grip(ctx, side, opening, settle=settle, gentle=gentle, label=label) for side in SIDES]
    motion = combine(*plans)
    motion.label = label
    return motion


def _limits12(ctx: SkillContext) -> JointLimits:
    return JointLimits.concat(ctx.arm_limits, ctx.arm_limits)


def _solve_pair(
    ctx: SkillContext,
    X_left: RigidTransform,
    X_right: RigidTransform,
    *,
    seed: np.ndarray,
    ignore: Iterable[str] = (),
    env_clearance: float | None = None,
    restarts: int = 10,
    continues: bool = False,
) -> np.ndarray:
    """Both TCPs at the targets, seeded from `seed`; a redundant arm pair whose keyframe
    `continues` from `seed` (a descent from a pre-grasp) stays near it (see ``solve_tcp``)."""
    targets = {"left": TcpTarget(X_left), "right": TcpTarget(X_right)}
    return ctx.ik.solve(
        targets,
        clearance=ctx.clearance,
        env_clearance=ctx.env_clearance if env_clearance is None else env_clearance,
        seed=seed,
        ignore=ignore,
        restarts=restarts,
        nominal=seed if continues and ctx.model.redundant else None,
    )


def _solve_near(
    ctx: SkillContext, X_left: RigidTransform, X_right: RigidTransform, *, ignore: Iterable[str]
) -> np.ndarray:
    """Both TCPs at the targets, the joints pulled toward (and seeded from) the current ones
    instead of the home pose: the IK branch the arms are on now."""
    ctx.track_ik.nominal = ctx.q.copy()
    targets = {"left": TcpTarget(X_left), "right": TcpTarget(X_right)}
    return ctx.track_ik.solve(
        targets, seed=ctx.q, clearance=ctx.clearance, env_clearance=0.0, ignore=ignore, restarts=3
    )


def _straight_together(
    ctx: SkillContext, q_goal: np.ndarray, *, label: str, ignore: Iterable[str] = ()
) -> Motion:
    """Both arms along the straight joint segment to `q_goal`, one timing for both; each TCP
    must stay within MAX_LINE_DEVIATION of a straight line and the segment collision-free."""
    for side in SIDES:
        sl = ctx.model.side_slice(side)
        dev = tcp_deviation(ctx, side, ctx.q[sl], q_goal[sl])
        if dev > MAX_LINE_DEVIATION:
            raise PlanningError(
                "not_straight", f"{label}: the {side} TCP leaves its line by {dev * 100:.1f} cm"
            )
    ctx.model.set_padding(ctx.clearance / 2, 0.0)
    with ctx.model.ignoring(ignore):
        if not ctx.edge_free(ctx.q, q_goal):
            raise PlanningError("path_in_collision", f"{label}: the straight two-arm move collides")
    traj = time_path(np.vstack([ctx.q, q_goal]), _limits12(ctx), ctx.dt)
    ctx.q = np.asarray(q_goal, float).copy()
    return ctx.motion_of(traj, label)


def track_together(
    ctx: SkillContext,
    pose_at: Callable[[float], RigidTransform],
    distance: float,
    rotation: float,
    *,
    label: str,
    ignore: Iterable[str] = (),
    env_clearance: float = 0.0,
) -> Motion:
    """Move the object both hands hold along ``pose_at(s)`` (its world pose, s in [0, 1],
    ``pose_at(0)`` where it is now), exactly at the control samples.

    Both TCP targets follow from the object pose and the grasps; s is timed by one
    jerk-limited profile for `distance` (m) and `rotation` (rad) at TRACK_SPEED /
    TRACK_ROTATION (scaled by the context's speed), slowed down until every joint of both arms
    stays within its velocity limit. A bimanual IK runs at every sample (seeded from and pulled
    toward the previous one; inter-arm clearance, `env_clearance` to the scene; objects in
    `ignore` are not checked), and every step between samples is collision-checked.
    ``info["object_poses"]`` is the planned object pose at each sample."""
    name = ctx.model.held_together
    if name is None:
        raise PlanningError("not_held_together", f"{label}: the hands do not hold one object")
    X_WO0 = ctx.model.held_pose("left", ctx.q)
    X_OT = {side: X_WO0.inverse() @ ctx.model.tcp_pose(ctx.q, side) for side in SIDES}
    limits = _limits12(ctx)
    duration = max(
        distance / (TRACK_SPEED * ctx.speed), rotation / (TRACK_ROTATION * ctx.speed), 0.2
    )
    ignore = list(ignore)
    with ctx.model.ignoring(ignore):
        for _ in range(4):
            s = path_parameter(duration, ctx.dt)
            poses = [pose_at(float(x)) for x in s]
            q, prev = [ctx.q.copy()], ctx.q.copy()
            for X_WO in poses[1:]:
                ctx.track_ik.nominal = prev
                targets = {side: TcpTarget(X_WO @ X_OT[side]) for side in SIDES}
                prev = ctx.track_ik.solve(
                    targets,
                    seed=prev,
                    clearance=ctx.clearance,
                    env_clearance=env_clearance,
                    restarts=3,
                )
                q.append(prev)
            Q = np.array(q)
            step = np.abs(np.diff(Q, axis=0))
            if np.max(step) > TRACK_MAX_STEP:
                raise PlanningError("track_discontinuous", f"{label}: IK switched branches")
            speed = float(np.max(step / ctx.dt / limits.velocity))
            if speed <= 1.0:
                break
            duration *= speed * 1.1
        else:
            raise PlanningError("track_too_fast", f"{label}: the joints cannot follow the path")
        ctx.model.set_padding(ctx.clearance / 2, 0.0)
        if not all(ctx.edge_free(a, b) for a, b in zip(Q[:-1], Q[1:], strict=True)):
            raise PlanningError("path_in_collision", f"{label}: the two-arm path collides")
    ctx.q = Q[-1].copy()
    openings = np.tile([ctx.opening[side] for side in SIDES], (len(Q), 1))
    return Motion(Q, openings, label=label, info={"object_poses": poses})


def straight_object_path(
    X_a: RigidTransform, X_b: RigidTransform
) -> tuple[Callable[[float], RigidTransform], float, float]:
    """The straight path between two object poses (position linear, rotation slerped):
    ``(pose_at, distance, rotation angle)``."""
    p_a, p_b = X_a.translation(), X_b.translation()
    slerp = PiecewiseQuaternionSlerp(
        [0.0, 1.0], [X_a.rotation().ToQuaternion(), X_b.rotation().ToQuaternion()]
    )
    angle = float(X_a.rotation().InvertAndCompose(X_b.rotation()).ToAngleAxis().angle())

    def pose_at(s: float) -> RigidTransform:
        s = float(np.clip(s, 0.0, 1.0))
        R = RotationMatrix(slerp.orientation(s)) if angle > 1e-9 else X_a.rotation()
        return RigidTransform(R, p_a + s * (p_b - p_a))

    return pose_at, float(np.linalg.norm(p_b - p_a)), angle


def carry_together(
    ctx: SkillContext,
    X_WO_goal: RigidTransform,
    *,
    label: str = "carry together",
    ignore: Iterable[str] = (),
    env_clearance: float = 0.0,
) -> Motion:
    """Carry the object both hands hold in a straight line (and a slerp of its rotation) to
    `X_WO_goal` (see :func:`track_together`)."""
    name = ctx.model.held_together
    if name is None:
        raise PlanningError("not_held_together", f"{label}: the hands do not hold one object")
    X_WO = ctx.model.held_pose("left", ctx.q)
    pose_at, distance, angle = straight_object_path(X_WO, X_WO_goal)
    return track_together(
        ctx, pose_at, distance, angle, label=label, ignore=ignore, env_clearance=env_clearance
    )


def pick_together(
    ctx: SkillContext,
    name: str,
    *,
    lift: float = 0.08,
    pairs: Sequence[GraspPair] | None = None,
    inset: float = END_INSET,
    kinds: Sequence[str] = ("top",),
    wrist: Mapping[str, float] | None = None,
) -> Motion:
    """Both arms approach object `name` at once, descend onto their grasps (arriving on the
    same step), close on the same step and lift it `lift` (m) straight up, keeping its
    orientation. `pairs` (best first) replaces :func:`two_hand_grasps`. `wrist` ({side: +1 or
    -1}) puts that arm's wrist on the branch whose wrist angle has that sign
    (:func:`on_wrist_branch`: the same TCP poses), e.g. the branch a later carry needs.
    Afterwards both hands hold it; ``info["grasps"]`` is the pair used. On failure nothing is
    changed."""
    from bicoord_drake.planning.motion import plan_path

    if any(side in ctx.model.held for side in SIDES):
        raise PlanningError("gripper_busy", f"both hands must be free to pick {name!r} together")
    if pairs is None:
        pairs = two_hand_grasps(ctx, name, inset=inset, kinds=kinds)
    reasons = []
    for pair in list(pairs)[:MAX_PAIR_TRIES]:
        try:
            with ctx.transaction():
                q_pre = _solve_pair(ctx, pair.left.X_WPre, pair.right.X_WPre, seed=ctx.q)
                q_grasp = _solve_pair(
                    ctx,
                    pair.left.X_WG,
                    pair.right.X_WG,
                    seed=q_pre,
                    ignore=[name],
                    env_clearance=0.0,
                    continues=True,
                )
                for side, sign in (wrist or {}).items():
                    q_pre = on_wrist_branch(ctx, q_pre, side, sign)
                    q_grasp = on_wrist_branch(ctx, q_grasp, side, sign)
                waypoints = plan_path(ctx.model, ctx.q, q_pre, env_clearance=0.0)
                approach = ctx.motion_of(time_path(waypoints, _limits12(ctx), ctx.dt), "approach")
                ctx.q = q_pre.copy()
                descend = _straight_together(ctx, q_grasp, label="descend", ignore=[name])
                close = grip_together(ctx, 0.0, label="close together")
                ctx.model.attach_both(name, ctx.q)
                X_WO = ctx.model.held_pose("left", ctx.q)
                X_up = RigidTransform(X_WO.rotation(), X_WO.translation() + [0.0, 0.0, lift])
                up = carry_together(ctx, X_up, label="lift together", ignore=[name])
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        motion = approach.then(descend).then(close).then(up)
        i = approach.num_steps + descend.num_steps + close.num_steps - 3
        motion.events = sorted(motion.events + [(i, side, "attach", name) for side in SIDES])
        motion.label = f"pick {name} together"
        motion.info = {"grasps": pair, "grip_index": i, "object_poses": up.info["object_poses"]}
        return motion
    raise PlanningError(
        "pick_failed",
        f"both hands cannot pick {name!r}: tried {min(len(pairs), MAX_PAIR_TRIES)} grasp pairs "
        f"({', '.join(reasons)})",
    )


def release_together(
    ctx: SkillContext,
    *,
    opening: float = 1.0,
    gentle: bool = False,
    back: float = 0.06,
    ignore: Iterable[str] = (),
) -> Motion:
    """Open both grippers on the same steps (`gentle`: a gentle release, see
    :func:`~bicoord_drake.planning.skills.arm.grip`),
    leave the object where it is and back both TCPs off `back` (m) along their approach axes
    at once. Objects in `ignore` (e.g. the support) are not checked on the way back."""
    name = ctx.model.held_together
    if name is None:
        raise PlanningError("not_held_together", "the hands do not hold one object to release")
    X_WO = ctx.model.held_pose("left", ctx.q)
    with ctx.transaction():
        opened = grip_together(ctx, opening, gentle=gentle, label="open together")
        ctx.model.detach_both(X_WO=X_WO)
        away = {}
        for side in SIDES:
            X = ctx.model.tcp_pose(ctx.q, side)
            away[side] = RigidTransform(X.rotation(), X.translation() - back * X.rotation().col(0))
        free = [name, *ignore]
        q_away = _solve_pair(
            ctx, away["left"], away["right"], seed=ctx.q, ignore=free, env_clearance=0.0
        )
        try:
            back_off = _straight_together(ctx, q_away, label="back off together", ignore=free)
        except PlanningError as err:
            if err.reason != "not_straight":
                raise
            # the IK took another wrist branch (e.g. hands reaching across toward each other):
            # solve again pulled toward the joints the arms have now
            q_away = _solve_near(ctx, away["left"], away["right"], ignore=free)
            back_off = _straight_together(ctx, q_away, label="back off together", ignore=free)
    motion = opened.then(back_off)
    i = opened.num_steps - 1
    motion.events = sorted(motion.events + [(i, side, "detach", name) for side in SIDES])
    motion.label = f"release {name} together"
    motion.info = {"release_index": i}
    return motion


def on_wrist_branch(ctx: SkillContext, q: np.ndarray, side: str, sign: float) -> np.ndarray:
    """`q` with `side`'s wrist angle of sign `sign`: if it has the other sign, the other
    branch of the same TCP pose (forearm roll and wrist rotation turned half a turn, the wrist
    angle negated; the wrist parts are symmetric, so the arm's geometry is unchanged). The
    wrist's joints are the embodiment's ``wrist_flip``; an arm without one (``None``) has no
    such branch and `q` is returned as it is. Raises PlanningError("wrist_branch") when that
    wrist angle or roll is outside the joint limits."""
    q = np.asarray(q, dtype=float).copy()
    flip = ctx.model.embodiment.wrist_flip
    if flip is None:
        return q
    base = ctx.model.side_slice(side).start
    if q[base + flip.pitch] * sign >= 0:
        return q
    for j in (flip.first_roll, flip.second_roll):
        i = base + j
        q[i] -= np.pi if q[i] > 0 else -np.pi
        q[i] = np.clip(q[i], ctx.model.lower[i], ctx.model.upper[i])  # +-pi is at the limit
    q[base + flip.pitch] = -q[base + flip.pitch]
    if not ctx.model.within_limits(q):
        raise PlanningError("wrist_branch", f"the {side} wrist cannot take the other branch")
    return q

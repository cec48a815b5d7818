"""Throw and catch: one arm throws what it holds into a container the other arm holds.

:func:`toss` plans the throw as a jerk-limited windup and a release inside a
constant-velocity coast (:func:`~bicoord_drake.planning.throwing.throw_release`), the release
velocity with the least spin the joints allow (:func:`least_spin_velocity`), and the catch so
that the container waits, level, under the predicted ballistic path
(:func:`~bicoord_drake.planning.throwing.throw_and_catch`); the flight is checked against both
arms.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Literal

import numpy as np
from pydrake.all import JacobianWrtVariable, RigidTransform, RotationMatrix

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.objects import BowlShape, BoxShape
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import arm_base, naturalness, turned_onto
from bicoord_drake.planning.ik import TcpTarget
from bicoord_drake.planning.motion import plan_path
from bicoord_drake.planning.skills.arm import grip, move, solve_tcp
from bicoord_drake.planning.skills.core import Motion, SkillContext, periods
from bicoord_drake.planning.skills.shapes import half_extent
from bicoord_drake.planning.throwing import (
    ThrowPlan,
    ballistic_landing,
    release_joint_velocity,
    throw_and_catch,
    throw_release,
)
from bicoord_drake.planning.timing import GRAVITY, SEGMENT_QUANTUM, JointLimits, time_path

#: Throws: squeeze (N) kept on the object from the windup to the release. A light grip leaves
#: almost no elastic energy in the pads, so opening does not kick the object sideways.
THROW_SQUEEZE = 1.0
#: Throws: finger clearance per side (m) commanded over the release period (then fully open).
#: 3 mm since the "lagged" contact approximation (#31): with 1.5 mm the pads let a thrown roll
#: go 92-100 ms after the ramp starts instead of 60-63 ms under SAP, so it left late and high
#: and hit the catcher's gripper (cook, 8 of 30 seeds lost); with 3 mm those seeds fly as planned.
RELEASE_GAP = 0.003
#: Throws: measured delay (s) from the start of that opening ramp until a lightly held object
#: flies free (the plan puts the release state there, inside the constant-velocity coast).
RELEASE_DELAY = 0.042
#: Throws: constant-velocity coast (s) before and after the release sample (one and three
#: periods at 15 Hz).
THROW_COAST = (0.07, 0.2)
#: Throws: the share of each joint's velocity limit the release velocity may use.
THROW_SPEED_SHARE = 0.9


def toss(
    ctx: SkillContext,
    thrower: str,
    catcher: str,
    *,
    release: Sequence[float] | None = None,
    speed: float = 1.1,
    angle: float = np.radians(45),
    catch_height: float = 0.12,
    margin: float = 0.3,
    start: Literal["early", "late"] = "early",
    hold_after: float = 0.8,
    aim: Sequence[float] = (0.0, 0.0),
    long_axis: Literal["across", "along"] = "across",
    coast_after: float | None = None,
) -> Motion:
    """Throw the object held by `thrower` into the container held by `catcher`.

    The object leaves from `release` (its centre; default 12 cm from the middle on the
    thrower's side, 25 cm above the table) at `speed` (m/s), `angle` (rad) above the
    horizontal, toward the catcher's side. The release state lies inside the constant-
    velocity coast of a :func:`~bicoord_drake.planning.throwing.throw_release` profile,
    RELEASE_DELAY after the control step that starts opening the fingers (the thrower keeps
    only a light squeeze during the throw). The catcher carries its container, level, with
    its bottom `catch_height` (m) above the table, so that its centre lies under the
    predicted ballistic path (midway between where the object crosses the rim and where it
    reaches the bottom) plus `aim` (a horizontal world offset in m, e.g. to land beside
    what is already in it), and is there `margin` s before the object reaches the rim
    (:func:`~bicoord_drake.planning.throwing.throw_and_catch`). The flight is checked against
    both arms. ``info`` holds the predicted release, rim crossing and landing (motion sample
    indices and seconds from the motion's start); its ``anchor`` is the release sample, which
    an expert below 15 Hz executes (:func:`~bicoord_drake.tasks.base.follow`). On failure
    nothing is changed.

    A box is turned on the way to the release so that its long side lies across the flight
    (`long_axis` "across": landing end first, it would pivot up onto its end) or, for a short
    drop into the container (`long_axis` "along"), along it: the thrower's fingers then close
    across the flight and stay clear of the catcher's hand on the far rim. `coast_after` (s,
    default THROW_COAST[1]) is how long the hand keeps the release velocity after the release
    sample before it brakes: a short throw over the container ends sooner, clear of the
    catcher (at least RELEASE_DELAY, for the object to leave first).
    """
    if thrower == catcher:
        raise ValueError("thrower and catcher must be different arms")
    if long_axis not in ("across", "along"):
        raise ValueError(f"long_axis must be 'across' or 'along', got {long_axis!r}")
    if coast_after is not None and coast_after < RELEASE_DELAY:
        raise ValueError(f"coast_after must be >= RELEASE_DELAY ({RELEASE_DELAY} s)")
    held, bowl = ctx.model.held.get(thrower), ctx.model.held.get(catcher)
    if held is None:
        raise PlanningError("gripper_empty", f"{thrower} holds nothing to throw")
    if bowl is None or not isinstance(ctx.model.object(bowl.name).shape, BowlShape):
        raise PlanningError("no_container", f"{catcher} must hold a bowl to catch with")
    with ctx.transaction():
        return _toss(
            ctx,
            thrower,
            catcher,
            held,
            bowl,
            release,
            speed,
            angle,
            catch_height,
            margin,
            start,
            hold_after,
            np.asarray(aim, dtype=float),
            long_axis,
            THROW_COAST[1] if coast_after is None else coast_after,
        )


def _toss(
    ctx: SkillContext,
    thrower,
    catcher,
    held,
    bowl,
    release,
    speed,
    angle,
    catch_height,
    margin,
    start,
    hold_after,
    aim,
    long_axis="across",
    coast_after=THROW_COAST[1],
) -> Motion:
    name, shape = held.name, ctx.model.object(held.name).shape
    gripper = ctx.model.embodiment.arm.gripper
    direction = np.array([1.0, 0.0, 0.0]) if thrower == "left" else np.array([-1.0, 0, 0])
    if release is None:
        release = (-0.12 * direction[0], -0.05, TABLE_TOP + 0.25)
    p_rel = np.asarray(release, dtype=float)
    v = speed * (np.cos(angle) * direction + np.sin(angle) * np.array([0.0, 0.0, 1.0]))

    throw, q_wind, soft = _throw(ctx, thrower, held, p_rel, v, long_axis, coast_after)
    # The catch: where the object (as oriented at the release) crosses the rim and the
    # bottom of the raised bowl.
    R = ctx.model.held_pose(thrower, ctx.with_arm(thrower, throw.q_release)).rotation().matrix()
    cup = ctx.model.object(bowl.name).shape
    z_bowl = TABLE_TOP + catch_height
    R_held = ctx.model.held_pose(catcher, ctx.q).rotation()
    R_WB = turned_onto(R_held, R_held.col(2), np.array([0.0, 0.0, 1.0]))  # levelled, yaw kept
    h = max(half_extent(shape, R, [0, 0, 1.0]), 0.01)
    rim, t_rim = ballistic_landing(p_rel, v, z_bowl + cup.height + h)
    bottom, t_bottom = ballistic_landing(p_rel, v, z_bowl + cup.wall + h)
    centre = (rim + bottom) / 2
    # The object's footprint, from the rim crossing to the bottom, must fit inside the wall.
    across = np.array([-direction[1], direction[0], 0.0])
    along_extent = float(np.linalg.norm((rim - bottom)[:2])) / 2 + half_extent(shape, R, direction)
    across_extent = half_extent(shape, R, across)
    reach = np.hypot(abs(aim @ direction[:2]) + along_extent, abs(aim @ across[:2]) + across_extent)
    if reach > cup.radius - cup.wall:
        raise PlanningError(
            "catch_too_steep", f"the object would hit the rim ({reach:.3f} m from the axis)"
        )
    p_bowl = np.array([*(centre[:2] - aim[:2]), z_bowl])
    q_catch = _catch_pose(ctx, catcher, bowl, R_WB, p_bowl, direction)
    q_start, o_start = ctx.q.copy(), dict(ctx.opening)
    # The thrower: windup (catcher still), then the throw with the catcher moving in.
    windup = move(ctx, thrower, q_wind, label="windup")
    loosen = grip(ctx, thrower, soft, settle=0.13, label="loosen")
    c_goal = ctx.q.copy()
    c_goal[ctx.model.side_slice(catcher)] = q_catch
    c_path = plan_path(ctx.model, ctx.q, c_goal, arms=(catcher,), env_clearance=0.0)
    c_traj = time_path(c_path[:, ctx.model.side_slice(catcher)], ctx.arm_limits, ctx.dt)
    flight = RELEASE_DELAY + t_rim  # release sample -> the object reaches the rim
    kwargs = {"margin": margin, "start": start, "hold_after": hold_after}
    try:
        plan = throw_and_catch(throw, c_traj, flight, thrower, **kwargs)
    except PlanningError as err:
        if err.reason != "catch_too_late":
            raise
        # The thrower waits at its windup until the catcher can make it. (Asking
        # throw_release for a later release makes ruckig pick a much longer profile.)
        ready = int(np.floor((throw.release_time + flight - margin) / ctx.dt + 1e-9))
        wait = c_traj.num_steps - ready
        throw = replace(
            throw,
            trajectory=throw.trajectory.delayed(wait),
            release_index=throw.release_index + wait,
        )
        plan = throw_and_catch(throw, c_traj, flight, thrower, **kwargs)
    r = throw.release_index
    half = half_extent(shape, held.X_GO.rotation(), [0, 1, 0])
    gap = float(np.clip(gripper.opening(half + RELEASE_GAP), 0, 1))
    num_samples = plan.trajectory.num_steps + 1
    opening = release_openings(num_samples, r, soft, gap, gripper.opening_rate, ctx.dt)
    throw_motion = ctx.motion_of(plan.trajectory, "throw and catch", 0.0)
    throw_motion.openings[:, SIDES.index(thrower)] = opening
    throw_motion.openings[:, SIDES.index(catcher)] = ctx.opening[catcher]
    prep = ctx.sequence([{thrower: windup}, {thrower: loosen}], ctx.still(q_start, o_start))
    motion = prep.then(throw_motion)
    offset = prep.num_steps - 1
    # Check: arms against each other and the scene, the object while it is held and its
    # flight against both arms until it is over the rim.
    i_rel = offset + r
    if not ctx.checked(motion, ctx.clearance / 2, 0.0, span=(0, i_rel + 1)):
        raise PlanningError("path_in_collision", "the throw collides before the release")
    if not ctx.checked(motion, ctx.clearance / 2, 0.0, ignore=[name], span=(i_rel, None)):
        raise PlanningError("arm_conflict", "the throw and the catch collide")
    X_WO_rel = ctx.model.held_pose(thrower, motion.q[i_rel])
    ctx.model.detach(thrower, X_WO=X_WO_rel)
    motion.events.append((i_rel + 1, thrower, "detach", name))
    motion.events.sort()
    _check_flight(ctx, motion, name, X_WO_rel.rotation(), p_rel, v, i_rel, t_rim)
    rest = RigidTransform(X_WO_rel.rotation(), [*centre[:2], z_bowl + cup.wall + h + 0.002])
    ctx.model.set_object_pose(name, rest)
    ctx.q = motion.q[-1].copy()
    ctx.opening[thrower] = 1.0
    motion.label = f"toss {name} {thrower}->{catcher}"
    # The fingers start opening at the release sample: below 15 Hz, where only every k-th
    # planned sample is executed, the expert holds the motion's start until it is one
    # (Motion.anchor), so the opening starts on time as at 15 Hz rather than up to a control
    # period early (the station's interpolation from the executed sample before it) or late.
    motion.anchor = i_rel
    motion.info.update(
        release_index=offset + r,
        release_time=(offset + r) * ctx.dt + RELEASE_DELAY,
        release_position=p_rel,
        release_velocity=v,
        landing_point=centre,
        rim_crossing=rim,
        rim_time=(offset + r) * ctx.dt + flight,
        landing_time=(offset + r) * ctx.dt + RELEASE_DELAY + t_bottom,
        catch_arrival_index=offset + plan.catch.arrival_index,
        bowl_pose=RigidTransform(R_WB, p_bowl),
    )
    return motion


def release_openings(
    num_samples: int, release: int, soft: float, gap: float, rate: float, dt: float
) -> np.ndarray:
    """The thrower's opening per sample: the light grip `soft` up to sample `release`, then
    a linear ramp to the release clearance `gap` over one :data:`SEGMENT_QUANTUM` (at 15 Hz:
    the next sample), then fully open at `rate` (opening units per second; the object has left
    the fingers). The same opening in time at every control period `dt`, so RELEASE_DELAY
    (measured at 15 Hz) holds at every rate."""
    steps = np.arange(num_samples) - release
    quanta = SEGMENT_QUANTUM / dt
    ramp = soft + (gap - soft) * np.clip(steps / quanta, 0.0, 1.0)
    opened = gap + rate * dt * (steps - quanta)
    return np.minimum(np.where(steps >= quanta, opened, ramp), 1.0)


def _catch_pose(
    ctx: SkillContext,
    catcher,
    bowl,
    R_WB: RotationMatrix,
    p_bowl: np.ndarray,
    direction: np.ndarray,
) -> np.ndarray:
    """Catcher joints holding its bowl with the bowl frame at `p_bowl`, turned from `R_WB`
    (levelled: a bowl that sags in the grasp, as measured by :meth:`refresh_grasps`, is
    levelled by tilting the gripper) about the vertical. The gripper goes to the far
    side of the flight: its body spans the rim above the bowl, so the object must not pass
    over it on the way in."""
    X_BT = bowl.X_GO.inverse() @ RigidTransform([ctx.model.embodiment.arm.gripper.tcp_x, 0, 0])
    base = arm_base(ctx.model.embodiment, catcher)
    toward_base = (base - p_bowl)[:2] / np.linalg.norm((base - p_bowl)[:2])
    options = []
    for yaw in np.linspace(0, 2 * np.pi, 12, endpoint=False):
        X_WB = RigidTransform(RotationMatrix.MakeZRotation(yaw) @ R_WB, p_bowl)
        X_WT = X_WB @ X_BT
        side = (X_WT.translation() - p_bowl)[:2]
        side /= max(np.linalg.norm(side), 1e-9)
        score = 2 * side @ direction[:2] + 0.5 * side @ toward_base + naturalness(X_WT, base)
        options.append((score, X_WT))
    reasons = []
    for _, X_WT in sorted(options, key=lambda o: -o[0])[:6]:
        try:
            return solve_tcp(ctx, catcher, TcpTarget(X_WT))
        except PlanningError as err:
            reasons.append(err.reason)
    raise PlanningError(
        "catch_unreachable",
        f"{catcher} cannot hold its bowl at {np.round(p_bowl, 3)} ({', '.join(reasons)})",
    )


def _throw(
    ctx: SkillContext,
    thrower: str,
    held,
    p_rel: np.ndarray,
    v: np.ndarray,
    long_axis: Literal["across", "along"] = "across",
    coast_after: float = THROW_COAST[1],
) -> tuple[ThrowPlan, np.ndarray, float]:
    """The thrower's :class:`ThrowPlan`, its windup joints and the light-grip opening.

    The object's centre passes `p_rel` with velocity `v` RELEASE_DELAY after the release
    sample (inside the coast, whose joint velocity gives exactly `v` there). The windup lies
    on the same joint line, far enough back to reach that velocity. A box may be turned
    about the vertical on the way to the release (quarter turns, as held or squared to the
    flight): the shortest along the flight (its long side across) first - with `long_axis`
    "along", the longest - then the one with the least spin."""
    obj = ctx.model.object(held.name)
    gripper = ctx.model.embodiment.arm.gripper
    limits = JointLimits.from_embodiment(ctx.model.embodiment, arms=1, speed=1.0)
    X_OT = held.X_GO.inverse() @ RigidTransform([gripper.tcp_x, 0.0, 0.0])
    R_WO = ctx.model.held_pose(thrower, ctx.q).rotation()
    direction = v[:2] / max(float(np.linalg.norm(v[:2])), 1e-9)
    yaws = [0.0]
    if isinstance(obj.shape, BoxShape):
        # Quarter turns, as held and with the box's x axis squared to the flight.
        x = R_WO.matrix()[:2, 0]
        square = np.arctan2(direction[1], direction[0]) - np.arctan2(x[1], x[0])
        yaws = [k * np.pi / 2 + offset for offset in (square, 0.0) for k in range(4)]
    options, reasons = [], []
    for yaw in yaws:
        R_rel = RotationMatrix.MakeZRotation(yaw) @ R_WO
        X_WT = RigidTransform(R_rel, p_rel) @ X_OT
        # A long object flies with its long axis across the flight: landing end first, it
        # would pivot up onto its end.
        length = half_extent(obj.shape, R_rel.matrix(), [*direction, 0.0])
        try:
            q_rel = solve_tcp(ctx, thrower, TcpTarget(X_WT))
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        J = _throw_jacobian(ctx, thrower, ctx.with_arm(thrower, q_rel), held.X_GO.translation())
        # The least spin the joint speeds allow, and the slowest joints (a shorter windup).
        for least_spin in (True, False):
            try:
                qd = least_spin_velocity(
                    J, v, limits.velocity * THROW_SPEED_SHARE, least_spin=least_spin
                )
            except PlanningError as err:
                reasons.append(err.reason)
                continue
            rank = round(length / 0.005) * (1 if long_axis == "across" else -1)
            options.append((rank, abs(float(J[1] @ qd)), q_rel, qd))
    # The shortest along the flight (long axis across it; "along": the longest) first, then
    # the least spin.
    for *_, q_rel, qd in sorted(options, key=lambda o: o[:2]):
        q_sample = q_rel - RELEASE_DELAY * qd
        # Joint-line distance (in seconds of release velocity) to reach it from rest.
        a = float(np.min(limits.acceleration / np.maximum(np.abs(qd), 1e-9)))
        j = float(np.min(limits.jerk / np.maximum(np.abs(qd), 1e-9)))
        ramp = 0.5 * (1 / a + a / j) if a * a / j <= 1 else np.sqrt(1 / j)
        # Timed on the segment quantum: the same throw at every control rate.
        coast = (periods(THROW_COAST[0], SEGMENT_QUANTUM), periods(coast_after, SEGMENT_QUANTUM))
        q_wind = q_sample - (coast[0] * SEGMENT_QUANTUM + 1.3 * ramp) * qd
        try:
            if not np.all((q_wind >= limits.lower) & (q_wind <= limits.upper)):
                raise PlanningError("throw_joint_limits", "the windup is out of range")
            plan = throw_release(
                q_wind,
                q_sample,
                limits,
                ctx.dt,
                qd_release=qd,
                coast=coast,
                grid=SEGMENT_QUANTUM,
            )
            with ctx.model.padded(0.0, 0.0):
                if not all(
                    ctx.model.collision_free(ctx.with_arm(thrower, q))
                    for q in (q_wind, *plan.trajectory.q)
                ):
                    raise PlanningError("throw_in_collision", "the windup or throw collides")
        except PlanningError as err:
            reasons.append(err.reason)
            continue
        break
    else:
        raise PlanningError(
            "throw_unreachable",
            f"{thrower} cannot release at {np.round(p_rel, 3)} with {np.round(v, 2)} m/s "
            f"({', '.join(reasons)})",
        )
    half = half_extent(obj.shape, held.X_GO.rotation(), [0, 1, 0])
    soft = float(np.clip(gripper.opening(half - THROW_SQUEEZE / gripper.finger_kp), 0, 1))
    return plan, q_wind, soft


def _throw_jacobian(ctx: SkillContext, side: str, q: np.ndarray, p_GQ: np.ndarray) -> np.ndarray:
    """(6, n) Jacobian of a throw (n arm joints): the gripper's angular velocity about its own x
    (approach), y (finger) and z axes, then the velocity of point Q (fixed in the gripper
    link) in the world."""
    plant = ctx.model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, ctx.model.full_q(q))
    frame = ctx.model.gripper_bodies[side].body_frame()
    arm = ctx.model.arms[side]
    v_indices = np.array(
        [
            plant.GetJointByName(j, arm).velocity_start()
            for j in ctx.model.embodiment.arm.joint_names
        ]
    )
    J = plant.CalcJacobianSpatialVelocity(
        context,
        JacobianWrtVariable.kV,
        frame,
        np.asarray(p_GQ, dtype=float),
        plant.world_frame(),
        plant.world_frame(),
    )[:, v_indices]
    R = frame.CalcPoseInWorld(context).rotation().matrix()
    return np.vstack([R.T @ J[:3], J[3:]])


def _check_flight(ctx: SkillContext, motion, name, R_WO, p_rel, v, i_rel, t_end) -> None:
    """The flying object must clear both arms and the scene until it is over the rim."""
    saved = ctx.model.object_pose(name)
    ctx.model.set_padding(0.0, 0.0)
    try:
        for t in np.arange(0.05, t_end - 0.02, 0.01):
            p = p_rel + v * t + np.array([0.0, 0.0, -0.5 * GRAVITY * t * t])
            k = i_rel + (RELEASE_DELAY + t) / ctx.dt
            i = min(int(k), motion.num_steps - 2)
            q = motion.q[i] + (k - i) * (motion.q[i + 1] - motion.q[i])
            ctx.model.set_object_pose(name, RigidTransform(R_WO, p))
            if not ctx.model.collision_free(q):
                pairs = ctx.model.colliding_pairs(q)
                raise PlanningError(
                    "flight_blocked", f"{name} in flight hits {pairs[:1]} at t = {t:.2f} s"
                )
    finally:
        ctx.model.set_object_pose(name, saved)


def least_spin_velocity(
    J: np.ndarray, v: np.ndarray, cap: np.ndarray, *, least_spin: bool = True
) -> np.ndarray:
    """Release joint velocity for the throw Jacobian `J` (:func:`_throw_jacobian`):
    point velocity `v`, no turn about the gripper's x and z axes (a loosened object leaves
    without being turned against the pads), and the least turn about the finger axis (a
    tumbling object lands on an edge or an end) that keeps every joint within `cap` (rad/s);
    without `least_spin`, the one nearest the minimum-norm joint velocity within `cap`.

    Five equations leave one free direction n: qd = qd0 + t n, and the finger-axis rate is
    linear in t, so the best t is the unconstrained one clipped to the interval the caps allow.
    """
    A, spin = J[[0, 2, 3, 4, 5]], J[1]
    qd0 = release_joint_velocity(A, np.zeros(J.shape[1]), np.r_[0.0, 0.0, v])
    n = np.linalg.svd(A)[2][-1]
    lo, hi = -np.inf, np.inf
    for q0, ni, c in zip(qd0, n, cap, strict=True):
        if abs(ni) < 1e-12:
            if abs(q0) > c:
                lo, hi = np.inf, -np.inf
            continue
        a, b = sorted(((-c - q0) / ni, (c - q0) / ni))
        lo, hi = max(lo, a), min(hi, b)
    if lo > hi:
        j = int(np.argmax(np.abs(qd0) / cap))
        raise PlanningError("throw_too_fast", f"joint {j} would need {qd0[j]:.2f} rad/s")
    rate = float(spin @ n)
    t = -float(spin @ qd0) / rate if abs(rate) > 1e-9 and least_spin else 0.0
    return qd0 + float(np.clip(t, lo, hi)) * n

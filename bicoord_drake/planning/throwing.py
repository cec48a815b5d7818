"""Throw and catch timing on the control-step grid (see :mod:`bicoord_drake.planning.timing`).

- :func:`throw_release` - one-arm (n-DoF) Ruckig from rest to a release state with non-zero target
  velocity, a short constant-velocity coast around the release step, then a velocity-interface
  Ruckig that brakes to rest; the release lies exactly on a control step.
- :func:`release_joint_velocity` - the joint velocity that gives a TCP velocity.
- :func:`ballistic_landing` and :func:`schedule_catch` put the catcher under the landing point
  before the object arrives; :func:`throw_and_catch` assembles the two-arm trajectory.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from ruckig import ControlInterface, DurationDiscretization, InputParameter, Ruckig, Synchronization

from bicoord_drake.models.embodiment import Side
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.timing import (
    _GRID_TOL,
    CONTROL_DT,
    GRAVITY,
    JointLimits,
    TimedTrajectory,
    _calculate,
    _check_dim,
    _Concat,
    _Linear,
    _rounded_up,
    _RuckigSegment,
    _steps_at_least,
    _Timeline,
    concatenate,
    stack_arms,
)


def release_joint_velocity(
    jacobian: np.ndarray | Callable[[np.ndarray], np.ndarray],
    q: np.ndarray,
    tcp_velocity: np.ndarray,
    tol: float = 1e-3,
) -> np.ndarray:
    """Joint velocity that gives the TCP `tcp_velocity` at configuration `q`.

    `jacobian` is a (3, n) translational Jacobian, or a (6, n) spatial one with rows
    ``[angular; linear]`` (Drake's order), or a callable ``q -> J``. A 3-vector velocity uses
    only the linear rows (the minimum-norm solution leaves the wrist free); a 6-vector is a full
    spatial velocity ``[w; v]``. ``PlanningError('throw_unreachable')`` if J cannot produce it.
    """
    J = np.asarray(jacobian(np.asarray(q, float)) if callable(jacobian) else jacobian, float)
    v = np.asarray(tcp_velocity, dtype=float)
    if J.shape[0] == 6 and v.shape == (3,):
        J = J[3:]
    if J.shape[0] != v.shape[0]:
        raise ValueError(f"Jacobian has {J.shape[0]} rows, velocity has {v.shape[0]}")
    qd, *_ = np.linalg.lstsq(J, v, rcond=1e-6)
    residual = float(np.linalg.norm(J @ qd - v))
    if residual > tol * max(1.0, float(np.linalg.norm(v))):
        raise PlanningError(
            "throw_unreachable", f"the TCP velocity is out of the Jacobian's range ({residual:.3g})"
        )
    return qd


@dataclass(frozen=True)
class ThrowPlan:
    """A throwing arm's motion: from rest through the release state, braking to rest.

    At sample ``release_index`` (time ``release_time = release_index * dt``) the arm is exactly at
    ``q_release`` with velocity ``qd_release``; it moves at that constant velocity for
    ``coast`` = (before, after) periods of its grid around the release, so the first-order hold
    between actions reproduces the release velocity exactly. Command the gripper opening in
    action ``release_index``: the station's hold ramps the jaw open during the following period,
    while (with the default coast of (1, 1)) the arm target still moves at exactly ``qd_release``.
    """

    trajectory: TimedTrajectory
    release_index: int
    q_release: np.ndarray
    qd_release: np.ndarray
    coast: tuple[int, int]

    @property
    def release_time(self) -> float:
        return self.release_index * self.trajectory.dt


def throw_release(
    q_start: np.ndarray,
    q_release: np.ndarray,
    limits: JointLimits,
    dt: float = CONTROL_DT,
    *,
    qd_release: np.ndarray | None = None,
    tcp_velocity: np.ndarray | None = None,
    jacobian: np.ndarray | Callable[[np.ndarray], np.ndarray] | None = None,
    release_at: float | None = None,
    coast: tuple[int, int] = (1, 1),
    grid: float | None = None,
) -> ThrowPlan:
    """Plan a throw for one arm: reach `q_release` with a non-zero velocity on a control step.

    Give the release joint velocity `qd_release` directly, or `tcp_velocity` plus `jacobian` (see
    :func:`release_joint_velocity`). The arm starts at rest at `q_start`; Ruckig (Time
    synchronization, target velocity = release velocity) brings it to the start of the coast; it
    coasts through the release at constant velocity; a velocity-interface Ruckig brakes it to rest.
    `release_at` (s, rounded up to the grid) asks for a later release. Every sample is checked
    against `limits` (position limits included): ``PlanningError('throw_*' / 'timing_limits')``.

    `grid` (s, default `dt`) is the period the profile is timed on and `coast` counts. With
    :data:`~bicoord_drake.planning.timing.SEGMENT_QUANTUM` the throw is the same continuous
    motion at every control rate: it starts less than one control period late (at rest), so that
    the release instant falls on a control step, and is sampled every `dt`.
    """
    q0 = np.asarray(q_start, dtype=float)
    q_rel = np.asarray(q_release, dtype=float)
    n = len(q0)
    _check_dim(limits, n)
    if qd_release is None:
        if tcp_velocity is None or jacobian is None:
            raise ValueError("give qd_release, or tcp_velocity and jacobian")
        qd_release = release_joint_velocity(jacobian, q_rel, tcp_velocity)
    v = np.asarray(qd_release, dtype=float)
    if np.any(np.abs(v) > limits.velocity):
        j = int(np.argmax(np.abs(v) / limits.velocity))
        raise PlanningError(
            "throw_too_fast",
            f"release velocity of joint {j} is {v[j]:.3f} rad/s, limit {limits.velocity[j]:.3f}",
        )
    before, after = coast
    if before < 0 or after < 0:
        raise ValueError("coast steps must be >= 0")
    step = dt if grid is None else float(grid)
    if step <= 0:
        raise ValueError(f"grid must be > 0 s, got {grid}")
    q_coast0 = q_rel - before * step * v
    q_coast1 = q_rel + after * step * v

    otg = Ruckig(n, step)
    inp = _inputs(n, limits, q0, np.zeros(n))
    inp.target_position, inp.target_velocity = list(q_coast0), list(v)
    inp.target_acceleration = [0.0] * n
    inp.synchronization = Synchronization.Time
    if release_at is not None:
        steps = _steps_at_least(release_at, step) - before
        if steps <= 0:
            raise PlanningError("timing_infeasible", f"release at {release_at} s is too early")
        inp.minimum_duration = steps * step
    approach = _calculate(otg, inp, n, "throw approach")
    if release_at is not None and approach.duration > inp.minimum_duration + _GRID_TOL:
        raise PlanningError(
            "timing_infeasible",
            f"the release needs {approach.duration + before * step:.3f} s, asked for {release_at}",
        )

    brake_inp = _inputs(n, limits, q_coast1, v)
    brake_inp.control_interface = ControlInterface.Velocity
    brake_inp.target_velocity, brake_inp.target_acceleration = [0.0] * n, [0.0] * n
    brake_inp.synchronization = Synchronization.Time
    brake = _calculate(otg, brake_inp, n, "throw brake")

    pieces: list[_Timeline] = [_RuckigSegment(approach, stretchable=False)]
    if before + after:
        pieces.append(_Linear(q_coast0, v, (before + after) * step))
    pieces.append(_RuckigSegment(brake, stretchable=False))
    if abs(step - dt) < _GRID_TOL:
        trajectory = concatenate([TimedTrajectory._sample(p, dt) for p in pieces])
        release_index = int(round(approach.duration / dt)) + before
    else:
        # Start late (at rest) by less than a period: the release instant on a control step.
        t_release = approach.duration + before * step
        release_index = _steps_at_least(t_release, dt)
        lead = release_index * dt - t_release
        if lead > _GRID_TOL:
            pieces.insert(0, _Linear(q0, np.zeros(n), lead))
        trajectory = TimedTrajectory._sample(_rounded_up(_Concat(pieces), dt), dt)
    trajectory.q[release_index] = q_rel  # exactly on the release state
    trajectory.qd[release_index] = v
    # Ruckig's position_extrema are unreliable with time synchronization + discrete durations
    # (measured: 5 cm low), so sweep the continuous motion at 10 samples per control period.
    dense = np.array(
        [trajectory.at(t)[0] for t in np.linspace(0, trajectory.duration, 10 * len(trajectory.q))]
    )
    lo, hi = dense.min(axis=0), dense.max(axis=0)
    if np.any(lo < limits.lower - 1e-9) or np.any(hi > limits.upper + 1e-9):
        j = int(np.argmax(np.maximum(limits.lower - lo, hi - limits.upper)))
        raise PlanningError(
            "throw_joint_limits",
            f"joint {j} sweeps [{lo[j]:.3f}, {hi[j]:.3f}], limits "
            f"[{limits.lower[j]:.3f}, {limits.upper[j]:.3f}]",
        )
    trajectory.check_limits(limits)
    return ThrowPlan(trajectory, release_index, q_rel, v, (before, after))


def _inputs(n: int, limits: JointLimits, q: np.ndarray, v: np.ndarray) -> InputParameter:
    inp = InputParameter(n)
    inp.current_position, inp.current_velocity = list(q), list(v)
    inp.current_acceleration = [0.0] * n
    inp.max_velocity = list(limits.velocity)
    inp.max_acceleration = list(limits.acceleration)
    inp.max_jerk = list(limits.jerk)
    inp.duration_discretization = DurationDiscretization.Discrete
    return inp


def ballistic_landing(
    p0: np.ndarray, v0: np.ndarray, z_land: float, g: float = GRAVITY
) -> tuple[np.ndarray, float]:
    """Where and when a point released at `p0` with velocity `v0` comes down to height `z_land`.

    Returns (landing point, flight time), taking the descending crossing. Drag is ignored.
    ``PlanningError('throw_unreachable')`` if the apex stays below `z_land`.
    """
    p0, v0 = np.asarray(p0, dtype=float), np.asarray(v0, dtype=float)
    dz = p0[2] - z_land
    disc = v0[2] ** 2 + 2 * g * dz
    if disc < 0:
        raise PlanningError("throw_unreachable", f"the object never comes down to z = {z_land}")
    t = (v0[2] + np.sqrt(disc)) / g
    if t <= 0:
        raise PlanningError("throw_unreachable", "the landing height is behind the release")
    land = p0 + v0 * t + np.array([0.0, 0.0, -0.5 * g * t * t])
    land[2] = z_land
    return land, float(t)


@dataclass(frozen=True)
class CatchSchedule:
    """When the catcher moves: start step, the step it is in place, the predicted landing."""

    start_index: int
    arrival_index: int
    landing_time: float
    slack: float  # s between the catcher's arrival and the landing


def schedule_catch(
    release_time: float,
    flight_time: float,
    catcher: TimedTrajectory,
    *,
    margin: float = 0.2,
    start: Literal["early", "late"] = "early",
) -> CatchSchedule:
    """Start step of the catcher's trajectory so it is in place `margin` s before landing.

    "early" starts at step 0 (waits in place longest); "late" starts as late as the margin allows.
    ``PlanningError('catch_too_late')`` if even starting at once leaves less than `margin`.
    """
    dt = catcher.dt
    landing = release_time + flight_time
    latest_arrival = int(np.floor((landing - margin) / dt + 1e-9))
    latest_start = latest_arrival - catcher.num_steps
    if latest_start < 0:
        raise PlanningError(
            "catch_too_late",
            f"catcher needs {catcher.duration:.3f} s, object lands at {landing:.3f} s "
            f"(margin {margin} s)",
        )
    start_index = 0 if start == "early" else latest_start
    arrival = start_index + catcher.num_steps
    return CatchSchedule(start_index, arrival, landing, landing - arrival * dt)


@dataclass(frozen=True)
class ThrowCatchPlan:
    """Two-arm throw and catch on one two-arm (2 n-DoF) trajectory."""

    trajectory: TimedTrajectory
    throw: ThrowPlan
    catch: CatchSchedule
    thrower: Side


def throw_and_catch(
    throw: ThrowPlan,
    catcher: TimedTrajectory,
    flight_time: float,
    thrower: Side,
    *,
    margin: float = 0.2,
    start: Literal["early", "late"] = "early",
    hold_after: float = 0.5,
) -> ThrowCatchPlan:
    """Combine a throwing arm's :class:`ThrowPlan` and the catcher's one-arm trajectory (to its
    catching pose) into one two-arm trajectory; the catcher is in place `margin` s before the
    predicted landing, and both then hold for at least `hold_after` s past the landing."""
    schedule = schedule_catch(throw.release_time, flight_time, catcher, margin=margin, start=start)
    catcher = catcher.delayed(schedule.start_index)
    dt = catcher.dt
    end = max(
        throw.trajectory.num_steps,
        catcher.num_steps,
        _steps_at_least(schedule.landing_time + hold_after, dt),
    )
    throwing, catching = throw.trajectory.padded(end), catcher.padded(end)
    pair = (throwing, catching) if thrower == "left" else (catching, throwing)
    return ThrowCatchPlan(stack_arms(*pair), throw, schedule, thrower)

"""Ruckig time parameterization on the control-step grid: paths, two-arm sync, handovers.

Everything here produces a :class:`TimedTrajectory`: samples at ``t_k = k * dt`` (the control
rate, 15 Hz by default) of a continuous jerk-limited motion, with position, velocity and
acceleration at every sample. Every piece of a trajectory lasts a whole number of control periods
(Ruckig's ``DurationDiscretization.Discrete``), so pieces chain on the grid, the last sample sits
exactly on the goal, and a throw releases exactly on a control step (recorded actions replay the
demonstration through the station's first-order hold).

Key functions:

- :func:`time_path` - a (K, n) joint polyline (the collision-checked path) timed *exactly along
  its segments*: a 1-DoF Ruckig on the path parameter of each segment, with limits
  ``min_j(limit_j / |dq_j|)``, so every joint meets its own velocity, acceleration and jerk limit
  and the motion never leaves the straight segment (Ruckig's phase synchronization silently falls
  back to time synchronization and then bows off the line). Corners are passed at rest - a
  non-zero velocity through a corner would need infinite acceleration on an exact polyline;
  collinear runs are merged into one segment. Each segment lasts a whole number of
  :data:`SEGMENT_QUANTUM` (the 15 Hz period) at any rate, so a path lasts the same time at every
  rate; at 15 Hz (and its multiples) every corner is a sample, so the station's linear
  interpolation between samples never cuts one. With a two-arm path both arms start
  and arrive at the same instant by construction.
- :func:`synchronize` / :func:`rendezvous` - arms with separate paths: the faster one is
  uniformly slowed (time-scaled, which keeps its path and only lowers velocity, acceleration and
  jerk) so both arrive at the same control step, optionally at a requested time.
- Throws and catches are timed on the same grid in :mod:`bicoord_drake.planning.throwing`.
- :meth:`TimedTrajectory.to_actions` turns a two-arm trajectory plus gripper schedules into the
  station's (N, 2 (n + 1)) action array ``[left n, left opening, right n, right opening]``
  (:class:`~bicoord_drake.models.layout.ActionLayout`; (N, 14) for two 6-joint arms).

Joint vectors are ``[left n, right n]`` for two arms of n joints each (n from the embodiment:
6 for the ViperX, 7 for the Panda; :func:`arm_slices`); every function also works for one arm
with matching :class:`JointLimits`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from ruckig import (
    DurationDiscretization,
    InputParameter,
    Result,
    Ruckig,
    Trajectory,
)

from bicoord_drake.models.embodiment import Embodiment, GripperSpec, Side
from bicoord_drake.models.layout import ActionLayout
from bicoord_drake.planning.errors import PlanningError

#: Default control period (15 Hz).
CONTROL_DT = 1.0 / 15.0
#: The longest planning period (s): the experts plan on this grid or a finer one, never a
#: coarser one (:func:`planning_substeps`).
MAX_PLANNING_PERIOD = CONTROL_DT
#: Every straight segment of a timed path lasts a whole number of these (s), at any control
#: rate: the reference rate's period, so a path lasts the same time at 10, 15, 30 or 50 Hz.
#: Rounding each segment up to the control period instead made a path of many short segments
#: 4 % shorter at 50 Hz and 4 % longer at 10 Hz than at 15 Hz (put_objects_cabinet). At rates
#: whose period divides it (15, 30, 45 Hz ...) every corner is still a sample; at others a
#: corner may fall between two samples, where the motion is at rest, so the station's linear
#: interpolation between them cuts it by the path's travel in half a period of its jerk-limited
#: stop: under 1e-4 rad at 50 Hz and 2e-3 rad at 10 Hz with the ViperX's limits
#: (tests/planning/test_time_in_seconds.py).
SEGMENT_QUANTUM = CONTROL_DT
#: Standard gravity (m/s^2).
GRAVITY = 9.81

_GRID_TOL = 1e-9  # how far a duration may sit from the dt grid (s)
_LIMIT_TOL = 1e-6  # relative slack when checking limits on samples

State = tuple[np.ndarray, np.ndarray, np.ndarray]


def planning_substeps(control_period: float) -> int:
    """k, the planned samples per control step: the smallest whole number with
    ``control_period / k <= MAX_PLANNING_PERIOD`` (1/15 s). At 15 Hz and faster k = 1 (the
    experts plan on the control grid); at 10 Hz k = 2 (they plan at 20 Hz), at 5 Hz 3, at 12 Hz
    2 (24 Hz).

    Why: every motion and every wait of a plan lasts a whole number of samples, rounded up, so
    each of a demonstration's 30-60 plan boundaries adds half a sample period on average. On
    the 10 Hz grid that made demonstrations 3-9 % longer than at 15 Hz
    (benchmarks/rate_invariance.md). Planned on the finer grid and executed every k-th sample
    on one clock carried across motions (:func:`bicoord_drake.tasks.base.expert_actions`),
    only the episode's end is rounded to the control period."""
    if not control_period > 0:
        raise ValueError(f"control_period must be > 0 s, got {control_period!r}")
    return max(1, int(np.ceil(control_period / MAX_PLANNING_PERIOD * (1.0 - 1e-9))))


# --------------------------------------------------------------------------------------------
# Limits
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class JointLimits:
    """Per-joint position, velocity, acceleration and jerk limits (all arrays of length n)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    def __post_init__(self) -> None:
        arrays = [np.asarray(getattr(self, f), dtype=float) for f in _LIMIT_FIELDS]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            raise ValueError("JointLimits: all limits must be 1-D arrays of the same length")
        if np.any(arrays[0] > arrays[1]):
            raise ValueError("JointLimits: lower must not exceed upper")
        if any(np.any(a <= 0) for a in arrays[2:]):
            raise ValueError("JointLimits: velocity, acceleration and jerk limits must be > 0")
        for name, a in zip(_LIMIT_FIELDS, arrays, strict=True):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def n(self) -> int:
        return len(self.lower)

    @classmethod
    def from_embodiment(
        cls, embodiment: Embodiment, arms: int = 2, speed: float = 1.0
    ) -> JointLimits:
        """Limits of `arms` copies of the embodiment's arm ([left n, right n] for two).

        `speed` slows every motion uniformly: velocity x speed, acceleration x speed^2,
        jerk x speed^3 (the limits of the same motion played 1/speed times slower).
        """
        if arms not in (1, 2):
            raise ValueError("arms must be 1 or 2")
        joints = embodiment.arm.joints

        def tile(values: list[float]) -> np.ndarray:
            return np.tile(np.array(values, dtype=float), arms)

        return cls(
            lower=tile([j.lower for j in joints]),
            upper=tile([j.upper for j in joints]),
            velocity=tile([j.velocity_limit for j in joints]),
            acceleration=tile([j.acceleration_limit for j in joints]),
            jerk=tile([j.jerk_limit for j in joints]),
        ).scaled(speed)

    def scaled(self, speed: float) -> JointLimits:
        """The same limits for a motion `speed` times as fast (v*s, a*s^2, j*s^3)."""
        if speed <= 0:
            raise ValueError(f"speed must be > 0, got {speed}")
        return JointLimits(
            self.lower,
            self.upper,
            self.velocity * speed,
            self.acceleration * speed**2,
            self.jerk * speed**3,
        )

    def select(self, index: slice | Sequence[int] | np.ndarray) -> JointLimits:
        """The limits of a subset of joints (e.g. ``arm_slices(n)['left']``)."""
        return JointLimits(*(getattr(self, f)[index] for f in _LIMIT_FIELDS))

    def arm(self, side: Side) -> JointLimits:
        """One arm's limits of two-arm limits ``[left n, right n]``."""
        if self.n % 2:
            raise ValueError(f"arm() needs two-arm limits, these are for {self.n} joints")
        return self.select(arm_slices(self.n // 2)[side])

    @staticmethod
    def concat(*parts: JointLimits) -> JointLimits:
        """Stack limits of several arms into one vector (left first)."""
        return JointLimits(*(np.concatenate([getattr(p, f) for p in parts]) for f in _LIMIT_FIELDS))


_LIMIT_FIELDS = ("lower", "upper", "velocity", "acceleration", "jerk")


def arm_slices(arm_joints: int) -> dict[Side, slice]:
    """Where each arm's joints sit in a two-arm joint vector ``[left n, right n]``."""
    return {"left": slice(0, arm_joints), "right": slice(arm_joints, 2 * arm_joints)}


# --------------------------------------------------------------------------------------------
# Continuous timelines (kept so a trajectory can be stretched and densely checked)
# --------------------------------------------------------------------------------------------


class _Timeline:
    """A continuous motion on [0, duration]; `evaluate` clamps t into that interval."""

    duration: float
    n: int
    stretchable: bool = True

    def evaluate(self, t: float) -> State:
        raise NotImplementedError


class _PathSegment(_Timeline):
    """q = q0 + s(t) * (q1 - q0) with s(t) a 1-DoF Ruckig trajectory from 0 to 1."""

    def __init__(self, q0: np.ndarray, q1: np.ndarray, traj: Trajectory) -> None:
        self.q0, self.dq, self.q1, self.traj = q0, q1 - q0, q1, traj
        self.duration, self.n = traj.duration, len(q0)

    def evaluate(self, t: float) -> State:
        p, v, a = self.traj.at_time(min(max(t, 0.0), self.duration))
        s = 1.0 if t >= self.duration else min(max(p[0], 0.0), 1.0)  # stay on the segment
        q = self.q1.copy() if s == 1.0 else self.q0 + s * self.dq
        return q, v[0] * self.dq, a[0] * self.dq


class _RuckigSegment(_Timeline):
    """A multi-DoF Ruckig trajectory, used as is."""

    def __init__(self, traj: Trajectory, stretchable: bool = True) -> None:
        self.traj, self.stretchable = traj, stretchable
        self.duration, self.n = traj.duration, traj.degrees_of_freedom

    def evaluate(self, t: float) -> State:
        p, v, a = self.traj.at_time(min(max(t, 0.0), self.duration))
        return np.array(p), np.array(v), np.array(a)


class _Linear(_Timeline):
    """Constant velocity (a hold when v = 0)."""

    def __init__(self, q0: np.ndarray, v: np.ndarray, duration: float) -> None:
        self.q0, self.v = np.asarray(q0, float), np.asarray(v, float)
        self.duration, self.n = duration, len(self.q0)
        self.stretchable = not np.any(self.v)

    def evaluate(self, t: float) -> State:
        t = min(max(t, 0.0), self.duration)
        return self.q0 + t * self.v, self.v.copy(), np.zeros(self.n)


class _Scaled(_Timeline):
    """`inner` played `k` times slower: t -> inner(t / k), velocities / k, accelerations / k^2."""

    def __init__(self, inner: _Timeline, k: float) -> None:
        self.inner, self.k = inner, k
        self.duration, self.n, self.stretchable = inner.duration * k, inner.n, inner.stretchable

    def evaluate(self, t: float) -> State:
        tau = self.inner.duration if t >= self.duration else t / self.k
        q, v, a = self.inner.evaluate(tau)
        return q, v / self.k, a / self.k**2


class _Concat(_Timeline):
    def __init__(self, parts: Sequence[_Timeline]) -> None:
        self.parts = list(parts)
        self.starts = np.concatenate([[0.0], np.cumsum([p.duration for p in self.parts])])
        self.duration, self.n = float(self.starts[-1]), self.parts[0].n
        self.stretchable = all(p.stretchable for p in self.parts)

    def evaluate(self, t: float) -> State:
        if t >= self.duration:
            return self.parts[-1].evaluate(self.parts[-1].duration)
        i = int(np.searchsorted(self.starts, t, side="right")) - 1
        i = min(max(i, 0), len(self.parts) - 1)
        return self.parts[i].evaluate(t - self.starts[i])


class _Stack(_Timeline):
    """Several arms side by side; each part is held at its end after it finishes."""

    def __init__(self, parts: Sequence[_Timeline]) -> None:
        self.parts = list(parts)
        self.duration = max(p.duration for p in self.parts)
        self.n = sum(p.n for p in self.parts)
        self.stretchable = all(p.stretchable for p in self.parts)

    def evaluate(self, t: float) -> State:
        states = [p.evaluate(t) for p in self.parts]
        return tuple(np.concatenate([s[i] for s in states]) for i in range(3))  # type: ignore[return-value]


def _on_grid(timeline: _Timeline, dt: float) -> tuple[_Timeline, int]:
    """Snap a timeline whose duration is (within float error) a multiple of dt onto the grid."""
    steps = int(round(timeline.duration / dt))
    if abs(steps * dt - timeline.duration) > _GRID_TOL:
        raise PlanningError(
            "timing_grid", f"duration {timeline.duration} s is not a multiple of dt = {dt}"
        )
    if steps == 0 or steps * dt == timeline.duration:
        return timeline, steps
    return _Scaled(timeline, steps * dt / timeline.duration), steps


# --------------------------------------------------------------------------------------------
# TimedTrajectory
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TimedTrajectory:
    """Samples of a joint motion at ``times = k * dt``, k = 0..N-1.

    ``q``, ``qd``, ``qdd`` are (N, n). The first sample is the start and the last the goal; the
    motion lasts ``duration = (N - 1) * dt``. The continuous motion behind the samples is kept
    (:meth:`at`) so the trajectory can be stretched exactly (:meth:`stretched`).
    """

    dt: float
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    _timeline: _Timeline = field(repr=False)

    @classmethod
    def _sample(cls, timeline: _Timeline, dt: float) -> TimedTrajectory:
        timeline, steps = _on_grid(timeline, dt)
        times = [k * dt for k in range(steps)] + [timeline.duration]  # last one: the goal exactly
        states = [timeline.evaluate(min(t, timeline.duration)) for t in times]
        q, qd, qdd = (np.array([s[i] for s in states]) for i in range(3))
        return cls(dt, q, qd, qdd, timeline)

    @classmethod
    def hold(cls, q: np.ndarray, steps: int = 0, dt: float = CONTROL_DT) -> TimedTrajectory:
        """Stand still at `q` for `steps` control periods (steps + 1 samples)."""
        q = np.asarray(q, dtype=float)
        return cls._sample(_Linear(q, np.zeros_like(q), steps * dt), dt)

    # -- properties ---------------------------------------------------------------------------

    @property
    def times(self) -> np.ndarray:
        return np.arange(len(self.q)) * self.dt

    @property
    def num_steps(self) -> int:
        """Number of control periods (samples - 1)."""
        return len(self.q) - 1

    @property
    def duration(self) -> float:
        return self.num_steps * self.dt

    @property
    def n(self) -> int:
        return self.q.shape[1]

    @property
    def start(self) -> np.ndarray:
        return self.q[0]

    @property
    def goal(self) -> np.ndarray:
        return self.q[-1]

    def at(self, t: float) -> State:
        """Continuous (q, qd, qdd) at time t (clamped to [0, duration])."""
        return self._timeline.evaluate(min(max(t, 0.0), self._timeline.duration))

    # -- composition --------------------------------------------------------------------------

    def then(self, *others: TimedTrajectory) -> TimedTrajectory:
        """This trajectory followed by `others` (each must start where the previous ended)."""
        return concatenate([self, *others])

    def stretched(self, num_steps: int) -> TimedTrajectory:
        """The same path played uniformly slower so it lasts `num_steps` control periods.

        Velocity, acceleration and jerk scale by 1/k, 1/k^2, 1/k^3 (k >= 1), so limits keep
        holding. Refused for trajectories with a non-zero boundary velocity piece (a throw).
        """
        if num_steps < self.num_steps:
            raise PlanningError(
                "timing_infeasible",
                f"cannot compress {self.num_steps} steps into {num_steps} without breaking limits",
            )
        if num_steps == self.num_steps:
            return self
        if self.num_steps == 0:
            return TimedTrajectory.hold(self.goal, num_steps, self.dt)
        if not self._timeline.stretchable:
            raise PlanningError("timing_infeasible", "a throw trajectory cannot be stretched")
        k = num_steps / self.num_steps
        return TimedTrajectory._sample(_Scaled(self._timeline, k), self.dt)

    def delayed(self, steps: int) -> TimedTrajectory:
        """Wait `steps` control periods at the start, then play this trajectory."""
        if steps <= 0:
            return self
        return TimedTrajectory.hold(self.start, steps, self.dt).then(self)

    def padded(self, num_steps: int) -> TimedTrajectory:
        """Hold the goal at the end so the trajectory lasts `num_steps` periods (>= current)."""
        if num_steps <= self.num_steps:
            return self
        return self.then(TimedTrajectory.hold(self.goal, num_steps - self.num_steps, self.dt))

    def arm(self, side: Side) -> TimedTrajectory:
        """One arm's joints of a two-arm trajectory ``[left n, right n]``."""
        if self.n % 2:
            raise ValueError(f"arm() needs a two-arm trajectory, this one has {self.n} DoF")
        sl = arm_slices(self.n // 2)[side]
        return TimedTrajectory(
            self.dt, self.q[:, sl], self.qd[:, sl], self.qdd[:, sl], _Select(self._timeline, sl)
        )

    # -- checks and actions ------------------------------------------------------------------

    def limit_ratios(self, limits: JointLimits) -> dict[str, float]:
        """max |qd|/vmax and |qdd|/amax over samples, and the worst position-limit violation."""
        _check_dim(limits, self.n)
        below = np.max(limits.lower - self.q)
        above = np.max(self.q - limits.upper)
        return {
            "velocity": float(np.max(np.abs(self.qd) / limits.velocity)),
            "acceleration": float(np.max(np.abs(self.qdd) / limits.acceleration)),
            "position_violation": float(max(below, above, 0.0)),
        }

    def check_limits(self, limits: JointLimits, tol: float = _LIMIT_TOL) -> None:
        """Raise PlanningError('timing_limits') if any sample breaks a limit."""
        r = self.limit_ratios(limits)
        if r["velocity"] > 1 + tol or r["acceleration"] > 1 + tol or r["position_violation"] > tol:
            raise PlanningError("timing_limits", f"limits broken at a sample: {r}")

    def to_actions(self, left_opening: Opening = 1.0, right_opening: Opening = 1.0) -> np.ndarray:
        """(N, 2 (n + 1)) actions ``[left n, left opening, right n, right opening]`` of a
        two-arm trajectory ``[left n, right n]``. An opening is a constant, an (N,) array or a
        callable ``times -> (N,)``."""
        if self.n % 2:
            raise ValueError(f"to_actions needs a two-arm trajectory, this one has {self.n} DoF")
        layout = ActionLayout(self.n // 2)
        left, right = self.q[:, : layout.arm_joints], self.q[:, layout.arm_joints :]
        openings = {
            "left": _opening_array(left_opening, self.times),
            "right": _opening_array(right_opening, self.times),
        }
        return layout.compose({"left": left, "right": right}, openings)


class _Select(_Timeline):
    def __init__(self, inner: _Timeline, sl: slice) -> None:
        self.inner, self.sl = inner, sl
        self.duration, self.stretchable = inner.duration, inner.stretchable
        self.n = len(range(*sl.indices(inner.n)))

    def evaluate(self, t: float) -> State:
        return tuple(x[self.sl] for x in self.inner.evaluate(t))  # type: ignore[return-value]


Opening = float | np.ndarray | Callable[[np.ndarray], np.ndarray]


def _opening_array(opening: Opening, times: np.ndarray) -> np.ndarray:
    values = opening(times) if callable(opening) else opening
    arr = np.broadcast_to(np.asarray(values, dtype=float), times.shape)
    return np.clip(arr, 0.0, 1.0)


def concatenate(trajectories: Sequence[TimedTrajectory], tol: float = 1e-6) -> TimedTrajectory:
    """Play trajectories one after another; each must start at the previous one's end state."""
    trajs = list(trajectories)
    if not trajs:
        raise ValueError("concatenate needs at least one trajectory")
    dt, n = trajs[0].dt, trajs[0].n
    for a, b in zip(trajs, trajs[1:], strict=False):
        if b.dt != dt or b.n != n:
            raise ValueError("concatenate: trajectories differ in dt or number of joints")
        gap = max(np.max(np.abs(a.q[-1] - b.q[0])), np.max(np.abs(a.qd[-1] - b.qd[0])))
        if gap > tol:
            raise PlanningError("timing_discontinuous", f"segments do not join (gap {gap:.3g})")
    if len(trajs) == 1:
        return trajs[0]
    stack = [trajs[0].q] + [t.q[1:] for t in trajs[1:]]
    q = np.vstack(stack)
    qd = np.vstack([trajs[0].qd] + [t.qd[1:] for t in trajs[1:]])
    qdd = np.vstack([trajs[0].qdd] + [t.qdd[1:] for t in trajs[1:]])
    return TimedTrajectory(dt, q, qd, qdd, _Concat([t._timeline for t in trajs]))


def stack_arms(left: TimedTrajectory, right: TimedTrajectory) -> TimedTrajectory:
    """[left, right] side by side; the shorter one holds its goal until the longer one ends."""
    if left.dt != right.dt:
        raise ValueError("stack_arms: trajectories differ in dt")
    steps = max(left.num_steps, right.num_steps)
    left, right = left.padded(steps), right.padded(steps)
    return TimedTrajectory(
        left.dt,
        np.hstack([left.q, right.q]),
        np.hstack([left.qd, right.qd]),
        np.hstack([left.qdd, right.qdd]),
        _Stack([left._timeline, right._timeline]),
    )


# --------------------------------------------------------------------------------------------
# Paths
# --------------------------------------------------------------------------------------------


def _check_dim(limits: JointLimits, n: int) -> None:
    if limits.n != n:
        raise ValueError(f"limits are for {limits.n} joints, the motion has {n}")


def _merge_collinear(points: np.ndarray, tol: float) -> np.ndarray:
    """Drop repeated points and interior points lying on the line between their neighbours."""
    keep = [points[0]]
    for p in points[1:]:
        if np.linalg.norm(p - keep[-1]) > tol:
            keep.append(p)
    pts = np.array(keep)
    if len(pts) <= 2:
        return pts
    out = [pts[0]]
    run_start = 0
    for i in range(2, len(pts)):
        # Can the run pts[run_start..i] be one segment?  All interior points on the chord, in order.
        a, b = pts[run_start], pts[i]
        chord = b - a
        length2 = float(chord @ chord)
        inner = pts[run_start + 1 : i]
        s = (inner - a) @ chord / length2
        off = np.linalg.norm(inner - a - s[:, None] * chord, axis=1)
        ordered = np.all(np.diff(np.concatenate([[0.0], s, [1.0]])) > 0)
        if not (ordered and np.all(off <= tol)):
            out.append(pts[i - 1])
            run_start = i - 1
    out.append(pts[-1])
    return np.array(out)


def _path_limits(dq: np.ndarray, limits: JointLimits) -> tuple[float, float, float]:
    moving = np.abs(dq) > 0
    mag = np.abs(dq[moving])
    return (
        float(np.min(limits.velocity[moving] / mag)),
        float(np.min(limits.acceleration[moving] / mag)),
        float(np.min(limits.jerk[moving] / mag)),
    )


def _ruckig_1dof(vmax: float, amax: float, jmax: float, dt: float) -> Trajectory:
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [1.0], [0.0], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [vmax], [amax], [jmax]
    inp.duration_discretization = DurationDiscretization.Discrete
    return _calculate(Ruckig(1, dt), inp, 1, "path segment")


def _calculate(otg: Ruckig, inp: InputParameter, n: int, what: str) -> Trajectory:
    traj = Trajectory(n)
    try:
        result = otg.calculate(inp, traj)
    except (RuntimeError, ValueError) as exc:
        # ruckig raises on invalid input; a result code missing from its Python enum (e.g. -101
        # on very long segments) surfaces as ValueError
        raise PlanningError("timing_failed", f"ruckig {what}: {exc}") from exc
    if result not in (Result.Working, Result.Finished):
        raise PlanningError("timing_failed", f"ruckig {what}: {result}")
    return traj


def time_path(
    waypoints: np.ndarray,
    limits: JointLimits,
    dt: float = CONTROL_DT,
    *,
    merge_tol: float = 1e-9,
) -> TimedTrajectory:
    """Time a joint polyline exactly along its segments, at rest at every corner.

    `waypoints` is (K, n) (both arms' joints move both arms together: they start and arrive
    together).
    Each straight run is a 1-DoF jerk-limited Ruckig profile of its path parameter lasting a
    whole number of :data:`SEGMENT_QUANTUM` (the same at every rate); corners are visited at
    rest; the whole path is held at its goal up to the next control step. Raises
    ``PlanningError('joint_limits')`` if a waypoint is outside the position limits.
    """
    pts = np.atleast_2d(np.asarray(waypoints, dtype=float))
    _check_dim(limits, pts.shape[1])
    if not np.all(np.isfinite(pts)):
        raise PlanningError("timing_failed", "waypoints contain non-finite values")
    bad = (pts < limits.lower - 1e-9) | (pts > limits.upper + 1e-9)
    if np.any(bad):
        k, j = np.argwhere(bad)[0]
        raise PlanningError(
            "joint_limits", f"waypoint {k} joint {j} = {pts[k, j]:.4f} out of range"
        )
    pts = _merge_collinear(pts, merge_tol)
    segments = [
        _PathSegment(a, b, _ruckig_1dof(*_path_limits(b - a, limits), SEGMENT_QUANTUM))
        for a, b in zip(pts, pts[1:], strict=False)
    ]
    if not segments:
        return TimedTrajectory.hold(pts[0], 0, dt)
    if abs(dt - SEGMENT_QUANTUM) < _GRID_TOL:
        # at the reference rate every corner is a sample
        return concatenate([TimedTrajectory._sample(s, dt) for s in segments])
    return TimedTrajectory._sample(_rounded_up(_Concat(segments), dt), dt)


def _rounded_up(timeline: _Timeline, dt: float) -> _Timeline:
    """`timeline` followed by a hold at its end up to the next multiple of `dt`."""
    steps = _steps_at_least(timeline.duration, dt)
    pad = steps * dt - timeline.duration
    if pad <= _GRID_TOL:
        return timeline
    q_end = timeline.evaluate(timeline.duration)[0]
    return _Concat([timeline, _Linear(q_end, np.zeros_like(q_end), pad)])


def synchronize(
    *trajectories: TimedTrajectory, num_steps: int | None = None
) -> list[TimedTrajectory]:
    """Stretch trajectories so all end at the same control step (the slowest's, or `num_steps`).

    Stretching is a uniform slow-down of each path, so paths and limits are kept.
    """
    longest = max(t.num_steps for t in trajectories)
    steps = longest if num_steps is None else num_steps
    if steps < longest:
        raise PlanningError(
            "timing_infeasible", f"needs {longest} control steps, {steps} were requested"
        )
    return [t.stretched(steps) for t in trajectories]


def rendezvous(
    left_path: np.ndarray,
    right_path: np.ndarray,
    limits: JointLimits,
    dt: float = CONTROL_DT,
    *,
    arrive_at: float | None = None,
) -> TimedTrajectory:
    """Both arms follow their own paths ((K, n) each) and reach their last waypoints (the
    meeting configurations, e.g. for a handover) at the same control step.

    `limits` are for both arms (2 n joints). `arrive_at` (s from the start, rounded up to the
    grid) requests a later common arrival; ``PlanningError('timing_infeasible')`` if an arm
    cannot make it by then.
    """
    _check_dim(limits, 2 * np.shape(left_path)[1])
    left = time_path(left_path, limits.arm("left"), dt)
    right = time_path(right_path, limits.arm("right"), dt)
    steps = None if arrive_at is None else _steps_at_least(arrive_at, dt)
    left, right = synchronize(left, right, num_steps=steps)
    return stack_arms(left, right)


def _steps_at_least(t: float, dt: float) -> int:
    return max(int(np.ceil(t / dt - 1e-9)), 0)


# --------------------------------------------------------------------------------------------
# Gripper schedules
# --------------------------------------------------------------------------------------------


def opening_rate(gripper: GripperSpec) -> float:
    """The fastest opening change the finger velocity limit allows (opening units per second)."""
    return gripper.opening_rate


def gripper_schedule(
    num_samples: int,
    initial: float,
    events: Sequence[tuple[int, float]] = (),
    *,
    rate: float | None = None,
    dt: float = CONTROL_DT,
) -> np.ndarray:
    """Opening per sample: starts at `initial`; at sample index i of each ``(i, target)`` event
    it moves to `target` - at once, or at `rate` opening units per second."""
    out = np.empty(num_samples)
    value, target, k_event = float(initial), float(initial), 0
    evs = sorted(events)
    step = np.inf if rate is None else rate * dt
    for k in range(num_samples):
        while k_event < len(evs) and evs[k_event][0] <= k:
            target = float(evs[k_event][1])
            k_event += 1
        value += float(np.clip(target - value, -step, step))
        out[k] = value
    return np.clip(out, 0.0, 1.0)

"""Collision-checked joint-space paths for one or both arms.

:func:`plan_path` returns waypoints ``(K, 12)`` in ``q12`` whose straight segments are all
collision-free - held objects included - under the requested clearances, checked at a given
*resolution*: between two checked configurations no point of the robot moves more than
``resolution`` metres (a per-joint bound on the lever arm of every link, from
:meth:`PlanningModel.path_distance`, not a joint-angle step).

Search, in order: the straight segment; one random via-point (around the midpoint, then anywhere);
a bidirectional RRT-Connect; then random shortcutting. With ``refine``, a
``KinematicTrajectoryOptimization`` (SNOPT) seeded from that path smooths it under
minimum-distance constraints; its result is sampled back into waypoints and kept only if it
passes the same dense check. Every returned path is re-verified densely before it is returned;
a path that fails is never returned (``PlanningError`` instead).

If ``clearance >= resolution`` and ``env_clearance >= resolution / 2``, a path that passes the
check is collision-free in continuous motion, not only at the checked samples.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence

import numpy as np
from pydrake.all import (
    BsplineBasis,
    BsplineTrajectory,
    KinematicTrajectoryOptimization,
    KnotVectorType,
    MinimumDistanceLowerBoundConstraint,
    SnoptSolver,
    SolverOptions,
)

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.model import PlanningModel

#: RRT-Connect extension step, as a bound on robot-point motion (m).
RRT_STEP = 0.25


def plan_path(
    model: PlanningModel,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    *,
    arms: Sequence[str] = SIDES,
    clearance: float = 0.01,
    env_clearance: float = 0.005,
    resolution: float = 0.01,
    ignore: Iterable[str] = (),
    refine: bool = False,
    via_tries: int = 200,
    max_time: float = 5.0,
    shortcut_iters: int = 60,
    rng: np.random.Generator | int | None = 0,
) -> np.ndarray:
    """Collision-free waypoints (K, 12) from `q_start` to `q_goal` (both q12).

    Only the joints of `arms` move (the others must be equal in start and goal).
    `clearance` (m) applies between the two arms and what they hold, `env_clearance` (m) to
    each arm's self pairs, the table and the objects; objects in `ignore` are not checked.
    Raises PlanningError ('start_in_collision', 'goal_in_collision', 'no_path',
    'path_in_collision').
    """
    q_start, q_goal = _check_input(model, q_start, q_goal, arms)
    moving = np.zeros(12, bool)
    for side in arms:
        moving[model.side_slice(side)] = True
    rng = np.random.default_rng(rng)
    with model.ignoring(ignore):
        model.set_padding(clearance, env_clearance)
        model.checker.set_edge_step_size(resolution)
        for q, what in ((q_start, "start"), (q_goal, "goal")):
            if not model.collision_free(q):
                raise PlanningError(f"{what}_in_collision", _pairs_text(model, q, what))
        planner = _Planner(model, moving, rng)
        path = planner.solve(q_start, q_goal, via_tries, max_time)
        path = planner.shortcut(path, shortcut_iters)
        if refine:
            refined = refine_path(model, path, clearance=clearance, env_clearance=env_clearance)
            if refined is not None and verify_path(model, refined, resolution):
                path = refined
        model.set_padding(clearance, env_clearance)
        if not verify_path(model, path, resolution):
            raise PlanningError(
                "path_in_collision",
                "the planned path failed the final dense collision check "
                f"at {resolution * 100:.1f} cm resolution",
            )
    return path


def verify_path(model: PlanningModel, path: np.ndarray, resolution: float = 0.01) -> bool:
    """Whether every straight segment of `path` is collision-free (current padding) when
    checked so that no robot point moves more than `resolution` between checks."""
    configs = []
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(1, int(np.ceil(model.path_distance(a, b) / resolution)))
        for t in np.linspace(0.0, 1.0, n + 1)[:-1]:
            configs.append(model.full_q(a + t * (b - a)))
    configs.append(model.full_q(path[-1]))
    return bool(np.all(model.checker.CheckConfigsCollisionFree(configs)))


def sample_configuration(
    model: PlanningModel,
    rng: np.random.Generator,
    *,
    clearance: float = 0.03,
    env_clearance: float = 0.01,
    tcp_region: tuple[np.ndarray, np.ndarray] | None = None,
    max_tries: int = 100_000,
) -> np.ndarray:
    """A uniformly random q12 within the limits that is collision-free with the given
    clearances and, with `tcp_region` = (lower xyz, upper xyz), has both TCPs inside it."""
    model.set_padding(clearance, env_clearance)
    for _ in range(max_tries):
        q = rng.uniform(model.lower, model.upper)
        if tcp_region is not None:
            lo, hi = tcp_region
            ps = [model.tcp_pose(q, side).translation() for side in SIDES]
            if not all(np.all(p >= lo) and np.all(p <= hi) for p in ps):
                continue
        if model.collision_free(q):
            return q
    raise PlanningError("no_sample", f"no valid configuration in {max_tries} samples")


# --------------------------------------------------------------------------------------------
# search
# --------------------------------------------------------------------------------------------


class _Planner:
    def __init__(self, model: PlanningModel, moving: np.ndarray, rng: np.random.Generator):
        self.m = model
        self.moving = moving
        self.rng = rng
        self.lower, self.upper = model.lower, model.upper
        self.edge_checks = 0

    def free(self, q: np.ndarray) -> bool:
        return self.m.collision_free(q)

    def edge(self, a: np.ndarray, b: np.ndarray) -> bool:
        self.edge_checks += 1
        return bool(self.m.checker.CheckEdgeCollisionFree(self.m.full_q(a), self.m.full_q(b)))

    def random(self) -> np.ndarray:
        q = self.base.copy()
        q[self.moving] = self.rng.uniform(self.lower[self.moving], self.upper[self.moving])
        return q

    def solve(self, start, goal, via_tries: int, max_time: float) -> np.ndarray:
        self.base = start.copy()
        if self.edge(start, goal):
            return np.array([start, goal])
        deadline = time.perf_counter() + max_time
        mid = 0.5 * (start + goal)
        span = np.abs(goal - start)
        for k in range(via_tries):
            if k < via_tries // 2:  # near the midpoint, spreading out
                sigma = 0.2 + 1.5 * k / via_tries + 0.5 * span
                v = mid.copy()
                v[self.moving] += self.rng.normal(0.0, sigma[self.moving])
                v = np.clip(v, self.lower, self.upper)
            else:
                v = self.random()
            if self.free(v) and self.edge(start, v) and self.edge(v, goal):
                return np.array([start, v, goal])
            if time.perf_counter() > deadline:
                break
        path = self.rrt_connect(start, goal, deadline)
        if path is None:
            raise PlanningError(
                "no_path",
                f"no collision-free path found within {max_time:.1f} s "
                f"({self.edge_checks} edge checks)",
            )
        return path

    def rrt_connect(self, start, goal, deadline) -> np.ndarray | None:
        trees = [([start], [-1]), ([goal], [-1])]
        w = self.m.joint_radius
        while time.perf_counter() < deadline:
            target = self.random()
            a, b = trees
            new = self._extend(a, target, w)
            if new is not None:
                reached = self._connect(b, a[0][new], w)
                if reached is not None:
                    pa, pb = self._branch(a, new), self._branch(b, reached)
                    path = pa[::-1] + pb
                    if trees[0][0][0] is not start:
                        path = path[::-1]
                    return np.array(path)
            trees.reverse()
        return None

    def _nearest(self, tree, q, w) -> int:
        nodes = np.asarray(tree[0])
        return int(np.argmin(np.abs(nodes - q) @ w))

    def _steer(self, q_from, q_to, w) -> np.ndarray:
        d = float(np.abs(q_to - q_from) @ w)
        if d <= RRT_STEP:
            return q_to
        return q_from + (q_to - q_from) * (RRT_STEP / d)

    def _extend(self, tree, target, w) -> int | None:
        i = self._nearest(tree, target, w)
        q_new = self._steer(tree[0][i], target, w)
        if self.edge(tree[0][i], q_new):
            tree[0].append(q_new)
            tree[1].append(i)
            return len(tree[0]) - 1
        return None

    def _connect(self, tree, target, w) -> int | None:
        while True:
            i = self._nearest(tree, target, w)
            q_new = self._steer(tree[0][i], target, w)
            if not self.edge(tree[0][i], q_new):
                return None
            tree[0].append(q_new)
            tree[1].append(i)
            if np.array_equal(q_new, target):
                return len(tree[0]) - 1

    @staticmethod
    def _branch(tree, i) -> list[np.ndarray]:
        out = []
        while i >= 0:
            out.append(tree[0][i])
            i = tree[1][i]
        return out

    def shortcut(self, path: np.ndarray, iters: int) -> np.ndarray:
        """Random shortcutting: drop waypoints, then try joining random points of two segments."""
        path = [p for p in path]
        i = 0
        while i < len(path) - 2:  # greedy: drop intermediate waypoints first
            if self.edge(path[i], path[i + 2]):
                path.pop(i + 1)
            else:
                i += 1
        for _ in range(iters):
            if len(path) < 3:
                break
            i, j = sorted(self.rng.choice(len(path) - 1, 2, replace=False))
            if i == j:
                continue
            a = path[i] + self.rng.uniform() * (path[i + 1] - path[i])
            b = path[j] + self.rng.uniform() * (path[j + 1] - path[j])
            if self.edge(a, b):
                path = path[: i + 1] + [a, b] + path[j + 1 :]
                path = [p for k, p in enumerate(path) if k == 0 or not np.allclose(p, path[k - 1])]
        return np.array(path)


# --------------------------------------------------------------------------------------------
# trajectory optimisation refinement
# --------------------------------------------------------------------------------------------


def refine_path(
    model: PlanningModel,
    path: np.ndarray,
    *,
    clearance: float = 0.01,
    env_clearance: float = 0.005,
    num_control_points: int = 12,
    num_samples: int = 25,
    margin: float = 0.005,
    output_points: int = 40,
) -> np.ndarray | None:
    """Smooth `path` with KinematicTrajectoryOptimization (path length + duration cost,
    velocity limits, minimum distances + `margin` at `num_samples` interior samples), seeded
    from the path. Returns `output_points` waypoints sampled from the result, or None if the
    optimiser fails. The result is *not* yet dense-checked (``plan_path`` does that)."""
    m = model
    nq = m.num_positions
    order = 4
    seed = _resample(m, path, num_control_points)
    basis = BsplineBasis(order, num_control_points, KnotVectorType.kClampedUniform, 0.0, 1.0)
    traj = BsplineTrajectory(basis, [m.full_q(q).reshape(-1, 1) for q in seed])
    kto = KinematicTrajectoryOptimization(traj)
    prog = kto.get_mutable_prog()
    fixed = m.full_q(path[0])
    moving = np.zeros(nq, bool)
    moving[m.q12_indices] = np.any(np.abs(path - path[0]) > 0, axis=0)
    lower, upper = fixed.copy(), fixed.copy()
    lower[m.q12_indices] = np.where(moving[m.q12_indices], m.lower, path[0])
    upper[m.q12_indices] = np.where(moving[m.q12_indices], m.upper, path[0])
    kto.AddPositionBounds(lower, upper)
    vmax = np.zeros(nq)
    vmax[m.q12_indices] = np.tile([j.velocity_limit for j in m.embodiment.arm.joints], 2)
    kto.AddVelocityBounds(-vmax, vmax)
    kto.AddPathPositionConstraint(m.full_q(path[0]), m.full_q(path[0]), 0.0)
    kto.AddPathPositionConstraint(m.full_q(path[-1]), m.full_q(path[-1]), 1.0)
    kto.AddPathVelocityConstraint(np.zeros(nq), np.zeros(nq), 0.0)
    kto.AddPathVelocityConstraint(np.zeros(nq), np.zeros(nq), 1.0)
    kto.AddDurationCost(1.0)
    kto.AddPathLengthCost(1.0)
    for kind, bound in (("arms", clearance), ("env", env_clearance)):
        c = MinimumDistanceLowerBoundConstraint(
            m.plant, bound + margin, m.distance_context(kind), None, 0.01
        )
        for s in np.linspace(0.0, 1.0, num_samples + 2)[1:-1]:
            kto.AddPathPositionConstraint(c, float(s))
    solver = SnoptSolver()
    options = SolverOptions()
    options.SetOption(solver.solver_id(), "Major feasibility tolerance", 1e-4)
    options.SetOption(solver.solver_id(), "Major optimality tolerance", 1e-4)
    result = solver.Solve(prog, None, options)
    if not result.is_success():
        return None
    out = kto.ReconstructTrajectory(result)
    ts = np.linspace(out.start_time(), out.end_time(), output_points)
    waypoints = np.array([m.q12(out.value(t).ravel()) for t in ts])
    waypoints[0], waypoints[-1] = path[0], path[-1]
    if not all(m.within_limits(q) for q in waypoints):
        return None
    return waypoints


def _resample(model: PlanningModel, path: np.ndarray, n: int) -> np.ndarray:
    """`n` points spaced evenly (in robot-motion length) along the polyline `path`."""
    seg = np.array([model.path_distance(a, b) for a, b in zip(path[:-1], path[1:], strict=True)])
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] == 0:
        return np.repeat(path[:1], n, axis=0)
    s = np.linspace(0.0, cum[-1], n)
    return np.array([np.interp(s, cum, path[:, j]) for j in range(path.shape[1])]).T


# --------------------------------------------------------------------------------------------
# input checks and messages
# --------------------------------------------------------------------------------------------


def _check_input(model, q_start, q_goal, arms) -> tuple[np.ndarray, np.ndarray]:
    q_start = np.asarray(q_start, dtype=float)
    q_goal = np.asarray(q_goal, dtype=float)
    for q, what in ((q_start, "start"), (q_goal, "goal")):
        if q.shape != (12,) or not np.all(np.isfinite(q)):
            raise ValueError(f"q_{what} must be a finite 12-vector, got shape {q.shape}")
        if not model.within_limits(q):
            bad = np.flatnonzero((q < model.lower - 1e-6) | (q > model.upper + 1e-6))
            raise PlanningError(f"{what}_out_of_limits", f"q12 entries {bad.tolist()} violate limits")
    if not arms or set(arms) - set(SIDES):
        raise ValueError(f"arms must be a non-empty subset of {SIDES}, got {arms}")
    for side in SIDES:
        sl = model.side_slice(side)
        if side not in arms and not np.allclose(q_start[sl], q_goal[sl]):
            raise ValueError(f"the {side} arm is not planned for but its start and goal differ")
    return q_start, q_goal


def _pairs_text(model: PlanningModel, q: np.ndarray, what: str) -> str:
    pairs = model.colliding_pairs(q)
    listed = ", ".join(f"{a} - {b} ({d * 100:+.1f} cm beyond clearance)" for a, b, d in pairs[:4])
    return f"the {what} configuration violates its clearance: {listed or 'unknown pair'}"

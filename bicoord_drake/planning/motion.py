"""Collision-checked joint-space paths for one or both arms.

:func:`plan_path` returns waypoints ``(K, 2 n)`` in the model's configuration ``q`` (both arms'
n joints) whose straight segments are all collision-free - held objects included - under the
requested clearances, checked at a given *resolution*: between two checked configurations no
point of the robot moves more than ``resolution`` metres (a per-joint bound on the lever arm of
every link, from :meth:`PlanningModel.path_distance`, not a joint-angle step).

Search, in order: the straight segment; a via-point (one arm at a time in either order, then
random around the midpoint, then anywhere); a bidirectional RRT-Connect; then random
shortcutting. The search checks at a coarse resolution (rejecting colliding segments early, in
bisection order) and the path it finds is then verified at the requested resolution; if that
fails the search is repeated at the requested resolution. With ``refine``, a
``KinematicTrajectoryOptimization`` (SNOPT) seeded from the path smooths it under
minimum-distance constraints; its result is sampled back into waypoints and kept only if it
passes the same dense check. A path that fails the dense check is never returned
(``PlanningError`` instead).

Between two checks a robot point is at most ``resolution / 2`` from where it was checked, so
with ``clearance >= resolution`` and ``env_clearance >= resolution`` a checked path is
collision-free in continuous motion, not only at the samples.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator, Mapping, Sequence

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
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.models.table import TABLE_SIZE
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.model import PlanningModel

#: RRT-Connect extension step, as a bound on robot-point motion (m).
RRT_STEP = 0.25
#: Resolution (m) of the checks while searching; found paths are then verified at the fine
#: resolution, and the search is repeated at that resolution if the verification fails.
SEARCH_RESOLUTION = 0.04
#: SNOPT major-iteration cap of the trajectory refinement.
KTO_MAJOR_ITERATIONS = 100


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
    rrt_iters: int = 3000,
    shortcut_iters: int = 20,
    max_time: float = 30.0,
    rng: np.random.Generator | int | None = 0,
) -> np.ndarray:
    """Collision-free waypoints (K, 2 n) from `q_start` to `q_goal` (both arms' joints).

    Only the joints of `arms` move (the others must be equal in start and goal).
    `clearance` (m) applies between the two arms and what they hold, `env_clearance` (m) to
    each arm's self pairs, the table and the objects; objects in `ignore` are not checked.
    The search is seeded by `rng` and bounded by iteration counts (`via_tries`, `rrt_iters`,
    `shortcut_iters`), so it is reproducible; `max_time` (s) is only a safety stop.
    Raises PlanningError ('start_in_collision', 'goal_in_collision', 'no_path',
    'path_in_collision'; '*_out_of_limits').
    """
    q_start, q_goal = _check_input(model, q_start, q_goal, arms)
    moving = np.zeros(model.num_joints, bool)
    for side in arms:
        moving[model.side_slice(side)] = True
    rng = np.random.default_rng(rng)
    with model.ignoring(ignore), model.padded(clearance, env_clearance):
        for q, what in ((q_start, "start"), (q_goal, "goal")):
            if not model.collision_free(q):
                raise PlanningError(f"{what}_in_collision", _pairs_text(model, q, what))
        path = None
        deadline = time.perf_counter() + max_time
        for search_resolution in dict.fromkeys([max(SEARCH_RESOLUTION, resolution), resolution]):
            planner = _Planner(model, moving, rng, search_resolution)
            candidate = planner.solve(q_start, q_goal, via_tries, rrt_iters, deadline)
            candidate = planner.shortcut(candidate, shortcut_iters)
            if verify_path(model, candidate, resolution):
                path = candidate
                break
        if path is None:
            raise PlanningError(
                "path_in_collision",
                f"every path found failed the dense collision check at {resolution * 100:.1f} cm",
            )
        if refine:
            refined = refine_path(model, path, clearance=clearance, env_clearance=env_clearance)
            model.set_padding(clearance, env_clearance)
            if refined is not None and verify_path(model, refined, resolution):
                path = refined
    return path


def verify_path(model: PlanningModel, path: np.ndarray, resolution: float = 0.01) -> bool:
    """Whether every straight segment of `path` is collision-free (current padding) when
    checked so that no robot point moves more than `resolution` between checks."""
    path = np.asarray(path, dtype=float)
    if not all(model.within_limits(q) for q in path):
        return False
    return all(model.edge_free(a, b, resolution) for a, b in zip(path[:-1], path[1:], strict=True))


def sample_configuration(
    model: PlanningModel,
    rng: np.random.Generator,
    *,
    clearance: float = 0.03,
    env_clearance: float = 0.01,
    tcp_regions: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    max_tries: int = 200_000,
) -> np.ndarray:
    """A uniformly random configuration (both arms) within the joint limits, collision-free
    with the given clearances, with each TCP in its box `tcp_regions[side]` = (lower xyz,
    upper xyz), if any. Used for reachable IK targets (FK of a sample) and for test and
    benchmark cases."""
    regions = {
        side: (np.asarray(lo), np.asarray(hi)) for side, (lo, hi) in (tcp_regions or {}).items()
    }
    with model.padded(clearance, env_clearance):
        for _ in range(max_tries):
            q = rng.uniform(model.lower, model.upper)
            if all(
                _inside(model.tcp_pose(q, side).translation(), box) for side, box in regions.items()
            ):
                if model.collision_free(q):
                    return q
    raise PlanningError("no_sample", f"no valid configuration in {max_tries} samples")


def _inside(p: np.ndarray, box: tuple[np.ndarray, np.ndarray]) -> bool:
    return bool(np.all(p >= box[0]) and np.all(p <= box[1]))


def table_region(margin: float = 0.05, height: float = 0.6) -> tuple[np.ndarray, np.ndarray]:
    """The box above the table top (from `margin` to `height` above it), for `tcp_regions`."""
    sx, sy = TABLE_SIZE
    return (
        np.array([-sx / 2, -sy / 2, TABLE_TOP + margin]),
        np.array([sx / 2, sy / 2, TABLE_TOP + height]),
    )


# --------------------------------------------------------------------------------------------
# search
# --------------------------------------------------------------------------------------------


class _Planner:
    def __init__(self, model: PlanningModel, moving: np.ndarray, rng, resolution: float):
        self.m = model
        self.moving = moving
        self.rng = rng
        self.resolution = resolution
        self.lower, self.upper = model.lower, model.upper
        self.edge_checks = 0

    def free(self, q: np.ndarray) -> bool:
        return self.m.collision_free(q)

    def edge(self, a: np.ndarray, b: np.ndarray, endpoints: bool = False) -> bool:
        """Segment check (the ends are assumed free unless `endpoints`)."""
        self.edge_checks += 1
        return self.m.edge_free(a, b, self.resolution, endpoints=endpoints)

    def random(self) -> np.ndarray:
        q = self.base.copy()
        q[self.moving] = self.rng.uniform(self.lower[self.moving], self.upper[self.moving])
        return q

    def solve(self, start, goal, via_tries: int, rrt_iters: int, deadline: float) -> np.ndarray:
        self.base = start.copy()
        if self.edge(start, goal):
            return np.array([start, goal])
        for v in self._vias(start, goal, via_tries):
            if self.free(v) and self.edge(start, v) and self.edge(v, goal):
                return np.array([start, v, goal])
            if time.perf_counter() > deadline:
                break
        path = self.rrt_connect(start, goal, rrt_iters, deadline)
        if path is None:
            raise PlanningError(
                "no_path",
                f"no collision-free path: straight line, {via_tries} via-points and "
                f"{rrt_iters} RRT-Connect iterations failed ({self.edge_checks} edge checks)",
            )
        return path

    def _vias(self, start, goal, tries: int) -> Iterator[np.ndarray]:
        """Via-point candidates: one arm at a time (either order: often untangles a swap), then
        around the midpoint with a spread that grows, then anywhere within the limits."""
        if self.moving.all():
            for first in (self.m.side_slice(side) for side in SIDES):
                v = start.copy()
                v[first] = goal[first]
                yield v
        mid, span = 0.5 * (start + goal), np.abs(goal - start)
        for k in range(tries):
            if k < tries // 2:
                v = mid.copy()
                sigma = 0.2 + 1.5 * k / tries + 0.5 * span[self.moving]
                v[self.moving] += self.rng.normal(0.0, sigma)
                yield np.clip(v, self.lower, self.upper)
            else:
                yield self.random()

    def rrt_connect(self, start, goal, iters: int, deadline: float) -> np.ndarray | None:
        """Bidirectional RRT-Connect over the moving joints (trees alternate roles)."""
        trees = [([start], [-1]), ([goal], [-1])]  # (nodes, parent indices)
        w = self.m.joint_radius
        for _ in range(iters):
            if time.perf_counter() > deadline:
                return None
            a, b = trees
            new = self._extend(a, self.random(), w)
            if new is not None:
                reached = self._connect(b, a[0][new], w)
                if reached is not None:
                    path = self._branch(a, new)[::-1] + self._branch(b, reached)
                    if a[0][0] is not start:
                        path.reverse()
                    return np.array(path)
            trees.reverse()
        return None

    def _nearest(self, tree, q, w) -> int:
        d = np.abs(np.asarray(tree[0]) - q) * w
        n = self.m.arm_joints
        return int(np.argmin(np.maximum(d[:, :n].sum(1), d[:, n:].sum(1))))

    def _steer(self, q_from, q_to) -> np.ndarray:
        d = self.m.path_distance(q_from, q_to)
        if d <= RRT_STEP:
            return q_to
        return q_from + (q_to - q_from) * (RRT_STEP / d)

    def _extend(self, tree, target, w) -> int | None:
        i = self._nearest(tree, target, w)
        q_new = self._steer(tree[0][i], target)
        if self.edge(tree[0][i], q_new):
            tree[0].append(q_new)
            tree[1].append(i)
            return len(tree[0]) - 1
        return None

    def _connect(self, tree, target, w) -> int | None:
        while True:
            i = self._nearest(tree, target, w)
            q_new = self._steer(tree[0][i], target)
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
            if self.edge(a, b, endpoints=True):
                path = _dedupe(path[: i + 1] + [a, b] + path[j + 1 :])
        return np.array(path)


def _dedupe(path: list[np.ndarray]) -> list[np.ndarray]:
    """Drop waypoints equal (to 1e-9) to their predecessor; the two ends are kept exactly."""
    out = [path[0]]
    for p in path[1:-1]:
        if not np.allclose(p, out[-1], rtol=0.0, atol=1e-9):
            out.append(p)
    if len(out) > 1 and np.allclose(path[-1], out[-1], rtol=0.0, atol=1e-9):
        out.pop()
    out.append(path[-1])
    return out


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
    num_samples: int | None = None,
    margin: float = 0.005,
    output_points: int | None = None,
) -> np.ndarray | None:
    """Smooth `path` with KinematicTrajectoryOptimization (path length + duration cost,
    velocity limits, minimum distances + `margin` at `num_samples` interior samples - default:
    one per 10 cm of robot motion, 20 to 60), seeded from the path. Returns `output_points`
    waypoints (default: one per 2 cm of motion, at most 400) sampled from the result, or None
    if the optimiser fails. The result is *not* yet dense-checked (``plan_path`` does that)."""
    m = model
    nq = m.num_positions
    order = 4
    length = sum(m.path_distance(a, b) for a, b in zip(path[:-1], path[1:], strict=True))
    if num_samples is None:
        num_samples = int(np.clip(length / 0.1, 20, 60))
    if output_points is None:
        output_points = int(np.clip(length / 0.02, 10, 400))
    seed = _resample(m, path, num_control_points)
    basis = BsplineBasis(order, num_control_points, KnotVectorType.kClampedUniform, 0.0, 1.0)
    traj = BsplineTrajectory(basis, [m.full_q(q).reshape(-1, 1) for q in seed])
    kto = KinematicTrajectoryOptimization(traj)
    prog = kto.get_mutable_prog()
    fixed = m.full_q(path[0])
    moving = np.zeros(nq, bool)
    moving[m.q_indices] = np.any(np.abs(path - path[0]) > 0, axis=0)
    lower, upper = fixed.copy(), fixed.copy()
    lower[m.q_indices] = np.where(moving[m.q_indices], m.lower, path[0])
    upper[m.q_indices] = np.where(moving[m.q_indices], m.upper, path[0])
    kto.AddPositionBounds(lower, upper)
    vmax = np.zeros(nq)
    vmax[m.q_indices] = np.tile([j.velocity_limit for j in m.embodiment.arm.joints], 2)
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
    options.SetOption(solver.solver_id(), "Major iterations limit", KTO_MAJOR_ITERATIONS)
    result = solver.Solve(prog, None, options)
    # SNOPT often ends with info 41 ("cannot improve") on feasible points: judge feasibility.
    if not (
        result.is_success()
        or prog.CheckSatisfied(prog.GetAllConstraints(), result.GetSolution(), 1e-3)
    ):
        return None
    out = kto.ReconstructTrajectory(result)
    ts = np.linspace(out.start_time(), out.end_time(), output_points)
    waypoints = np.array([m.planning_q(out.value(t).ravel()) for t in ts])
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
        if q.shape != (model.num_joints,) or not np.all(np.isfinite(q)):
            raise ValueError(
                f"q_{what} must be a finite {model.num_joints}-vector, got shape {q.shape}"
            )
        if not model.within_limits(q):
            bad = np.flatnonzero((q < model.lower - 1e-6) | (q > model.upper + 1e-6))
            raise PlanningError(
                f"{what}_out_of_limits", f"q entries {bad.tolist()} are outside the joint limits"
            )
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

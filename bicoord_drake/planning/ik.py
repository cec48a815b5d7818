"""Bimanual inverse kinematics with inter-arm and environment clearance.

Both arms are solved in one nonlinear program over ``q = [left n, right n]`` (the model's
planning configuration; fingers fixed at the model's
openings): TCP position within ``pos_tol`` per axis, orientation within ``rot_tol`` (or only the
approach axis, gripper x, when ``free_axis``), a minimum distance ``clearance`` between the two
arms (and what they hold), a minimum distance ``env_clearance`` between each arm and the table,
the objects and itself, and a quadratic cost toward the nominal pose. Both clearances are set
per call (a handover brings the grippers within 2 cm; transport wants a margin).

Order of work:

1. Closed form, when the embodiment declares one (``Embodiment.closed_form_ik``, e.g. the
   ViperX's 6-joint spherical wrist; checked once per model): every exact branch of each arm
   (up to 8), combinations sorted by the cost; the first that meets both clearances is the
   answer. This is exact and takes about a millisecond. Other arms (the 7-joint Panda) start
   at step 2.
2. Otherwise the two-stage solve of the planning measurements note: a pose-only program (the
   arms decouple; it converges from the nominal pose), then the full program seeded from that
   answer (or from the closed-form branches). Seeds: the caller's ``seed`` (e.g. the previous
   keyframe), then the nominal pose; restarts perturb them or re-draw the failing arm.
3. SNOPT, then one IPOPT run from the best attempt as a fallback (IPOPT only, if SNOPT is
   unavailable).

Every answer is re-checked independently (pose errors, joint limits, the collision checker);
a failure raises :class:`PlanningError` naming the constraint that failed ('ik_unreachable':
position or orientation out of reach; 'ik_collision': which clearance, between which bodies).

>>> ik = BimanualIK(PlanningModel(demo_scene("cubes")))                # doctest: +SKIP
>>> q = ik.solve({"left": TcpTarget(X_WL), "right": TcpTarget(X_WR)}, clearance=0.03)
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from pydrake.all import (
    InverseKinematics,
    IpoptSolver,
    MinimumDistanceLowerBoundConstraint,
    RigidTransform,
    SnoptSolver,
    SolverOptions,
)

from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.sim.station import rigid_transform

#: Seeds of restarts are the base seed plus N(0, RESTART_SIGMA^2) per joint (rad).
RESTART_SIGMA = 0.4
#: Iteration cap of SNOPT (infeasible clearance programs otherwise run for seconds).
SNOPT_MAJOR_ITERATIONS = 100
#: Iteration cap of the IPOPT fallback (it is slow to give up on infeasible programs).
IPOPT_MAX_ITER = 200
#: Slack (m) by which the independent collision check trusts the optimiser's distances.
CHECK_SLACK = 1e-4
#: The smallest distance bound (m) the IK's clearance constraints use: 1 um, far below any
#: clearance that matters, but never exactly touching (see ``_add_clearance``).
MIN_BOUND = 1e-6


@dataclass(frozen=True)
class TcpTarget:
    """A TCP goal X_WT. `pos_tol` (m) bounds each position axis; `rot_tol` (rad) the rotation
    angle. With `free_axis`, any rotation about the gripper's x (approach) axis is allowed and
    `rot_tol` bounds the approach-axis direction only."""

    X_WT: RigidTransform
    pos_tol: float = 1e-3
    rot_tol: float = 0.01
    free_axis: bool = False

    def error(self, X_WA: RigidTransform) -> tuple[float, float]:
        """(max per-axis position error, rotation error) of an achieved TCP pose X_WA."""
        dp = float(np.max(np.abs(X_WA.translation() - self.X_WT.translation())))
        R = X_WA.rotation().matrix()
        R_t = self.X_WT.rotation().matrix()
        if self.free_axis:
            c = float(np.clip(R[:, 0] @ R_t[:, 0], -1.0, 1.0))
        else:
            c = float(np.clip((np.trace(R_t.T @ R) - 1.0) / 2.0, -1.0, 1.0))
        return dp, float(np.arccos(c))


class BimanualIK:
    """IK for one or both arms of a :class:`PlanningModel` (see the module docstring)."""

    def __init__(
        self,
        model: PlanningModel,
        *,
        nominal: np.ndarray | None = None,
        weights: np.ndarray | None = None,
        analytic: bool = True,
        solver: str = "snopt",
    ) -> None:
        """`nominal` (default: home) is the pose the cost pulls toward; `weights` weigh that
        cost per joint; `analytic` uses closed-form branches as exact candidates and seeds
        when the embodiment declares a closed form; `solver` is "snopt" (IPOPT as fallback) or
        "ipopt"."""
        self.model = model
        self.nominal = model.home.copy() if nominal is None else np.asarray(nominal, float)
        self.weights = (
            np.ones(model.num_joints) if weights is None else np.asarray(weights, dtype=float)
        )
        self.analytic = analytic and has_closed_form(model) and closed_form_applies(model)
        self._snopt = SnoptSolver()
        self._ipopt = IpoptSolver()
        self._use_snopt = solver == "snopt" and self._snopt.available() and self._snopt.enabled()
        self._snopt_options = SolverOptions()
        self._snopt_options.SetOption(
            self._snopt.solver_id(), "Major iterations limit", SNOPT_MAJOR_ITERATIONS
        )
        self._ipopt_options = SolverOptions()
        self._ipopt_options.SetOption(self._ipopt.solver_id(), "max_iter", IPOPT_MAX_ITER)
        self._ipopt_options.SetOption(self._ipopt.solver_id(), "max_cpu_time", 0.25)
        self._ipopt_options.SetOption(self._ipopt.solver_id(), "print_level", 0)
        self.last_attempts = 0
        self.last_method = ""

    # ------------------------------------------------------------------ public API
    def solve(
        self,
        targets: Mapping[str, TcpTarget],
        *,
        clearance: float = 0.03,
        env_clearance: float = 0.01,
        seed: np.ndarray | None = None,
        restarts: int = 10,
        ignore: Iterable[str] = (),
        q_fixed: Mapping[str, np.ndarray] | None = None,
        rng: np.random.Generator | int | None = 0,
        nominal: np.ndarray | None = None,
    ) -> np.ndarray:
        """Joint angles q (both arms) reaching `targets` ({side: TcpTarget}) with `clearance`
        (m) between the arms and `env_clearance` (m) to everything else; objects in `ignore`
        are not checked. Arms in `q_fixed` ({side: its n angles}) stay put. `nominal` replaces the
        pose the cost pulls toward for this call. Raises PlanningError."""
        unknown = set(targets) - set(SIDES)
        if unknown or not targets:
            raise ValueError(f"targets must be keyed by 'left'/'right', got {sorted(targets)}")
        q_fixed = dict(q_fixed or {})
        if set(q_fixed) & set(targets):
            raise ValueError("an arm cannot both have a target and be fixed")
        rng = np.random.default_rng(rng)
        saved = self.nominal
        if nominal is not None:
            self.nominal = np.asarray(nominal, dtype=float)
        try:
            seeds = self._seeds(seed, q_fixed)
            with self.model.ignoring(ignore), self.model.padded(clearance, env_clearance):
                return self._solve(targets, clearance, env_clearance, seeds, restarts, q_fixed, rng)
        finally:
            self.nominal = saved

    def solve_single(
        self,
        side: str,
        target: TcpTarget,
        q_other: np.ndarray,
        **kwargs,
    ) -> np.ndarray:
        """One arm reaches `target` while the other stays at `q_other` (its n angles); returns
        both arms' q. Keyword arguments are those of :meth:`solve`."""
        other = other_side(side)
        return self.solve({side: target}, q_fixed={other: np.asarray(q_other)}, **kwargs)

    # ------------------------------------------------------------------ internals
    def _seeds(self, seed: np.ndarray | None, q_fixed: Mapping[str, np.ndarray]) -> list:
        seeds = [] if seed is None else [np.asarray(seed, dtype=float).copy()]
        seeds.append(self.nominal.copy())
        for s in seeds:
            for side, q in q_fixed.items():
                s[self.model.side_slice(side)] = q
        return seeds

    def _program(self, targets, q_fixed, nominal):
        m = self.model
        ik = InverseKinematics(m.plant, m.distance_context("env"), with_joint_limits=True)
        prog, q = ik.get_mutable_prog(), ik.q()
        fixed = m.full_q(nominal)
        free = np.zeros(m.num_positions, bool)
        free[m.q_indices] = True
        for side in q_fixed:
            free[m.arm_indices[side]] = False
        prog.AddBoundingBoxConstraint(fixed[~free], fixed[~free], q[~free])
        world = m.plant.world_frame()
        labelled = []
        for side, t in targets.items():
            frame = m.tcp_frames[side]
            p = t.X_WT.translation()
            tol = np.full(3, t.pos_tol)
            b = ik.AddPositionConstraint(frame, np.zeros(3), world, p - tol, p + tol)
            labelled.append((b, f"{side} TCP position (tol {t.pos_tol * 1e3:.1f} mm)"))
            if t.free_axis:
                axis = t.X_WT.rotation().matrix()[:, 0]
                b = ik.AddAngleBetweenVectorsConstraint(
                    world, axis, frame, np.array([1.0, 0, 0]), 0.0, t.rot_tol
                )
                labelled.append((b, f"{side} TCP approach axis (tol {t.rot_tol:.3f} rad)"))
            else:
                b = ik.AddOrientationConstraint(
                    world, t.X_WT.rotation(), frame, RigidTransform().rotation(), t.rot_tol
                )
                labelled.append((b, f"{side} TCP orientation (tol {t.rot_tol:.3f} rad)"))
        prog.AddQuadraticErrorCost(np.diag(self.weights), self.nominal, q[m.q_indices])
        return ik, prog, q, labelled

    def _add_clearance(self, prog, q, clearance, env_clearance):
        m = self.model
        out = []
        for kind, bound, label in (
            ("arms", clearance, f"inter-arm clearance {clearance * 100:.1f} cm"),
            ("env", env_clearance, f"environment clearance {env_clearance * 100:.1f} cm"),
        ):
            # A bound of exactly 0 lets the solver converge onto touching geometry, where
            # Drake's box-box gradient can abort the process ("Unreachable code" in
            # BoxBoxGradient: clean_table seed 0's drop, drake 1.51); MIN_BOUND keeps it off.
            c = MinimumDistanceLowerBoundConstraint(
                m.plant, max(bound, MIN_BOUND), m.distance_context(kind), None, 0.01
            )
            out.append((prog.AddConstraint(c, q), label))
        return out

    def _run(self, prog, q, q0, solver=None):
        solver = solver or (self._snopt if self._use_snopt else self._ipopt)
        self.last_attempts += 1
        options = self._ipopt_options if solver is self._ipopt else self._snopt_options
        return solver.Solve(prog, self.model.full_q(q0), options)

    def _solve(self, targets, clearance, env_clearance, seeds, restarts, q_fixed, rng):
        m = self.model
        self.last_attempts = 0
        self.last_method = ""
        free = np.ones(m.num_joints, bool)
        for side in q_fixed:
            free[m.side_slice(side)] = False

        # Closed-form branches (when the arm has a spherical wrist) are exact pose solutions:
        # the first that meets the clearances wins, the others seed the optimiser.
        starts = self._analytic_starts(targets, seeds[0]) if self.analytic else []
        m.set_padding(max(clearance - CHECK_SLACK, 0.0), max(env_clearance - CHECK_SLACK, 0.0))
        for s in starts:
            if m.collision_free(s):
                self.last_method = "analytic"
                return s

        # Stage 1: pose only (the arms decouple; converges from the nominal pose).
        _, pose_prog, q1, pose_labels = self._program(targets, q_fixed, seeds[0])
        if not starts:
            unreachable = self.analytic  # the closed form already found no branch
            tries = min(restarts, 2) if unreachable else restarts
            try:
                starts = [self._pose_only(targets, pose_prog, q1, pose_labels, seeds, tries, rng)]
            except PlanningError as err:
                if unreachable:  # the closed form says why
                    why = "; ".join(
                        closed_form_diagnosis(m, side, t.X_WT) for side, t in targets.items()
                    )
                    raise PlanningError("ik_unreachable", why) from err
                raise

        # Stage 2: with clearances, seeded from pose solutions; restarts find new branches by
        # re-running stage 1 from perturbed seeds.
        _, prog, q, labels = self._program(targets, q_fixed, seeds[0])
        labels = labels + self._add_clearance(prog, q, clearance, env_clearance)
        best, best_violation, pose_ok = None, np.inf, list(starts)
        for k in range(restarts + 1):
            if k < len(starts):
                s = starts[k]
            else:
                s = seeds[k % len(seeds)].copy()
                if k % 2:  # a new branch: anywhere within the limits
                    s[free] = rng.uniform(m.lower[free], m.upper[free])
                else:
                    s[free] += rng.normal(0.0, RESTART_SIGMA * (1 + k / 4), free.sum())
                r = self._run(pose_prog, q1, np.clip(s, m.lower, m.upper))
                s = m.planning_q(r.GetSolution(q1))
                if not self._pose_met(targets, s):
                    continue
                pose_ok.append(s)
            r = self._run(prog, q, s)
            x = r.GetSolution(q)
            if self._accept(targets, m.planning_q(x), clearance, env_clearance):
                self.last_method = "snopt" if self._use_snopt else "ipopt"
                return m.planning_q(x)
            if self._pose_met(targets, m.planning_q(x)):
                pose_ok.append(m.planning_q(x))
            violation = self._violation(prog, x)
            if violation < best_violation:
                best, best_violation = x, violation
        if self._use_snopt and best is not None:
            r = self._run(prog, q, m.planning_q(best), solver=self._ipopt)
            x = r.GetSolution(q)
            if self._accept(targets, m.planning_q(x), clearance, env_clearance):
                self.last_method = "ipopt"
                return m.planning_q(x)
        # Every pose solution found violates a clearance: report the closest call.
        m.set_padding(clearance, env_clearance)
        pairs = [m.colliding_pairs(p) for p in pose_ok if m.within_limits(p)]
        pairs = max((p for p in pairs if p), key=lambda p: p[0][2], default=None)
        if pairs is not None:
            a, b, d = pairs[0]
            kind = "inter-arm" if _cross_arm(a, b) else "environment"
            bound = clearance if kind == "inter-arm" else env_clearance
            raise PlanningError(
                "ik_collision",
                f"{kind} clearance {bound * 100:.1f} cm cannot be met at the targets for "
                f"{', '.join(sorted(targets))}: best pose solution has {a} - {b} at "
                f"{(d + bound) * 100:.1f} cm ({len(pose_ok)} pose solutions, "
                f"{self.last_attempts} solver runs)",
            )
        failed = self._failed_labels(prog, best, labels)
        raise PlanningError(
            "ik_infeasible",
            f"no configuration meets: {'; '.join(failed) or 'all constraints jointly'} "
            f"(targets for {', '.join(sorted(targets))}, {self.last_attempts} solver runs)",
        )

    def _pose_only(self, targets, prog, q, labelled, seeds, restarts, rng) -> np.ndarray:
        """Stage 1: pose constraints only. Restarts perturb only the arms still failing."""
        m = self.model
        s = seeds[0]
        for k in range(len(seeds) + restarts):
            r = self._run(prog, q, s)
            x = r.GetSolution(q)
            if self._pose_met(targets, m.planning_q(x)) and m.within_limits(m.planning_q(x)):
                return m.planning_q(x)
            if k + 1 < len(seeds):
                s = seeds[k + 1]
                continue
            failing = {
                label.split()[0] for b, label in labelled if not prog.CheckSatisfied(b, x, 1e-4)
            }
            s = np.clip(m.planning_q(x), m.lower, m.upper)
            base = seeds[k % len(seeds)]
            for side in failing:
                sl = m.side_slice(side)
                if k % 2:
                    s[sl] = rng.uniform(m.lower[sl], m.upper[sl])
                else:
                    s[sl] = base[sl] + rng.normal(0.0, RESTART_SIGMA * (1 + k / 4), m.arm_joints)
            s = np.clip(s, m.lower, m.upper)
        failed = self._failed_labels(prog, x, labelled)
        what = "; ".join(failed) if failed else "the pose constraints jointly"
        raise PlanningError(
            "ik_unreachable",
            f"TCP target out of reach: {what} cannot be met within the joint limits",
        )

    def _analytic_starts(self, targets, seed) -> list[np.ndarray]:
        """Exact pose solutions (all branch combinations) sorted by weighted distance to seed."""
        m = self.model
        per_side = {}
        for side in SIDES:
            sl = m.side_slice(side)
            if side not in targets:
                per_side[side] = [seed[sl]]
                continue
            sols = arm_ik_closed_form(m, side, targets[side].X_WT, seed[sl])
            if not sols:
                return []
            per_side[side] = sols
        combos = [np.concatenate([a, b]) for a in per_side["left"] for b in per_side["right"]]
        cost = [float(self.weights @ (c - self.nominal) ** 2) for c in combos]
        return [combos[i] for i in np.argsort(cost)]

    def _accept(self, targets, q: np.ndarray, clearance: float, env_clearance: float) -> bool:
        """Independent check of a solver answer (solver status aside: SNOPT may report that it
        cannot improve a point that meets every constraint)."""
        m = self.model
        if not np.all(np.isfinite(q)) or not m.within_limits(q, 1e-6):
            return False
        if not self._pose_met(targets, q):
            return False
        m.set_padding(max(clearance - CHECK_SLACK, 0.0), max(env_clearance - CHECK_SLACK, 0.0))
        return m.collision_free(q)

    def _pose_met(self, targets, q: np.ndarray) -> bool:
        if not np.all(np.isfinite(q)):
            return False
        for side, t in targets.items():
            dp, dr = t.error(self.model.tcp_pose(q, side))
            if dp > t.pos_tol * (1 + 1e-3) + 1e-7 or dr > t.rot_tol * (1 + 1e-3) + 1e-7:
                return False
        return True

    @staticmethod
    def _violation(prog, x) -> float:
        total = 0.0
        for b in prog.GetAllConstraints():
            v = b.evaluator().Eval(prog.GetBindingVariableValues(b, x))
            lb, ub = b.evaluator().lower_bound(), b.evaluator().upper_bound()
            total += float(np.sum(np.maximum(lb - v, 0) + np.maximum(v - ub, 0)))
        return total

    @staticmethod
    def _failed_labels(prog, x, labelled) -> list[str]:
        if x is None:
            return []
        return [label for b, label in labelled if not prog.CheckSatisfied(b, x, 1e-4)]


def _cross_arm(a: str, b: str) -> bool:
    arm_a, arm_b = a.split("/")[0], b.split("/")[0]
    return arm_a.endswith("_arm") and arm_b.endswith("_arm") and arm_a != arm_b


# --------------------------------------------------------------------------------------------
# Closed form for a 6-joint arm with a spherical wrist (waist z, shoulder y, elbow y,
# forearm roll x, wrist angle y, wrist rotate x, zero-rotation joint origins in one plane)
# --------------------------------------------------------------------------------------------


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _wrap_into(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, near: np.ndarray):
    """Shift each angle by multiples of 2 pi into [lower, upper], nearest to `near`; None if
    some angle has no such representative."""
    out = np.empty_like(q)
    for i, (a, lo, hi, n) in enumerate(zip(q, lower, upper, near, strict=True)):
        k = np.arange(np.ceil((lo - a) / (2 * np.pi)), np.floor((hi - a) / (2 * np.pi)) + 1)
        if k.size == 0:
            return None
        cand = a + 2 * np.pi * k
        out[i] = cand[np.argmin(np.abs(cand - n))]
    return out


def arm_ik_closed_form(
    model: PlanningModel, side: str, X_WT: RigidTransform, near: np.ndarray | None = None
) -> list[np.ndarray]:
    """All exact joint solutions (up to 8 branches, within limits, each FK-verified) putting the
    TCP of `side` at X_WT; angles are wrapped nearest to `near`. Empty if unreachable. Only for
    an embodiment declaring ``closed_form_ik="spherical_wrist_6r"`` (ValueError otherwise)."""
    if not has_closed_form(model):
        raise ValueError(f"embodiment {model.embodiment.name!r} declares no closed-form IK")
    arm = model.embodiment.arm
    j = arm.joints
    near = model.home[model.side_slice(side)] if near is None else near
    X_BT = rigid_transform(model.embodiment.base_pose(side)).inverse() @ X_WT
    R, p = X_BT.rotation().matrix(), X_BT.translation()
    w = p - (j[5].origin.xyz[0] + arm.gripper.tcp_x) * R[:, 0]  # wrist centre
    height = w[2] - j[0].origin.xyz[2] - j[1].origin.xyz[2]
    a = np.array(j[2].origin.xyz)[[0, 2]]
    L1, L2 = float(np.linalg.norm(a)), j[3].origin.xyz[0] + j[4].origin.xyz[0]
    alpha = float(np.arctan2(a[1], a[0]))
    rxy, yaw = float(np.hypot(w[0], w[1])), float(np.arctan2(w[1], w[0]))
    sols = []
    for q1, r in ((yaw, rxy), (yaw + np.pi, -rxy)):
        c3 = (r * r + height * height - L1 * L1 - L2 * L2) / (2 * L1 * L2)
        if abs(c3) > 1.0:
            continue
        for delta in (np.arccos(c3), -np.arccos(c3)):
            q3 = delta - alpha
            v = L1 * np.array([np.cos(alpha), np.sin(alpha)]) + L2 * np.array(
                [np.cos(q3), -np.sin(q3)]
            )
            q2 = np.arctan2(v[1], v[0]) - np.arctan2(height, r)
            M = (_rot(2, q1) @ _rot(1, q2 + q3)).T @ R  # = Rx(q4) Ry(q5) Rx(q6)
            b = float(np.arccos(np.clip(M[0, 0], -1.0, 1.0)))
            for q5 in (b, -b):
                sb = np.sin(q5)
                if abs(sb) < 1e-9:  # wrist singularity: only q4 + q6 is determined
                    q4, q6 = near[3], np.arctan2(-M[1, 2], M[1, 1]) - near[3]
                else:
                    q4 = np.arctan2(M[1, 0] / sb, -M[2, 0] / sb)
                    q6 = np.arctan2(M[0, 1] / sb, M[0, 2] / sb)
                q = _wrap_into(np.array([q1, q2, q3, q4, q5, q6]), arm.lower, arm.upper, near)
                if q is not None:
                    sols.append(q)
    out = []
    q_both = model.home.copy()
    sl = model.side_slice(side)
    for q in sols:
        q_both[sl] = q
        X = model.tcp_pose(q_both, side)
        if (
            np.linalg.norm(X.translation() - X_WT.translation()) < 1e-6
            and np.linalg.norm(X.rotation().matrix() - X_WT.rotation().matrix()) < 1e-6
        ):
            out.append(q)
    return out


def closed_form_diagnosis(model: PlanningModel, side: str, X_WT: RigidTransform) -> str:
    """Why :func:`arm_ik_closed_form` has no solution for `side` at X_WT (or that it has)."""
    arm = model.embodiment.arm
    j = arm.joints
    n = len(arm_ik_closed_form(model, side, X_WT))
    if n:
        return f"{side} TCP pose is reachable ({n} branches)"
    X_BT = rigid_transform(model.embodiment.base_pose(side)).inverse() @ X_WT
    R, p = X_BT.rotation().matrix(), X_BT.translation()
    w = p - (j[5].origin.xyz[0] + arm.gripper.tcp_x) * R[:, 0]
    shoulder = np.array(j[0].origin.xyz) + np.array(j[1].origin.xyz)
    reach_max = float(np.linalg.norm(np.array(j[2].origin.xyz)[[0, 2]])) + (
        j[3].origin.xyz[0] + j[4].origin.xyz[0]
    )
    d = float(np.linalg.norm(w - shoulder))
    if d > reach_max:
        return (
            f"{side} TCP position out of reach: for this orientation the wrist centre is "
            f"{d:.3f} m from the shoulder, the arm reaches {reach_max:.3f} m"
        )
    return (
        f"{side} TCP orientation cannot be met within the joint limits at this position "
        "(every closed-form branch violates a limit)"
    )


def has_closed_form(model: PlanningModel) -> bool:
    """Whether the model's embodiment declares the closed form of :func:`arm_ik_closed_form`
    (``Embodiment.closed_form_ik``)."""
    return model.embodiment.closed_form_ik == "spherical_wrist_6r"


def closed_form_applies(model: PlanningModel, trials: int = 8) -> bool:
    """Whether :func:`arm_ik_closed_form` recovers random configurations of this arm."""
    rng = np.random.default_rng(0)
    for _ in range(trials):
        q_both = rng.uniform(model.lower, model.upper)
        for side in SIDES:
            q = q_both[model.side_slice(side)]
            sols = arm_ik_closed_form(model, side, model.tcp_pose(q_both, side), q)
            if not any(np.allclose(s, q, atol=1e-6) for s in sols):
                return False
    return True

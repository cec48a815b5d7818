"""Skills: the vocabulary task experts are written in.

A skill plans one arm's part of a stage as an :class:`ArmPlan` - joint samples on the control grid,
a gripper-opening schedule and attach/detach events - from IK keyframes, collision-checked joint
paths and ruckig timing. :func:`merge` runs two arm plans at the same time and checks the
combined two-arm motion against collisions sample by sample (at the checker's resolution); if
the arms would meet it delays one of them until they do not, so both arms act together whenever
that is safe. The result, a :class:`Motion`, turns into the 14-dim actions the station takes.

Every planning failure raises :class:`~bicoord_drake.planning.errors.PlanningError` with a reason.

>>> skills = Skills(PlanningModel(scene))                               # doctest: +SKIP
>>> left = skills.pick("left", "cube_a")
>>> right = skills.pick("right", "cube_b")
>>> motion = skills.merge(left, right)     # both arms pick at once
>>> for action in motion.actions(): sim.step(action)
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import Grasp, arm_base, grasp_candidates, place_candidates
from bicoord_drake.planning.ik import BimanualIK, TcpTarget
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.timing import ARM_SLICES, CONTROL_DT, JointLimits, time_path

#: Grasp candidates tried per pick before giving up.
MAX_GRASP_TRIES = 6
#: Sub-samples checked between two control samples of a merged motion.
MERGE_SUBSTEPS = 4


@dataclass
class ArmPlan:
    """One arm's motion on the control grid: q (N, 6), opening (N,), events by sample index."""

    side: str
    q: np.ndarray
    opening: np.ndarray
    events: list[tuple[int, str, str]] = field(default_factory=list)  # (index, kind, object)
    label: str = ""

    @property
    def num_steps(self) -> int:
        return len(self.q)

    def then(self, *others: ArmPlan) -> ArmPlan:
        """This plan followed by `others` (each starts where the previous one ends)."""
        q, opening, events, n = [self.q], [self.opening], list(self.events), len(self.q)
        for other in others:
            if other.side != self.side:
                raise ValueError("cannot chain plans of different arms")
            if np.max(np.abs(other.q[0] - q[-1][-1])) > 1e-6:
                raise ValueError(f"plan {other.label!r} does not start where the previous ends")
            q.append(other.q[1:])
            opening.append(other.opening[1:])
            events += [(i + n - 1, kind, name) for i, kind, name in other.events]
            n += len(other.q) - 1
        labels = "+".join(p.label for p in (self, *others) if p.label)
        return ArmPlan(self.side, np.concatenate(q), np.concatenate(opening), events, labels)

    def stretched(self, num_steps: int) -> ArmPlan:
        """The same motion slowed uniformly to `num_steps` samples (velocities and
        accelerations only shrink); events keep their place along the motion."""
        if num_steps <= self.num_steps:
            return self
        t = np.linspace(0.0, self.num_steps - 1, num_steps)
        old = np.arange(self.num_steps)
        q = np.column_stack([np.interp(t, old, self.q[:, j]) for j in range(self.q.shape[1])])
        scale = (num_steps - 1) / (self.num_steps - 1)
        events = [(int(np.ceil(i * scale)), k, n) for i, k, n in self.events]
        return ArmPlan(self.side, q, np.interp(t, old, self.opening), events, self.label)

    def padded(self, num_steps: int) -> ArmPlan:
        """Hold the last sample until the plan has `num_steps` samples."""
        extra = num_steps - self.num_steps
        if extra <= 0:
            return self
        return ArmPlan(
            self.side,
            np.vstack([self.q, np.repeat(self.q[-1:], extra, 0)]),
            np.concatenate([self.opening, np.repeat(self.opening[-1:], extra)]),
            list(self.events),
            self.label,
        )

    def delayed(self, steps: int) -> ArmPlan:
        """Hold the first sample for `steps` more samples before starting."""
        if steps <= 0:
            return self
        return ArmPlan(
            self.side,
            np.vstack([np.repeat(self.q[:1], steps, 0), self.q]),
            np.concatenate([np.repeat(self.opening[:1], steps), self.opening]),
            [(i + steps, k, n) for i, k, n in self.events],
            self.label,
        )


@dataclass
class Motion:
    """A two-arm motion on the control grid: q12 (N, 12), openings (N, 2) [left, right]."""

    q: np.ndarray
    openings: np.ndarray
    events: list[tuple[int, str, str, str]] = field(default_factory=list)  # (i, side, kind, obj)
    label: str = ""

    @property
    def num_steps(self) -> int:
        return len(self.q)

    def actions(self) -> np.ndarray:
        """(N-1, 14) actions: every sample after the start, as the station's action layout."""
        q, g = self.q[1:], self.openings[1:]
        return np.column_stack([q[:, :6], g[:, 0], q[:, 6:], g[:, 1]])


class Skills:
    """Plans skills for both arms of a :class:`PlanningModel`, tracking where the robot is.

    `speed` scales the embodiment's joint velocity limits (accelerations by speed^2, jerks by
    speed^3). The tracked state (joint angles, openings, held objects) advances as skills are
    planned; call :meth:`sync` with measured values before planning from a new situation.
    """

    def __init__(
        self,
        model: PlanningModel,
        *,
        speed: float = 0.5,
        dt: float = CONTROL_DT,
        clearance: float = 0.03,
        env_clearance: float = 0.005,
    ) -> None:
        self.model = model
        self.ik = BimanualIK(model)
        self.dt = dt
        self.clearance = clearance
        self.env_clearance = env_clearance
        self.limits6 = JointLimits.from_embodiment(model.embodiment, arms=1, speed=speed)
        self.q = model.home.copy()
        self.opening = {side: model.embodiment.home_opening for side in SIDES}
        g = model.embodiment.arm.gripper
        self._gripper_steps = max(
            3, int(np.ceil((g.finger_max - g.finger_min) / g.finger_velocity_limit / dt))
        )

    # ------------------------------------------------------------------ state
    def sync(
        self,
        q12: np.ndarray,
        openings: dict[str, float] | None = None,
        object_poses: dict[str, RigidTransform] | None = None,
    ) -> None:
        """Adopt measured joint angles, commanded openings and free objects' poses."""
        self.q = np.asarray(q12, dtype=float).copy()
        if openings:
            self.opening.update(openings)
        held = {h.name for h in self.model.held.values()}
        for name, X in (object_poses or {}).items():
            if name not in held:
                self.model.set_object_pose(name, X)

    def arm_q(self, side: str) -> np.ndarray:
        return self.q[ARM_SLICES[side]].copy()

    def _q12(self, side: str, q6: np.ndarray) -> np.ndarray:
        q = self.q.copy()
        q[ARM_SLICES[side]] = q6
        return q

    # ------------------------------------------------------------------ primitives
    def move(
        self,
        side: str,
        q6_goal: np.ndarray,
        *,
        label: str = "move",
        ignore: Iterable[str] = (),
        straight: bool = False,
    ) -> ArmPlan:
        """A collision-checked, timed joint path of one arm (the other stays where it is)."""
        from bicoord_drake.planning.motion import plan_path

        start = self.q.copy()
        goal = self._q12(side, np.asarray(q6_goal, float))
        if straight:
            with self.model.ignoring(ignore):
                if not self._edge_free(start, goal):
                    raise PlanningError(
                        "path_in_collision", f"{label}: the straight {side} move collides"
                    )
            waypoints = np.vstack([start, goal])
        else:
            waypoints = plan_path(
                self.model, start, goal, arms=(side,), ignore=ignore, env_clearance=0.0
            )
        traj = time_path(waypoints[:, ARM_SLICES[side]], self.limits6, self.dt)
        self.q = goal
        return ArmPlan(side, traj.q, np.full(len(traj.q), self.opening[side]), label=label)

    def _edge_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        n = max(2, int(np.ceil(np.max(np.abs(b - a)) / 0.01)) + 1)
        return all(self.model.collision_free(a + s * (b - a)) for s in np.linspace(0, 1, n))

    def grip(
        self, side: str, opening: float, *, settle_steps: int = 3, label: str = "grip"
    ) -> ArmPlan:
        """Open or close one gripper (arm still), then hold for `settle_steps`."""
        start = self.opening[side]
        n = self._gripper_steps + settle_steps
        ramp = np.clip(np.arange(n + 1) / self._gripper_steps, 0, 1)
        q6 = self.arm_q(side)
        self.opening[side] = float(opening)
        return ArmPlan(
            side, np.repeat(q6[None], n + 1, 0), start + ramp * (opening - start), label=label
        )

    def hold(self, side: str, steps: int, label: str = "hold") -> ArmPlan:
        """Stay still for `steps` control periods."""
        return ArmPlan(
            side,
            np.repeat(self.arm_q(side)[None], steps + 1, 0),
            np.full(steps + 1, self.opening[side]),
            label=label,
        )

    def solve_tcp(
        self,
        side: str,
        target: TcpTarget,
        *,
        seed6: np.ndarray | None = None,
        ignore: Iterable[str] = (),
        env_clearance: float | None = None,
    ) -> np.ndarray:
        """Six joint angles of `side` reaching `target` with the other arm fixed."""
        other = "right" if side == "left" else "left"
        seed = self.q.copy() if seed6 is None else self._q12(side, seed6)
        q12 = self.ik.solve_single(
            side,
            target,
            self.arm_q(other),
            seed=seed,
            clearance=self.clearance,
            env_clearance=self.env_clearance if env_clearance is None else env_clearance,
            ignore=ignore,
        )
        return q12[ARM_SLICES[side]]

    def move_tcp(
        self,
        side: str,
        X_WT: RigidTransform,
        *,
        label: str = "move_tcp",
        ignore: Iterable[str] = (),
        straight: bool = False,
        free_axis: bool = False,
    ) -> ArmPlan:
        q6 = self.solve_tcp(side, TcpTarget(X_WT, free_axis=free_axis), ignore=ignore)
        return self.move(side, q6, label=label, ignore=ignore, straight=straight)

    # ------------------------------------------------------------------ manipulation
    def pick(
        self, side: str, name: str, *, lift: float = 0.10, kinds: Sequence[str] | None = None
    ) -> ArmPlan:
        """Approach, grasp and lift object `name` with `side`; it is attached afterwards."""
        obj = self.model.object(name)
        X_WO = self.model.object_pose(name)
        base = arm_base(self.model.embodiment, side)
        grasps = grasp_candidates(
            obj, self.model.embodiment.arm.gripper, X_WO=X_WO, base=base, kinds=kinds
        )
        reasons = []
        for grasp in grasps[:MAX_GRASP_TRIES]:
            try:
                q_pre, q_grasp, q_lift = self._grasp_keyframes(side, name, grasp, lift)
            except PlanningError as err:
                reasons.append(err.reason)
                continue
            saved = (self.q.copy(), dict(self.opening))
            try:
                approach = self.move(side, q_pre, label="approach")
                descend = self.move(side, q_grasp, label="descend", ignore=[name], straight=True)
                close = self.grip(side, 0.0, label="close")
                self.model.attach(name, side, self.q)
                up = self.move(side, q_lift, label="lift", ignore=[name], straight=True)
            except PlanningError as err:
                if side in self.model.held:
                    self.model.detach(side, X_WO=X_WO)
                self.q, self.opening = saved
                reasons.append(err.reason)
                continue
            plan = approach.then(descend, close, up)
            plan.events.append(
                (approach.num_steps + descend.num_steps + close.num_steps - 3, "attach", name)
            )
            plan.label = f"pick {name}"
            return plan
        raise PlanningError(
            "pick_failed",
            f"{side} cannot pick {name!r}: tried "
            f"{min(len(grasps), MAX_GRASP_TRIES)} grasps ({', '.join(reasons)})",
        )

    def _grasp_keyframes(self, side: str, name: str, grasp: Grasp, lift: float):
        q_pre = self.solve_tcp(side, TcpTarget(grasp.X_WPre))
        q_grasp = self.solve_tcp(side, TcpTarget(grasp.X_WG), seed6=q_pre, ignore=[name])
        X_lift = RigidTransform(grasp.X_WG.rotation(), grasp.X_WG.translation() + [0, 0, lift])
        q_lift = self.solve_tcp(side, TcpTarget(X_lift), seed6=q_grasp, ignore=[name])
        return q_pre, q_grasp, q_lift

    def place(
        self,
        side: str,
        X_WO_goal: RigidTransform,
        *,
        approach_height: float = 0.06,
        retreat: float = 0.06,
        ignore: Iterable[str] = (),
    ) -> ArmPlan:
        """Carry the held object above `X_WO_goal`, lower it there, release and back off.

        The object's symmetric yaws about the goal are tried, most natural first."""
        held = self.model.held.get(side)
        if held is None:
            raise PlanningError("gripper_empty", f"{side} holds nothing to place")
        ignore = list(ignore)
        shape = self.model.object(held.name).shape
        base = arm_base(self.model.embodiment, side)
        reasons = []
        # The model keeps held poses in the gripper link frame; grasps.py works in the TCP frame.
        X_TO = RigidTransform([-self.model.embodiment.arm.gripper.tcp_x, 0, 0]) @ held.X_GO
        for cand in place_candidates(X_TO, X_WO_goal, shape, base=base, lift=approach_height):
            try:
                q_above = self.solve_tcp(side, TcpTarget(cand.X_WPre), ignore=ignore)
                q_place = self.solve_tcp(
                    side,
                    TcpTarget(cand.X_WG),
                    seed6=q_above,
                    ignore=ignore + [held.name],
                    env_clearance=0.0,
                )
                X_away = RigidTransform(
                    cand.X_WG.rotation(), cand.X_WG.translation() + [0, 0, retreat]
                )
                q_away = self.solve_tcp(side, TcpTarget(X_away), seed6=q_place, ignore=[held.name])
            except PlanningError as err:
                reasons.append(err.reason)
                continue
            return self._place_moves(side, held.name, cand.X_WO, q_above, q_place, q_away, ignore)
        raise PlanningError(
            "place_failed",
            f"{side} cannot place {held.name!r} at "
            f"{np.round(X_WO_goal.translation(), 3)} ({', '.join(reasons)})",
        )

    def _place_moves(self, side, name, X_WO, q_above, q_place, q_away, ignore) -> ArmPlan:
        carry = self.move(side, q_above, label="carry", ignore=ignore)
        lower = self.move(side, q_place, label="lower", ignore=ignore + [name], straight=True)
        release = self.grip(side, 1.0, label="release")
        self.model.detach(side, X_WO=X_WO)
        back = self.move(side, q_away, label="back off", ignore=[name], straight=True)
        plan = carry.then(lower, release, back)
        plan.events.append((carry.num_steps + lower.num_steps - 2, "detach", name))
        plan.label = f"place {name}"
        return plan

    def lift(self, side: str, height: float) -> ArmPlan:
        """Raise the TCP straight up by `height` (m), keeping its orientation."""
        X = self.model.tcp_pose(self.q, side)
        X_up = RigidTransform(X.rotation(), X.translation() + [0, 0, height])
        return self.move_tcp(side, X_up, label="lift", straight=True)

    def retreat(self, side: str, q6: np.ndarray | None = None) -> ArmPlan:
        """Back to `q6` (default: home) along a collision-free path."""
        q6 = self.model.home[ARM_SLICES[side]] if q6 is None else q6
        return self.move(side, q6, label="retreat")

    # ------------------------------------------------------------------ two arms
    def merge(
        self,
        left: ArmPlan | None,
        right: ArmPlan | None,
        *,
        max_delay: int = 90,
        stretch: bool = True,
    ) -> Motion:
        """Run both plans at once. With `stretch`, the shorter plan is first slowed to last as
        long as the longer one, so both arms keep acting together; if the arms would then come
        closer than the checker allows, the plans run at their own pace and the later-starting
        one is delayed (first the right, then the left) until they do not."""
        plans = {"left": left, "right": right}
        for side in SIDES:
            if plans[side] is None:
                plans[side] = self.hold(side, 0)
        starts = {s: plans[s].q[0] for s in SIDES}
        n = max(p.num_steps for p in plans.values())
        moving = {s: bool(np.any(plans[s].q != plans[s].q[0])) for s in SIDES}
        if stretch and all(moving.values()):
            motion = _combine(plans["left"].stretched(n), plans["right"].stretched(n))
            if self._motion_free(motion, starts):
                return motion
        attempts = [("right", 0)] + [
            (s, d) for d in range(3, max_delay + 1, 3) for s in ("right", "left")
        ]
        for side, delay in attempts:
            trial = dict(plans)
            trial[side] = trial[side].delayed(delay)
            motion = _combine(trial["left"], trial["right"])
            if self._motion_free(motion, starts):
                return motion
        raise PlanningError(
            "arm_conflict",
            f"the arms' plans ({plans['left'].label!r}, "
            f"{plans['right'].label!r}) collide at every delay up to {max_delay}",
        )

    def _motion_free(self, motion: Motion, starts: dict) -> bool:
        """Check a merged motion densely (MERGE_SUBSTEPS per control period): the arms against
        each other and the scene. Objects that change hands within the motion are left out;
        their clearance to the static scene was checked when each arm's plan was made."""
        moving = {name for _, _, _, name in motion.events}
        with self.model.ignoring(moving):
            for i in range(1, motion.num_steps):
                a, b = motion.q[i - 1], motion.q[i]
                if np.array_equal(a, b):
                    continue
                for s in np.linspace(0, 1, MERGE_SUBSTEPS + 1)[1:]:
                    if not self.model.collision_free(a + s * (b - a)):
                        return False
        return True


def _combine(left: ArmPlan, right: ArmPlan) -> Motion:
    n = max(left.num_steps, right.num_steps)
    left, right = left.padded(n), right.padded(n)
    events = [(i, "left", k, o) for i, k, o in left.events]
    events += [(i, "right", k, o) for i, k, o in right.events]
    return Motion(
        np.hstack([left.q, right.q]),
        np.column_stack([left.opening, right.opening]),
        sorted(events),
        f"{left.label} | {right.label}",
    )

"""Skills: the vocabulary task experts are written in.

A skill plans one arm's part of a stage as an :class:`ArmPlan` - joint samples on the control grid,
a gripper-opening schedule and attach/detach events - from IK keyframes, collision-checked joint
paths and ruckig timing. :func:`merge` runs two arm plans at the same time and checks the
combined two-arm motion against collisions sample by sample (at the checker's resolution); if
the arms would meet it delays one of them until they do not, so both arms act together whenever
that is safe. The result, a :class:`Motion`, turns into the 14-dim actions the station takes.

Skills of one arm return an :class:`ArmPlan`: :meth:`Skills.pick`, :meth:`~Skills.place`,
:meth:`~Skills.lift`, :meth:`~Skills.retreat`, :meth:`~Skills.pour` (tilt a held container about
its rim and back), :meth:`~Skills.push` (a held tool's tip along a straight line),
:meth:`~Skills.stabilize` (grasp and keep still), :meth:`~Skills.release`, :meth:`~Skills.hold`.
Skills of both arms return a :class:`Motion`: :meth:`~Skills.handover` (a rendezvous in mid-air,
the receiver closes before the giver opens) and :meth:`~Skills.toss` (a throw released on the
control grid into a container the other arm holds under the predicted landing point).

Every planning failure raises :class:`~bicoord_drake.planning.errors.PlanningError` with a reason.

>>> skills = Skills(PlanningModel(scene))                               # doctest: +SKIP
>>> left = skills.pick("left", "cube_a")
>>> right = skills.pick("right", "cube_b")
>>> motion = skills.merge(left, right)     # both arms pick at once
>>> for action in motion.actions(): sim.step(action)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from pydrake.all import AngleAxis, JacobianWrtVariable, RigidTransform, RotationMatrix

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.objects import BowlShape, BoxShape, CylinderShape, SphereShape
from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.grasps import (
    Grasp,
    arm_base,
    grasp_candidates,
    naturalness,
    place_candidates,
    symmetric_yaws,
)
from bicoord_drake.planning.ik import BimanualIK, TcpTarget
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.planning.timing import (
    ARM_SLICES,
    CONTROL_DT,
    GRAVITY,
    JointLimits,
    ThrowPlan,
    TimedTrajectory,
    ballistic_landing,
    release_joint_velocity,
    rendezvous,
    throw_and_catch,
    throw_release,
    time_path,
)

#: Grasp candidates tried per pick before giving up.
MAX_GRASP_TRIES = 6
#: Sub-samples checked between two control samples of a merged motion.
MERGE_SUBSTEPS = 4
#: Cartesian skills (pour, push): TCP speed (m/s) and rotation rate (rad/s) at speed = 1.
TRACK_SPEED = 0.25
TRACK_ROTATION = 1.2
#: Cartesian skills: the largest joint step (rad) between two samples (more means the IK
#: solution jumped to another branch).
TRACK_MAX_STEP = 0.3
#: Throws: squeeze (N) kept on the object from the windup to the release. A light grip leaves
#: almost no elastic energy in the pads, so opening does not kick the object sideways.
THROW_SQUEEZE = 1.0
#: Throws: finger clearance per side (m) commanded over the release period (then fully open).
RELEASE_GAP = 0.0015
#: Throws: measured delay (s) from the start of that opening ramp until a lightly held object
#: flies free (the plan puts the release state there, inside the constant-velocity coast).
RELEASE_DELAY = 0.042
#: Throws: constant-velocity control periods before and after the release sample.
THROW_COAST = (1, 3)
#: Throws: the share of each joint's velocity limit the release velocity may use.
THROW_SPEED_SHARE = 0.9


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
    info: dict[str, Any] = field(default_factory=dict)  # skill-specific plan data

    @property
    def num_steps(self) -> int:
        return len(self.q)

    def then(self, other: Motion) -> Motion:
        """This motion followed by `other` (which must start where this one ends). Events are
        re-indexed; ``info`` is merged as is (the later motion's keys win)."""
        if np.max(np.abs(other.q[0] - self.q[-1])) > 1e-6:
            raise ValueError(f"motion {other.label!r} does not start where the previous ends")
        n = self.num_steps - 1
        events = self.events + [(i + n, side, k, o) for i, side, k, o in other.events]
        return Motion(
            np.vstack([self.q, other.q[1:]]),
            np.vstack([self.openings, other.openings[1:]]),
            events,
            f"{self.label}; {other.label}",
            {**self.info, **other.info},
        )

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
        self.speed = speed
        g = model.embodiment.arm.gripper
        self._gripper_steps = max(
            3, int(np.ceil((g.finger_max - g.finger_min) / g.finger_velocity_limit / dt))
        )
        self._track_ik = BimanualIK(model)  # its nominal follows the previous sample
        self._stabilized: dict[str, np.ndarray] = {}  # side -> model lift of what it steadies
        self._jac_context = model.plant.CreateDefaultContext()
        self._v_indices = {
            side: np.array(
                [
                    model.plant.GetJointByName(j, model.arms[side]).velocity_start()
                    for j in model.embodiment.arm.joint_names
                ]
            )
            for side in SIDES
        }

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
        clearance: float | None = None,
    ) -> ArmPlan:
        """A collision-checked, timed joint path of one arm (the other stays where it is).

        A `clearance` (m) between the arms, if given, is checked with no environment margin
        (close two-arm work such as a handover)."""
        from bicoord_drake.planning.motion import plan_path

        start = self.q.copy()
        goal = self._q12(side, np.asarray(q6_goal, float))
        if clearance is not None:
            self.model.set_padding(clearance * 0.8, 0.0)
        if straight:
            with self.model.ignoring(ignore):
                if not self._edge_free(start, goal):
                    raise PlanningError(
                        "path_in_collision", f"{label}: the straight {side} move collides"
                    )
            waypoints = np.vstack([start, goal])
        else:
            kwargs = {} if clearance is None else {"clearance": clearance * 0.8}
            waypoints = plan_path(
                self.model, start, goal, arms=(side,), ignore=ignore, env_clearance=0.0, **kwargs
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
        clearance: float | None = None,
    ) -> np.ndarray:
        """Six joint angles of `side` reaching `target` with the other arm fixed."""
        other = "right" if side == "left" else "left"
        seed = self.q.copy() if seed6 is None else self._q12(side, seed6)
        q12 = self.ik.solve_single(
            side,
            target,
            self.arm_q(other),
            seed=seed,
            clearance=self.clearance if clearance is None else clearance,
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
        clearance: float | None = None,
    ) -> ArmPlan:
        """Move the TCP of `side` to `X_WT` (see :meth:`move`)."""
        target = TcpTarget(X_WT, free_axis=free_axis)
        q6 = self.solve_tcp(side, target, ignore=ignore, clearance=clearance)
        return self.move(
            side, q6, label=label, ignore=ignore, straight=straight, clearance=clearance
        )

    # ------------------------------------------------------------------ manipulation
    def refresh_grasps(self, object_poses: dict[str, RigidTransform]) -> None:
        """Re-measure each held object's pose in its gripper from measured poses (a grasp
        settles by a few mm when the fingers close), so later placements aim right. Held
        objects missing from `object_poses` keep their grasp."""
        for side, held in list(self.model.held.items()):
            X_WO = object_poses.get(held.name)
            if X_WO is None:
                continue
            self.model.detach(side, X_WO=X_WO)
            self.model.attach(held.name, side, self.q, X_WO=X_WO)

    def pick(
        self,
        side: str,
        name: str,
        *,
        lift: float = 0.10,
        kinds: Sequence[str] | None = None,
        grasps: Sequence[Grasp] | None = None,
        approach_opening: float | None = None,
    ) -> ArmPlan:
        """Approach, grasp and lift object `name` with `side`; it is attached afterwards.

        `grasps` (best first) replaces the generated candidates, e.g. for one part of a
        compound object. With `approach_opening` the jaw narrows to that opening during the
        approach (so a finger entering a container stays by its wall)."""
        X_WO = self.model.object_pose(name)
        if grasps is None:
            base = arm_base(self.model.embodiment, side)
            grasps = grasp_candidates(
                self.model.object(name),
                self.model.embodiment.arm.gripper,
                X_WO=X_WO,
                base=base,
                kinds=kinds,
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
                if approach_opening is not None:  # narrow the jaw on the way, not after
                    ramp = np.clip(np.arange(approach.num_steps) / self._gripper_steps, 0, 1)
                    approach.opening = approach.opening + ramp * (
                        approach_opening - approach.opening
                    )
                    self.opening[side] = approach_opening
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
        opening: float = 1.0,
    ) -> ArmPlan:
        """Carry the held object above `X_WO_goal`, lower it there, release and back off.

        The object's symmetric yaws about the goal are tried, most natural first. The gripper
        opens to `opening` (less than 1 inside a container, so the fingers miss its walls)."""
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
            return self._place_moves(
                side, held.name, cand.X_WO, q_above, q_place, q_away, ignore, opening
            )
        raise PlanningError(
            "place_failed",
            f"{side} cannot place {held.name!r} at "
            f"{np.round(X_WO_goal.translation(), 3)} ({', '.join(reasons)})",
        )

    def _place_moves(
        self, side, name, X_WO, q_above, q_place, q_away, ignore, opening=1.0
    ) -> ArmPlan:
        carry = self.move(side, q_above, label="carry", ignore=ignore)
        lower = self.move(side, q_place, label="lower", ignore=ignore + [name], straight=True)
        release = self.grip(side, opening, label="release")
        self.model.detach(side, X_WO=X_WO)
        back = self.move(side, q_away, label="back off", ignore=ignore + [name], straight=True)
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

    def stabilize(self, side: str, name: str, *, kinds: Sequence[str] | None = None) -> ArmPlan:
        """Grasp object `name` where it is and keep still with the gripper closed on it.

        The object is attached to `side` (it rides with that gripper in the planning model), so
        the other arm can work around it; a merged motion holds this arm's last sample for as
        long as the other arm needs. :meth:`release` lets go."""
        X_WO = self.model.object_pose(name)
        plan = self.pick(side, name, lift=0.0, kinds=kinds)
        plan.label = f"stabilize {name}"
        # It still rests on its support: the model keeps it a hair above, so that the other
        # arm's planning does not see the support touching this arm.
        lift = np.array([0.0, 0.0, self.env_clearance + 0.001])
        self.model.detach(side, X_WO=X_WO)
        self.model.attach(
            name, side, self.q, RigidTransform(X_WO.rotation(), X_WO.translation() + lift)
        )
        self._stabilized[side] = lift
        return plan

    def release(self, side: str, *, back: float = 0.06, label: str = "release") -> ArmPlan:
        """Open the gripper where it is, leave the object there and back off `back` (m) along
        the approach axis."""
        held = self.model.held.get(side)
        if held is None:
            raise PlanningError("gripper_empty", f"{side} holds nothing to release")
        X_WO = self.model.held_pose(side, self.q)
        lift = self._stabilized.pop(side, None)
        if lift is not None:
            X_WO = RigidTransform(X_WO.rotation(), X_WO.translation() - lift)
        opened = self.grip(side, 1.0, label="open")
        self.model.detach(side, X_WO=X_WO)
        X = self.model.tcp_pose(self.q, side)
        X_back = RigidTransform(X.rotation(), X.translation() - back * X.rotation().col(0))
        away = self.move_tcp(side, X_back, label="back off", ignore=[held.name], straight=True)
        plan = opened.then(away)
        plan.events.append((opened.num_steps - 1, "detach", held.name))
        plan.label = f"{label} {held.name}"
        return plan

    def pour(
        self,
        side: str,
        angle: float,
        *,
        direction: Sequence[float] | None = None,
        hold_steps: int = 8,
        back: bool = True,
        ignore: Iterable[str] = (),
        pivot: Sequence[float] | None = None,
    ) -> ArmPlan:
        """Tilt the held container by `angle` (rad) about the horizontal axis through its rim
        point in `direction`, hold `hold_steps`, and tilt back.

        The rim point stays fixed, so the content leaves over that lip. The TCP follows the exact
        rotation (IK at every control sample). Without a `direction`, the horizontal axes are
        tried beside the grasp first (toward the other arm first), never over the gripper.
        `pivot` (a world point, e.g. a spout's lip) replaces the rim point: the container turns
        about the horizontal axis through it, across `direction`."""
        held = self.model.held.get(side)
        if held is None:
            raise PlanningError("gripper_empty", f"{side} holds no container to pour from")
        if direction is not None:
            options = [np.asarray(direction, dtype=float)]
        else:
            # Beside the grasp first (not over the gripper), toward the other arm first.
            X_WO = self.model.held_pose(side, self.q)
            grip = self.model.tcp_pose(self.q, side).translation() - X_WO.translation()
            grip[2] = 0.0
            grip /= max(float(np.linalg.norm(grip)), 1e-9)
            toward = np.array([1.0, 0, 0]) if side == "left" else np.array([-1.0, 0, 0])
            dirs = [toward, np.array([0, 1.0, 0]), np.array([0, -1.0, 0]), -toward]
            dirs = [d for d in dirs if d @ grip < 0.7]
            options = sorted(dirs, key=lambda d: abs(float(d @ grip)) - 0.1 * float(d @ toward))
        reasons = []
        for d in options:
            saved = self.q.copy()
            try:
                return self._pour(side, held.name, angle, d, hold_steps, back, ignore, pivot)
            except PlanningError as err:
                self.q = saved
                reasons.append(err.reason)
        raise PlanningError(
            "pour_failed",
            f"{side} cannot tilt {held.name!r} by {angle:.2f} rad ({', '.join(reasons)})",
        )

    def _pour(self, side, name, angle, d, hold_steps, back, ignore, pivot=None) -> ArmPlan:
        X_WO = self.model.held_pose(side, self.q)
        shape = self.model.object(name).shape
        up = X_WO.rotation().col(2)
        d = d - (d @ up) * up
        if np.linalg.norm(d) < 1e-6:
            raise ValueError("the pour direction must not be parallel to the container axis")
        d /= np.linalg.norm(d)
        if pivot is None:
            top, radius = _rim(shape, X_WO.rotation().matrix(), d)
            pivot = X_WO.translation() + top * up + radius * d
        pivot = np.asarray(pivot, dtype=float)
        axis = np.cross(up, d)  # a positive turn about it tips the mouth toward d
        X_WT0 = self.model.tcp_pose(self.q, side)

        def turned(a: float) -> RigidTransform:
            R = RotationMatrix(_axis_angle(axis, a))
            return RigidTransform(R @ X_WT0.rotation(), pivot + R @ (X_WT0.translation() - pivot))

        reach = float(np.linalg.norm(X_WT0.translation() - pivot)) * abs(angle)
        tilt = self._track(
            side, lambda s: turned(s * angle), reach, abs(angle), label="tilt", ignore=ignore
        )
        plans = [tilt, self.hold(side, hold_steps, label="pour")]
        if back:
            plans.append(
                self._track(
                    side,
                    lambda s: turned((1 - s) * angle),
                    reach,
                    abs(angle),
                    label="tilt back",
                    ignore=ignore,
                )
            )
        plan = plans[0].then(*plans[1:])
        plan.label = f"pour {name} toward {np.round(d, 2).tolist()}"
        return plan

    def push(
        self,
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
        held = self.model.held.get(side)
        if held is None:
            raise PlanningError("gripper_empty", f"{side} holds no tool to push with")
        ignore = list(ignore)
        shape = self.model.object(held.name).shape
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        X_WT = self.model.tcp_pose(self.q, side)
        X_WO = self.model.held_pose(side, self.q)
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

        above = self.move_tcp(side, tcp_at(start + up), label="above start", ignore=ignore)
        free = ignore + [held.name]  # the tool itself touches what it pushes
        plans = [above]
        legs = ((start + up, start, "down"), (start, end, "push"), (end, end + up, "up"))
        for a, b, label in legs:
            dist = float(np.linalg.norm(b - a))
            plans.append(self._track(side, line(a, b), dist, 0.0, label=label, ignore=free))
        plan = plans[0].then(*plans[1:])
        plan.label = f"push with {held.name}"
        return plan

    def _track(
        self,
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
        other = "right" if side == "left" else "left"
        duration = max(
            distance / (TRACK_SPEED * self.speed), rotation / (TRACK_ROTATION * self.speed), 0.2
        )
        q_other = self.arm_q(other)
        with self.model.ignoring(ignore):  # once: entering it costs a filter rebuild
            q6 = self._track_samples(side, pose_at, duration, q_other, ignore, label)
            self.model.set_padding(self.clearance / 2, 0.0)
            q = [self._q12(side, x) for x in q6]
            if not all(self._edge_free(a, b) for a, b in zip(q[:-1], q[1:], strict=True)):
                raise PlanningError("path_in_collision", f"{label}: the {side} path collides")
        self.q = q[-1].copy()
        return ArmPlan(side, q6, np.full(len(q6), self.opening[side]), label=label)

    def _track_samples(self, side, pose_at, duration, q_other, ignore, label) -> np.ndarray:
        """(N, 6) joint samples of :meth:`_track`, slowed until the joints keep up."""
        for _ in range(4):
            rate = 1.0 / duration
            s_limits = JointLimits(
                np.zeros(1),
                np.ones(1),
                np.array([rate]),
                np.array([6 * rate]),
                np.array([60 * rate]),
            )
            s = time_path(np.array([[0.0], [1.0]]), s_limits, self.dt).q[:, 0]
            q, prev = [self.q.copy()], self.q.copy()
            for s_k in s[1:]:
                self._track_ik.nominal = prev
                prev = self._track_ik.solve_single(
                    side,
                    TcpTarget(pose_at(float(s_k))),
                    q_other,
                    seed=prev,
                    clearance=self.clearance,
                    env_clearance=0.0,
                    ignore=ignore,
                    restarts=3,
                )
                q.append(prev)
            q6 = np.array(q)[:, ARM_SLICES[side]]
            if np.max(np.abs(np.diff(q6, axis=0))) > TRACK_MAX_STEP:
                raise PlanningError("track_discontinuous", f"{label}: IK switched branches")
            speed = np.max(np.abs(np.diff(q6, axis=0)) / self.dt / self.limits6.velocity)
            if speed <= 1.0:
                return q6
            duration *= speed * 1.1
        raise PlanningError("track_too_fast", f"{label}: the joints cannot follow the path")

    # ------------------------------------------------------------------ two arms
    def merge(
        self,
        left: ArmPlan | None,
        right: ArmPlan | None,
        *,
        max_delay: int = 90,
        stretch: bool = True,
        ignore: Iterable[str] = (),
    ) -> Motion:
        """Run both plans at once. With `stretch`, the shorter plan is first slowed to last as
        long as the longer one, so both arms keep acting together; if the arms would then come
        closer than the checker allows, the plans run at their own pace and the later-starting
        one is delayed (first the right, then the left) until they do not. Objects in `ignore`
        (e.g. a container one arm steadies while the other reaches into it) are left out of
        that check."""
        plans = {"left": left, "right": right}
        for side in SIDES:
            if plans[side] is None:
                plans[side] = self.hold(side, 0)
        starts = {s: plans[s].q[0] for s in SIDES}
        n = max(p.num_steps for p in plans.values())
        moving = {s: bool(np.any(plans[s].q != plans[s].q[0])) for s in SIDES}
        if stretch and all(moving.values()):
            motion = _combine(plans["left"].stretched(n), plans["right"].stretched(n))
            if self._motion_free(motion, starts, ignore):
                return motion
        attempts = [("right", 0)] + [
            (s, d) for d in range(3, max_delay + 1, 3) for s in ("right", "left")
        ]
        for side, delay in attempts:
            trial = dict(plans)
            trial[side] = trial[side].delayed(delay)
            motion = _combine(trial["left"], trial["right"])
            if self._motion_free(motion, starts, ignore):
                return motion
        raise PlanningError(
            "arm_conflict",
            f"the arms' plans ({plans['left'].label!r}, "
            f"{plans['right'].label!r}) collide at every delay up to {max_delay}",
        )

    def _motion_free(self, motion: Motion, starts: dict, ignore: Iterable[str] = ()) -> bool:
        """Check a merged motion densely (MERGE_SUBSTEPS per control period): the arms against
        each other and the scene. Objects that change hands within the motion are left out;
        their clearance to the static scene was checked when each arm's plan was made."""
        moving = {name for _, _, _, name in motion.events} | set(ignore)
        with self.model.ignoring(moving):
            for i in range(1, motion.num_steps):
                a, b = motion.q[i - 1], motion.q[i]
                if np.array_equal(a, b):
                    continue
                for s in np.linspace(0, 1, MERGE_SUBSTEPS + 1)[1:]:
                    if not self.model.collision_free(a + s * (b - a)):
                        return False
        return True

    def handover(
        self,
        giver: str,
        receiver: str,
        *,
        meet: Sequence[float] = (0.0, -0.05, 0.95),
        clearance: float = 0.005,
        retreat: float = 0.06,
        kinds: Sequence[str] = ("side", "top"),
        tip_margin: float = 0.003,
    ) -> Motion:
        """Hand the object held by `giver` to `receiver` in mid-air at `meet` (object centre).

        The receiver grasps across a different axis than the giver (perpendicular fingers, not
        from the giver's side), its fingertips stopping `tip_margin` short of the far face. Both
        arms move at once and arrive at the meeting at the same control step (a
        :func:`~bicoord_drake.planning.timing.rendezvous`) with at least `clearance` (m) between
        them; then the receiver closes, the giver opens and backs off `retreat` (m). If the
        simultaneous approach collides, the giver arrives first (``info["rendezvous"]`` False).
        ``info`` gives the sample indices of the meeting, the receiver's grip and the giver's
        release. On failure nothing is changed.
        """
        if giver == receiver:
            raise ValueError("giver and receiver must be different arms")
        held = self.model.held.get(giver)
        if held is None:
            raise PlanningError("gripper_empty", f"{giver} holds nothing to hand over")
        if receiver in self.model.held:
            raise PlanningError("gripper_busy", f"{receiver} already holds something")
        with self._transaction():
            return self._handover(
                giver, receiver, held, meet, clearance, retreat, kinds, tip_margin
            )

    def _handover(self, giver, receiver, held, meet, clearance, retreat, kinds, tip_margin):
        name, gripper = held.name, self.model.embodiment.arm.gripper
        obj = self.model.object(name)
        X_GT = RigidTransform([gripper.tcp_x, 0.0, 0.0])
        X_OT = held.X_GO.inverse() @ X_GT
        R_WO = (self.model.gripper_pose(self.q, giver) @ held.X_GO).rotation()
        closed = float(
            np.clip(gripper.opening(_half_extent(obj.shape, held.X_GO.rotation(), [0, 1, 0])), 0, 1)
        )
        self.model.set_gripper(giver, closed)  # the giver's fingers really are closed on it
        try:
            q_meet, q_pre, grasp = self._meeting(
                giver,
                receiver,
                name,
                X_OT,
                R_WO,
                np.asarray(meet, float),
                clearance,
                kinds,
                tip_margin,
            )
            motion = self._meet_motion(giver, receiver, q_meet, q_pre, clearance)
        finally:
            self.model.set_gripper(giver, self.model.embodiment.home_opening)
        X_WO = self.model.held_pose(giver, q_meet)
        self.q = q_meet.copy()
        close = self.grip(receiver, 0.0, label="receive")
        self.model.detach(giver, X_WO=X_WO)
        self.model.attach(name, receiver, self.q, X_WO)
        opened = self.grip(giver, 1.0, label="let go")
        X = self.model.tcp_pose(self.q, giver)
        X_back = RigidTransform(X.rotation(), X.translation() - retreat * X.rotation().col(0))
        back = self.move_tcp(
            giver, X_back, label="back off", ignore=[name], straight=True, clearance=clearance
        )
        rest = self._sequence([{receiver: close}, {giver: opened}, {giver: back}], motion)
        i_receive = motion.num_steps + close.num_steps - 2
        i_release = i_receive + opened.num_steps - 1
        rest.events += [(i_receive, receiver, "attach", name), (i_release, giver, "detach", name)]
        rest.events.sort()
        rest.label = f"handover {name} {giver}->{receiver}"
        rest.info.update(
            meet_index=motion.num_steps - 1,
            receive_index=i_receive,
            release_index=i_release,
            receiver_grasp=grasp,
        )
        return rest

    def _meeting(self, giver, receiver, name, X_OT, R_WO, p_meet, clearance, kinds, tip_margin):
        """Joint angles at the meeting, the receiver's pregrasp and its grasp (best first)."""
        obj = self.model.object(name)
        gripper = self.model.embodiment.arm.gripper
        bases = {s: arm_base(self.model.embodiment, s) for s in SIDES}
        metas = []
        for yaw in symmetric_yaws(obj.shape) if isinstance(obj.shape, BoxShape) else [0.0]:
            X_WO = RigidTransform(RotationMatrix.MakeZRotation(yaw) @ R_WO, p_meet)
            X_WTg = X_WO @ X_OT
            metas.append((naturalness(X_WTg, bases[giver]), X_WO, X_WTg))
        metas.sort(key=lambda m: -m[0])
        reasons: list[str] = []
        for _, X_WO, X_WTg in metas:
            Rg = X_WTg.rotation().matrix()
            grasps = grasp_candidates(
                obj, gripper, X_WO=X_WO, base=bases[receiver], kinds=list(kinds)
            )
            for grasp in grasps:
                Rr = grasp.X_WG.rotation().matrix()
                if abs(Rr[:, 1] @ Rg[:, 1]) > 0.3 or Rr[:, 0] @ Rg[:, 0] > 0.5:
                    continue  # same finger axis, or coming from the giver's side
                a = Rr[:, 0]
                reach = _half_extent(obj.shape, X_WO.rotation().matrix(), a)
                tip = (grasp.X_WG.translation() - X_WO.translation()) @ a + gripper.pad_length / 2
                shift = max(0.0, tip - reach + tip_margin)
                X_WG = RigidTransform(grasp.X_WG.rotation(), grasp.X_WG.translation() - shift * a)
                X_pre = RigidTransform(X_WG.rotation(), X_WG.translation() - 0.08 * a)
                try:
                    q_meet = self.ik.solve(
                        {giver: TcpTarget(X_WTg), receiver: TcpTarget(X_WG)},
                        clearance=clearance,
                        env_clearance=self.env_clearance,
                        seed=self.q,
                        restarts=4,
                    )
                    q_pre = self.ik.solve_single(
                        receiver,
                        TcpTarget(X_pre),
                        q_meet[ARM_SLICES[giver]],
                        seed=q_meet,
                        clearance=clearance,
                        env_clearance=self.env_clearance,
                        restarts=4,
                    )
                except PlanningError as err:
                    reasons.append(err.reason)
                    continue
                self.model.set_padding(clearance * 0.8, 0.0)
                if not self._edge_free(q_pre, q_meet):
                    reasons.append("approach_in_collision")
                    continue
                return q_meet, q_pre, grasp
        raise PlanningError(
            "handover_failed",
            f"no meeting of {giver} and {receiver} at {np.round(p_meet, 3)} for {name!r} "
            f"({', '.join(sorted(set(reasons))) or 'no grasp across another axis'})",
        )

    def _meet_motion(self, giver, receiver, q_meet, q_pre, clearance) -> Motion:
        """Both arms from where they are to the meeting, arriving at the same control step."""
        from bicoord_drake.planning.motion import plan_path

        start = self.q.copy()
        g_goal = start.copy()
        g_goal[ARM_SLICES[giver]] = q_meet[ARM_SLICES[giver]]
        r_goal = start.copy()
        r_goal[ARM_SLICES[receiver]] = q_pre[ARM_SLICES[receiver]]
        g_path = plan_path(self.model, start, g_goal, arms=(giver,), env_clearance=0.0)
        r_path = plan_path(self.model, start, r_goal, arms=(receiver,), env_clearance=0.0)
        r_path = np.vstack([r_path, q_meet[None]])
        paths = {giver: g_path[:, ARM_SLICES[giver]], receiver: r_path[:, ARM_SLICES[receiver]]}
        limits = JointLimits.concat(self.limits6, self.limits6)
        traj = rendezvous(paths["left"], paths["right"], limits, self.dt)
        motion = self._motion_of(traj, "meet")
        if self._checked(motion, clearance * 0.8, 0.0):
            motion.info["rendezvous"] = True
            return motion
        # Fallback: the giver arrives first, then the receiver comes in.
        g_plan = self._arm_plan(giver, time_path(paths[giver], self.limits6, self.dt), "give")
        r_path = plan_path(
            self.model, g_goal, q_pre, arms=(receiver,), clearance=clearance, env_clearance=0.0
        )
        r_path = np.vstack([r_path, q_meet[None]])[:, ARM_SLICES[receiver]]
        r_plan = self._arm_plan(receiver, time_path(r_path, self.limits6, self.dt), "receive")
        motion = self._sequence([{giver: g_plan}, {receiver: r_plan}], self._still(start))
        if not self._checked(motion, clearance * 0.8, 0.0):
            raise PlanningError("arm_conflict", f"{giver} and {receiver} collide on the way")
        motion.info["rendezvous"] = False
        return motion

    def toss(
        self,
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
    ) -> Motion:
        """Throw the object held by `thrower` into the container held by `catcher`.

        The object leaves from `release` (its centre; default 12 cm from the middle on the
        thrower's side, 25 cm above the table) at `speed` (m/s), `angle` (rad) above the
        horizontal, toward the catcher's side. The release state lies inside the constant-
        velocity coast of a :func:`~bicoord_drake.planning.timing.throw_release` profile,
        RELEASE_DELAY after the control step that starts opening the fingers (the thrower keeps
        only a light squeeze during the throw). The catcher carries its container, level, with
        its bottom `catch_height` (m) above the table, so that its centre lies under the
        predicted ballistic path (midway between where the object crosses the rim and where it
        reaches the bottom) plus `aim` (a horizontal world offset in m, e.g. to land beside
        what is already in it), and is there `margin` s before the object reaches the rim
        (:func:`~bicoord_drake.planning.timing.throw_and_catch`). The flight is checked against
        both arms. ``info`` holds the predicted release, rim crossing and landing (motion sample
        indices and seconds from the motion's start). On failure nothing is changed.
        """
        if thrower == catcher:
            raise ValueError("thrower and catcher must be different arms")
        held, bowl = self.model.held.get(thrower), self.model.held.get(catcher)
        if held is None:
            raise PlanningError("gripper_empty", f"{thrower} holds nothing to throw")
        if bowl is None or not isinstance(self.model.object(bowl.name).shape, BowlShape):
            raise PlanningError("no_container", f"{catcher} must hold a bowl to catch with")
        with self._transaction():
            return self._toss(
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
            )

    def _toss(
        self,
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
    ) -> Motion:
        from bicoord_drake.planning.motion import plan_path

        name, shape = held.name, self.model.object(held.name).shape
        gripper = self.model.embodiment.arm.gripper
        direction = np.array([1.0, 0.0, 0.0]) if thrower == "left" else np.array([-1.0, 0, 0])
        if release is None:
            release = (-0.12 * direction[0], -0.05, TABLE_TOP + 0.25)
        p_rel = np.asarray(release, dtype=float)
        v = speed * (np.cos(angle) * direction + np.sin(angle) * np.array([0.0, 0.0, 1.0]))

        throw, q_wind, soft = self._throw(thrower, held, p_rel, v)
        # The catch: where the object (as oriented at the release) crosses the rim and the
        # bottom of the raised bowl.
        R = self.model.held_pose(thrower, self._q12(thrower, throw.q_release)).rotation().matrix()
        cup = self.model.object(bowl.name).shape
        z_bowl = TABLE_TOP + catch_height
        R_WB = _levelled(self.model.held_pose(catcher, self.q).rotation())
        h = max(_half_extent(shape, R, [0, 0, 1.0]), 0.01)
        rim, t_rim = ballistic_landing(p_rel, v, z_bowl + cup.height + h)
        bottom, t_bottom = ballistic_landing(p_rel, v, z_bowl + cup.wall + h)
        centre = (rim + bottom) / 2
        # The object's footprint, from the rim crossing to the bottom, must fit inside the wall.
        across = np.array([-direction[1], direction[0], 0.0])
        along_extent = float(np.linalg.norm((rim - bottom)[:2])) / 2 + _half_extent(
            shape, R, direction
        )
        across_extent = _half_extent(shape, R, across)
        reach = np.hypot(
            abs(aim @ direction[:2]) + along_extent, abs(aim @ across[:2]) + across_extent
        )
        if reach > cup.radius - cup.wall:
            raise PlanningError(
                "catch_too_steep", f"the object would hit the rim ({reach:.3f} m from the axis)"
            )
        p_bowl = np.array([*(centre[:2] - aim[:2]), z_bowl])
        q_catch = self._catch_pose(catcher, bowl, R_WB, p_bowl, direction)
        q_start, o_start = self.q.copy(), dict(self.opening)
        # The thrower: windup (catcher still), then the throw with the catcher moving in.
        windup = self.move(thrower, q_wind, label="windup")
        loosen = self.grip(thrower, soft, settle_steps=2, label="loosen")
        c_goal = self.q.copy()
        c_goal[ARM_SLICES[catcher]] = q_catch
        c_path = plan_path(self.model, self.q, c_goal, arms=(catcher,), env_clearance=0.0)
        c_traj = time_path(c_path[:, ARM_SLICES[catcher]], self.limits6, self.dt)
        flight = RELEASE_DELAY + t_rim  # release sample -> the object reaches the rim
        kwargs = {"margin": margin, "start": start, "hold_after": hold_after}
        try:
            plan = throw_and_catch(throw, c_traj, flight, thrower, **kwargs)
        except PlanningError as err:
            if err.reason != "catch_too_late":
                raise
            # The thrower waits at its windup until the catcher can make it. (Asking
            # throw_release for a later release makes ruckig pick a much longer profile.)
            ready = int(np.floor((throw.release_time + flight - margin) / self.dt + 1e-9))
            wait = c_traj.num_steps - ready
            throw = replace(
                throw,
                trajectory=throw.trajectory.delayed(wait),
                release_index=throw.release_index + wait,
            )
            plan = throw_and_catch(throw, c_traj, flight, thrower, **kwargs)
        r = throw.release_index
        n = plan.trajectory.num_steps + 1
        opening = np.full(n, soft)
        half = _half_extent(shape, held.X_GO.rotation(), [0, 1, 0])
        opening[r + 1] = float(np.clip(gripper.opening(half + RELEASE_GAP), 0, 1))
        opening[r + 2 :] = 1.0
        throw_motion = self._motion_of(plan.trajectory, "throw and catch", 0.0)
        throw_motion.openings[:, SIDES.index(thrower)] = opening
        throw_motion.openings[:, SIDES.index(catcher)] = self.opening[catcher]
        prep = self._sequence([{thrower: windup}, {thrower: loosen}], self._still(q_start, o_start))
        motion = prep.then(throw_motion)
        offset = prep.num_steps - 1
        # Check: arms against each other and the scene, the object while it is held and its
        # flight against both arms until it is over the rim.
        i_rel = offset + r
        if not self._checked(motion, self.clearance / 2, 0.0, span=(0, i_rel + 1)):
            raise PlanningError("path_in_collision", "the throw collides before the release")
        if not self._checked(motion, self.clearance / 2, 0.0, ignore=[name], span=(i_rel, None)):
            raise PlanningError("arm_conflict", "the throw and the catch collide")
        X_WO_rel = self.model.held_pose(thrower, motion.q[i_rel])
        self.model.detach(thrower, X_WO=X_WO_rel)
        motion.events.append((i_rel + 1, thrower, "detach", name))
        motion.events.sort()
        self._check_flight(motion, name, X_WO_rel.rotation(), p_rel, v, i_rel, t_rim)
        rest = RigidTransform(X_WO_rel.rotation(), [*centre[:2], z_bowl + cup.wall + h + 0.002])
        self.model.set_object_pose(name, rest)
        self.q = motion.q[-1].copy()
        self.opening[thrower] = 1.0
        motion.label = f"toss {name} {thrower}->{catcher}"
        motion.info.update(
            release_index=offset + r,
            release_time=(offset + r) * self.dt + RELEASE_DELAY,
            release_position=p_rel,
            release_velocity=v,
            landing_point=centre,
            rim_crossing=rim,
            rim_time=(offset + r) * self.dt + flight,
            landing_time=(offset + r) * self.dt + RELEASE_DELAY + t_bottom,
            catch_arrival_index=offset + plan.catch.arrival_index,
            bowl_pose=RigidTransform(R_WB, p_bowl),
        )
        return motion

    def _catch_pose(
        self, catcher, bowl, R_WB: RotationMatrix, p_bowl: np.ndarray, direction: np.ndarray
    ) -> np.ndarray:
        """Catcher joints holding its bowl with the bowl frame at `p_bowl`, turned from `R_WB`
        (levelled: a bowl that sags in the grasp, as measured by :meth:`refresh_grasps`, is
        levelled by tilting the gripper) about the vertical. The gripper goes to the far
        side of the flight: its body spans the rim above the bowl, so the object must not pass
        over it on the way in."""
        X_BT = bowl.X_GO.inverse() @ RigidTransform([self.model.embodiment.arm.gripper.tcp_x, 0, 0])
        base = arm_base(self.model.embodiment, catcher)
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
                return self.solve_tcp(catcher, TcpTarget(X_WT))
            except PlanningError as err:
                reasons.append(err.reason)
        raise PlanningError(
            "catch_unreachable",
            f"{catcher} cannot hold its bowl at {np.round(p_bowl, 3)} ({', '.join(reasons)})",
        )

    def _throw(
        self,
        thrower: str,
        held,
        p_rel: np.ndarray,
        v: np.ndarray,
    ) -> tuple[ThrowPlan, np.ndarray, float]:
        """The thrower's :class:`ThrowPlan`, its windup joints and the light-grip opening.

        The object's centre passes `p_rel` with velocity `v` RELEASE_DELAY after the release
        sample (inside the coast, whose joint velocity gives exactly `v` there). The windup lies
        on the same joint line, far enough back to reach that velocity. A box may be turned
        about the vertical on the way to the release (quarter turns, as held or squared to the
        flight): the shortest along the flight (its long side across) first, then the one with
        the least spin."""
        obj = self.model.object(held.name)
        gripper = self.model.embodiment.arm.gripper
        limits = JointLimits.from_embodiment(self.model.embodiment, arms=1, speed=1.0)
        X_OT = held.X_GO.inverse() @ RigidTransform([gripper.tcp_x, 0.0, 0.0])
        R_WO = self.model.held_pose(thrower, self.q).rotation()
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
            length = _half_extent(obj.shape, R_rel.matrix(), [*direction, 0.0])
            try:
                q_rel = self.solve_tcp(thrower, TcpTarget(X_WT))
            except PlanningError as err:
                reasons.append(err.reason)
                continue
            J = self._throw_jacobian(thrower, self._q12(thrower, q_rel), held.X_GO.translation())
            # The least spin the joint speeds allow, and the slowest joints (a shorter windup).
            for least_spin in (True, False):
                try:
                    qd = _least_spin_velocity(
                        J, v, limits.velocity * THROW_SPEED_SHARE, least_spin=least_spin
                    )
                except PlanningError as err:
                    reasons.append(err.reason)
                    continue
                options.append((round(length / 0.005), abs(float(J[1] @ qd)), q_rel, qd))
        # The shortest along the flight (long axis across it) first, then the least spin.
        for *_, q_rel, qd in sorted(options, key=lambda o: o[:2]):
            q_sample = q_rel - RELEASE_DELAY * qd
            # Joint-line distance (in seconds of release velocity) to reach it from rest.
            a = float(np.min(limits.acceleration / np.maximum(np.abs(qd), 1e-9)))
            j = float(np.min(limits.jerk / np.maximum(np.abs(qd), 1e-9)))
            ramp = 0.5 * (1 / a + a / j) if a * a / j <= 1 else np.sqrt(1 / j)
            q_wind = q_sample - (THROW_COAST[0] * self.dt + 1.3 * ramp) * qd
            try:
                if not np.all((q_wind >= limits.lower) & (q_wind <= limits.upper)):
                    raise PlanningError("throw_joint_limits", "the windup is out of range")
                plan = throw_release(
                    q_wind, q_sample, limits, self.dt, qd_release=qd, coast=THROW_COAST
                )
                with self.model.padded(0.0, 0.0):
                    if not all(
                        self.model.collision_free(self._q12(thrower, q))
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
        half = _half_extent(obj.shape, held.X_GO.rotation(), [0, 1, 0])
        soft = float(np.clip(gripper.opening(half - THROW_SQUEEZE / gripper.finger_kp), 0, 1))
        return plan, q_wind, soft

    def _throw_jacobian(self, side: str, q12: np.ndarray, p_GQ: np.ndarray) -> np.ndarray:
        """(6, 6) Jacobian of a throw: the gripper's angular velocity about its own x
        (approach), y (finger) and z axes, then the velocity of point Q (fixed in the gripper
        link) in the world."""
        plant = self.model.plant
        plant.SetPositions(self._jac_context, self.model.full_q(q12))
        frame = self.model.gripper_bodies[side].body_frame()
        J = plant.CalcJacobianSpatialVelocity(
            self._jac_context,
            JacobianWrtVariable.kV,
            frame,
            np.asarray(p_GQ, dtype=float),
            plant.world_frame(),
            plant.world_frame(),
        )[:, self._v_indices[side]]
        R = frame.CalcPoseInWorld(self._jac_context).rotation().matrix()
        return np.vstack([R.T @ J[:3], J[3:]])

    def _check_flight(self, motion, name, R_WO, p_rel, v, i_rel, t_end) -> None:
        """The flying object must clear both arms and the scene until it is over the rim."""
        saved = self.model.object_pose(name)
        self.model.set_padding(0.0, 0.0)
        try:
            for t in np.arange(0.05, t_end - 0.02, 0.01):
                p = p_rel + v * t + np.array([0.0, 0.0, -0.5 * GRAVITY * t * t])
                k = i_rel + (RELEASE_DELAY + t) / self.dt
                i = min(int(k), motion.num_steps - 2)
                q = motion.q[i] + (k - i) * (motion.q[i + 1] - motion.q[i])
                self.model.set_object_pose(name, RigidTransform(R_WO, p))
                if not self.model.collision_free(q):
                    pairs = self.model.colliding_pairs(q)
                    raise PlanningError(
                        "flight_blocked", f"{name} in flight hits {pairs[:1]} at t = {t:.2f} s"
                    )
        finally:
            self.model.set_object_pose(name, saved)

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        """On an exception inside the block, put the tracked state (joints, openings, what is
        held, object poses) back as it was, then re-raise."""
        q, opening, stabilized = self.q.copy(), dict(self.opening), dict(self._stabilized)
        held = self.model.held
        poses = {o.name: self.model.object_pose(o.name) for o in self.model.scene.objects}
        try:
            yield
        except BaseException:
            for side in SIDES:
                now = self.model.held.get(side)
                if now is not None and (side not in held or held[side].name != now.name):
                    self.model.detach(side, X_WO=poses[now.name])
            for side, h in held.items():
                if side not in self.model.held:
                    X_WO = self.model.gripper_pose(q, side) @ h.X_GO
                    self.model.attach(h.name, side, q, X_WO)
            held_names = {h.name for h in held.values()}
            for name, X in poses.items():
                if name not in held_names:
                    self.model.set_object_pose(name, X)
            for side in SIDES:
                self.model.set_gripper(side, self.model.embodiment.home_opening)
            self.q, self.opening, self._stabilized = q, opening, stabilized
            raise

    # ------------------------------------------------------------------ motion helpers
    def _checked(
        self,
        motion: Motion,
        clearance: float,
        env_clearance: float,
        *,
        ignore: Iterable[str] = (),
        span: tuple[int, int | None] = (0, None),
    ) -> bool:
        """Whether the samples span[0]..span[1]-1 of `motion` and the straight steps between
        them are collision-free (no robot point moves more than 1 cm between checks)."""
        q = motion.q[span[0] : span[1]]
        self.model.set_padding(clearance, env_clearance)
        with self.model.ignoring(ignore):
            for a, b in zip(q[:-1], q[1:], strict=True):
                n = max(1, int(np.ceil(self.model.path_distance(a, b) / 0.01)))
                if not all(
                    self.model.collision_free(a + s * (b - a)) for s in np.linspace(0, 1, n + 1)
                ):
                    return False
        return True

    def _still(self, q12: np.ndarray | None = None, openings: dict | None = None) -> Motion:
        """A one-sample motion: both arms at `q12` (default: now)."""
        q12 = self.q if q12 is None else q12
        o = self.opening if openings is None else openings
        return Motion(np.array(q12, float)[None], np.array([[o["left"], o["right"]]], float))

    def _sequence(self, parts: Sequence[dict[str, ArmPlan]], start: Motion) -> Motion:
        """`start` followed by each part in turn; in a part, an arm without a plan (or with the
        shorter plan) holds its last sample until the other arm is done."""
        motion = start
        for part in parts:
            n = max(p.num_steps for p in part.values())
            plans = {}
            for k, side in enumerate(SIDES):
                p = part.get(side)
                if p is None:
                    p = ArmPlan(side, motion.q[-1:, ARM_SLICES[side]], motion.openings[-1:, k])
                plans[side] = p.padded(n)
            motion = motion.then(_combine(plans["left"], plans["right"]))
        return motion

    def _motion_of(self, traj: TimedTrajectory, label: str, opening: float | None = None) -> Motion:
        """A 12-DoF trajectory as a motion, grippers as they are (or all at `opening`)."""
        o = [self.opening[s] if opening is None else opening for s in SIDES]
        return Motion(traj.q.copy(), np.tile(np.array(o, float), (len(traj.q), 1)), label=label)

    def _arm_plan(self, side: str, traj: TimedTrajectory, label: str) -> ArmPlan:
        return ArmPlan(side, traj.q.copy(), np.full(len(traj.q), self.opening[side]), label=label)


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


def _least_spin_velocity(
    J: np.ndarray, v: np.ndarray, cap: np.ndarray, *, least_spin: bool = True
) -> np.ndarray:
    """Release joint velocity for the throw Jacobian `J` (:meth:`Skills._throw_jacobian`):
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


def _levelled(R_WB: RotationMatrix) -> RotationMatrix:
    """`R_WB` turned by the smallest rotation that makes its z axis vertical (its yaw kept)."""
    z = R_WB.col(2)
    axis = np.cross(z, [0.0, 0.0, 1.0])
    s, c = float(np.linalg.norm(axis)), float(z[2])
    if s < 1e-9:
        return R_WB
    tilt = RotationMatrix(AngleAxis(np.arctan2(s, c), axis / s))
    return tilt @ R_WB


def _half_extent(shape, R: np.ndarray, u: Sequence[float]) -> float:
    """Half the extent of `shape` (orientation R in the frame of u) along the unit vector u."""
    u = np.asarray(u, dtype=float)
    R = np.asarray(R.matrix() if hasattr(R, "matrix") else R, dtype=float)
    if isinstance(shape, BoxShape):
        return float(np.abs(R.T @ u) @ (np.asarray(shape.size) / 2))
    if isinstance(shape, CylinderShape):
        c = abs(float(R[:, 2] @ u))
        return c * shape.length / 2 + shape.radius * float(np.sqrt(max(0.0, 1 - c * c)))
    if isinstance(shape, SphereShape):
        return shape.radius
    if isinstance(shape, BowlShape):
        c = abs(float(R[:, 2] @ u))
        return c * shape.height / 2 + shape.radius * float(np.sqrt(max(0.0, 1 - c * c)))
    raise PlanningError("unsupported_shape", f"no extent for {type(shape).__name__}")


def _rim(shape, R_WO: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """(height of the container's mouth above its frame, distance from the axis to the rim in
    the horizontal direction d)."""
    if isinstance(shape, BowlShape):
        return shape.height, shape.radius
    if isinstance(shape, CylinderShape):
        return shape.length / 2, shape.radius
    if isinstance(shape, BoxShape):
        half = np.asarray(shape.size) / 2
        return float(half[2]), float(np.abs(R_WO[:, :2].T @ d) @ half[:2])
    raise PlanningError("unsupported_shape", f"cannot pour from a {type(shape).__name__}")


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix of `angle` about the unit `axis` (Rodrigues)."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


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

"""The core of the skills: plans on the planning grid and the shared planning context.

Time is seconds: every duration a skill takes (a hold, a release, a delay) is in seconds and
becomes a whole number of sample periods of the planning model (:func:`periods`), so a plan
looks the same at 10, 15 or 50 Hz and only its sampling changes. The sample period is the
station's control period at 15 Hz and faster, and a k-th of it below 15 Hz
(:func:`~bicoord_drake.planning.timing.planning_substeps`: 1/20 s at 10 Hz), where every k-th
sample is executed (:func:`~bicoord_drake.tasks.base.expert_actions`).

:class:`ArmPlan` is one arm's motion (joint samples, a gripper-opening schedule, attach/detach
events), :class:`Motion` both arms'. :class:`SkillContext` is what every skill plans from and
advances: the planning model (object poses, what each gripper holds), the arms' joint angles
and commanded openings, the timing limits and clearances. :meth:`SkillContext.sync` adopts
measured values, :meth:`SkillContext.transaction` rolls a failed multi-step plan back, and
:func:`merge` runs two arm plans at the same time, delaying one only if the arms would meet.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.all import RigidTransform

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.geometry import transform_points
from bicoord_drake.models.layout import ActionLayout
from bicoord_drake.planning.clearance import points_to_boxes, shape_points
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.planning.ik import BimanualIK
from bicoord_drake.planning.model import HeldObject, PlanningModel, bisection_order
from bicoord_drake.planning.timing import JointLimits, TimedTrajectory

#: Longest time (s) between two configurations :func:`merge` checks densely (the samples and
#: the sub-samples between them): four per period at 15 Hz.
MERGE_CHECK_PERIOD = 1.0 / 60.0
#: :func:`merge` tries delays of one plan in multiples of MERGE_DELAY_STRIDE (s), up to
#: MERGE_MAX_DELAY (s).
MERGE_DELAY_STRIDE = 0.2
MERGE_MAX_DELAY = 6.0
#: A held object measured farther than this (m) from its hand at a run boundary is no longer
#: held (:meth:`SkillContext.refresh_grasps`): a grasp settles by millimetres, a lost object
#: lies centimetres away.
GRASP_LOST_DISTANCE = 0.02


def periods(seconds: float, dt: float) -> int:
    """The whole number of sample periods `dt` nearest to `seconds` (>= 0): a duration's
    length on the planning grid (at most half a period off)."""
    if seconds < 0:
        raise ValueError(f"a duration must be >= 0 s, got {seconds}")
    return int(np.floor(seconds / dt + 0.5))


@dataclass
class ArmPlan:
    """One arm's motion on the control grid: q (N, n), opening (N,), events by sample index."""

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
    """A two-arm motion on the planning grid: q (N, 2 n) [left n, right n], openings (N, 2)
    [left, right].

    ``anchor``: a sample that must be executed at a control step (a throw's release: the
    fingers start opening there). Below 15 Hz only every k-th planned sample is executed
    (:func:`~bicoord_drake.planning.timing.planning_substeps`); the expert's
    :func:`~bicoord_drake.tasks.base.follow` then holds the motion's start for up to k - 1
    samples so that the anchor is one of them. None: any phase will do."""

    q: np.ndarray
    openings: np.ndarray
    events: list[tuple[int, str, str, str]] = field(default_factory=list)  # (i, side, kind, obj)
    label: str = ""
    info: dict[str, Any] = field(default_factory=dict)  # skill-specific plan data
    anchor: int | None = None

    @property
    def num_steps(self) -> int:
        return len(self.q)

    def then(self, other: Motion) -> Motion:
        """This motion followed by `other` (which must start where this one ends). Events are
        re-indexed; ``info`` is merged as is (the later motion's keys win); the anchor is
        this motion's, else `other`'s (re-indexed)."""
        if np.max(np.abs(other.q[0] - self.q[-1])) > 1e-6:
            raise ValueError(f"motion {other.label!r} does not start where the previous ends")
        n = self.num_steps - 1
        events = self.events + [(i + n, side, k, o) for i, side, k, o in other.events]
        anchor = self.anchor
        if anchor is None and other.anchor is not None:
            anchor = other.anchor + n
        return Motion(
            np.vstack([self.q, other.q[1:]]),
            np.vstack([self.openings, other.openings[1:]]),
            events,
            f"{self.label}; {other.label}",
            {**self.info, **other.info},
            anchor,
        )

    def delayed(self, samples: int) -> Motion:
        """The same motion after holding its first sample for `samples` more samples (events
        and the anchor move with it; ``info`` is kept as is)."""
        if samples <= 0:
            return self
        return Motion(
            np.vstack([np.repeat(self.q[:1], samples, 0), self.q]),
            np.vstack([np.repeat(self.openings[:1], samples, 0), self.openings]),
            [(i + samples, side, k, o) for i, side, k, o in self.events],
            self.label,
            self.info,
            None if self.anchor is None else self.anchor + samples,
        )

    def actions(self) -> np.ndarray:
        """(N-1, 2 (n + 1)) actions: every sample after the start, in the station's action
        layout (:class:`~bicoord_drake.models.layout.ActionLayout`; 14 numbers for 6-joint
        arms)."""
        q, g = self.q[1:], self.openings[1:]
        layout = ActionLayout(q.shape[1] // 2)
        arms = {"left": q[:, : layout.arm_joints], "right": q[:, layout.arm_joints :]}
        return layout.compose(arms, {"left": g[:, 0], "right": g[:, 1]})


class _Rehearsed(Exception):
    """Ends a :meth:`SkillContext.rehearsal` block so that its transaction rolls back."""


class SkillContext:
    """The state skills plan from and advance, for both arms of a :class:`PlanningModel`.

    `speed` scales the embodiment's joint velocity limits (accelerations by speed^2, jerks by
    speed^3). Plans are sampled every ``dt`` seconds: the planning model's ``control_period``
    unless given. For an expert that is the planning period of
    :meth:`~bicoord_drake.tasks.base.WorldView.planning_model`: the station's control period at
    15 Hz and faster, a k-th of it below 15 Hz (k from
    :func:`~bicoord_drake.planning.timing.planning_substeps`; 1/20 s at 10 Hz), of which every
    k-th sample is executed. Every duration a skill takes is a whole number of ``dt``. The
    tracked state (joint angles ``q``, commanded ``opening`` per side, held
    objects in ``model``) advances as skills are planned; call :meth:`sync` with measured values
    before planning from a new situation.
    """

    def __init__(
        self,
        model: PlanningModel,
        *,
        speed: float = 0.5,
        dt: float | None = None,
        clearance: float = 0.03,
        env_clearance: float = 0.005,
    ) -> None:
        self.model = model
        self.ik = BimanualIK(model)
        #: Seconds between two planned samples (see the class docstring).
        self.dt = dt = model.control_period if dt is None else float(dt)
        self.clearance = clearance
        self.env_clearance = env_clearance
        #: One arm's timing limits (the embodiment's, slowed by `speed`).
        self.arm_limits = JointLimits.from_embodiment(model.embodiment, arms=1, speed=speed)
        self.q = model.home.copy()
        self.opening = {side: model.embodiment.home_opening for side in SIDES}
        self.speed = speed
        g = model.embodiment.arm.gripper
        self.gripper_steps = max(
            3, int(np.ceil((g.finger_max - g.finger_min) / g.finger_velocity_limit / dt))
        )
        self.track_ik = BimanualIK(model)  # its nominal follows the previous sample
        self.stabilized: dict[str, np.ndarray] = {}  # side -> model lift of what it steadies
        #: object -> how the plans since the last plan boundary set it down (``place``
        #: records it), so an expert that finds it fallen on the way can place it again
        #: (:mod:`bicoord_drake.tasks.recovery`).
        self.placements: dict[str, Any] = {}
        #: object -> (side that set it down, its placement, the measured pose it came to rest
        #: at): what the expert set down on the table top and has not picked up since, so it
        #: can place again what was knocked away (:func:`~bicoord_drake.tasks.recovery.knocked`).
        self.settled: dict[str, tuple[str, Any, RigidTransform]] = {}
        #: object -> the frame the model gives it in its body's frame (a shape symmetry: a
        #: cube picked up again after it fell on another face); measured poses are turned
        #: into it (:meth:`modelled`). Empty: the model's frames are the bodies'.
        self.frames: dict[str, RigidTransform] = {}
        #: How the expert picks an object up again after it fell, ``picker(side, name)`` ->
        #: the pick's plan: a task whose objects need grasps of its own sets it (None: ``pick``
        #: with generated grasps; :mod:`bicoord_drake.tasks.recovery`).
        self.picker: Callable[[str, str], ArmPlan] | None = None

    def steps(self, seconds: float) -> int:
        """Sample periods that `seconds` last on this context's grid (:func:`periods`)."""
        return periods(seconds, self.dt)

    # ------------------------------------------------------------------ state
    def sync(
        self,
        q: np.ndarray,
        openings: dict[str, float] | None = None,
        object_poses: dict[str, RigidTransform] | None = None,
    ) -> None:
        """Adopt measured joint angles, commanded openings and free objects' poses."""
        self.q = np.asarray(q, dtype=float).copy()
        if openings:
            self.opening.update(openings)
        held = {h.name for h in self.model.held.values()}
        for name, X in self.modelled(object_poses or {}).items():
            if name not in held:
                self.model.set_object_pose(name, X)

    def refresh_grasps(self, object_poses: dict[str, RigidTransform]) -> None:
        """Re-measure each held object's pose in its gripper from measured poses (a grasp
        settles by a few mm when the fingers close), so later placements aim right. Held
        objects missing from `object_poses` keep their grasp. A held object no longer in its
        hand (:meth:`lost_grasps`: slipped out, dropped) raises
        ``PlanningError('grasp_lost')``: planning on would carry it where it is not."""
        if lost := self.lost_grasps(object_poses):
            side, name, gap = lost[0]
            raise PlanningError(
                "grasp_lost",
                f"{side} no longer holds {name!r}: measured {gap * 100:.1f} cm from its hand",
            )
        object_poses = self.modelled(object_poses)
        for side, held in list(self.model.held.items()):
            X_WO = object_poses.get(held.name)
            if X_WO is None:
                continue
            self.model.detach(side, X_WO=X_WO)
            together = bool(self.model.holders(held.name))  # the other hand holds it too
            self.model.attach(held.name, side, self.q, X_WO=X_WO, together=together)

    def lost_grasps(self, object_poses: dict[str, RigidTransform]) -> list[tuple[str, str, float]]:
        """The grasps the measured poses (body frames) show lost: ``(side, object, gap)`` for
        each held object whose surface lies farther than ``GRASP_LOST_DISTANCE`` from its
        hand (the gap in m). Held objects missing from `object_poses` count as held."""
        object_poses = self.modelled(object_poses)
        lost = []
        for side, held in self.model.held.items():
            X_WO = object_poses.get(held.name)
            if X_WO is None:
                continue
            gap = self.hand_gap(side, held.name, X_WO)
            if gap > GRASP_LOST_DISTANCE:
                lost.append((side, held.name, gap))
        return lost

    def modelled(self, object_poses: dict[str, RigidTransform]) -> dict[str, RigidTransform]:
        """Measured body poses as the model's object frames (:attr:`frames`)."""
        if not self.frames:
            return object_poses
        return {n: X @ self.frames[n] if n in self.frames else X for n, X in object_poses.items()}

    def hand_gap(self, side: str, name: str, X_WO: RigidTransform) -> float:
        """Least distance (m) from the surface of object `name` at `X_WO` to `side`'s hand
        (its gripper and fingers at the tracked opening, at the tracked joints); 0 where they
        overlap, as a held object between the fingers does."""
        arm = self.model.embodiment.arm
        X_TO = self.model.tcp_pose(self.q, side).inverse() @ X_WO
        points = shape_points(self.model.object(name).shape)
        return points_to_boxes(transform_points(X_TO, points), arm.hand_boxes(self.opening[side]))

    def arm_q(self, side: str) -> np.ndarray:
        """The joint angles of `side` (a copy)."""
        return self.q[self.model.side_slice(side)].copy()

    def with_arm(self, side: str, q_arm: np.ndarray) -> np.ndarray:
        """Both arms' joint angles with `side`'s replaced by `q_arm` (the state is not
        changed)."""
        q = self.q.copy()
        q[self.model.side_slice(side)] = q_arm
        return q

    @contextmanager
    def transaction(self) -> Iterator[None]:
        """On an exception inside the block, put the tracked state (joints, openings, what is
        held, object poses) back as it was, then re-raise."""
        q, opening, stabilized = self.q.copy(), dict(self.opening), dict(self.stabilized)
        placements = dict(self.placements)
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
                    together = bool(self.model.holders(h.name))
                    self.model.attach(h.name, side, q, X_WO, together=together)
            held_names = {h.name for h in held.values()}
            for name, X in poses.items():
                if name not in held_names:
                    self.model.set_object_pose(name, X)
            for side in SIDES:
                self.model.set_gripper(side, self.model.embodiment.home_opening)
            self.q, self.opening, self.stabilized = q, opening, stabilized
            self.placements = placements
            raise

    @contextmanager
    def tuned(
        self,
        *,
        speed: float | None = None,
        clearance: float | None = None,
        env_clearance: float | None = None,
    ) -> Iterator[None]:
        """Plan with another `speed`, inter-arm `clearance` (m) and/or clearance from the scene
        `env_clearance` (m) meanwhile (None: keep)."""
        saved = self.speed, self.clearance, self.env_clearance
        self.speed = saved[0] if speed is None else speed
        self.clearance = saved[1] if clearance is None else clearance
        self.env_clearance = saved[2] if env_clearance is None else env_clearance
        try:
            yield
        finally:
            self.speed, self.clearance, self.env_clearance = saved

    @contextmanager
    def rehearsal(self) -> Iterator[None]:
        """Plan inside the block only to see whether it can be planned: afterwards everything
        :meth:`transaction` restores, and the checker's padding, is put back as it was, whether
        the block raised or not."""
        with self.model.keeping_padding():
            try:
                with self.transaction():
                    yield
                    raise _Rehearsed
            except _Rehearsed:
                pass

    # ------------------------------------------------------------------ motions
    def edge_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the straight joint-space segment a -> b is collision-free (1 cm joint steps,
        at the model's current padding)."""
        n = max(2, int(np.ceil(np.max(np.abs(b - a)) / 0.01)) + 1)
        return all(self.model.collision_free(a + s * (b - a)) for s in np.linspace(0, 1, n))

    def checked(
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

    def still(self, q: np.ndarray | None = None, openings: dict | None = None) -> Motion:
        """A one-sample motion: both arms at `q` (default: now)."""
        q = self.q if q is None else q
        o = self.opening if openings is None else openings
        return Motion(np.array(q, float)[None], np.array([[o["left"], o["right"]]], float))

    def sequence(self, parts: Sequence[dict[str, ArmPlan]], start: Motion) -> Motion:
        """`start` followed by each part in turn; in a part, an arm without a plan (or with the
        shorter plan) holds its last sample until the other arm is done."""
        motion = start
        for part in parts:
            n = max(p.num_steps for p in part.values())
            plans = {}
            for k, side in enumerate(SIDES):
                p = part.get(side)
                if p is None:
                    sl = self.model.side_slice(side)
                    p = ArmPlan(side, motion.q[-1:, sl], motion.openings[-1:, k])
                plans[side] = p.padded(n)
            motion = motion.then(combine(plans["left"], plans["right"]))
        return motion

    def motion_of(self, traj: TimedTrajectory, label: str, opening: float | None = None) -> Motion:
        """A two-arm trajectory as a motion, grippers as they are (or all at `opening`)."""
        o = [self.opening[s] if opening is None else opening for s in SIDES]
        return Motion(traj.q.copy(), np.tile(np.array(o, float), (len(traj.q), 1)), label=label)

    def arm_plan(self, side: str, traj: TimedTrajectory, label: str) -> ArmPlan:
        """A one-arm trajectory of `side` as an arm plan, its gripper as it is."""
        return ArmPlan(side, traj.q.copy(), np.full(len(traj.q), self.opening[side]), label=label)


def hold(ctx: SkillContext, side: str, seconds: float = 0.0, label: str = "hold") -> ArmPlan:
    """Stay still for `seconds` (0: one sample, where the arm is)."""
    steps = ctx.steps(seconds)
    return ArmPlan(
        side,
        np.repeat(ctx.arm_q(side)[None], steps + 1, 0),
        np.full(steps + 1, ctx.opening[side]),
        label=label,
    )


def hold_still(ctx: SkillContext, seconds: float, label: str = "hold") -> Motion:
    """Both arms stay still for `seconds` (e.g. while what they put down comes to rest)."""
    return combine(hold(ctx, "left", seconds, label), hold(ctx, "right", seconds, label))


def plan_both(
    ctx: SkillContext,
    plans: dict[str, Callable[[], ArmPlan]],
    order: Sequence[str] = SIDES,
) -> tuple[ArmPlan, ArmPlan]:
    """Plan one part for each arm, to run at the same time (:func:`merge`): returns the
    (left, right) plans. Each arm's plan is made with the other arm where its own plan ends,
    so the arm planned second works around the first (a wide hand chooses its grasp or place
    yaw by the other hand). `order` is tried first; if the second arm then finds no plan, the
    other order is tried, and if that fails too the first order's error is raised. On failure
    nothing is changed."""
    first = list(order)
    if sorted(first) != sorted(SIDES):
        raise ValueError(f"order must name both arms, got {order}")
    errors: list[PlanningError] = []
    for sides in (first, first[::-1]):
        out: dict[str, ArmPlan] = {}
        try:
            with ctx.transaction():
                for side in sides:
                    out[side] = plans[side]()
        except PlanningError as err:
            errors.append(err)
            continue
        return out["left"], out["right"]
    raise errors[0]


def merge(
    ctx: SkillContext,
    left: ArmPlan | None,
    right: ArmPlan | None,
    *,
    max_delay: float = MERGE_MAX_DELAY,
    stretch: bool = True,
    ignore: Iterable[str] = (),
) -> Motion:
    """Run both plans at once. With `stretch`, the shorter plan is first slowed to last as
    long as the longer one, so both arms keep acting together; if the arms would then come
    closer than the checker allows, the plans run at their own pace and the later-starting
    one is delayed (first the right, then the left, in steps of MERGE_DELAY_STRIDE up to
    `max_delay` seconds) until they do not. An object one arm
    carries is part of that check from its pick to its release (:func:`_carried_free`: on
    its hand, against the other arm); before its pick and after its release it is left out,
    as is an object the arms pass between them. Objects in `ignore` (e.g. a container one
    arm steadies while the other reaches into it) are left out of the whole check.

    The check first holds the fingers as the model has them (as a rule the home opening, the
    widest); only if no timing passes that way is it done again with each hand's fingers as
    open as they can be at each sample (:func:`_finger_bounds`: a narrowed jaw leaving a
    narrow place, planned that way)."""
    plans = {"left": left, "right": right}
    for side in SIDES:
        if plans[side] is None:
            plans[side] = hold(ctx, side, 0)
    starts = {s: plans[s].q[0] for s in SIDES}
    n = max(p.num_steps for p in plans.values())
    moving = {s: bool(np.any(plans[s].q != plans[s].q[0])) for s in SIDES}
    candidates = []
    if stretch and all(moving.values()):
        candidates.append(combine(plans["left"].stretched(n), plans["right"].stretched(n)))
    stride = max(1, ctx.steps(MERGE_DELAY_STRIDE))
    attempts = [("right", 0)] + [
        (s, d) for d in range(stride, ctx.steps(max_delay) + 1, stride) for s in ("right", "left")
    ]
    for side, delay in attempts:
        trial = dict(plans)
        trial[side] = trial[side].delayed(delay)
        candidates.append(combine(trial["left"], trial["right"]))
    for fingers in (False, True):
        for motion in candidates:
            if _motion_free(ctx, motion, starts, ignore, fingers=fingers):
                return motion
    raise PlanningError(
        "arm_conflict",
        f"the arms' plans ({plans['left'].label!r}, "
        f"{plans['right'].label!r}) collide at every delay up to {max_delay:g} s",
    )


def _finger_bounds(ctx: SkillContext, motion: Motion) -> list[dict[str, float]]:
    """Per sample of `motion`, each side's widest opening commanded over the last
    ``ctx.gripper_steps`` samples (the fingers' full stroke takes no longer): a bound on how
    open its fingers are there."""
    o = motion.openings
    w = ctx.gripper_steps
    bounds = [o[max(0, i - w) : i + 1].max(axis=0) for i in range(len(o))]
    return [{side: float(b[k]) for k, side in enumerate(SIDES)} for b in bounds]


def _motion_free(
    ctx: SkillContext,
    motion: Motion,
    starts: dict,
    ignore: Iterable[str] = (),
    *,
    fingers: bool = False,
) -> bool:
    """Check a merged motion densely (at most MERGE_CHECK_PERIOD apart): the arms against
    each other and the scene, then each carried object against the other arm.

    First pass: objects picked or released anywhere in the motion are left out; their
    clearance to the static scene was checked when each arm's plan was made. Second pass
    (:func:`_carried_free`): between its pick and its release each object one arm carries
    rides on that hand at its grasp and is checked against the other arm and what that one
    holds. The fingers are as the model has them, or with `fingers` at :func:`_finger_bounds`.

    The samples are checked first, coarse to fine (a colliding merge, as most of
    :func:`merge`'s delays are, is rejected after a few checks), then the substeps between
    them: the same configurations as one dense pass, so the same verdict."""
    moving = {name for _, _, _, name in motion.events} | set(ignore)
    q = motion.q
    steps = [i for i in range(1, motion.num_steps) if not np.array_equal(q[i - 1], q[i])]
    if not steps:
        return True
    bounds = _finger_bounds(ctx, motion) if fingers else [None] * motion.num_steps
    with ctx.model.ignoring(moving):
        if not _steps_free(ctx, q, steps, bounds):
            return False
    return _carried_free(ctx, motion, steps, bounds, ignore)


def _steps_free(ctx: SkillContext, q: np.ndarray, steps: list[int], bounds: list) -> bool:
    """Whether the samples q[i], i in `steps`, (coarse to fine) and the sub-samples between
    each and the sample before it (:func:`merge_substeps`) are collision-free as the model is
    now."""
    between = np.linspace(0, 1, merge_substeps(ctx.dt) + 1)[1:-1]
    for k in bisection_order(len(steps) - 1).astype(int):
        i = steps[k]
        if not ctx.model.collision_free(q[i], bounds[i]):
            return False
    for i in steps:
        a, b = q[i - 1], q[i]
        for s in between:
            if not ctx.model.collision_free(a + s * (b - a), bounds[i]):
                return False
    return True


def merge_substeps(dt: float) -> int:
    """Pieces each control period is cut into by the dense check of a merged motion."""
    return max(1, int(np.ceil(dt / MERGE_CHECK_PERIOD - 1e-9)))


def carried_spans(
    ctx: SkillContext, motion: Motion, ignore: Iterable[str] = ()
) -> list[tuple[int, int, HeldObject]]:
    """The objects one arm carries in `motion`, as (first, last sample, hold): from its pick
    (or the start, if it is held then) to its release (or the end), at the grasp the model has
    (a held object's) or the one its release pose gives at the release sample.

    Only simple carries are found: one arm picks and/or releases the object once. An object
    both arms hold or pass between them, one picked or released more than once, and those in
    `ignore` are not carried here (the check leaves them out, as before)."""
    events: dict[str, list[tuple[int, str, str]]] = {}
    for i, side, kind, name in motion.events:
        events.setdefault(name, []).append((i, side, kind))
    ignore = set(ignore)
    spans = []
    for name in sorted(events):
        evs = sorted(events[name])
        sides = {side for _, side, _ in evs}
        kinds = [kind for _, _, kind in evs]
        if name in ignore or len(sides) != 1:
            continue
        (side,) = sides
        held = ctx.model.held.get(side)
        if kinds == ["attach"]:
            if held is None or held.name != name or len(ctx.model.holders(name)) != 1:
                continue
            spans.append((evs[0][0], motion.num_steps - 1, held))
        elif kinds in (["detach"], ["attach", "detach"]):
            if ctx.model.holders(name):
                continue
            last = evs[-1][0]
            X_GO = ctx.model.gripper_pose(motion.q[last], side).inverse()
            X_GO = X_GO @ ctx.model.object_pose(name)
            first = evs[0][0] if kinds[0] == "attach" else 0
            spans.append((first, last, HeldObject(name, side, X_GO)))
    return spans


def _carried_free(
    ctx: SkillContext, motion: Motion, steps: list[int], bounds: list, ignore: Iterable[str]
) -> bool:
    """Whether every object carried in `motion` (:func:`carried_spans`) keeps the arms'
    clearance from the other arm, and what that one holds, while it is carried.

    It rides on its hand (as a held object does in the model), and only the pairs between
    the two arms are checked (:meth:`PlanningModel.arms_only`): its clearance from the scene,
    its support at the pick and the release included, is the single-arm plan's to check.
    Objects held throughout the motion stay held; steps are grouped by what is carried."""
    spans = carried_spans(ctx, motion, ignore)
    if not spans:
        return True
    moved = {name for _, _, _, name in motion.events}
    base = {s: h for s, h in ctx.model.held.items() if h.name not in moved}
    groups: dict[tuple, list[int]] = {}
    for i in steps:
        key = tuple(k for k, (a, b, _) in enumerate(spans) if a <= i <= b)
        if key:
            groups.setdefault(key, []).append(i)
    with ctx.model.ignoring(ignore), ctx.model.arms_only():
        for key, group in groups.items():
            held = dict(base)
            for k in key:
                h = spans[k][2]
                if h.side in held:  # the hand holds something else: not a simple carry
                    break
                held[h.side] = h
            else:
                with ctx.model.holding(held):
                    if not _steps_free(ctx, motion.q, group, bounds):
                        return False
    return True


def combine(left: ArmPlan, right: ArmPlan) -> Motion:
    """Both plans from the same step, the shorter one holding its last sample: no collision
    check (for plans already checked against each other, e.g. one arm's track planned with
    the other arm where it holds)."""
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

"""Disturbances of an expert's demonstration (issue #54): a push on a task object, a grasp that
opens, a knock on a placed object, each at a step drawn from the episode's seed.

>>> parse_disturb("push,drop")
('push', 'drop')
>>> trace = ExpertTrace(sim)        # doctest: +SKIP
>>> ...                             # a clean run: trace.capture() each step, trace.read()
>>> schedule = plan_disturbances(("push",), seed, trace, sim.station)   # doctest: +SKIP
>>> driver = DisturbanceDriver(sim, schedule)       # doctest: +SKIP
>>> executed = driver.before_step(frame, action)    # then sim.step(executed)

Kinds (:data:`DISTURBANCE_KINDS`):

- ``push``: an external force on a free task object resting on the table (touched by nothing
  but its support), for :data:`PUSH_SECONDS`, through the plant's applied-spatial-force input
  (``MultibodyPlant.get_applied_spatial_force_input_port``: physics moves the object, no pose
  is ever set). It fires after :data:`EARLIEST_SECONDS`, during the plan that runs up to the
  expert's first plan boundary after that, on an object the expert acts on only from that
  boundary on, and ends :data:`SETTLE_SECONDS` before it: the expert measures the object where
  the push left it and plans from there.
- ``drop``: the executed command of a gripper holding an object alone (not with the other
  hand), just lifted off its support (at most :data:`DROP_HEIGHT` above where it lay at the
  start) and :data:`DROP_EDGE_MARGIN` inside the table's edge, opened
  evenly to fully open over :data:`DROP_OPEN_SECONDS`, then held open to the end of
  :data:`DROP_SECONDS` (a grip that loosens, and lets go: fingers that closed again while the
  object still fell between them would pinch and fling it; the expert's command
  stays the label, what ran is the episode's ``joint_action/executed``), with a plan boundary
  after it. The expert picks the object up again (:mod:`bicoord_drake.tasks.recovery`).
- ``knock``: a push on an object the expert placed (held, then released and at rest alone on
  the table top, or on a flat marker there: not on another object, a shelf or in a drawer,
  where the expert would not put it back), clear of the table's
  edge and the other free objects (a fixture, such as the marker it was set down on, may be
  in its way), that slides without tipping over as friction stops it
  (:func:`topples_when_slid`: a block standing on its end is not knocked), with a plan
  boundary after it at which one of the expert's hands is free and before which nothing is set
  on it (:func:`_knock_fits`). An object the expert set
  down on the table top it places again (:func:`~bicoord_drake.tasks.recovery.knocked`).

The force is horizontal, of a magnitude that slides the object :data:`PUSH_DISTANCE` on its
support: from the object's mass and the combined friction coefficient of its and the table's
contact geometry (Drake's ``2 a b / (a + b)``), a force ``k mu m g`` for ``T`` seconds slides it
``k (k - 1) mu g T^2 / 2``. It acts below the centre of mass, at the height ``h (1 - 1/k)``
above the support where its moment balances that of friction (``h``: the centre of mass's
height above the support), so the object slides instead of tipping; its direction (drawn) keeps
the object's predicted path clear of the table's edge and of the other objects (their extents
from their collision primitives). Measured: a 4 cm jigsaw cube asked for 4 cm slides 2.9 cm
(the contact's friction is not quite Coulomb's), a few cm as intended.

Where a disturbance may fire comes from a clean run of the expert on the same seed
(:class:`ExpertTrace`: per control step, which objects the robot touches, what touches what,
each object's speed, and the *plan boundaries*, the steps at which the expert read the
measured world before planning on). An object is acted on from the first step the robot, or
an object the robot has handled, touches it. The object, step, direction and distance are
then drawn from ``default_rng([DISTURB_STREAM, seed, k])`` (k: the kind's index), independent
of the scene's and the action noise's draws, so the same seed gives the same disturbance.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, get_args

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:
    from bicoord_drake.sim.simulation import Simulation
    from bicoord_drake.sim.station import Station

DisturbanceKind = Literal["push", "drop", "knock"]
#: Every disturbance kind, in the order they are planned and recorded.
DISTURBANCE_KINDS: tuple[str, ...] = get_args(DisturbanceKind)
#: Mixed with an episode's seed into the seeds of its disturbance draws (one per kind).
DISTURB_STREAM = 0x50555348  # "PUSH"

#: No disturbance in the first half second (the scene's objects settle on their supports).
EARLIEST_SECONDS = 0.5
#: How long a push's (and a knock's) force acts.
PUSH_SECONDS = 0.1
#: How far (m) a push slides its object on the table: drawn per episode in this range.
PUSH_DISTANCE = (0.03, 0.05)
#: Time a pushed object has to come to rest before the expert measures it again.
SETTLE_SECONDS = 0.6
#: How long a dropping gripper takes to open: its executed command rises evenly from closed
#: to :data:`DROP_OPENING` over this time, or is the expert's where that is wider (a grip
#: that loosens: a gripper snapped open flicks a squeezed small cube off the table; over
#: 0.5 s the arm lifted the cube on by up to 5 cm before it slipped out).
DROP_OPEN_SECONDS = 0.25
#: How long a drop acts: the opening, then the gripper held open while the object falls clear.
DROP_SECONDS = 1.0
#: The opening a dropping gripper is commanded (fully open).
DROP_OPENING = 1.0
#: A drop fires only while its object is this far (m) inside the table's edge: what falls
#: stays on the table, where the expert can pick it up again.
DROP_EDGE_MARGIN = 0.12
#: A drop starts only where its object is at most this high (m) above where it lay at the
#: start (just lifted off): a cube let fall 5-7 cm onto the table top
#: (the arm lifts on while the grip loosens) can rebound at 3 m/s, spinning at 70 rad/s, and
#: leave the table (traced: build_tower_with_blocks seed 14), where no expert can pick it up.
DROP_HEIGHT = 0.02
#: A pushed object's predicted path (1.5 times its distance) stays this far inside the table's
#: edge and this far from every other object's footprint.
EDGE_MARGIN = 0.08
CLEARANCE = 0.03
#: Speed (m/s) under which an object counts as at rest.
REST_SPEED = 0.01
#: Horizontal directions tried for a push, from a drawn angle on.
DIRECTIONS = 12
GRAVITY = 9.81
#: The name the trace gives the table and fixed objects (an object's support).
SUPPORT = "support"


class NoDisturbanceWindow(ValueError):  # noqa: N818 - the reason a seed is recorded as failed
    """No step of the episode admits the disturbance (its reason says why)."""


def parse_disturb(value: Any) -> tuple[str, ...]:
    """The disturbance kinds of a setting: None, ``""``, ``"none"`` or ``[]`` for none; a kind,
    a comma list ``"push,drop"`` or a list. Each kind once, in :data:`DISTURBANCE_KINDS` order;
    an unknown kind is a ValueError naming it and the valid ones."""
    if value is None:
        return ()
    if isinstance(value, str):
        items = [v.strip() for v in value.split(",") if v.strip()]
    elif isinstance(value, list | tuple):
        items = list(value)
    else:
        raise ValueError(
            f"write KIND or KIND,KIND with kinds {', '.join(DISTURBANCE_KINDS)} (or none), "
            f"got {value!r}"
        )
    if items in (["none"], []):
        return ()
    unknown = [v for v in items if v not in DISTURBANCE_KINDS]
    if unknown:
        raise ValueError(
            f"unknown disturbance kind {', '.join(map(repr, unknown))}; kinds: "
            f"{', '.join(DISTURBANCE_KINDS)} (or none)"
        )
    return tuple(k for k in DISTURBANCE_KINDS if k in items)


class Disturbance(BaseModel):
    """One disturbance of an episode, as recorded in its file (``disturbances/``).

    It acts during the control steps ``step .. step + duration - 1`` (control step t runs from
    frame t to frame t + 1). A push or knock applies `force` (N, world frame) and `torque`
    (N m, world frame) at `point` (m, in the body frame of `body`); a drop opens the gripper of
    `side`, which held `body`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: DisturbanceKind
    step: int = Field(ge=0, description="the first control step it acts in")
    duration: int = Field(ge=1, description="control steps it acts for")
    body: str = Field(description="the object pushed, knocked or dropped")
    side: str = Field("", description="drop: the gripper forced open; empty otherwise")
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _side_for_drops(self) -> Disturbance:
        if (self.kind == "drop") != bool(self.side):
            raise ValueError(f"a {self.kind} {'needs' if self.kind == 'drop' else 'has no'} side")
        return self

    @property
    def wrench(self) -> np.ndarray:
        """(6,) ``[torque, force]`` in the world frame, about `point` (Drake's SpatialForce)."""
        return np.array([*self.torque, *self.force], dtype=float)

    @property
    def end(self) -> int:
        """The first control step after it."""
        return self.step + self.duration

    def active(self, step: int) -> bool:
        """Whether it acts in control step `step`."""
        return self.step <= step < self.end

    def describe(self) -> str:
        """A short phrase: ``push on 'cube' (0.6 N)``, ``drop of 'cube' (left gripper)``."""
        if self.kind == "drop":
            return f"drop of {self.body!r} ({self.side} gripper)"
        return f"{self.kind} on {self.body!r} ({float(np.linalg.norm(self.force)):.2g} N)"


def recovery_row(disturbance: Disturbance, end: int) -> list:
    """The stage-annotation row of the recovery from `disturbance`: frames ``[step, end)``, in
    the stage rows' layout ``[start, end, subgoal, left, right, score]`` (no score)."""
    plan = "re-plan from the measured state"
    return [
        disturbance.step,
        int(end),
        f"recover from the {disturbance.describe()}",
        plan,
        plan,
        0.0,
    ]


# --------------------------------------------------------------------------- applying
class DisturbanceDriver:
    """Applies disturbances to a running :class:`~bicoord_drake.sim.simulation.Simulation`:
    call :meth:`before_step` with the control step about to run and the action commanded, and
    step the simulation with the action it returns. Pushes and knocks set the plant's applied
    spatial force input for their steps (cleared afterwards); drops return the action with the
    gripper open. Without disturbances it changes nothing."""

    def __init__(self, sim: Simulation, disturbances: Iterable[Disturbance]) -> None:
        self.sim = sim
        self.disturbances = tuple(disturbances)
        bodies = sim.station.object_bodies
        unknown = sorted({d.body for d in self.disturbances} - set(bodies))
        if unknown:
            raise ValueError(f"disturbance of {unknown}: no such object; objects: {sorted(bodies)}")
        self._index = {d.body: bodies[d.body].index() for d in self.disturbances}
        self._port = sim.station.plant.get_applied_spatial_force_input_port()
        self._open_steps = steps_of(DROP_OPEN_SECONDS, sim.station.config.control_period)
        self._forcing = False

    def forces(self, step: int) -> list:
        """The ``ExternallyAppliedSpatialForce`` list of control step `step`."""
        from pydrake.all import ExternallyAppliedSpatialForce, SpatialForce

        out = []
        for d in self.disturbances:
            if d.kind == "drop" or not d.active(step):
                continue
            f = ExternallyAppliedSpatialForce()
            f.body_index = self._index[d.body]
            f.p_BoBq_B = np.array(d.point, dtype=float)
            f.F_Bq_W = SpatialForce(np.array(d.torque, float), np.array(d.force, float))
            out.append(f)
        return out

    def before_step(self, step: int, action: np.ndarray) -> np.ndarray:
        """Set the forces of control step `step`; the action to execute for `action` (the
        same array unless a drop acts now)."""
        forces = self.forces(step)
        if forces or self._forcing:
            self._port.FixValue(self.sim.plant_context, forces)
            self._forcing = bool(forces)
        drops = [d for d in self.disturbances if d.kind == "drop" and d.active(step)]
        if not drops:
            return action
        executed = np.array(action, dtype=np.float64)
        layout = self.sim.station.layout
        for d in drops:
            i = layout.gripper(d.side)
            # at least the opening the loosening grip has reached by now: the same whether
            # the command is the expert's or a replayed executed one (idempotent)
            share = min(1.0, (step - d.step + 1) / self._open_steps)
            executed[i] = max(executed[i], DROP_OPENING * share)
        return executed

    def clear(self) -> None:
        """Remove any force still applied (before a reset)."""
        if self._forcing:
            self._port.FixValue(self.sim.plant_context, [])
            self._forcing = False


# --------------------------------------------------------------------------- the clean run
@dataclass
class FrameFacts:
    """What a clean run showed at one frame (before that control step's action)."""

    #: object -> the sides any of whose bodies touch it
    robot: dict[str, frozenset[str]]
    #: object -> the sides whose fingers touch it
    fingers: dict[str, frozenset[str]]
    #: object -> the other objects it touches (:data:`SUPPORT` for the table and fixtures, and a
    #: fixture's name too)
    touching: dict[str, frozenset[str]]
    #: object -> pose (7,) xyz + wxyz
    poses: dict[str, np.ndarray]
    #: object -> linear speed, m/s
    speeds: dict[str, float]


class ExpertTrace:
    """A clean run of the expert, frame by frame (:meth:`capture` before each control step),
    and its plan boundaries: the frames at which the expert read the measured world before
    commanding that frame's action (:meth:`read`), frame 0 left out."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.frames: list[FrameFacts] = []
        self.reads: set[int] = set()
        st = sim.station
        plant = st.plant
        fixed = {o.name for o in st.scene.objects if o.fixed}
        #: body index -> object name; the support bodies (table, fixtures, world)
        self._names = {int(b.index()): n for n, b in st.object_bodies.items()}
        self._support = {int(b.index()) for n, b in st.object_bodies.items() if n in fixed}
        self._support |= {
            int(i) for i in plant.GetBodyIndices(plant.GetModelInstanceByName("table"))
        }
        self._support.add(int(plant.world_body().index()))

    @property
    def boundaries(self) -> list[int]:
        return sorted(f for f in self.reads if f >= 1)

    def read(self) -> None:
        """The expert read the world now (a plan boundary at the current frame)."""
        self.reads.add(self.sim.steps)

    def capture(self) -> None:
        """Record the current frame's facts."""
        sim = self.sim
        st = sim.station
        plant, context = st.plant, sim.plant_context
        robot, fingers = sim.contacts()
        touching: dict[str, set[str]] = {n: set() for n in st.object_bodies}
        for a, b in sim.contact_pairs():
            for x, y in ((a, b), (b, a)):
                if x in self._names:
                    if y in self._support:
                        touching[self._names[x]].add(SUPPORT)
                    if y in self._names:
                        touching[self._names[x]].add(self._names[y])
        speeds = {
            n: float(
                np.linalg.norm(plant.EvalBodySpatialVelocityInWorld(context, b).translational())
            )
            for n, b in st.object_bodies.items()
        }
        self.frames.append(
            FrameFacts(
                robot={n: frozenset(s) for n, s in robot.items()},
                fingers={n: frozenset(s) for n, s in fingers.items()},
                touching={n: frozenset(s) for n, s in touching.items()},
                poses={n: np.array(p) for n, p in sim.object_poses().items()},
                speeds=speeds,
            )
        )


# --------------------------------------------------------------------------- planning
def steps_of(seconds: float, dt: float) -> int:
    """Control steps (at least 1) that `seconds` last at period `dt`."""
    return max(1, int(math.ceil(seconds / dt - 1e-9)))


def plan_disturbances(
    kinds: Sequence[str], seed: int, trace: ExpertTrace, station: Station
) -> list[Disturbance]:
    """One disturbance of each of `kinds` for episode `seed`, from its clean run `trace`
    (:class:`NoDisturbanceWindow` when a kind has no window)."""
    planners = {"push": _plan_push, "drop": _plan_drop, "knock": _plan_knock}
    out = []
    for kind in parse_disturb(kinds):
        rng = np.random.default_rng([DISTURB_STREAM, int(seed), DISTURBANCE_KINDS.index(kind)])
        out.append(planners[kind](rng, trace, station))
    return out


def schedule_of(
    drawn: Mapping[str, Disturbance | str], kinds: Sequence[str]
) -> tuple[list[Disturbance], str | None]:
    """The disturbances of `kinds` from `drawn` (kind -> its disturbance, or the reason it has
    no window), and None; or ``([], "no_disturbance_window: REASON")`` with the reason of the
    first kind (in :data:`DISTURBANCE_KINDS` order) that has none."""
    kinds = parse_disturb(kinds)
    for kind in kinds:
        if not isinstance(drawn[kind], Disturbance):
            return [], f"no_disturbance_window: {drawn[kind]}"
    return [drawn[k] for k in kinds], None  # type: ignore[misc]  # all disturbances here


def acted_on(trace: ExpertTrace, name: str) -> int | None:
    """The first frame at which the robot touches object `name`, or `name` touches an object
    the robot has handled (touched at that frame or before: what it carries, places or
    pushes); None if never. From there on the expert acts on `name`, directly or through what
    it handles."""
    handled: set[str] = set()
    for t, f in enumerate(trace.frames):
        handled |= {o for o, sides in f.robot.items() if sides}
        if name in handled or f.touching[name] & handled:
            return t
    return None


def _free_on_support(f: FrameFacts, name: str, fixtures: set[str]) -> bool:
    """Resting on the table or a fixture alone (nothing else touching it), at rest."""
    return (
        SUPPORT in f.touching[name]
        and f.touching[name] <= {SUPPORT, *fixtures}
        and not f.robot[name]
        and f.speeds[name] < REST_SPEED
    )


def _on_table_top(station: Station, name: str, pose: np.ndarray) -> bool:
    """Whether object `name` at `pose` (7,) stands on the table top (its lowest point within
    1 cm of it: a flat marker under it allowed), not on a shelf or in a holder."""
    from bicoord_drake.models.scene import ON_TABLE_TOP_TOLERANCE, TABLE_TOP

    pose = np.asarray(pose, dtype=float)
    bottom = pose[2] - _extent(station, name, _rotation(pose[3:]), (0, 0, -1))
    return abs(bottom - TABLE_TOP) < ON_TABLE_TOP_TOLERANCE


def _knock_fits(
    frames: list[FrameFacts],
    boundaries: Sequence[int],
    name: str,
    fixtures: set[str],
    step: int,
    duration: int,
) -> bool:
    """Whether a knock on `name` may start at `step`: the clean run shows it resting alone on
    its support from then until the expert's first plan boundary after the knock (nothing is
    set on it or against it before the expert can see that it moved: what the motion under way
    stacks on it would land where it stood), and one hand holding nothing at that boundary (a
    hand that can put it back)."""
    later = [b for b in boundaries if step + duration <= b < len(frames)]
    if not later:
        return False
    boundary = later[0]
    if not all(_free_on_support(frames[t], name, fixtures) for t in range(step, boundary + 1)):
        return False
    holding = set().union(*frames[boundary].fingers.values())
    return len(holding) < 2


def _candidates(scene) -> list[str]:
    """The task's free objects (no fixtures, no sliding parts, no distractors)."""
    return [o.name for o in scene.free_objects if o.slide is None]


def _plan_push(rng: np.random.Generator, trace: ExpertTrace, station: Station) -> Disturbance:
    dt = station.config.control_period
    duration, settle = steps_of(PUSH_SECONDS, dt), steps_of(SETTLE_SECONDS, dt)
    earliest = steps_of(EARLIEST_SECONDS, dt)
    frames = trace.frames
    later = [b for b in trace.boundaries if b > earliest + duration + settle]
    if not later:
        raise NoDisturbanceWindow("push: the expert's first plan leaves no time for a push")
    boundary = later[0]  # the first re-plan after the earliest push
    distance = float(rng.uniform(*PUSH_DISTANCE))
    angle = float(rng.uniform(0.0, 2 * math.pi))
    u = float(rng.random())
    windows: dict[str, list[int]] = {}
    fixtures = {o.name for o in station.scene.objects if o.fixed}
    for name in _candidates(station.scene):
        first = acted_on(trace, name)
        if first is None or first < boundary:
            continue  # never acted on, or by the plan the push would fall in
        steps = [
            s
            for s in range(earliest, boundary - duration - settle + 1)
            if all(_free_on_support(frames[t], name, fixtures) for t in range(s, s + duration + 1))
        ]
        if steps:
            windows[name] = steps
    pushes = []
    for name in sorted(windows):
        f = frames[windows[name][0]]
        force = slide_push(station, name, f.poses, distance, angle, f.touching[name])
        if force is not None:
            pushes.append((name, force))
    if not pushes:
        raise NoDisturbanceWindow(
            f"push: no task object rests free on the table, clear of the others, during the "
            f"expert's first plan (steps {earliest}-{boundary}) and is acted on only after it"
        )
    name, (force, point) = pushes[int(rng.integers(len(pushes)))]
    steps = windows[name]
    step = steps[min(int(u * len(steps)), len(steps) - 1)]
    return Disturbance(
        kind="push", step=step, duration=duration, body=name, force=force, point=point
    )


def _plan_knock(rng: np.random.Generator, trace: ExpertTrace, station: Station) -> Disturbance:
    dt = station.config.control_period
    duration, settle = steps_of(PUSH_SECONDS, dt), steps_of(SETTLE_SECONDS, dt)
    frames = trace.frames
    last = trace.boundaries[-1] if trace.boundaries else 0
    distance = float(rng.uniform(*PUSH_DISTANCE))
    angle = float(rng.uniform(0.0, 2 * math.pi))
    u = float(rng.random())
    fixtures = {o.name for o in station.scene.objects if o.fixed}
    knocks = []
    for name in _candidates(station.scene):
        held = [t for t, f in enumerate(frames) if f.fingers[name]]
        if not held:
            continue  # never placed by the expert
        released = max(t for t, f in enumerate(frames) if f.robot[name]) + 1
        steps = [
            s
            for s in range(released + settle, last - duration - settle + 1)
            if _knock_fits(frames, trace.boundaries, name, fixtures, s, duration)
        ]
        if not steps:
            continue
        f = frames[steps[0]]
        if not _on_table_top(station, name, f.poses[name]):
            continue  # on a shelf, in a holder: the expert puts back only what it set on the table
        # clear of the other free objects; a fixture (a marker it was set down on) may be
        # in the way: the object slides off it, or stops against it
        force = slide_push(station, name, f.poses, distance, angle, {*f.touching[name], *fixtures})
        if force is not None and not topples_when_slid(station, name, f.poses[name], force[0]):
            knocks.append((name, steps, force))
    if not knocks:
        raise NoDisturbanceWindow(
            "knock: no object the expert placed rests alone on its support, with room to "
            "slide and a plan boundary after it"
        )
    name, steps, (force, point) = knocks[int(rng.integers(len(knocks)))]
    step = steps[min(int(u * len(steps)), len(steps) - 1)]
    return Disturbance(
        kind="knock", step=step, duration=duration, body=name, force=force, point=point
    )


def _plan_drop(rng: np.random.Generator, trace: ExpertTrace, station: Station) -> Disturbance:
    dt = station.config.control_period
    duration = steps_of(DROP_SECONDS, dt)
    earliest = steps_of(EARLIEST_SECONDS, dt)
    frames = trace.frames
    last = trace.boundaries[-1] if trace.boundaries else 0
    u = float(rng.random())
    drops = []
    from bicoord_drake.models.table import TABLE_SIZE

    inside = np.asarray(TABLE_SIZE) / 2 - DROP_EDGE_MARGIN
    for name in _candidates(station.scene):
        for side in ("left", "right"):
            steps = [
                s
                for s in range(earliest, last - duration + 1)
                if frames[s].poses[name][2] - frames[0].poses[name][2] <= DROP_HEIGHT
                and all(
                    frames[t].fingers[name] == {side}
                    and not frames[t].touching[name]
                    and np.all(np.abs(frames[t].poses[name][:2]) <= inside)
                    for t in range(s, s + duration)
                )
            ]
            if steps:
                drops.append((name, side, steps))
    if not drops:
        raise NoDisturbanceWindow(
            "drop: no gripper holds an object off its support with a plan boundary after it"
        )
    name, side, steps = drops[int(rng.integers(len(drops)))]
    step = steps[min(int(u * len(steps)), len(steps) - 1)]
    return Disturbance(kind="drop", step=step, duration=duration, body=name, side=side)


# --------------------------------------------------------------------------- the force
def combined_friction(station: Station, name: str) -> float:
    """The friction coefficient of object `name` on the table: Drake's combination
    ``2 a b / (a + b)`` of the two geometries' dynamic coefficients (the smallest of each)."""
    plant = station.plant
    inspector = station.scene_graph.model_inspector()

    def coefficient(body) -> float:
        values = []
        for g in plant.GetCollisionGeometriesForBody(body):
            props = inspector.GetProximityProperties(g)
            if props is not None and props.HasProperty("material", "coulomb_friction"):
                values.append(props.GetProperty("material", "coulomb_friction").dynamic_friction())
        if not values:
            raise ValueError(f"{body.name()}: no friction on its collision geometry")
        return min(values)

    a = coefficient(station.object_bodies[name])
    b = coefficient(plant.GetBodyByName("table_top"))
    return 2 * a * b / (a + b)


def slide_factor(distance: float, mu: float, seconds: float) -> float:
    """k such that a force ``k mu m g`` for `seconds` slides a body `distance` (m) on a support
    of friction `mu`: ``k (k - 1) mu g T^2 / 2 = distance``."""
    c = 2 * distance / (mu * GRAVITY * seconds**2)
    return (1 + math.sqrt(1 + 4 * c)) / 2


def _extent(station: Station, name: str, R: np.ndarray, u: Sequence[float]) -> float:
    """How far object `name` (rotation R) reaches from its origin along the unit vector u: the
    support function of its collision primitives (boxes, cylinders, capsules, spheres)."""
    u = np.asarray(u, dtype=float)
    reach = 0.0
    for prim in station.scene.object(name).shape.primitives():
        X = prim.pose.matrix()
        R_i = R @ X[:3, :3]
        centre = float((R @ X[:3, 3]) @ u)
        if prim.kind == "box":
            h = float(np.abs(R_i.T @ u) @ (np.asarray(prim.size) / 2))
        elif prim.kind == "sphere":
            h = prim.size[0]
        else:  # cylinder or capsule: (radius, length) along the local z
            r, length = prim.size[0], prim.size[1]
            c = min(1.0, abs(float(R_i[:, 2] @ u)))
            h = c * length / 2 + (r if prim.kind == "capsule" else r * math.sqrt(1 - c * c))
        reach = max(reach, centre + h)
    return reach


def _rolling_axis(station: Station, name: str, R: np.ndarray) -> np.ndarray | None:
    """For an object made of round parts only (cylinders, capsules, spheres) lying on its
    side: its axis in the table's plane (a push across it would roll it); None otherwise."""
    prims = station.scene.object(name).shape.primitives()
    if any(p.kind == "box" for p in prims):
        return None
    axes = [R @ p.pose.matrix()[:3, 2] for p in prims if p.kind != "sphere"]
    if not axes:
        return np.zeros(3)  # a ball rolls every way
    axis = axes[0]
    if abs(axis[2]) > 0.7:
        return None  # standing
    return np.array([axis[0], axis[1], 0.0]) / math.hypot(axis[0], axis[1])


def slide_push(
    station: Station,
    name: str,
    poses: Mapping[str, np.ndarray],
    distance: float,
    angle: float,
    ignore: Iterable[str] = (),
) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    """The force (N, world frame) and its point (m, body frame) that slide object `name`,
    resting on the table at ``poses[name]``, `distance` along the first of :data:`DIRECTIONS`
    horizontal directions from `angle` (rad) whose path (1.5 times `distance`) keeps
    :data:`EDGE_MARGIN` inside the table's edge and :data:`CLEARANCE` from the other objects
    of `poses` (but those in `ignore`, e.g. its support); a round object lying on its side (a
    roller, a pen) is pushed along its axis only (across, it would roll). None: no direction is
    clear, or the object is a ball."""
    from bicoord_drake.models.table import TABLE_SIZE

    pose = np.asarray(poses[name], dtype=float)
    R = _rotation(pose[3:])
    units = [
        np.array([math.cos(a), math.sin(a), 0.0])
        for a in (angle + 2 * math.pi * j / DIRECTIONS for j in range(DIRECTIONS))
    ]
    axis = _rolling_axis(station, name, R)
    if axis is not None:
        if not np.any(axis):
            return None  # a ball
        units = sorted((axis, -axis), key=lambda v: -float(v @ units[0]))
    hx, hy = (
        max(_extent(station, name, R, u), _extent(station, name, R, -u)) for u in np.eye(3)[:2]
    )
    skip = {name, *ignore}
    others = [
        (other, np.asarray(p[:2], float), _rotation(p[3:]))
        for other, p in poses.items()
        if other not in skip
    ]
    half = np.asarray(TABLE_SIZE) / 2 - EDGE_MARGIN - np.array([hx, hy])

    def clear(q: np.ndarray) -> bool:
        for other, c, R_other in others:
            gap = q - c
            d = float(np.linalg.norm(gap))
            if d < 1e-9:
                return False
            u = np.array([*(gap / d), 0.0])
            need = _extent(station, name, R, -u) + _extent(station, other, R_other, u)
            if d < need + CLEARANCE:
                return False
        return True

    for unit in units:
        path = [pose[:2] + s * 1.5 * distance * unit[:2] for s in np.linspace(0.0, 1.0, 7)]
        if any(np.any(np.abs(q) > half) for q in path) or not all(clear(q) for q in path[1:]):
            continue
        body = station.object_bodies[name]
        mu = combined_friction(station, name)
        dt = station.config.control_period
        k = slide_factor(distance, mu, steps_of(PUSH_SECONDS, dt) * dt)
        com_W, height = _centre_of_mass(station, name, pose, R)
        point_W = np.array([com_W[0], com_W[1], com_W[2] - height / k])
        force = k * mu * float(body.default_mass()) * GRAVITY * unit
        return _triple(force), _triple(R.T @ (point_W - pose[:3]))
    return None


def topples_when_slid(
    station: Station, name: str, pose: np.ndarray, direction: Sequence[float]
) -> bool:
    """Whether object `name`, standing at `pose` (7,) and sliding along `direction`, tips over
    its leading edge as friction brakes it: the friction at its base turns it forward with the
    moment ``mu m g h`` (h: its centre of mass above the table), which its weight holds only
    while ``mu h`` stays within the leading edge's distance from the centre of mass. A 12 cm
    block standing on a 4 cm end tips (0.85 x 6 cm against 2 cm); a 4 cm cube does not (1.7
    against 2 cm)."""
    pose = np.asarray(pose, dtype=float)
    R = _rotation(pose[3:])
    unit = np.asarray(direction, dtype=float)
    unit = unit / np.linalg.norm(unit)
    com_W, height = _centre_of_mass(station, name, pose, R)
    lead = _extent(station, name, R, unit) - float((com_W - pose[:3]) @ unit)
    return combined_friction(station, name) * height > lead


def _centre_of_mass(
    station: Station, name: str, pose: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, float]:
    """Object `name`'s centre of mass (world, m) at `pose` (7,; rotation R) and its height
    above what it stands on (its lowest point, or the table top if that is lower; >= 0)."""
    from bicoord_drake.models.scene import TABLE_TOP

    com_W = pose[:3] + R @ np.asarray(station.object_bodies[name].default_com(), dtype=float)
    bottom = max(pose[2] - _extent(station, name, R, (0, 0, -1)), TABLE_TOP)
    return com_W, max(float(com_W[2] - bottom), 0.0)


def _rotation(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(wxyz, dtype=float) / np.linalg.norm(wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _triple(v: Any) -> tuple[float, float, float]:
    a, b, c = (float(x) for x in v)
    return (a, b, c)


# --------------------------------------------------------------------------- records
def disturbance_records(disturbances: Iterable[Disturbance]) -> list[dict[str, Any]]:
    """Plain mappings of `disturbances` (what episode files store)."""
    return [d.model_dump(mode="json") for d in disturbances]


def from_records(records: Iterable[Mapping[str, Any]]) -> list[Disturbance]:
    """The disturbances of stored mappings."""
    return [Disturbance.model_validate(dict(r)) for r in records]

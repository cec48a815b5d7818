"""The :class:`Task` interface every benchmark task implements, and the experts' world view.

A task file reads top to bottom like its description::

    @register_task
    class Jigsaw(Task):
        \"\"\"Fill the empty cells of a 3x3 grid with spare cubes.

        Description: ...
        Randomization: ...
        Stages: ...
        Success: ...
        \"\"\"

        name = "jigsaw"
        step_limit = 800
        supported_robots = ("aloha_viperx", "franka_pair")   # default: the default robot only
        instructions_seen = (...)
        instructions_unseen = (...)

        def sample_scene(self, seed): ...      # all randomness from default_rng(seed)
        def stages(self, scene): ...
        def expert(self, scene, view): ...     # yields one action per planned sample

A task never touches HDF5 or the simulator directly: the runner steps the simulation with the
expert's actions and the expert reads privileged state through a read-only :class:`WorldView`.
Whatever drives an expert does it through :func:`expert_actions`: at 15 Hz and faster it is the
expert's own stream; below 15 Hz the expert plans on a finer grid (k samples per control step,
:func:`~bicoord_drake.planning.timing.planning_substeps`) and every k-th sample is executed.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from bicoord_drake.models.appearance import Split
from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.layout import ActionLayout, default_embodiment
from bicoord_drake.models.robots import EMBODIMENTS
from bicoord_drake.models.scene import Scene
from bicoord_drake.stages.stage import Stage, WorldState

if TYPE_CHECKING:
    from bicoord_drake.planning.model import PlanningModel
    from bicoord_drake.planning.skills import Motion, SkillContext
    from bicoord_drake.sim.simulation import Simulation

#: Fewest instruction paraphrases a task must provide (seen + unseen).
MIN_INSTRUCTIONS = 10

#: An axis-aligned box in world coordinates, ``((x, y, z) lower, (x, y, z) upper)`` in metres.
Region = tuple[tuple[float, float, float], tuple[float, float, float]]


class WorldView:
    """Read-only privileged state of a running simulation, for experts.

    Every accessor returns fresh copies; nothing here can step or modify the simulation.
    """

    def __init__(self, sim: Simulation) -> None:
        self._sim = sim
        #: Planned samples the expert has yielded so far, counted by :func:`expert_actions`
        #: (0 when something else drives the expert): the stream index of its next sample,
        #: which tells :func:`follow` which of them the station will execute.
        self.plan_samples = 0

    @property
    def scene(self) -> Scene:
        return self._sim.station.scene

    @property
    def embodiment(self):
        return self._sim.station.embodiment

    @property
    def layout(self) -> ActionLayout:
        """Where each arm's joints and opening sit in actions and joint states."""
        return self._sim.station.layout

    @property
    def config(self):
        """The station's (frozen) StationConfig."""
        return self._sim.station.config

    @property
    def time(self) -> float:
        return self._sim.time

    @property
    def steps(self) -> int:
        """Control steps taken since reset."""
        return self._sim.steps

    def joint_state(self) -> np.ndarray:
        """Measured [left q (n), left opening, right q (n), right opening] (:attr:`layout`)."""
        return self._sim.joint_state()

    def tcp_pose(self, side: str) -> np.ndarray:
        """TCP pose of one arm: xyz + quaternion wxyz, world frame."""
        if side not in SIDES:
            raise ValueError(f"side must be one of {SIDES}, got {side!r}")
        return self._sim.tcp_pose(side)

    def object_poses(self) -> dict[str, np.ndarray]:
        """Every scene object's pose (7,) xyz + wxyz."""
        return {name: np.array(p) for name, p in self._sim.object_poses().items()}

    def object_pose(self, name: str) -> np.ndarray:
        poses = self._sim.object_poses()
        if name not in poses:
            raise KeyError(f"no object {name!r}; objects: {sorted(poses)}")
        return np.array(poses[name])

    def arm_positions(self) -> np.ndarray:
        """Measured joint angles of both arms (2 n,): left then right (``SkillContext.sync``)."""
        return self.layout.arm_positions(self.joint_state())

    def gripper_openings(self) -> dict[str, float]:
        """Measured gripper openings per side (1 = open)."""
        return self.layout.openings(self.joint_state())

    @property
    def substeps(self) -> int:
        """k, the expert's planned samples per control step: 1 at 15 Hz and faster, 2 at
        10 Hz (:func:`~bicoord_drake.planning.timing.planning_substeps`)."""
        from bicoord_drake.planning.timing import planning_substeps

        return planning_substeps(self.config.control_period)

    def planning_model(self) -> PlanningModel:
        """A new planning model of this scene and robot, its plans sampled every control
        period / :attr:`substeps` (kinematics and collision for the planners; an expert builds
        its skill context on it): the control period at 15 Hz and faster, 1/20 s at 10 Hz."""
        from bicoord_drake.planning.model import PlanningModel

        period = self.config.control_period / self.substeps
        return PlanningModel(self.scene, self.embodiment, period)

    def object_transforms(self) -> dict:
        """Every object's pose as a Drake ``RigidTransform`` X_WO (for ``SkillContext.sync``)."""
        from pydrake.all import Quaternion, RigidTransform

        return {
            name: RigidTransform(Quaternion(p[3:] / np.linalg.norm(p[3:])), p[:3])
            for name, p in self._sim.object_poses().items()
        }

    def finger_contacts(self) -> dict[str, set[str]]:
        """For each object, the sides whose fingers touch it now."""
        return {name: set(sides) for name, sides in self._sim.finger_contacts().items()}

    def state(self, action: np.ndarray) -> WorldState:
        """A :class:`WorldState` snapshot (what the stage predicates see)."""
        return WorldState.capture(self._sim, action)

    def note_recovered(self) -> None:
        """The expert has recovered from a disturbance here (it picked up and, where it had
        placed it, placed again what fell: :mod:`bicoord_drake.tasks.recovery`). Nothing
        changes in the world; a generator watching the expert ends the recovery's annotation
        at this step."""


def follow(ctx: SkillContext, view: WorldView, motion: Motion) -> Iterator[np.ndarray]:
    """Yield `motion`'s actions, then bring `ctx` up to date with the world: the joint
    positions it planned to (``ctx.q``), the measured object poses and, from them, the pose of
    each held object in its gripper (:meth:`SkillContext.refresh_grasps`).

    Where the measured world shows that an object the motion carried fell on the way (out of
    its hand, or resting far from where the motion set it down), the expert picks it up again
    and, if the motion had placed it, places it again before planning on; an object it set
    down on the table earlier and finds knocked away, it places again where it can
    (:mod:`bicoord_drake.tasks.recovery`).

    An expert runs every motion through this, so each plan starts from what happened.

    A motion with an ``anchor`` (a throw's release) is held at its start for as many samples
    (fewer than ``view.substeps``) as put the anchor on a sample the station executes
    (:func:`expert_actions` executes every k-th; at 15 Hz and faster every one: no hold)."""
    from functools import partial

    from bicoord_drake.tasks.recovery import (
        carried_by,
        fallen,
        knocked,
        recover_drops,
        recover_knocks,
    )

    if motion.anchor is not None:
        motion = anchored(motion, view.plan_samples, view.substeps)
    held, placed = carried_by(ctx, motion)
    placements = dict(ctx.placements)
    ctx.placements.clear()
    yield from motion.actions()
    poses = view.object_transforms()
    lost, missed = fallen(ctx, poses, held, placed, placements)
    knocks = knocked(ctx, poses, motion, placed, placements)
    run = partial(follow, ctx, view)
    if knocks and not lost:
        # the knocked objects first: what the motion set down on one may have missed it
        yield from recover_knocks(ctx, view, run, knocks, missed, placements)
        return
    if lost or missed:  # (a knock found now is found again where this recovery ends)
        yield from recover_drops(ctx, view, run, lost, missed, placements)
        return
    ctx.sync(ctx.q, object_poses=poses)
    ctx.refresh_grasps(poses)


def anchored(motion: Motion, plan_samples: int, k: int) -> Motion:
    """`motion` held at its start for the fewest samples (0 to k - 1) that make its
    ``anchor`` an executed sample, when the expert has yielded `plan_samples` samples before
    it and every k-th is executed (samples k - 1, 2 k - 1, ...: :func:`execute_every`)."""
    if motion.anchor is None:
        return motion
    # Motion sample i >= 1 is the expert's sample number plan_samples + i - 1.
    return motion.delayed((k - 1 - (plan_samples + motion.anchor - 1)) % k)


def expert_actions(task: Task, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
    """The actions `task`'s expert commands, one per control step of `view`'s station: what
    drives an expert (the generator, the expert policy) drives it through this.

    The expert plans on a grid of k = ``view.substeps`` samples per control step (k = 1 at
    15 Hz and faster: its actions pass unchanged, the same objects) and this executes every
    k-th (:func:`execute_every`: one clock over the whole episode, each executed sample
    reached at its planned time, so only the episode's end is rounded to the control period,
    not every motion and wait), counting the samples in ``view.plan_samples`` (:func:`follow`
    puts a throw's release on an executed sample with it). Where the expert reads `view`
    after a skipped sample (a motion that ends on one), it sees the world as of the last
    executed sample: up to k - 1 samples (less than a control period) behind its plan."""
    counted = _counted(task.expert(scene, view), view)
    if view.substeps == 1:
        return counted
    return execute_every(counted, view.substeps, view.layout.gripper_indices)


def _counted(samples: Iterable[np.ndarray], view: WorldView) -> Iterator[np.ndarray]:
    for sample in samples:
        view.plan_samples += 1
        yield sample


def execute_every(
    samples: Iterable[np.ndarray], k: int, grippers: Sequence[int] = ()
) -> Iterator[np.ndarray]:
    """Samples k - 1, 2 k - 1, 3 k - 1, ... of `samples` (planned actions, k per control
    step: sample s is planned for (s + 1) / k control periods after the start, and control
    step n reaches its action at n + 1 periods) and, if the last sample is not among them, the
    last sample too (so the plan's final pose is commanded: the end is rounded up by less
    than a period). k = 1: `samples` themselves.

    The arm joints are the executed sample's. A gripper opening the plan reaches and leaves
    between two executed samples (a short pulse) is not lost: each entry of `grippers` (the
    action's opening indices) is the one of the samples since the previous executed one that
    lies farthest from the opening executed before (at the start: from the first sample); on
    a monotone ramp - every open and close of the skills - that is the executed sample's own.
    If that changes the plan's last action, the last action follows it unchanged."""
    if k < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    if k == 1:
        yield from samples
        return
    grippers = list(grippers)
    previous: np.ndarray | None = None
    window: list[np.ndarray] = []  # the samples since the previous executed one
    sample = None
    for i, sample in enumerate(samples):
        window.append(sample)
        if i % k == k - 1:
            previous = _executed(window, previous, grippers)
            window = []
            yield previous
    if window:  # the last sample was skipped
        previous = _executed(window, previous, grippers)
        yield previous
    if previous is not None and previous is not sample and not np.array_equal(previous, sample):
        yield sample  # the plan's last action, as planned


def _executed(
    window: list[np.ndarray], previous: np.ndarray | None, grippers: list[int]
) -> np.ndarray:
    """The action executed for `window` (the samples since `previous`, the last executed
    action, None at the start): the window's last sample, each gripper entry the window's
    farthest from `previous` (at the start: from the window's first; ties: the latest)."""
    action = window[-1]
    if not grippers or len(window) == 1:
        return action
    values = np.array([sample[grippers] for sample in window], dtype=float)
    reference = values[0] if previous is None else np.asarray(previous, dtype=float)[grippers]
    gap = np.abs(values - reference)
    latest_max = len(window) - 1 - np.argmax(gap[::-1], axis=0)
    if np.all(gap[latest_max, np.arange(len(grippers))] <= gap[-1]):
        return action
    action = np.array(action, dtype=float)
    action[grippers] = values[latest_max, np.arange(len(grippers))]
    return action


class Task(ABC):
    """One benchmark task: scene sampler, stages, instructions and expert.

    Subclasses set the class attributes and implement :meth:`sample_scene`, :meth:`stages` and
    :meth:`expert`; the docstring has the sections Description / Randomization / Stages /
    Success. Instances are stateless, so one instance serves every seed.
    """

    name: ClassVar[str]
    step_limit: ClassVar[int]
    #: A seed whose expert episode is kept: the default test suite runs it (tests/tasks/).
    ci_seed: ClassVar[int] = 0
    #: The expert's joint speed: a share of the robot's velocity limits (SkillContext ``speed``).
    expert_speed: ClassVar[float] = 0.5
    #: The robots (registered embodiment names) this task runs on: generation, environments and
    #: evaluation refuse any other (:func:`~bicoord_drake.tasks.registry.check_supported`). The
    #: default robot always; another one only where its expert keeps >= 85 % of seeds 0-29
    #: (``benchmarks/expert_success.py --embodiment NAME``; docs/adding_a_robot.md).
    supported_robots: ClassVar[tuple[str, ...]] = (default_embodiment(),)
    instructions_seen: ClassVar[tuple[str, ...]]
    instructions_unseen: ClassVar[tuple[str, ...]]

    @abstractmethod
    def sample_scene(self, seed: int) -> Scene:
        """The scene for `seed`: all randomness from ``np.random.default_rng(seed)``, every draw
        recorded in ``Scene.draws`` (so episode -> scene round-trips)."""

    @abstractmethod
    def stages(self, scene: Scene) -> list[Stage]:
        """The stage list for this scene (scores sum to 1)."""

    @abstractmethod
    def expert(self, scene: Scene, view: WorldView) -> Iterator[np.ndarray]:
        """Yield one action per planned sample (``view.layout``: 14 numbers for the ViperX
        pair), every ``ctx.dt`` seconds: one per control step at 15 Hz and faster, below 15 Hz
        ``view.substeps`` per step, of which :func:`expert_actions` executes every k-th; read
        state from `view` between yields.

        Raise :class:`bicoord_drake.planning.errors.PlanningError` when planning fails.
        """

    def skill_context(self, view: WorldView, **settings: float) -> SkillContext:
        """The expert's planning context: a new planning model of `view`'s scene, robot and
        control period, at the task's :attr:`expert_speed` (`settings`: other SkillContext
        settings, e.g. ``clearance``)."""
        from bicoord_drake.planning.skills import SkillContext

        return SkillContext(view.planning_model(), speed=self.expert_speed, **settings)

    def may_leave_table(self, scene: Scene) -> Mapping[str, tuple[Region, ...] | None]:
        """Task objects that may be off the table without ending an evaluation rollout early
        (``early_stop``, :class:`bicoord_drake.env.LostObjects`): name -> the world boxes
        (:data:`Region`) its origin may be in below the table top or outside the workspace (a
        bin on the floor beside the table), or None: anywhere (a tool the task's success no
        longer needs once used, which a policy may drop). Default: none - any free object of
        the scene on the floor or outside the workspace ends the rollout as a failure."""
        return {}

    def object_count(self, scene: Scene) -> int:
        """ON: objects the task manipulates or attends to (default: the movable ones)."""
        return len(scene.free_objects)

    def instructions(self, split: Split = "seen") -> tuple[str, ...]:
        if split == "seen":
            return tuple(self.instructions_seen)
        if split == "unseen":
            return tuple(self.instructions_unseen)
        raise ValueError(f"split must be 'seen' or 'unseen', got {split!r}")

    def instruction(self, rng: np.random.Generator, split: Split = "seen") -> str:
        """One paraphrase of the instruction, drawn with `rng`."""
        options = self.instructions(split)
        return options[int(rng.integers(len(options)))]

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"


def check_task_class(cls: type) -> None:
    """Raise TypeError/ValueError unless `cls` is a complete, well-formed Task subclass."""
    if not (isinstance(cls, type) and issubclass(cls, Task)):
        raise TypeError(f"{cls!r} is not a subclass of Task")
    if getattr(cls, "__abstractmethods__", None):
        missing = ", ".join(sorted(cls.__abstractmethods__))
        raise TypeError(f"task {cls.__name__} does not implement: {missing}")
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name.isidentifier() or name != name.lower():
        raise ValueError(f"task {cls.__name__}: name must be a lower-case identifier, got {name!r}")
    limit = getattr(cls, "step_limit", None)
    if not isinstance(limit, int) or limit <= 0:
        raise ValueError(f"task {name}: step_limit must be a positive int, got {limit!r}")
    speed = getattr(cls, "expert_speed", 0.5)
    if not isinstance(speed, int | float) or not 0 < speed <= 1:
        raise ValueError(f"task {name}: expert_speed must be in (0, 1], got {speed!r}")
    _check_supported_robots(name, getattr(cls, "supported_robots", None))
    ci_seed = getattr(cls, "ci_seed", 0)
    if not isinstance(ci_seed, int) or not 0 <= ci_seed < 2**32:
        raise ValueError(f"task {name}: ci_seed must be an int in [0, 2**32), got {ci_seed!r}")
    seen = tuple(getattr(cls, "instructions_seen", ()))
    unseen = tuple(getattr(cls, "instructions_unseen", ()))
    if not seen or not unseen:
        raise ValueError(f"task {name}: needs both seen and unseen instructions")
    if len(seen) + len(unseen) < MIN_INSTRUCTIONS:
        raise ValueError(
            f"task {name}: needs at least {MIN_INSTRUCTIONS} instruction paraphrases, "
            f"has {len(seen) + len(unseen)}"
        )
    overlap = set(seen) & set(unseen)
    if overlap:
        raise ValueError(f"task {name}: instructions both seen and unseen: {sorted(overlap)}")
    if not all(isinstance(s, str) and s.strip() for s in seen + unseen):
        raise ValueError(f"task {name}: instructions must be non-empty strings")


def _check_supported_robots(name: str, robots: object) -> None:
    """A task's ``supported_robots``: a non-empty tuple of registered robot names, without
    repeats, that includes the default robot."""
    if not isinstance(robots, tuple) or not robots:
        raise ValueError(
            f"task {name}: supported_robots must be a non-empty tuple of robot names, "
            f"got {robots!r}"
        )
    unknown = [r for r in robots if r not in EMBODIMENTS]
    if unknown:
        raise ValueError(
            f"task {name}: supported_robots names unregistered robots {unknown}; "
            f"robots: {', '.join(sorted(EMBODIMENTS))}"
        )
    if len(set(robots)) != len(robots):
        raise ValueError(f"task {name}: supported_robots repeats a robot: {robots!r}")
    if default_embodiment() not in robots:
        raise ValueError(
            f"task {name}: supported_robots must include the default robot "
            f"{default_embodiment()!r}, got {robots!r}"
        )


#: The control rate (Hz) at which TASKS.md gives the step limits.
STEP_LIMIT_RATE = 15.0


def step_limit_at(task: Task, control_rate: float) -> int:
    """`task`'s step limit at `control_rate` Hz: the same time as its limit at 15 Hz."""
    return int(np.ceil(task.step_limit * control_rate / STEP_LIMIT_RATE - 1e-9))

"""The policy-facing environment: the expert's simulator, observations and control path.

>>> env = make_env("jigsaw", 100000, resolution="160x120")           # doctest: +SKIP
>>> obs = env.reset()
>>> obs, info = env.step(obs["joint_state"])                          # one control period
>>> info["completed"], info["score"], info["success"], info["step"]

The settings are a :class:`~bicoord_drake.scenario.Scenario` (``make_env(scenario=FILE)``,
keyword arguments override it), the same definition generation and evaluation read. The
episode is assembled from one :class:`~bicoord_drake.episode_setup.EpisodeSetup` (task, seed,
randomize, split, embodiment, station settings) by
:func:`~bicoord_drake.episode_setup.assemble`, as generation and the expert check build theirs.
The task's step limit (TASKS.md, at 15 Hz) is scaled to the control rate
(:func:`~bicoord_drake.tasks.base.step_limit_at`): the same time at any rate.

Sizes follow the robot (``make_env(..., embodiment=NAME)``): ``env.layout`` is its
:class:`~bicoord_drake.models.layout.ActionLayout`, A = ``env.layout.action_size`` numbers
``[left q (n), left opening, right q (n), right opening]`` (n arm joints; A = 14 for the
default ViperX pair).

Observations (a dict): ``head_camera``, ``left_camera``, ``right_camera`` (H, W, 3) uint8 RGB
(absent with ``render=False``; with ``depth=True`` also ``<cam>_depth`` (H, W) uint16 mm),
``joint_state`` (A,) measured ``[left q (n), left opening, right q (n), right opening]``,
``left_endpose`` / ``right_endpose`` (7,) TCP xyz + quaternion wxyz in the world frame,
``object_poses`` (privileged: name -> (7,) xyz + wxyz of every task object, distractors left
out, in the order of ``observation.environment_state``, see
:mod:`bicoord_drake.data.environment_state`) and ``instruction`` (one paraphrase of the
task's instruction, from the *unseen* split by default).

Actions, one per control period (PRODUCT.md: the station moves the joint targets linearly from the
previous action to the new one over the period):

- ``action_mode="qpos"``: A numbers, the joint targets and gripper openings (1 = open), exactly
  what the expert commands (``joint_action/vector`` of the episode files).
- ``action_mode="endpose"``: 16 numbers ``[left xyz, left quat wxyz, left opening, right xyz,
  right quat wxyz, right opening]``, converted to joint targets by inverse kinematics seeded from
  the measured joint state (closed form when the arm has a spherical wrist, else the NLP IK). An
  unreachable end pose keeps that arm's previous joint target; ``info["ik_failed"]`` lists the
  arm.

An action of the wrong shape, or with NaN/inf, raises :class:`InvalidActionError` (a
``ValueError``) naming the problem and is not executed.

Info after each step: ``step`` (control steps since the reset), ``completed`` / ``credit`` (per
stage), ``score`` (:func:`bicoord_drake.metrics.stage_score` of the credits, the stages from the
start stage on: the same function as the evaluation's SSR), ``success``, ``done`` (success, the
stage of a stage rollout counted, the step limit, or an early stop), ``truncated`` (the step limit
ended it) and ``failure_reason`` (why an early stop ended it, else None).

Start from a stage: ``reset(seed, stage=k)`` (the demonstration of `seed` is looked up in
``make_env(..., data=DIR)``) or ``reset(stage=k, episode=path_or_Episode)`` restores the
simulator to the state recorded at the start of stage ``k`` of a demonstration (plant positions
and velocities ``stages/initial_state``, the action in effect and the one before it, the time),
so replaying the recorded actions from there reproduces the demonstration exactly. The stage
monitor treats stages ``0..k-1`` as already counted - they are replaced by always-true transient
stages, so the dependencies of stage ``k`` hold - and scores stage ``k`` and later. Such a *stage
rollout* is done as soon as stage ``k`` counts (``info["stage_success"]``) or at the step limit,
counted from the reset; ``stage=0`` is a stage rollout from the initial state.

A demonstration generated with disturbances (:mod:`bicoord_drake.sim.disturbances`) has them
applied again in a rollout reset from it, at the recorded control steps (``env.disturbances``):
a push's or knock's force through the plant, a drop's open gripper in place of the commanded
opening; so its replay reproduces it. A reset without such an episode applies none;
``reset(..., disturbances=[...])`` applies the ones given instead (an evaluation with
``disturb`` does: the disturbances the expert's demonstration of the seed gets).

Early stop (``make_env(..., early_stop=True)``; off by default here, on in evaluations): a rollout
whose task object is lost - nothing can bring it back - is done at once, a failure, with
``info["failure_reason"]`` saying which object, where and since when (``"object_left_table at
step 40: 'cube' is 0.71 m below the table top (since step 33)"``; None otherwise). An object is
lost (:class:`LostObjects`) when its origin is more than :data:`LOST_DROP` below the table top
(on the floor: the top is 4 cm thick) or more than :data:`LOST_MARGIN` outside the table's
footprint, no finger touching it, for :data:`LOST_SECONDS` in a row; distractors, fixtures and
what the task allows off the table (:meth:`~bicoord_drake.tasks.base.Task.may_leave_table`) are
not watched. Nothing else ends a rollout early: a slow policy keeps its whole step limit.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from bicoord_drake.config import StationConfig
from bicoord_drake.data.environment_state import environment_state, state_objects
from bicoord_drake.data.episode import Episode, read_episode
from bicoord_drake.episode_setup import Assembly, EpisodeSetup, assemble
from bicoord_drake.models.embodiment import SIDES, other_side
from bicoord_drake.models.layout import POSE_SIZE, ActionLayout
from bicoord_drake.models.scene import TABLE_TOP, Scene
from bicoord_drake.models.table import TABLE_SIZE
from bicoord_drake.scenario import (  # EVAL_SEED_START: re-exported
    EVAL_SEED_START,  # noqa: F401
    EVALUATION_DEFAULTS,
    Scenario,
    check_evaluation_seed,
    load_scenario,
    resolve,
)
from bicoord_drake.sim.disturbances import Disturbance, DisturbanceDriver, from_records
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.stages import WorldState
from bicoord_drake.stages.stage import Stage
from bicoord_drake.tasks.base import Region, Split, Task, WorldView, step_limit_at

ActionMode = Literal["qpos", "endpose"]
ACTION_MODES: tuple[str, ...] = ("qpos", "endpose")
#: Numbers per arm of an end-pose action: the TCP pose (xyz + wxyz) and the opening.
ENDPOSE_WIDTH = POSE_SIZE + 1
ENDPOSE_LAYOUT = "[left xyz, left wxyz, left opening, right xyz, right wxyz, right opening]"
#: The split of an environment's scenes and instructions unless the scenario sets one.
ENVIRONMENT_SPLIT = EVALUATION_DEFAULTS["split"]
#: Early stop: an object whose origin is this far below the table top (m) has left it (the top
#: is 4 cm thick, so it is beside the table, falling or on the floor).
LOST_DROP = 0.05
#: Early stop: an object whose origin is this far outside the table's footprint (m, along x or
#: y) has left the workspace (beyond the arms' bases, y = -0.42 to -0.55).
LOST_MARGIN = 0.15
#: Early stop: how long (s) an object must stay off the table, untouched by the fingers, to be
#: lost (a fall to the floor takes 0.4 s; an object caught in flight is not lost).
LOST_SECONDS = 0.5
#: The failure code of a rollout ended early because a task object left the table.
OBJECT_LEFT_TABLE = "object_left_table"


class InvalidActionError(ValueError):
    """An action of the wrong shape or with non-finite values; it was not executed."""


def make_env(
    task: str | Task | None = None,
    seed: int | None = None,
    *,
    scenario: Scenario | str | Path | None = None,
    action_mode: ActionMode = "qpos",
    resolution: str | tuple[int, int] | None = None,
    depth: bool | None = None,
    render: bool | None = None,
    fps: float | None = None,
    split: Split | None = None,
    randomize: bool | None = None,
    step_limit: int | None = None,
    data: str | Path | None = None,
    embodiment: str | None = None,
    early_stop: bool = False,
) -> Env:
    """An :class:`Env` for `task` (a name or a Task) whose station is built for `seed`.

    The settings are a :class:`~bicoord_drake.scenario.Scenario`: `scenario` (one, or a source
    for :func:`~bicoord_drake.scenario.load_scenario`: ``FILE.yaml``, ``FILE.yaml:NAME``, an
    episode file; default: the defaults), with the keyword arguments given set over it, and
    the unseen split unless one is set. `task` defaults to the scenario's and `seed` to its
    first evaluation seed, ``100000 * (1 + scenario.seed)`` (100000 without a scenario).

    `resolution` is ``"WxH"`` or ``(W, H)``; `render=False` drops the cameras (states only, much
    faster); `fps` is the control rate (the task's step limit scales with it); `step_limit`
    overrides the task's (TASKS.md); `data` is where ``reset(seed, stage=k)`` finds the
    demonstration of `seed`; `randomize` gives every scene its seed's randomization (`split`'s
    textures, lights, table height, clutter; a demonstration's scene keeps its own);
    `embodiment` names the robot (default: the ViperX pair); `early_stop` ends a rollout at once
    when a task object leaves the table (see the module docstring). A bad value raises a ValueError
    naming the argument or the scenario's field (an unknown embodiment lists the valid ones; a
    robot the task does not declare in ``Task.supported_robots`` is refused before anything is
    built, naming the robots it supports).
    """
    _check_action_mode(action_mode)
    base = scenario if isinstance(scenario, Scenario | None) else load_scenario(scenario)
    given = {
        "task": task if isinstance(task, str) else None,
        "resolution": resolution,
        "depth": depth,
        "render": render,
        "fps": fps,
        "split": split,
        "randomize": randomize,
        "embodiment": embodiment,
    }
    resolved = resolve(
        (base or Scenario()).to_dict(),
        given,
        source=None if scenario is None or isinstance(scenario, Scenario) else str(scenario),
        defaults={"split": ENVIRONMENT_SPLIT},
    )
    if seed is None:
        seed = check_evaluation_seed(resolved)
    setup = resolved.episode_setup(seed, task if isinstance(task, Task) else None)
    return Env(
        setup, action_mode=action_mode, step_limit=step_limit, data=data, early_stop=early_stop
    )


def _check_action_mode(action_mode: str) -> None:
    if action_mode not in ACTION_MODES:
        raise ValueError(f"action_mode must be 'qpos' or 'endpose', got {action_mode!r}")


class Env:
    """One task in simulation, stepped one control period per action (see the module docstring).

    Built from an :class:`~bicoord_drake.episode_setup.EpisodeSetup` (its seed is the first
    scene's; ``reset(seed)`` takes the same settings to another seed). Attributes a privileged
    (built-in) policy may read: ``task``, ``scene``, ``sim``, ``layout``, ``episode`` (the
    demonstration of the last reset, if any), ``stage`` (the stage of a stage rollout, else
    None), ``start_frame`` (its first recorded frame), ``action`` (the joint action in effect),
    ``failure`` (why an early stop ended the rollout, else None).
    """

    def __init__(
        self,
        setup: EpisodeSetup,
        *,
        action_mode: ActionMode = "qpos",
        step_limit: int | None = None,
        data: str | Path | None = None,
        early_stop: bool = False,
    ) -> None:
        _check_action_mode(action_mode)
        if step_limit is not None and step_limit < 1:
            raise ValueError(f"step_limit must be positive, got {step_limit}")
        self.action_mode: ActionMode = action_mode
        self.assembly: Assembly | None = None
        self.episode: Episode | None = None
        self.stage: int | None = None
        self.start_stage = 0
        self.start_frame = 0
        self.instruction = ""
        self.data = None if data is None else Path(data)
        self.early_stop = bool(early_stop)
        self.failure: str | None = None
        self._lost: LostObjects | None = None
        self._ik: _EndposeIK | None = None
        self._disturber: DisturbanceDriver | None = None
        self._build(setup)
        self.step_limit = int(step_limit or step_limit_at(self.task, self.config.control_rate))
        self._ready = False

    # ---------------------------------------------------------------- construction
    @property
    def setup(self) -> EpisodeSetup:
        """The settings of the current scene (task, seed, randomize, split, robot, station)."""
        return self._setup if self.assembly is None else self.assembly.setup

    @property
    def task(self) -> Task:
        return self.assembly.task

    @property
    def config(self) -> StationConfig:
        return self.setup.station

    @property
    def split(self) -> Split:
        return self.setup.split

    @property
    def randomize(self) -> bool:
        return self.setup.randomize

    @property
    def seed(self) -> int:
        return self.setup.seed

    @property
    def scene(self) -> Scene:
        return self.assembly.scene

    @property
    def sim(self) -> Simulation:
        return self.assembly.sim

    @property
    def embodiment(self) -> str:
        return self.setup.embodiment

    @property
    def layout(self) -> ActionLayout:
        """The robot's action / joint-state layout."""
        return self.assembly.layout

    @property
    def action_size(self) -> int:
        if self.action_mode == "endpose":
            return len(SIDES) * ENDPOSE_WIDTH
        return self.layout.action_size

    @property
    def stages(self) -> tuple[Stage, ...]:
        """The task's stages for the current scene (as defined by the task)."""
        return self.assembly.stages

    def _build(self, setup: EpisodeSetup) -> None:
        """Assemble `setup`'s episode (the simulation is kept when the scene is the same)."""
        self.assembly = assemble(setup, self.assembly)

    def world_view(self) -> WorldView:
        """Privileged read-only state of the simulation (what the expert sees)."""
        return WorldView(self.sim)

    def close(self) -> None:
        """Release the simulation (diagram, simulator, renderer) and the recorded episode; a
        later :meth:`reset` assembles a new one. Safe to call more than once."""
        if self.assembly is not None:
            self._setup = self.assembly.setup
        self.assembly = None
        self.episode = None
        self._ik = None
        self._disturber = None
        self._ready = False

    @property
    def disturbances(self) -> tuple:
        """The disturbances this rollout applies (those of the demonstration it was reset
        from; :class:`~bicoord_drake.sim.disturbances.Disturbance`)."""
        return () if self._disturber is None else self._disturber.disturbances

    # ---------------------------------------------------------------- reset
    def reset(
        self,
        seed: int | None = None,
        *,
        stage: int | None = None,
        episode: Episode | str | Path | None = None,
        disturbances: Sequence[Disturbance] | None = None,
    ) -> dict[str, Any]:
        """Start a rollout and return the first observation.

        Without `episode`: the scene of `seed` (default: the current one) from its initial state.
        With `episode` (a demonstration file or :class:`Episode`): its seed and scene; with
        `stage` = k, the simulator state recorded at the start of stage k, and the rollout is a
        *stage rollout*: done when stage k counts (stages before k count as done).

        `disturbances` (:class:`~bicoord_drake.sim.disturbances.Disturbance`, steps counted
        from the episode's first frame) are applied in this rollout instead of those the
        episode recorded; an empty sequence applies none. None (the default): the episode's
        recorded disturbances, none without an episode.
        """
        self._ready = False
        if self.assembly is None:  # closed: build the simulation again
            self._build(self._setup)
        if stage is not None and episode is None:
            episode = self._demonstration(self.seed if seed is None else int(seed))
        if episode is not None:
            episode = episode if isinstance(episode, Episode) else read_episode(episode, False)
            self._check_episode(episode, seed)
            self._build(self.setup.with_scene(episode.seed, episode.scene))
        elif seed is not None and int(seed) != self.seed:
            self._build(self.setup.for_seed(int(seed)))
        if stage is not None and not 0 <= int(stage) < len(self.stages):
            raise ValueError(f"stage must be in [0, {len(self.stages)}), got {stage}")
        self.episode = episode
        self.stage = None if stage is None else int(stage)
        if self._disturber is not None:
            self._disturber.clear()
        if disturbances is None:
            disturbances = from_records(episode.disturbances) if episode is not None else []
        self._disturber = DisturbanceDriver(self.sim, disturbances) if disturbances else None
        stage = self.stage or 0
        home = self.sim.station.embodiment.home_action()
        if stage == 0:
            self.sim.reset(home)
            self.action = home
            self.start_frame = 0
        else:
            self._restore(episode, stage)
        self.start_stage = stage
        self.monitor = self.assembly.new_monitor(given=stage)
        self.instruction = self.setup.instruction()
        self.steps = 0
        self.failure = None
        self._lost = (
            LostObjects(self.task, self.scene, self.config.control_rate)
            if self.early_stop
            else None
        )
        self.ik_failed: list[str] = []
        self._ready = True
        return self.observation()

    def _demonstration(self, seed: int) -> Path:
        """The episode file of `seed` in the environment's `data` directory."""
        if self.data is None:
            raise ValueError(
                "a stage reset needs the demonstration: reset(seed, stage=k, episode=...) or "
                "make_env(..., data=DIR)"
            )
        import h5py

        for path in sorted(Path(self.data).rglob("*.hdf5")):
            try:
                with h5py.File(path, "r") as f:
                    task, found = f.attrs.get("task"), f.attrs.get("seed")
            except OSError:
                continue
            task = task.decode() if isinstance(task, bytes) else task
            if task == self.task.name and found is not None and int(found) == seed:
                return path
        raise ValueError(f"{self.data}: no {self.task.name} demonstration with seed {seed}")

    def _check_episode(self, episode: Episode, seed: int | None) -> None:
        if episode.task != self.task.name:
            raise ValueError(
                f"{episode.path}: an episode of {episode.task!r}, not {self.task.name!r}"
            )
        if seed is not None and int(seed) != episode.seed:
            raise ValueError(f"{episode.path}: recorded with seed {episode.seed}, not {seed}")
        if len(episode.stages) != len(self.stages):
            raise ValueError(
                f"{episode.path}: {len(episode.stages)} stages recorded, the task has "
                f"{len(self.stages)}"
            )
        if episode.embodiment != self.embodiment:
            raise ValueError(
                f"{episode.path}: recorded with embodiment {episode.embodiment!r} but this "
                f"environment runs {self.embodiment!r} (make_env(..., "
                f"embodiment={episode.embodiment!r}); scripts/evaluate.py: --embodiment "
                f"{episode.embodiment})"
            )
        if abs(episode.fps - self.config.control_rate) > 1e-9:
            raise ValueError(
                f"{episode.path}: recorded at {episode.fps:g} Hz but this environment runs at "
                f"{self.config.control_rate:g} Hz (make_env(..., fps={episode.fps:g}))"
            )

    def _restore(self, episode: Episode, stage: int) -> None:
        """Put the simulator where the demonstration was at the start of `stage`."""
        if episode.initial_state is None or episode.initial_action is None:
            raise ValueError(
                f"{episode.path}: no stages/initial_state: regenerate it to reset at a stage"
            )
        start = int(episode.stages[stage][0])
        action = np.asarray(episode.initial_action[stage], dtype=float)
        before = episode.replay_action[start - 2] if start >= 2 else episode.initial_action[0]
        self.sim.restore(episode.initial_state[stage], action, before, start)
        self.action = action.copy()
        self.start_frame = start

    # ---------------------------------------------------------------- stepping
    def step(self, action: Any) -> tuple[dict[str, Any], dict[str, Any]]:
        """Execute one action for one control period; returns ``(obs, info)``."""
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        if self.done:
            why = self.failure or ("success" if self.monitor.success else "step limit")
            raise RuntimeError(
                f"the rollout is over ({why} after {self.steps} steps); call reset()"
            )
        a = self._validate(action)
        if self.action_mode == "endpose":
            a = self._endpose_to_qpos(a)
        else:
            self.ik_failed = []
        executed = a
        if self._disturber is not None:
            executed = self._disturber.before_step(self.start_frame + self.steps, a)
        self.sim.step(executed)
        self.action = a
        self.steps += 1
        state = WorldState.capture(self.sim, executed, self.scene)
        self.monitor.update(state)
        if self._lost is not None and not self._goal_reached():
            self.failure = self._lost.update(state, self.steps)
        return self.observation(), self.info()

    def _validate(self, action: Any) -> np.ndarray:
        try:
            a = np.asarray(action, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidActionError(
                f"action is not a numeric array ({exc}); not executed"
            ) from None
        if a.shape != (self.action_size,):
            layout = ENDPOSE_LAYOUT if self.action_mode == "endpose" else self.layout.describe()
            raise InvalidActionError(
                f"action must have shape ({self.action_size},) for action_mode="
                f"{self.action_mode!r} {layout}, got {a.shape}; not executed"
            )
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise InvalidActionError(
                f"action contains NaN or infinite values at indices {bad.tolist()}; not executed"
            )
        if self.action_mode == "endpose":
            for k, side in enumerate(SIDES):
                start = k * ENDPOSE_WIDTH + 3
                if np.linalg.norm(a[start : start + 4]) < 1e-6:
                    raise InvalidActionError(f"{side} quaternion is zero; not executed")
        return a

    def _endpose_to_qpos(self, a: np.ndarray) -> np.ndarray:
        if self._ik is None:  # the robot is the environment's for good
            self._ik = _EndposeIK(self.sim.station.embodiment)
        out = self.action.copy()
        measured = self.sim.joint_state()
        layout = self.layout
        self.ik_failed = []
        for k, side in enumerate(SIDES):
            start = k * ENDPOSE_WIDTH
            pose = a[start : start + POSE_SIZE]
            q = self._ik.solve(side, pose, measured[layout.arm(side)])
            if q is None:
                self.ik_failed.append(side)
            else:
                out[layout.arm(side)] = q
            out[layout.gripper(side)] = a[start + POSE_SIZE]
        return out

    # ---------------------------------------------------------------- reading
    @property
    def done(self) -> bool:
        """Success, the stage of a stage rollout counted, the step limit reached, or (early
        stop) a task object lost: :attr:`failure`."""
        if not self._ready or self.steps == 0:
            return False
        return self.steps >= self.step_limit or self._goal_reached() or self.failure is not None

    def _goal_reached(self) -> bool:
        if self.stage is not None:
            return self.monitor.completed()[self.stage] or self.monitor.success
        return self.monitor.success

    def observation(self) -> dict[str, Any]:
        """The current observation (see the module docstring)."""
        sim = self.sim
        obs: dict[str, Any] = {}
        if sim.station.cameras:
            obs.update(sim.images(depth=self.config.cameras.depth))
        obs["joint_state"] = sim.joint_state()
        obs["left_endpose"] = sim.tcp_pose("left")
        obs["right_endpose"] = sim.tcp_pose("right")
        poses = sim.object_poses()
        obs["object_poses"] = {name: poses[name] for name in self.state_objects}
        obs["instruction"] = self.instruction
        return obs

    @property
    def state_objects(self) -> tuple[str, ...]:
        """The objects of ``obs["object_poses"]`` and of the environment state, in its order
        (:func:`bicoord_drake.data.environment_state.state_objects`)."""
        return state_objects(self.scene)

    def environment_state(self) -> np.ndarray:
        """The current ``observation.environment_state`` (7 K,): the task objects' poses, laid
        out as the LeRobot export's (:mod:`bicoord_drake.data.environment_state`)."""
        return environment_state(self.sim.object_poses(), self.state_objects)

    def info(self) -> dict[str, Any]:
        """Stage completion, score so far, success, the step count and why an early stop ended
        the rollout (``failure_reason``, None when none did)."""
        completed = self.monitor.completed()
        info: dict[str, Any] = {
            "step": self.steps,
            "completed": completed,
            "credit": self.monitor.credit(),
            "score": self.monitor.score(),
            "success": self.monitor.success,
            "done": self.done,
            "truncated": (
                self.steps >= self.step_limit and not self._goal_reached() and self.failure is None
            ),
            "stage": self.stage,
            "failure_reason": self.failure,
        }
        if self.stage is not None:
            info["stage_success"] = completed[self.stage]
        if self.action_mode == "endpose":
            info["ik_failed"] = list(self.ik_failed)
        return info


# --------------------------------------------------------------------------- early stop
def off_table(xyz: np.ndarray) -> str | None:
    """Where a point (an object's origin) is off the table: more than :data:`LOST_DROP` below
    its top, or more than :data:`LOST_MARGIN` outside its footprint; None when it is not."""
    x, y, z = (float(v) for v in xyz[:3])
    if z < TABLE_TOP - LOST_DROP:
        return f"{TABLE_TOP - z:.2f} m below the table top"
    out = max(abs(x) - TABLE_SIZE[0] / 2, abs(y) - TABLE_SIZE[1] / 2)
    if out > LOST_MARGIN:
        return f"{out:.2f} m outside the table's edge"
    return None


def _inside(xyz: np.ndarray, region: Region) -> bool:
    lower, upper = (np.asarray(c, dtype=float) for c in region)
    return bool(np.all(xyz[:3] >= lower) and np.all(xyz[:3] <= upper))


class LostObjects:
    """The early-stop watch of one rollout: which task object is lost (see the module
    docstring). Watched: the scene's free objects (no fixtures, no distractors) but those the
    task lets leave the table anywhere; one it lets leave into regions is lost only outside
    them (:meth:`~bicoord_drake.tasks.base.Task.may_leave_table`)."""

    def __init__(self, task: Task, scene: Scene, control_rate: float) -> None:
        allowed = dict(task.may_leave_table(scene))
        free = [o.name for o in scene.free_objects]
        unknown = sorted(set(allowed) - set(free))
        if unknown:
            raise ValueError(
                f"task {task.name}: may_leave_table names {unknown}, not free objects of the "
                f"scene ({free})"
            )
        self.watched = [n for n in free if n not in allowed or allowed[n] is not None]
        self.regions: dict[str, tuple[Region, ...]] = {
            n: tuple(r) for n, r in allowed.items() if r is not None
        }
        #: Control steps in a row an object must be off the table to be lost.
        self.hold = max(1, int(np.ceil(LOST_SECONDS * control_rate - 1e-9)))
        self._since: dict[str, int] = {}

    def update(self, state: WorldState, step: int) -> str | None:
        """The failure reason after control step `step` (`state`: the world then), None while
        nothing is lost."""
        fingers = state.contacts if state.finger_contacts is None else state.finger_contacts
        for name in self.watched:
            pose = state.object_poses.get(name)
            why = None if pose is None else off_table(pose)
            if why is None or fingers.get(name) or self._allowed(name, pose):
                self._since.pop(name, None)
                continue
            first = self._since.setdefault(name, step)
            if step - first + 1 >= self.hold:
                return f"{OBJECT_LEFT_TABLE} at step {step}: {name!r} is {why} (since step {first})"
        return None

    def _allowed(self, name: str, pose: np.ndarray) -> bool:
        return any(_inside(pose, r) for r in self.regions.get(name, ()))


# --------------------------------------------------------------------------- helpers
class _EndposeIK:
    """TCP pose (xyz + wxyz) -> one arm's joint angles, nearest to a seed."""

    def __init__(self, embodiment) -> None:
        from bicoord_drake.planning.ik import BimanualIK, closed_form_applies, has_closed_form
        from bicoord_drake.planning.model import PlanningModel

        self.model = PlanningModel(Scene(), embodiment)
        self.closed_form = has_closed_form(self.model) and closed_form_applies(self.model)
        self._nlp = None if self.closed_form else BimanualIK(self.model, analytic=False)

    def solve(self, side: str, pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        """Joint angles (n,) putting `side`'s TCP at `pose`, or None when unreachable."""
        from pydrake.all import Quaternion, RigidTransform

        from bicoord_drake.planning.errors import PlanningError
        from bicoord_drake.planning.ik import TcpTarget, arm_ik_closed_form

        q = np.asarray(pose[3:7], dtype=float)
        X_WT = RigidTransform(Quaternion(q / np.linalg.norm(q)), np.asarray(pose[:3], float))
        if self.closed_form:
            sols = arm_ik_closed_form(self.model, side, X_WT, seed)
            if not sols:
                return None
            return min(sols, key=lambda s: float(np.sum((s - seed) ** 2)))
        q_both = self.model.home.copy()
        q_both[self.model.side_slice(side)] = seed
        other = other_side(side)
        try:
            out = self._nlp.solve(
                {side: TcpTarget(X_WT)},
                q_fixed={other: q_both[self.model.side_slice(other)]},
                clearance=0.0,
                env_clearance=0.0,
                seed=q_both,
                restarts=2,
            )
        except PlanningError:
            return None
        return out[self.model.side_slice(side)]

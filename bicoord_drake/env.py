"""The policy-facing environment: the expert's simulator, observations and control path.

>>> env = make_env("jigsaw", 100000, resolution="160x120")           # doctest: +SKIP
>>> obs = env.reset()
>>> obs, info = env.step(obs["joint_state"])                          # one control period
>>> info["completed"], info["score"], info["success"], info["step"]

Observations (a dict): ``head_camera``, ``left_camera``, ``right_camera`` (H, W, 3) uint8 RGB
(absent with ``render=False``; with ``depth=True`` also ``<cam>_depth`` (H, W) uint16 mm),
``joint_state`` (14,) measured ``[left q (6), left opening, right q (6), right opening]``,
``left_endpose`` / ``right_endpose`` (7,) TCP xyz + quaternion wxyz in the world frame, and
``instruction`` (one paraphrase of the task's instruction, from the *unseen* split by default).

Actions, one per control period (PRODUCT.md: the station moves the joint targets linearly from the
previous action to the new one over the period):

- ``action_mode="qpos"``: 14 numbers, the joint targets and gripper openings (1 = open), exactly
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
stage of a stage rollout counted, or the step limit) and ``truncated`` (the step limit ended it).

Start from a stage: ``reset(seed, stage=k)`` (the demonstration of `seed` is looked up in
``make_env(..., data=DIR)``) or ``reset(stage=k, episode=path_or_Episode)`` restores the
simulator to the state recorded at the start of stage ``k`` of a demonstration (plant positions
and velocities ``stages/initial_state``, the action in effect and the one before it, the time),
so replaying the recorded actions from there reproduces the demonstration exactly. The stage
monitor treats stages ``0..k-1`` as already counted - they are replaced by always-true transient
stages, so the dependencies of stage ``k`` hold - and scores stage ``k`` and later. Such a *stage
rollout* is done as soon as stage ``k`` counts (``info["stage_success"]``) or at the step limit,
counted from the reset; ``stage=0`` is a stage rollout from the initial state.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np

from bicoord_drake.config import CameraConfig, StationConfig, check_seed, parse_resolution
from bicoord_drake.data.episode import Episode, read_episode
from bicoord_drake.models.embodiment import other_side
from bicoord_drake.models.scene import Scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.stages.stage import Stage
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Split, Task, WorldView

ActionMode = Literal["qpos", "endpose"]
ACTION_SIZES: dict[str, int] = {"qpos": 14, "endpose": 16}
ACTION_LAYOUTS: dict[str, str] = {
    "qpos": "[left 6 joints, left opening, right 6 joints, right opening]",
    "endpose": "[left xyz, left wxyz, left opening, right xyz, right wxyz, right opening]",
}
#: First evaluation seed (PRODUCT.md: evaluation seeds are disjoint from generation seeds).
EVAL_SEED_START = 100000
SIDES = ("left", "right")


class InvalidActionError(ValueError):
    """An action of the wrong shape or with non-finite values; it was not executed."""


def make_env(
    task: str | Task,
    seed: int = EVAL_SEED_START,
    *,
    action_mode: ActionMode = "qpos",
    resolution: str | tuple[int, int] = "320x240",
    depth: bool = False,
    render: bool = True,
    fps: float = 15.0,
    split: Split = "unseen",
    randomize: bool = False,
    step_limit: int | None = None,
    data: str | Path | None = None,
) -> Env:
    """An :class:`Env` for `task` (a name or a Task) whose station is built for `seed`.

    `resolution` is ``"WxH"`` or ``(W, H)``; `render=False` drops the cameras (states only, much
    faster); `fps` is the control rate; `step_limit` overrides the task's (TASKS.md); `data` is
    where ``reset(seed, stage=k)`` finds the demonstration of `seed`; `randomize` gives every
    scene its seed's randomization (`split`'s textures, lights, table height, clutter; a
    demonstration's scene keeps its own).
    """
    if action_mode not in ACTION_SIZES:
        raise ValueError(f"action_mode must be 'qpos' or 'endpose', got {action_mode!r}")
    width, height = parse_resolution(resolution) if isinstance(resolution, str) else resolution
    config = StationConfig(
        control_rate=fps,
        render=render,
        cameras=CameraConfig(width=int(width), height=int(height), depth=depth),
    )
    task_obj = get_task(task) if isinstance(task, str) else task
    return Env(
        task_obj,
        config,
        seed=seed,
        action_mode=action_mode,
        split=split,
        randomize=randomize,
        step_limit=step_limit,
        data=data,
    )


class Env:
    """One task in simulation, stepped one control period per action (see the module docstring).

    Attributes a privileged (built-in) policy may read: ``task``, ``scene``, ``sim``,
    ``episode`` (the demonstration of the last reset, if any), ``stage`` (the stage of a stage
    rollout, else None), ``start_frame`` (its first recorded frame), ``action`` (the joint action
    in effect).
    """

    def __init__(
        self,
        task: Task,
        config: StationConfig,
        *,
        seed: int = EVAL_SEED_START,
        action_mode: ActionMode = "qpos",
        split: Split = "unseen",
        randomize: bool = False,
        step_limit: int | None = None,
        data: str | Path | None = None,
    ) -> None:
        if action_mode not in ACTION_SIZES:
            raise ValueError(f"action_mode must be 'qpos' or 'endpose', got {action_mode!r}")
        if step_limit is not None and step_limit < 1:
            raise ValueError(f"step_limit must be positive, got {step_limit}")
        self.task = task
        self.config = config
        self.action_mode: ActionMode = action_mode
        self.split: Split = split
        self.randomize = randomize
        self.step_limit = int(step_limit or task.step_limit)
        self.seed: int | None = None
        self.scene: Scene | None = None
        self.sim: Simulation | None = None
        self.episode: Episode | None = None
        self.stage: int | None = None
        self.start_stage = 0
        self.start_frame = 0
        self.instruction = ""
        self.data = None if data is None else Path(data)
        self._ik: _EndposeIK | None = None
        self._build(int(seed), None)
        self._ready = False

    # ---------------------------------------------------------------- construction
    @property
    def action_size(self) -> int:
        return ACTION_SIZES[self.action_mode]

    @property
    def stages(self) -> tuple[Stage, ...]:
        """The task's stages for the current scene (as defined by the task)."""
        return self._stages

    def _build(self, seed: int, scene: Scene | None) -> None:
        seed = check_seed(seed)
        if scene is None:
            scene = self.task.sample_scene(seed)
            scene = scene.randomized(self.split) if self.randomize else scene
        if self.sim is None or scene != self.scene:
            self.sim = Simulation(build_station(scene, self.config))
        self.seed, self.scene = seed, scene
        self._stages = tuple(self.task.stages(scene))

    def world_view(self) -> WorldView:
        """Privileged read-only state of the simulation (what the expert sees)."""
        return WorldView(self.sim)

    # ---------------------------------------------------------------- reset
    def reset(
        self,
        seed: int | None = None,
        *,
        stage: int | None = None,
        episode: Episode | str | Path | None = None,
    ) -> dict[str, Any]:
        """Start a rollout and return the first observation.

        Without `episode`: the scene of `seed` (default: the current one) from its initial state.
        With `episode` (a demonstration file or :class:`Episode`): its seed and scene; with
        `stage` = k, the simulator state recorded at the start of stage k, and the rollout is a
        *stage rollout*: done when stage k counts (stages before k count as done).
        """
        self._ready = False
        if stage is not None and episode is None:
            episode = self._demonstration(self.seed if seed is None else int(seed))
        if episode is not None:
            episode = episode if isinstance(episode, Episode) else read_episode(episode, False)
            self._check_episode(episode, seed)
            self._build(episode.seed, episode.scene)
        elif seed is not None and int(seed) != self.seed:
            self._build(int(seed), None)
        if stage is not None and not 0 <= int(stage) < len(self._stages):
            raise ValueError(f"stage must be in [0, {len(self._stages)}), got {stage}")
        self.episode = episode
        self.stage = None if stage is None else int(stage)
        stage = self.stage or 0
        home = self.sim.station.embodiment.home_action()
        if stage == 0:
            self.sim.reset(home)
            self.action = home
            self.start_frame = 0
        else:
            self._restore(episode, stage)
        self.start_stage = stage
        self.monitor = StageMonitor(self._stages, given=stage)
        rng = np.random.default_rng(self.seed)
        self.instruction = self.task.instruction(rng, self.split)
        self.steps = 0
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
        if len(episode.stages) != len(self._stages):
            raise ValueError(
                f"{episode.path}: {len(episode.stages)} stages recorded, the task has "
                f"{len(self._stages)}"
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
        before = episode.joint_action[start - 2] if start >= 2 else episode.initial_action[0]
        self.sim.restore(episode.initial_state[stage], action, before, start)
        self.action = action.copy()
        self.start_frame = start

    # ---------------------------------------------------------------- stepping
    def step(self, action: Any) -> tuple[dict[str, Any], dict[str, Any]]:
        """Execute one action for one control period; returns ``(obs, info)``."""
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        if self.done:
            raise RuntimeError(
                f"the rollout is over ({'success' if self.monitor.success else 'step limit'} "
                f"after {self.steps} steps); call reset()"
            )
        a = self._validate(action)
        if self.action_mode == "endpose":
            a = self._endpose_to_qpos(a)
        else:
            self.ik_failed = []
        self.sim.step(a)
        self.action = a
        self.steps += 1
        self.monitor.update(WorldState.capture(self.sim, a, self.scene))
        return self.observation(), self.info()

    def _validate(self, action: Any) -> np.ndarray:
        try:
            a = np.asarray(action, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidActionError(
                f"action is not a numeric array ({exc}); not executed"
            ) from None
        if a.shape != (self.action_size,):
            layout = ACTION_LAYOUTS[self.action_mode]
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
            for side, k in (("left", 3), ("right", 11)):
                if np.linalg.norm(a[k : k + 4]) < 1e-6:
                    raise InvalidActionError(f"{side} quaternion is zero; not executed")
        return a

    def _endpose_to_qpos(self, a: np.ndarray) -> np.ndarray:
        if self._ik is None:
            self._ik = _EndposeIK(self.sim.station.embodiment)
        out = self.action.copy()
        measured = self.sim.joint_state()
        self.ik_failed = []
        for k, side in enumerate(SIDES):
            pose = a[8 * k : 8 * k + 7]
            q = self._ik.solve(side, pose, measured[7 * k : 7 * k + 6])
            if q is None:
                self.ik_failed.append(side)
            else:
                out[7 * k : 7 * k + 6] = q
            out[7 * k + 6] = a[8 * k + 7]
        return out

    # ---------------------------------------------------------------- reading
    @property
    def done(self) -> bool:
        """Success, the stage of a stage rollout counted, or the step limit reached."""
        if not self._ready or self.steps == 0:
            return False
        return self.steps >= self.step_limit or self._goal_reached()

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
        obs["instruction"] = self.instruction
        return obs

    def info(self) -> dict[str, Any]:
        """Stage completion, score so far, success and the step count."""
        completed = self.monitor.completed()
        info: dict[str, Any] = {
            "step": self.steps,
            "completed": completed,
            "credit": self.monitor.credit(),
            "score": self.monitor.score(),
            "success": self.monitor.success,
            "done": self.done,
            "truncated": self.steps >= self.step_limit and not self._goal_reached(),
            "stage": self.stage,
        }
        if self.stage is not None:
            info["stage_success"] = completed[self.stage]
        if self.action_mode == "endpose":
            info["ik_failed"] = list(self.ik_failed)
        return info


# --------------------------------------------------------------------------- helpers
class _EndposeIK:
    """TCP pose (xyz + wxyz) -> one arm's joint angles, nearest to a seed."""

    def __init__(self, embodiment) -> None:
        from bicoord_drake.planning.ik import BimanualIK, closed_form_applies
        from bicoord_drake.planning.model import PlanningModel

        self.model = PlanningModel(Scene(), embodiment)
        self.closed_form = closed_form_applies(self.model)
        self._nlp = None if self.closed_form else BimanualIK(self.model, analytic=False)

    def solve(self, side: str, pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        """Joint angles (6,) putting `side`'s TCP at `pose`, or None when unreachable."""
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
        q12 = self.model.home.copy()
        q12[self.model.side_slice(side)] = seed
        other = other_side(side)
        try:
            out = self._nlp.solve(
                {side: TcpTarget(X_WT)},
                q_fixed={other: q12[self.model.side_slice(other)]},
                clearance=0.0,
                env_clearance=0.0,
                seed=q12,
                restarts=2,
            )
        except PlanningError:
            return None
        return out[self.model.side_slice(side)]

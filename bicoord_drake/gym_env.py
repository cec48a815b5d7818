"""Gymnasium interface: ``gymnasium.make("bicoord_drake/<task>-v0", ...)`` for every task.

>>> import gymnasium, bicoord_drake                                    # doctest: +SKIP
>>> env = gymnasium.make("bicoord_drake/jigsaw-v0", render_mode="rgb_array", resolution="160x120")
>>> obs, info = env.reset(seed=100000)
>>> obs, reward, terminated, truncated, info = env.step(obs["observation.state"])

:class:`BiCoordEnv` wraps :class:`bicoord_drake.env.Env` (what :func:`~bicoord_drake.make_env`
builds; it stays the project's own interface) in the standard Gymnasium API. The ids are
registered on ``import bicoord_drake``; ``gymnasium.make("bicoord_drake:bicoord_drake/jigsaw-v0")``
imports the package itself. Gymnasium 1.x has no plug-in entry points, so ``import gymnasium``
alone cannot register them.

Spaces, keyed like the LeRobot export (:mod:`bicoord_drake.data.export`):

- observation (``Dict``): ``observation.state`` (A,) float32 measured joints ``[left n, left
  opening, right n, right opening]`` (the robot's layout: A = 14 for the default ViperX pair);
  ``observation.endpose`` (14,) float32 both TCP poses (xyz + quaternion wxyz, left then
  right); ``observation.images.{head,left,right}`` (H, W, 3) uint8 RGB for the cameras that are
  on; ``task`` (``Text``) the instruction; with ``environment_state=True`` also
  ``observation.environment_state`` (7 K,) float32, the K task objects' poses (xyz + wxyz,
  the export's ``--environment-state`` layout, :mod:`bicoord_drake.data.environment_state`;
  names in :attr:`BiCoordEnv.environment_state_names`).
- action (``Box``): A joint targets and openings (``action_mode="qpos"``, the export's
  ``action``; bounds: the joint limits and [0, 1]) or 16 numbers of end poses
  (``action_mode="endpose"``: xyz, quaternion wxyz, opening per arm).

``reset(seed=s)`` starts the scene of seed ``s`` (the benchmark's seeds: evaluation seeds start
at 100000); ``reset()`` without a seed takes the next seed after the previous reset's (the first
one: the ``seed`` given to ``make``, default 100000). ``options={"stage": k, "episode": path}``
starts a stage rollout from a demonstration (:meth:`bicoord_drake.env.Env.reset`).

Reward: the progress of the stage score, ``info["score"]`` now minus before the step, so the
return of a rollout is its final stage score (the evaluation's per-rollout SSR term, 1.0 for a
success). It is negative when a persistent stage (an object at its goal) stops holding.
``terminated``: the task succeeded (in a stage rollout: that stage counted), or with
``early_stop=True`` a task object left the table (a failure: ``info["failure_reason"]`` says
which, :mod:`bicoord_drake.env`; None otherwise); ``truncated``: the step limit (the task's, or
``step_limit=``) ended it. ``info`` is the environment's (``score``,
``completed``, ``credit``, ``success``, ``step``, ...) plus ``is_success`` (LeRobot's name) and
``seed``. ``render()`` (``render_mode="rgb_array"``) returns the head camera's current image.

Keyword arguments of ``gymnasium.make``: ``scenario`` (a
:class:`~bicoord_drake.scenario.Scenario` or a source: ``FILE.yaml``, ``FILE.yaml:NAME``, an
episode file; the keyword arguments below override it), ``render`` (cameras on/off; off is much
faster), ``cameras`` (which of them are observed; default the scenario's), ``resolution``
(``"WxH"``), ``randomize``, ``split``, ``seed`` (default ``100000 * (1 + scenario.seed)``),
``action_mode``, ``fps`` (the task's step limit scales with it), ``step_limit``, ``data``
(demonstrations for stage resets), ``embodiment`` (the robot; default the ViperX pair; one
the task does not declare in ``Task.supported_robots`` is refused), ``environment_state``
(privileged object poses in the observation; off by default), ``early_stop`` (end a rollout
whose task object left the table; off by default).
"""

from __future__ import annotations

import ast
import string
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np
from gymnasium import spaces

from bicoord_drake.data.environment_state import (
    ENVIRONMENT_STATE,
    environment_state,
    feature_names,
)

if TYPE_CHECKING:
    from bicoord_drake.scenario import Scenario

NAMESPACE = "bicoord_drake"
VERSION = 0
ENTRY_POINT = "bicoord_drake.gym_env:BiCoordEnv"
STATE_KEY = "observation.state"
ENDPOSE_KEY = "observation.endpose"
TASK_KEY = "task"
#: Our camera names and their observation keys (the LeRobot export's image features).
IMAGE_KEYS = {
    "head_camera": "observation.images.head",
    "left_camera": "observation.images.left",
    "right_camera": "observation.images.right",
}
_RESET_OPTIONS = ("stage", "episode")


def env_id(task: str) -> str:
    """The Gymnasium id of `task`: ``bicoord_drake/<task>-v0``."""
    return f"{NAMESPACE}/{task}-v{VERSION}"


def builtin_task_names() -> tuple[str, ...]:
    """The tasks that ship with the package, without importing them (or Drake).

    Read from ``TASK_MODULES`` in ``bicoord_drake/tasks/__init__.py`` (each module is named
    after its task); ``tests/test_gym_env.py`` checks that this equals ``list_tasks()``. Where
    the source cannot be read, the tasks are imported and listed.
    """
    source = Path(__file__).with_name("tasks") / "__init__.py"
    try:
        tree = ast.parse(source.read_text(encoding="utf-8"))
        for node in tree.body:
            if isinstance(node, ast.AnnAssign | ast.Assign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                if any(isinstance(t, ast.Name) and t.id == "TASK_MODULES" for t in targets):
                    return tuple(ast.literal_eval(node.value))
    except (OSError, SyntaxError, ValueError):
        pass
    from bicoord_drake.tasks import list_tasks

    return tuple(list_tasks())


def register_envs(tasks: Iterable[str] | None = None) -> list[str]:
    """Register ``bicoord_drake/<task>-v0`` for `tasks` (default: every registered task,
    including ones registered by your own code) and return the ids; already registered ids are
    left alone."""
    if tasks is None:
        from bicoord_drake.tasks import list_tasks

        tasks = list_tasks()
    ids = []
    for task in tasks:
        ident = env_id(task)
        if ident not in gymnasium.registry:
            gymnasium.register(id=ident, entry_point=ENTRY_POINT, kwargs={"task": task})
        ids.append(ident)
    return ids


class BiCoordEnv(gymnasium.Env):
    """One BiCoord task as a Gymnasium environment (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 15}

    def __init__(
        self,
        task: str,
        render_mode: str | None = None,
        *,
        seed: int | None = None,
        scenario: Scenario | str | Path | None = None,
        render: bool | None = None,
        cameras: Sequence[str] | None = None,
        resolution: str | tuple[int, int] | None = None,
        randomize: bool | None = None,
        split: str | None = None,
        action_mode: str = "qpos",
        fps: float | None = None,
        step_limit: int | None = None,
        data: str | Path | None = None,
        embodiment: str | None = None,
        environment_state: bool = False,
        early_stop: bool = False,
    ) -> None:
        from bicoord_drake.config import CAMERA_NAMES, check_seed
        from bicoord_drake.env import ACTION_MODES, ENVIRONMENT_SPLIT, Env
        from bicoord_drake.scenario import (
            Scenario,
            ScenarioError,
            check_evaluation_seed,
            load_scenario,
            resolve,
        )

        register_envs()  # tasks registered by the user's code since the package import
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be 'qpos' or 'endpose', got {action_mode!r}")
        if scenario is None or isinstance(scenario, Scenario):
            base, source = scenario or Scenario(), None
        else:
            base, source = load_scenario(scenario), str(scenario)
        if base.task not in (None, task):
            raise ScenarioError(
                f"{source or 'scenario'}: task {base.task!r}, but this is the id of {task!r}"
            )
        given = {
            "resolution": resolution,
            "render": render,
            "fps": fps,
            "split": split,
            "randomize": randomize,
            "embodiment": embodiment,
        }
        settings = resolve(
            base.to_dict(), given, source=source, defaults={"split": ENVIRONMENT_SPLIT}
        )
        station = settings.station
        if cameras is None:
            cameras = station.cameras.names if station.render else ()
        cameras = tuple(cameras)
        unknown = [c for c in cameras if c not in CAMERA_NAMES]
        if unknown:
            raise ValueError(f"unknown cameras {unknown}; cameras are {list(CAMERA_NAMES)}")
        if cameras and not station.render:
            raise ValueError(f"cameras={list(cameras)} needs render=True")
        # The station renders the observed cameras, plus the head camera for render().
        wanted = set(cameras) | ({"head_camera"} if render_mode == "rgb_array" else set())
        station_cameras = tuple(c for c in CAMERA_NAMES if c in wanted)
        settings = settings.with_overrides(
            {"render": bool(station_cameras), "cameras": station_cameras or CAMERA_NAMES}
        )
        width, height = station.cameras.width, station.cameras.height
        fps = station.control_rate
        self.task_name = task
        self.render_mode = render_mode
        self.cameras = cameras
        self.metadata = {**type(self).metadata, "render_fps": fps}
        if seed is None:
            self._first_seed = check_evaluation_seed(settings)
        else:
            self._first_seed = check_seed(seed)
        setup = settings.episode_setup(self._first_seed, task)
        #: The project's environment this one wraps (privileged policies may ``bind`` to it).
        self.bicoord_env = Env(
            setup,
            action_mode=action_mode,  # type: ignore[arg-type]
            step_limit=step_limit,
            data=data,
            early_stop=early_stop,
        )
        self.step_limit = self.bicoord_env.step_limit
        #: The objects of ``observation.environment_state`` in the current scene (empty when it
        #: is off).
        self.state_objects: tuple[str, ...] = (
            self.bicoord_env.state_objects if environment_state else ()
        )
        self.environment_state = bool(environment_state)
        self.observation_space = self._observation_space(int(width), int(height))
        self.action_space = self._action_space()
        self._seed: int | None = None  # the scene seed of the last reset
        self._score = 0.0
        self._head: np.ndarray | None = None

    # ---------------------------------------------------------------- spaces
    def _observation_space(self, width: int, height: int) -> spaces.Dict:
        task = self.bicoord_env.task
        texts = [*task.instructions("seen"), *task.instructions("unseen")]
        charset = set(string.ascii_letters + string.digits + string.punctuation + " ")
        charset |= {ch for text in texts for ch in text}
        inf = np.inf
        pose_low = np.array([-inf] * 3 + [-1.0] * 4, dtype=np.float32)
        items: dict[str, spaces.Space] = {
            IMAGE_KEYS[cam]: spaces.Box(0, 255, (height, width, 3), np.uint8)
            for cam in self.cameras
        }
        state_size = self.bicoord_env.layout.state_size
        items[STATE_KEY] = spaces.Box(-inf, inf, (state_size,), np.float32)
        items[ENDPOSE_KEY] = spaces.Box(
            np.tile(pose_low, 2), -np.tile(pose_low, 2), (2 * len(pose_low),), np.float32
        )
        if getattr(self, "environment_state", False):
            size = len(self.state_objects) * len(pose_low)
            items[ENVIRONMENT_STATE] = spaces.Box(
                np.tile(pose_low, size // 7), -np.tile(pose_low, size // 7), (size,), np.float32
            )
        items[TASK_KEY] = spaces.Text(
            max(len(t) for t in texts), min_length=1, charset=frozenset(charset)
        )
        return spaces.Dict(items)

    def _action_space(self) -> spaces.Box:
        if self.bicoord_env.action_mode == "endpose":
            side_low = [-np.inf] * 3 + [-1.0] * 4 + [0.0]
            low = np.array(side_low * 2, dtype=np.float32)
            high = np.array([np.inf] * 3 + [1.0] * 5, dtype=np.float32)
            return spaces.Box(low, np.tile(high, 2), dtype=np.float32)
        from bicoord_drake.models.embodiment import SIDES

        arm, layout = self.bicoord_env.sim.station.embodiment.arm, self.bicoord_env.layout
        low = layout.compose(dict.fromkeys(SIDES, arm.lower), dict.fromkeys(SIDES, 0.0))
        high = layout.compose(dict.fromkeys(SIDES, arm.upper), dict.fromkeys(SIDES, 1.0))
        return spaces.Box(low.astype(np.float32), high.astype(np.float32))

    # ---------------------------------------------------------------- API
    @property
    def instruction(self) -> str:
        """The instruction of the current rollout (the ``task`` observation)."""
        return self.bicoord_env.instruction

    @property
    def task_description(self) -> str:
        """The instruction; LeRobot's evaluation reads it under this name."""
        return self.bicoord_env.instruction

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - set(_RESET_OPTIONS))
        if unknown:
            raise ValueError(f"unknown reset options {unknown}; known: {list(_RESET_OPTIONS)}")
        if options.get("episode") is not None:
            scene_seed = seed  # the demonstration's own seed (checked against `seed` if given)
        elif seed is not None:
            scene_seed = int(seed)
        elif self._seed is None:
            scene_seed = self._first_seed
        else:
            scene_seed = self._seed + 1
        raw = self.bicoord_env.reset(
            scene_seed, stage=options.get("stage"), episode=options.get("episode")
        )
        self._seed = self.bicoord_env.seed
        info = self._info(self.bicoord_env.info())
        self._score = info["score"]
        return self._observation(raw), info

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        raw, raw_info = self.bicoord_env.step(action)
        info = self._info(raw_info)
        reward = info["score"] - self._score
        self._score = info["score"]
        truncated = bool(info["truncated"])
        terminated = bool(info["done"]) and not truncated
        return self._observation(raw), float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The head camera's current RGB image (H, W, 3) uint8 with ``render_mode="rgb_array"``;
        None without a render mode."""
        if self.render_mode is None:
            return None
        if self._head is None:
            raise gymnasium.error.ResetNeeded("call reset() before render()")
        return self._head.copy()

    def close(self) -> None:
        """Release the simulator (the environment can be reset again afterwards)."""
        self._head = None
        self.bicoord_env.close()

    # ---------------------------------------------------------------- conversion
    def _observation(self, raw: dict[str, Any]) -> dict[str, Any]:
        self._head = raw.get("head_camera")
        obs: dict[str, Any] = {IMAGE_KEYS[cam]: np.asarray(raw[cam]) for cam in self.cameras}
        obs[STATE_KEY] = np.asarray(raw["joint_state"], dtype=np.float32).copy()
        obs[ENDPOSE_KEY] = np.concatenate([raw["left_endpose"], raw["right_endpose"]]).astype(
            np.float32
        )
        if self.environment_state:
            objects = tuple(raw["object_poses"])
            size = self.observation_space[ENVIRONMENT_STATE].shape[0]
            if 7 * len(objects) != size:
                raise ValueError(
                    f"seed {self.bicoord_env.seed}: the scene has {len(objects)} task objects, "
                    f"the observation space's {ENVIRONMENT_STATE} {size // 7}"
                )
            self.state_objects = objects  # jigsaw's names vary with the seed, not their count
            obs[ENVIRONMENT_STATE] = environment_state(raw["object_poses"], objects, np.float32)
        obs[TASK_KEY] = str(raw["instruction"])
        return obs

    @property
    def environment_state_names(self) -> list[str]:
        """The names of ``observation.environment_state`` for the current scene (as in the
        export's meta; :attr:`state_objects` are its objects)."""
        return feature_names(self.state_objects)

    def _info(self, raw: dict[str, Any]) -> dict[str, Any]:
        info = {k: list(v) if isinstance(v, list) else v for k, v in raw.items()}
        info["score"] = float(info["score"])
        info["is_success"] = bool(raw["success"])
        info["seed"] = self._seed
        return info


__all__ = [
    "BiCoordEnv",
    "ENTRY_POINT",
    "IMAGE_KEYS",
    "NAMESPACE",
    "builtin_task_names",
    "env_id",
    "register_envs",
]

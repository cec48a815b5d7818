"""LeRobot's own evaluation and training on BiCoord tasks: ``--env.type=bicoord``.

::

    lerobot-eval --env.discover_packages_path=bicoord_drake --env.type=bicoord \\
        --env.task=jigsaw --policy.path=outputs/act_jigsaw/checkpoints/last/pretrained_model \\
        --eval.n_episodes=10 --eval.batch_size=2 --policy.device=cpu --seed=0
    lerobot-train --env.discover_packages_path=bicoord_drake --env.type=bicoord \\
        --env.task=jigsaw --eval_freq=5000 --dataset.repo_id=... --policy.type=act ...

How lerobot finds it: ``--env.discover_packages_path=bicoord_drake`` makes lerobot's CLI
(``lerobot.configs.parser.load_plugin``) import ``bicoord_drake`` and then every module directly
inside it, this one among them; importing this module registers :class:`BiCoordEnvConfig` as
the ``EnvConfig`` choice ``"bicoord"`` (draccus then parses ``--env.type=bicoord`` and the
``--env.*`` fields) and the Gymnasium id :data:`ENV_ID`, which lerobot's ``make_env`` makes
``eval.batch_size`` times into a ``SyncVectorEnv``. ``import bicoord_drake`` never imports
this module (nor torch or lerobot).

:class:`LeRobotBiCoordEnv` wraps :class:`bicoord_drake.gym_env.BiCoordEnv` in the layout
lerobot's ``preprocess_observation`` reads: ``pixels`` (a dict ``head``/``left``/``right`` of
(H, W, 3) uint8 images, which become ``observation.images.<camera>``), ``agent_pos`` (the
joint state, ``observation.state``) and, with ``environment_state=true``,
``environment_state`` (the task objects' poses, ``observation.environment_state``): the feature
names of our LeRobot export (:mod:`bicoord_drake.data.export`), so a policy trained on an
export reads them unchanged. ``observation.endpose`` has no place in that layout: lerobot's
policies read ``observation.state`` and do not miss it. The prompt is the env's
``task_description`` (also ``task``): the rollout's instruction. Success is
``info["is_success"]``, which the vector env hands to lerobot as ``final_info["is_success"]``;
the step limit is ``_max_episode_steps`` (lerobot stops its rollout there, and so does the
env).

Early stop (``--env.early_stop=true``; off by default, as in
:func:`bicoord_drake.env.make_env`): a rollout whose task object has left the table (on the
floor or outside the workspace: nothing can bring it back) ends at once. lerobot-eval sees it
``terminated`` (not ``truncated``) with ``info["is_success"]`` False and
``info["failure_reason"]`` saying which object, where and since when (``final_info`` of the
vector env), and counts the episode as done there: its success rate is the one without early
stop. lerobot steps a batch until all of its envs are done (one done early is reset by the
vector env and runs on, unscored), so the time is saved whole with ``--eval.batch_size=1``.
``scripts/evaluate.py`` stops early by default.

Seeds: lerobot-eval resets batch ``b`` with seeds ``seed + b * batch_size + i``; the scene seed
is that plus ``seed_offset`` (default 100000, the benchmark's first evaluation seed), so
``--seed=0`` evaluates the scenes ``scripts/evaluate.py`` starts with (it also skips seeds
whose expert fails; lerobot does not). lerobot's default ``--seed=1000`` starts at 101000.

The environment renders the head camera for lerobot-eval's videos (it records up to 10
episodes), whatever the observation: keep ``render_mode=rgb_array``. Keep
``disable_env_checker=true`` (the default): Gymnasium's checker wraps the env, and lerobot then
no longer finds ``task_description`` (it reads the first env's attributes directly) and sends an
empty prompt.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from typing import Any

import gymnasium
from gymnasium import spaces

from bicoord_drake.data.environment_state import ENVIRONMENT_STATE, POSE_SIZE
from bicoord_drake.gym_env import IMAGE_KEYS, STATE_KEY, BiCoordEnv
from bicoord_drake.scenario import EVAL_SEED_START

#: The Gymnasium id lerobot makes (``BiCoordEnvConfig.gym_id``); the task is a keyword. Outside
#: the ``bicoord_drake/`` namespace, which holds one id per task (:mod:`bicoord_drake.gym_env`).
ENV_ID = "bicoord_lerobot/bicoord-v0"
#: What the config names as the module to import when the id is not registered.
MODULE = __name__
#: Our cameras by their short names, the keys of ``pixels`` (``observation.images.<name>``).
CAMERAS = {key.rsplit(".", 1)[1]: camera for camera, key in IMAGE_KEYS.items()}
OBS_TYPES = ("pixels_agent_pos", "pixels", "state")


def parse_cameras(cameras: str | tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """``"head,left"`` (or our names, ``head_camera``, ...) -> ``("head_camera", "left_camera")``;
    a ValueError naming the valid cameras otherwise."""
    names = cameras.split(",") if isinstance(cameras, str) else list(cameras)
    out = []
    for name in (n.strip() for n in names):
        if not name:
            continue
        camera = CAMERAS.get(name, name)
        if camera not in CAMERAS.values():
            raise ValueError(f"unknown camera {name!r}; cameras are {', '.join(CAMERAS)}")
        if camera not in out:
            out.append(camera)
    return tuple(out)


class LeRobotBiCoordEnv(gymnasium.ObservationWrapper):
    """A BiCoord task with observations in lerobot's ``pixels`` / ``agent_pos`` /
    ``environment_state`` layout (see the module docstring).

    `obs_type`: ``pixels_agent_pos`` (images and joint state), ``pixels`` or ``state`` (joint
    state only, no camera rendered for the observation). `cameras`: which cameras (``"head,
    left,right"``). `environment_state`: add the task objects' poses. `seed_offset`: added to
    every seed given to ``reset``. Other keywords go to :class:`BiCoordEnv` (``resolution``,
    ``fps``, ``step_limit``, ``embodiment``, ``action_mode``, ``randomize``, ``split``,
    ``early_stop``, ...).
    """

    def __init__(
        self,
        task: str,
        obs_type: str = "pixels_agent_pos",
        render_mode: str | None = "rgb_array",
        *,
        cameras: str | tuple[str, ...] = "head,left,right",
        environment_state: bool = False,
        seed_offset: int = EVAL_SEED_START,
        **kwargs: Any,
    ) -> None:
        if obs_type not in OBS_TYPES:
            raise ValueError(f"obs_type must be one of {', '.join(OBS_TYPES)}, got {obs_type!r}")
        pixels = obs_type != "state"
        observed = parse_cameras(cameras) if pixels else ()
        if pixels and not observed:
            raise ValueError(f"obs_type={obs_type!r} needs at least one camera")
        self.seed_offset = int(seed_offset)
        env = BiCoordEnv(
            task,
            render_mode,
            seed=self.seed_offset,
            render=pixels,
            cameras=observed,
            environment_state=environment_state,
            **kwargs,
        )
        super().__init__(env)
        self.obs_type = obs_type
        self.cameras = observed
        self.agent_pos = obs_type != "pixels"
        inner = env.observation_space
        items: dict[str, spaces.Space] = {}
        if observed:
            items["pixels"] = spaces.Dict(
                {name: inner[IMAGE_KEYS[cam]] for name, cam in CAMERAS.items() if cam in observed}
            )
        if self.agent_pos:
            items["agent_pos"] = inner[STATE_KEY]
        if environment_state:
            items["environment_state"] = inner[ENVIRONMENT_STATE]
        self.observation_space = spaces.Dict(items)

    # ---------------------------------------------------------------- what lerobot reads
    @property
    def task_description(self) -> str:
        """The instruction of the current rollout: lerobot's prompt."""
        return self.env.unwrapped.task_description

    @property
    def task(self) -> str:
        """The instruction too (lerobot falls back on ``task`` without ``task_description``)."""
        return self.env.unwrapped.task_description

    @property
    def _max_episode_steps(self) -> int:
        """The step limit, where lerobot's rollout stops (``env.call("_max_episode_steps")``)."""
        return int(self.env.unwrapped.step_limit)

    @property
    def bicoord_env(self) -> Any:
        """The wrapped :class:`bicoord_drake.env.Env`."""
        return self.env.unwrapped.bicoord_env

    # ---------------------------------------------------------------- API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        if seed is not None:
            seed = self.seed_offset + int(seed)
        obs, info = self.env.reset(seed=seed, options=options)
        return self.observation(obs), info

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.cameras:
            out["pixels"] = {
                name: observation[IMAGE_KEYS[cam]]
                for name, cam in CAMERAS.items()
                if cam in self.cameras
            }
        if self.agent_pos:
            out["agent_pos"] = observation[STATE_KEY]
        if ENVIRONMENT_STATE in observation:
            out["environment_state"] = observation[ENVIRONMENT_STATE]
        return out

    def close(self) -> None:
        """Close the Gymnasium environment (which releases the simulator)."""
        self.env.close()


def register_env() -> str:
    """Register :data:`ENV_ID` (once) and return it. No order enforcer and no checker, so
    ``gymnasium.make`` returns the :class:`LeRobotBiCoordEnv` itself: lerobot reads the prompt
    from the first env's own attributes."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=ENV_ID,
            entry_point=f"{MODULE}:LeRobotBiCoordEnv",
            order_enforce=False,
            disable_env_checker=True,
        )
    return ENV_ID


register_env()


# ------------------------------------------------------------------------ lerobot's EnvConfig
def environment_state_size(task: str, seed: int = EVAL_SEED_START) -> int:
    """The size of `task`'s ``observation.environment_state`` (7 numbers per task object; the
    count is the same for every seed). Imports the task (and Drake)."""
    from bicoord_drake.data.environment_state import state_objects
    from bicoord_drake.tasks import get_task

    return POSE_SIZE * len(state_objects(get_task(task).sample_scene(seed)))


if importlib.util.find_spec("lerobot") is not None:  # lerobot's CLI imports us: register
    from bicoord_drake.policies.lerobot_policy import preload_triton

    preload_triton()  # before torch, in case this process has rendered (see its docstring)
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.envs.configs import EnvConfig

    ACTION = "action"
    OBS_STATE = "observation.state"

    def _features_map() -> dict[str, str]:
        return {
            ACTION: ACTION,
            "agent_pos": OBS_STATE,
            "environment_state": ENVIRONMENT_STATE,
            **{f"pixels/{name}": key for key, name in _pixel_keys().items()},
        }

    def _pixel_keys() -> dict[str, str]:
        return {IMAGE_KEYS[cam]: name for name, cam in CAMERAS.items()}

    @EnvConfig.register_subclass("bicoord")
    @dataclass
    class BiCoordEnvConfig(EnvConfig):
        """``--env.type=bicoord``: one BiCoord task for lerobot-eval / lerobot-train.

        ``--env.task`` the task (``jigsaw``, ...); ``--env.obs_type`` ``pixels_agent_pos``
        (default), ``pixels`` or ``state``; ``--env.cameras`` (``head,left,right``);
        ``--env.observation_width/height`` the images' size (use the training data's);
        ``--env.environment_state=true`` adds the task objects' poses; ``--env.episode_length``
        the step limit (default: the task's at ``--env.fps``); ``--env.embodiment``,
        ``--env.action_mode``, ``--env.randomize``, ``--env.split``; ``--env.seed_offset``
        added to lerobot's seeds (default 100000: ``--seed=0`` gives the benchmark's
        evaluation seeds); ``--env.early_stop=true`` ends a rollout, as a failure, once a task
        object has left the table (off by default, as in ``make_env``; see the module
        docstring).
        """

        task: str | None = "jigsaw"
        fps: int = 15
        episode_length: int | None = None
        obs_type: str = "pixels_agent_pos"
        cameras: str = "head,left,right"
        observation_width: int = 320
        observation_height: int = 240
        environment_state: bool = False
        embodiment: str = "aloha_viperx"
        action_mode: str = "qpos"
        randomize: bool = False
        split: str = "unseen"
        seed_offset: int = EVAL_SEED_START
        early_stop: bool = False
        render_mode: str = "rgb_array"
        features: dict[str, PolicyFeature] = field(default_factory=dict)
        features_map: dict[str, str] = field(default_factory=_features_map)

        def __post_init__(self) -> None:
            from bicoord_drake.gym_env import builtin_task_names
            from bicoord_drake.models.layout import check_embodiment
            from bicoord_drake.policies import action_size_of

            if not self.task:
                raise ValueError(f"--env.task: give a task ({', '.join(builtin_task_names())})")
            if self.task not in builtin_task_names():
                from bicoord_drake.tasks import list_tasks  # tasks registered by user code

                if self.task not in list_tasks():
                    raise ValueError(
                        f"--env.task: unknown task {self.task!r}; tasks: {', '.join(list_tasks())}"
                    )
            if self.obs_type not in OBS_TYPES:
                raise ValueError(
                    f"--env.obs_type must be one of {', '.join(OBS_TYPES)}, got {self.obs_type!r}"
                )
            if self.action_mode not in ("qpos", "endpose"):
                raise ValueError(f"--env.action_mode must be qpos or endpose: {self.action_mode!r}")
            if self.render_mode != "rgb_array":
                raise ValueError(
                    "--env.render_mode must be rgb_array: lerobot-eval records videos of the "
                    "head camera"
                )
            if not self.disable_env_checker:
                raise ValueError(
                    "--env.disable_env_checker must stay true: Gymnasium's checker wrapper hides "
                    "the environment's task_description, and lerobot would send an empty prompt"
                )
            check_embodiment(self.embodiment)
            size = action_size_of(self.embodiment, self.action_mode)
            height, width = self.observation_height, self.observation_width
            features: dict[str, PolicyFeature] = {
                ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(size,))
            }
            if self.obs_type != "state":
                for camera in parse_cameras(self.cameras):
                    name = _pixel_keys()[IMAGE_KEYS[camera]]
                    features[f"pixels/{name}"] = PolicyFeature(
                        type=FeatureType.VISUAL, shape=(height, width, 3)
                    )
            if self.obs_type != "pixels":
                from bicoord_drake.models.layout import layout_of

                state = layout_of(self.embodiment).state_size
                features["agent_pos"] = PolicyFeature(type=FeatureType.STATE, shape=(state,))
            if self.environment_state:
                features["environment_state"] = PolicyFeature(
                    type=FeatureType.ENV,
                    shape=(environment_state_size(self.task, self.seed_offset),),
                )
            self.features = features

        @property
        def package_name(self) -> str:
            """The module lerobot imports when :data:`ENV_ID` is not registered: this one."""
            return MODULE

        @property
        def gym_id(self) -> str:
            return ENV_ID

        @property
        def gym_kwargs(self) -> dict[str, Any]:
            return {
                "task": self.task,
                "obs_type": self.obs_type,
                "render_mode": self.render_mode,
                "cameras": self.cameras,
                "environment_state": self.environment_state,
                "seed_offset": self.seed_offset,
                "resolution": (self.observation_width, self.observation_height),
                "fps": float(self.fps),
                "step_limit": self.episode_length,
                "embodiment": self.embodiment,
                "action_mode": self.action_mode,
                "randomize": self.randomize,
                "split": self.split,
                "early_stop": self.early_stop,
            }


__all__ = [
    "CAMERAS",
    "ENV_ID",
    "LeRobotBiCoordEnv",
    "environment_state_size",
    "parse_cameras",
    "register_env",
]

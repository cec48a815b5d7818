"""LeRobot checkpoints as policies: ``load_policy("lerobot:PATH")``, ``--policy lerobot:PATH``.

``PATH`` is what ``lerobot-train`` wrote (its output directory, whose
``checkpoints/last/pretrained_model`` is used), one checkpoint directory (``.../005000``, with
``pretrained_model/`` in it) or a ``pretrained_model`` folder itself (``config.json``,
``model.safetensors``, ``policy_preprocessor.json``, ``policy_postprocessor.json``). Any policy
type the installed lerobot knows (ACT, Diffusion, SmolVLA, pi0, ...) loads through lerobot's
own ``PreTrainedConfig.from_pretrained``, ``get_policy_class(type).from_pretrained`` and
``make_pre_post_processors(config, pretrained_path=...)`` (the saved pre/post-processor
pipelines: normalization statistics, tokenizer, device).

Each step the policy gets, under the names of the LeRobot export (:mod:`bicoord_drake.data.export`)
and only the features it was trained with: ``observation.state`` (the measured joints, as many
as the robot's layout has: 14 for the ViperX pair),
``observation.endpose`` (both TCP poses), ``observation.images.{head,left,right}`` as float CHW
tensors in [0, 1], resized (bilinear, antialiased) to the size in its config, and the
instruction as ``task``; a state-based checkpoint trained on an export with
``--environment-state`` also gets ``observation.environment_state``, the task objects' poses
computed from the live simulation by the export's own function
(:mod:`bicoord_drake.data.environment_state`). Its names (object order) are read from the
training dataset's ``meta/info.json`` (found through the checkpoint's ``train_config.json``)
and checked against the environment's scene: at ``bind(env)`` and on every observation of
:mod:`bicoord_drake.env` (its ``object_poses``). Where the dataset is gone, only the size is
checked (with a warning). Its ``select_action`` runs its action queue (chunks, temporal
ensembling) and ``reset`` empties it at the start of every rollout. Observations of
:mod:`bicoord_drake.env` and of the Gymnasium environment (:mod:`bicoord_drake.gym_env`, already
keyed by those names) are both accepted.

A checkpoint whose inputs the benchmark cannot provide (for any of its robots) is refused at
load time, naming what is missing and what the environment offers; one that needs a camera the
environment does not render (``--no-render``), or a state of another robot's size, fails its
first action the same way.

torch and lerobot are imported only here, when such a policy is loaded; without them (or
without what lerobot's policy modules import) loading says how to install them:
``pip install -e '.[train]' && pip install --no-deps lerobot==0.4.4``.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from bicoord_drake.data.environment_state import (
    ENVIRONMENT_STATE,
    POSE_SIZE,
    environment_state,
    mismatch,
    objects_of,
)
from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.layout import layout_of
from bicoord_drake.models.robots import EMBODIMENTS
from bicoord_drake.policies import PolicyLoadError, action_size_of, env_action_size

PREFIX = "lerobot:"
LEROBOT_PIN = "lerobot==0.4.4"
#: The [train] extra is the [lerobot] one plus what lerobot's policy and config modules import
#: (draccus, einops, diffusers, ...); lerobot itself goes in without its torch pin (pyproject).
INSTALL_HINT = f"pip install -e '.[train]' && pip install --no-deps {LEROBOT_PIN}"
STATE = "observation.state"
ENDPOSE = "observation.endpose"
ACTION = "action"
#: Both TCP poses (xyz + wxyz), whatever the robot.
ENDPOSE_SHAPE = (len(SIDES) * POSE_SIZE,)
#: Our camera names and the LeRobot image features they feed (as in the export).
IMAGE_FEATURES = {
    "head_camera": "observation.images.head",
    "left_camera": "observation.images.left",
    "right_camera": "observation.images.right",
}
#: Every input a BiCoord environment can provide, with its shape (images: 3 channels, any size;
#: the state: see :func:`state_shapes`).
OFFERED = {
    STATE: "(A,)",
    ENDPOSE: str(ENDPOSE_SHAPE),
    ENVIRONMENT_STATE: "(7 K,) (the K task objects' poses)",
    **{key: "(3, H, W)" for key in IMAGE_FEATURES.values()},
}
_CHECKPOINT_FILES = ("config.json", "model.safetensors")


def state_shapes() -> dict[tuple[int], list[str]]:
    """Each ``observation.state`` shape a registered robot gives -> the robots giving it."""
    shapes: dict[tuple[int], list[str]] = {}
    for name in EMBODIMENTS:
        shapes.setdefault((layout_of(name).state_size,), []).append(name)
    return shapes


def _offered() -> dict[str, str]:
    """:data:`OFFERED` with the state shapes of the registered robots."""
    states = " or ".join(f"{s} ({', '.join(n)})" for s, n in state_shapes().items())
    return {**OFFERED, STATE: states}


def find_checkpoint(path: str | Path) -> Path:
    """The ``pretrained_model`` folder of `path` (see the module docstring); PolicyLoadError
    saying what was looked for otherwise."""
    root = Path(path).expanduser()
    if not root.exists():
        raise PolicyLoadError(f"lerobot policy: {root} does not exist")
    candidates = [
        root,
        root / "pretrained_model",
        root / "checkpoints" / "last" / "pretrained_model",
    ]
    for candidate in candidates:
        if all((candidate / name).is_file() for name in _CHECKPOINT_FILES):
            return candidate
    raise PolicyLoadError(
        f"lerobot policy: no checkpoint in {root}: expected a lerobot-train output directory "
        "(checkpoints/last/pretrained_model), a checkpoint directory (pretrained_model/) or a "
        f"pretrained_model folder ({' and '.join(_CHECKPOINT_FILES)})"
    )


def preload_triton() -> None:
    """Load triton (if installed and not loaded yet) with its own LLVM symbols bound first.

    torchvision imports ``torch._dynamo``, which imports triton; triton's library carries its
    own LLVM, and loaded after a camera has rendered (Mesa's llvmpipe has put
    ``libLLVM-15`` in the process) it binds to Mesa's LLVM and the process segfaults.
    ``RTLD_DEEPBIND`` makes it use its own; loading it before any rendering needs nothing.
    Call this before importing torchvision or lerobot in a process that may have rendered.
    """
    import importlib.util
    import os

    if "triton" in sys.modules or not hasattr(os, "RTLD_DEEPBIND"):
        return
    try:
        if importlib.util.find_spec("triton") is None:
            return
    except (ImportError, ValueError):
        return
    flags = sys.getdlopenflags()
    sys.setdlopenflags(flags | os.RTLD_DEEPBIND)
    try:
        import triton  # noqa: F401
    except Exception:  # torch reports a broken triton itself, if it ever needs it
        pass
    finally:
        sys.setdlopenflags(flags)


def _require_lerobot() -> None:
    preload_triton()
    try:
        import torch  # noqa: F401
        from lerobot.configs.policies import PreTrainedConfig  # noqa: F401
        from lerobot.policies.factory import get_policy_class  # noqa: F401
    except ImportError as exc:
        raise PolicyLoadError(
            f"lerobot policies need torch, lerobot and the packages its policies import ({exc}); "
            f"install them with {INSTALL_HINT}"
        ) from None


def _required_inputs(config: Any) -> dict[str, tuple[str, tuple[int, ...]]]:
    """Input feature -> (type, shape) the policy needs from the environment: all of its
    ``input_features`` but the language tokens its own processors make from ``task`` and the
    placeholder cameras (``empty_camera_<i>``) that pi0-type policies fill themselves."""
    out = {}
    for key, feature in (config.input_features or {}).items():
        kind = getattr(feature.type, "value", str(feature.type))
        if kind == "LANGUAGE" or key.startswith("observation.images.empty_camera_"):
            continue
        out[key] = (kind, tuple(int(n) for n in feature.shape))
    return out


def check_features(config: Any, where: str = "this checkpoint") -> None:
    """PolicyLoadError unless a BiCoord environment can provide every input of `config`."""
    problems = []
    missing = []
    offered_shapes = _offered()
    for key, (_, shape) in _required_inputs(config).items():
        if key not in OFFERED:
            missing.append(f"{key} {shape}")
        elif key == STATE and shape not in state_shapes():
            problems.append(f"{key} has shape {shape}, the environment's is {offered_shapes[key]}")
        elif key == ENDPOSE and shape != ENDPOSE_SHAPE:
            problems.append(f"{key} has shape {shape}, the environment's is {OFFERED[key]}")
        elif key == ENVIRONMENT_STATE and (len(shape) != 1 or not shape[0] or shape[0] % POSE_SIZE):
            problems.append(f"{key} has shape {shape}, the environment's is {OFFERED[key]}")
        elif key in IMAGE_FEATURES.values() and (len(shape) != 3 or shape[0] != 3):
            problems.append(f"{key} has shape {shape}, expected (3, H, W) RGB")
    if missing or problems:
        offered = ", ".join(f"{k} {s}" for k, s in offered_shapes.items())
        text = []
        if missing:
            text.append(f"it needs {', '.join(missing)}, which the environment does not provide")
        text.extend(problems)
        raise PolicyLoadError(
            f"lerobot policy {where}: its input features do not match the environment: "
            f"{'; '.join(text)}. The environment offers: {offered} (images at any size, "
            "resized to the policy's)."
        )


def action_sizes() -> dict[int, list[str]]:
    """Each action size a BiCoord environment takes -> what takes it (``<robot> qpos``: its
    joint targets and openings; ``endpose``: both end poses with openings, any robot)."""
    sizes: dict[int, list[str]] = {}
    for name in EMBODIMENTS:
        sizes.setdefault(action_size_of(name, "qpos"), []).append(f"{name} qpos")
    sizes.setdefault(action_size_of(next(iter(EMBODIMENTS)), "endpose"), []).append("endpose")
    return sizes


def check_action(
    config: Any, where: str = "this checkpoint", action_size: int | None = None
) -> int:
    """The number of values in one action of `config`; PolicyLoadError naming both sizes when
    it is not `action_size` (the environment's), or, without it, when no BiCoord environment
    takes that size or the size does not go with the checkpoint's own ``observation.state``."""
    action = (config.output_features or {}).get(ACTION)
    if action is None:
        outputs = ", ".join(config.output_features or {}) or "none"
        raise PolicyLoadError(
            f"lerobot policy {where}: it has no '{ACTION}' output feature (outputs: {outputs})"
        )
    size = int(np.prod(action.shape))
    if action_size is not None:
        if size != int(action_size):
            raise PolicyLoadError(
                f"lerobot policy {where}: its actions have {size} numbers, the environment's "
                f"have {int(action_size)}"
            )
        return size
    sizes = action_sizes()
    offered = ", ".join(f"{n} ({', '.join(w)})" for n, w in sizes.items())
    if size not in sizes:
        raise PolicyLoadError(
            f"lerobot policy {where}: its actions have {size} numbers, the environment's have "
            f"{offered}"
        )
    state = (config.input_features or {}).get(STATE)
    if state is not None:
        n = int(np.prod(state.shape))
        robots = [name for name in EMBODIMENTS if layout_of(name).state_size == n]
        fits = {action_size_of(r, mode) for r in robots for mode in ("qpos", "endpose")}
        if robots and size not in fits:
            raise PolicyLoadError(
                f"lerobot policy {where}: its actions have {size} numbers, but an environment "
                f"whose {STATE} has {n} ({', '.join(robots)}) takes "
                f"{' or '.join(map(str, sorted(fits)))}"
            )
    return size


def dataset_info(checkpoint: Path) -> dict[str, Any] | None:
    """The ``meta/info.json`` of the dataset the checkpoint was trained on (its
    ``train_config.json`` names it: ``dataset.root``, else the LeRobot cache's ``repo_id``), or
    None when it cannot be found."""
    try:
        train = json.loads((checkpoint / "train_config.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    dataset = train.get("dataset") or {}
    roots = []
    if dataset.get("root"):
        roots.append(Path(dataset["root"]).expanduser())
    if dataset.get("repo_id"):
        home = os.environ.get("HF_LEROBOT_HOME")
        cache = Path(home) if home else Path.home() / ".cache" / "huggingface" / "lerobot"
        roots.append(cache / str(dataset["repo_id"]))
    for root in roots:
        try:
            return json.loads((root / "meta" / "info.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
    return None


def trained_state_objects(checkpoint: Path, size: int) -> tuple[str, ...] | None:
    """The objects of the checkpoint's ``observation.environment_state`` (from its dataset's
    feature names), or None with a warning when the dataset cannot be found;
    PolicyLoadError when the names do not describe `size` numbers of object poses."""
    info = dataset_info(checkpoint)
    names = (((info or {}).get("features") or {}).get(ENVIRONMENT_STATE) or {}).get("names")
    if not names:
        warnings.warn(
            f"lerobot policy {checkpoint}: the training dataset's meta/info.json (named by "
            f"train_config.json) is not found, so the object order of {ENVIRONMENT_STATE} "
            "cannot be checked against the environment's, only its size",
            stacklevel=3,
        )
        return None
    try:
        objects = objects_of(names)
    except ValueError as exc:
        raise PolicyLoadError(
            f"lerobot policy {checkpoint}: the dataset's {ENVIRONMENT_STATE} names are not a "
            f"BiCoord object-pose layout ({exc})"
        ) from None
    if len(names) != size:
        raise PolicyLoadError(
            f"lerobot policy {checkpoint}: the dataset names {len(names)} numbers of "
            f"{ENVIRONMENT_STATE}, the policy takes {size}"
        )
    return objects


def _step_names(pipeline_file: Path) -> set[str]:
    """Registry names of the steps of a saved processor pipeline."""
    try:
        steps = json.loads(pipeline_file.read_text(encoding="utf-8")).get("steps", [])
    except (OSError, ValueError):
        return set()
    return {s.get("registry_name") for s in steps if isinstance(s, dict)}


class LeRobotPolicy:
    """A LeRobot checkpoint behind the policy interface (see the module docstring).

    `device`: where the policy runs (default: the checkpoint's, if available there, else the
    first accelerator lerobot finds, else the CPU).
    """

    def __init__(
        self, path: str | Path, *, device: str | None = None, action_size: int | None = None
    ) -> None:
        self.path = find_checkpoint(path)
        _require_lerobot()
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.policies.factory import get_policy_class, make_pre_post_processors

        where = str(self.path)
        # lerobot prints progress ("Loading weights from local directory") on stdout, where
        # scripts/evaluate.py --json writes its report.
        with contextlib.redirect_stdout(sys.stderr):
            try:
                config = PreTrainedConfig.from_pretrained(self.path)
            except Exception as exc:
                raise PolicyLoadError(
                    f"lerobot policy {where}: cannot read its config.json "
                    f"({type(exc).__name__}: {exc})"
                ) from None
            if device is not None:
                config.device = device
            check_features(config, where)
            self.action_size = check_action(config, where, action_size)
            self.type = config.type
            try:
                policy_cls = get_policy_class(config.type)
            except ImportError as exc:
                raise PolicyLoadError(
                    f"lerobot policy {where}: the {config.type!r} policy needs packages that are "
                    f"not installed ({exc})"
                ) from None
            except Exception as exc:
                raise PolicyLoadError(
                    f"lerobot policy {where}: policy type {config.type!r} is not available in "
                    f"this lerobot ({type(exc).__name__}: {exc})"
                ) from None
            try:
                self.policy = policy_cls.from_pretrained(self.path, config=config)
                overrides = {}
                pre_file = self.path / "policy_preprocessor.json"
                if "device_processor" in _step_names(pre_file):
                    overrides["device_processor"] = {"device": str(config.device)}
                self.preprocessor, self.postprocessor = make_pre_post_processors(
                    config, pretrained_path=str(self.path), preprocessor_overrides=overrides
                )
            except PolicyLoadError:
                raise
            except Exception as exc:
                raise PolicyLoadError(
                    f"lerobot policy {where}: loading the {config.type} policy or its "
                    f"processors failed ({type(exc).__name__}: {exc})"
                ) from None
        self.config = config
        self.inputs = _required_inputs(config)
        self.instruction = ""
        #: The objects of the environment state the policy was trained on, in its order (None:
        #: unknown, only the size is checked; empty: the policy does not take it).
        self.state_objects: tuple[str, ...] | None = ()
        if ENVIRONMENT_STATE in self.inputs:
            size = int(np.prod(self.inputs[ENVIRONMENT_STATE][1]))
            self.state_objects = trained_state_objects(self.path, size)
        self.policy.eval()

    def __repr__(self) -> str:
        return f"LeRobotPolicy({self.type}, {str(self.path)!r})"

    # ---------------------------------------------------------------- policy interface
    def bind(self, env: Any) -> None:
        """Check that `env` (:class:`bicoord_drake.env.Env` or the Gymnasium environment)
        takes actions of the policy's size and provides the environment state the policy was
        trained on, object by object; called by the evaluation after every reset."""
        objects = getattr(getattr(env, "unwrapped", env), "state_objects", None)
        if objects:
            self.check_state_objects(tuple(objects))
        size = env_action_size(env)
        if size is not None and size != self.action_size:
            raise ValueError(
                f"lerobot policy {self.path}: its actions have {self.action_size} numbers, the "
                f"environment's have {size}"
            )

    def check_state_objects(self, objects: tuple[str, ...]) -> None:
        """ValueError unless `objects` (the environment state's, in order) are the ones the
        policy was trained on (when it takes the environment state and they are known; only
        their count for a positional layout, see :func:`~bicoord_drake.data.
        environment_state.mismatch`)."""
        problem = mismatch(self.state_objects, objects) if self.state_objects else None
        if problem:
            raise ValueError(
                f"lerobot policy {self.path}: {ENVIRONMENT_STATE} of this scene is not the one "
                f"it was trained on: {problem}"
            )

    def close(self) -> None:
        """Release the model and its processors (and the accelerator memory they held)."""
        policy = self.__dict__.pop("policy", None)
        self.__dict__.pop("preprocessor", None)
        self.__dict__.pop("postprocessor", None)
        if policy is None:
            return
        del policy
        import gc

        import torch

        gc.collect()
        if torch.cuda.is_available():
            torch.cuda.empty_cache()

    def reset(self, instruction: str) -> None:
        """A new rollout: empty the action queue, remember the instruction."""
        self.instruction = str(instruction)
        self.policy.reset()

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        """The next action (float64) for an environment observation."""
        import torch

        if "policy" not in self.__dict__:
            raise RuntimeError(f"lerobot policy {self.path} is closed")
        batch = self.batch(obs)
        with torch.inference_mode():
            batch = self.preprocessor(batch)
            action = self.policy.select_action(batch)
            action = self.postprocessor(action)
        return np.asarray(action.detach().to("cpu", torch.float32).numpy(), dtype=float).reshape(-1)

    # ---------------------------------------------------------------- observation -> batch
    def batch(self, obs: dict[str, Any]) -> dict[str, Any]:
        """`obs` as the LeRobot batch of size 1 the policy's preprocessor takes."""
        import torch

        available = self._features(obs)
        missing = [key for key in self.inputs if key not in available]
        if missing:
            hints = ["images need rendering on and the camera in the environment"]
            if ENVIRONMENT_STATE in missing:
                hints.append(
                    f"{ENVIRONMENT_STATE} needs gymnasium.make(..., environment_state=True) or "
                    "a bicoord_drake.env observation (its object_poses)"
                )
            raise ValueError(
                f"lerobot policy {self.path}: the observation lacks {', '.join(missing)} (it has "
                f"{', '.join(sorted(available)) or 'nothing the policy can use'}); "
                + "; ".join(hints)
            )
        batch: dict[str, Any] = {}
        for key, (kind, shape) in self.inputs.items():
            value = available[key]
            if kind == "VISUAL":
                batch[key] = _image_tensor(value, shape, torch)
            else:
                vector = np.asarray(value, dtype=np.float32).reshape(1, -1)
                if vector.shape[1] != int(np.prod(shape)):
                    raise ValueError(
                        f"lerobot policy {self.path}: {key} has {vector.shape[1]} numbers, the "
                        f"policy takes {shape} (trained on another robot?)"
                    )
                batch[key] = torch.as_tensor(vector.copy())
        task = obs.get("instruction", obs.get("task", self.instruction))
        batch["task"] = [str(task)]
        return batch

    def _features(self, obs: dict[str, Any]) -> dict[str, Any]:
        """The LeRobot features found in an observation of either environment."""
        out = {k: v for k, v in obs.items() if k in OFFERED}
        poses = obs.get("object_poses")
        if ENVIRONMENT_STATE in self.inputs and ENVIRONMENT_STATE not in out and poses:
            self.check_state_objects(tuple(poses))
        for key in (
            STATE,
            ENDPOSE,
            *([ENVIRONMENT_STATE] if ENVIRONMENT_STATE in self.inputs else []),
        ):
            value = observation_vector(obs, key)
            if key not in out and value is not None:
                out[key] = value
        for camera, key in IMAGE_FEATURES.items():
            if key not in out and camera in obs:
                out[key] = obs[camera]
        return out


def observation_vector(obs: dict[str, Any], key: str) -> Any:
    """The vector feature `key` (:data:`STATE`, :data:`ENDPOSE` or ``ENVIRONMENT_STATE``) of
    an observation of either environment, as a policy gets it: keyed by the feature (the
    Gymnasium environment) or made from :mod:`bicoord_drake.env`'s ``joint_state``,
    ``left_endpose``/``right_endpose`` or ``object_poses`` (the environment state of its
    objects in its order); None if the observation has neither."""
    if key in obs:
        return obs[key]
    if key == STATE:
        return obs.get("joint_state")
    if key == ENDPOSE and "left_endpose" in obs and "right_endpose" in obs:
        return np.concatenate([obs["left_endpose"], obs["right_endpose"]])
    poses = obs.get("object_poses")
    if key == ENVIRONMENT_STATE and poses:
        return environment_state(poses, tuple(poses))
    return None


def _image_tensor(image: Any, shape: tuple[int, ...], torch: Any) -> Any:
    """(H, W, 3) uint8 RGB -> (1, 3, h, w) float32 in [0, 1] at the policy's (h, w)."""
    array = np.asarray(image)
    if array.ndim != 3 or array.shape[-1] != 3:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {array.shape}")
    scale = 255.0 if array.dtype == np.uint8 else 1.0
    x = torch.from_numpy(np.ascontiguousarray(array)).permute(2, 0, 1).unsqueeze(0)
    x = x.to(torch.float32) / scale
    h, w = shape[-2], shape[-1]
    if tuple(x.shape[-2:]) != (h, w):
        x = torch.nn.functional.interpolate(
            x, size=(h, w), mode="bilinear", align_corners=False, antialias=True
        ).clamp_(0.0, 1.0)
    return x


def load_lerobot_policy(spec: str, **kwargs: Any) -> LeRobotPolicy:
    """``"lerobot:PATH"`` -> :class:`LeRobotPolicy` (keyword arguments: ``device``,
    ``action_size``: the environment's, checked before the weights are read)."""
    path = spec[len(PREFIX) :].strip()
    if not path:
        raise PolicyLoadError(f"policy {spec!r}: give a checkpoint path after 'lerobot:'")
    unknown = sorted(set(kwargs) - {"device", "action_size"})
    if unknown:
        raise PolicyLoadError(
            f"policy {spec!r}: unknown arguments {unknown} (known: device, action_size)"
        )
    return LeRobotPolicy(path, **kwargs)

"""Policies: what maps an observation to the next action, and how one is loaded.

A policy is any object with ``act(obs) -> action`` and, optionally, ``reset(instruction)``
(called at the start of every rollout) and ``bind(env)`` (called after ``env.reset()``, before
``reset``; a *privileged* hook the built-ins use to read the demonstration or the simulator -
a learned policy should not need it; the LeRobot adapter uses it only to check that the
scene's task objects are the ones its ``observation.environment_state`` was trained on).
Observations and actions are those of
:mod:`bicoord_drake.env`.

Load one with :func:`load_policy`:

- a built-in: ``"replay"`` (the recorded actions of the demonstration the environment was reset
  from), ``"expert"`` (the task's planner, in closed loop), ``"noop"`` (hold the action in
  effect);
- ``"package.module:name"``: a class (instantiated with the keyword arguments), a zero-argument
  factory (called), an object with ``act`` (used as is) or any other callable (used as
  ``act(obs)``, with a no-op ``reset``);
- ``"lerobot:PATH"``: a LeRobot checkpoint (a ``lerobot-train`` output directory or a
  ``pretrained_model`` folder) of any policy type lerobot has, with its saved pre/post-processors
  (:mod:`bicoord_drake.policies.lerobot_policy`; needs torch and lerobot, imported only then);
- ``"openpi:HOST:PORT"``: a policy server speaking openpi's websocket protocol, its action
  chunks consumed one action per step (:mod:`bicoord_drake.policies.openpi_policy`; needs
  openpi-client, imported only then);
- ``"lerobot-dataset:DIR"``: a LeRobot export's own actions, played back on the episodes' seeds
  (the episode of each rollout's task and seed; :mod:`bicoord_drake.policies.dataset_policy`;
  needs lerobot, imported only then).

A policy may also have ``close()`` (release a model, a connection): :func:`close_policy` calls it.
:func:`load_policy_for` loads a policy for an environment whose actions have a known size, so
that the checkpoint and remote policies refuse another size when they are loaded.
"""

from __future__ import annotations

import importlib
import inspect
import re
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable
from urllib.parse import parse_qsl

import numpy as np

from bicoord_drake.policies.builtin import ExpertPolicy, NoopPolicy, ReplayPolicy

#: Built-in policies by name.
BUILTINS: dict[str, type] = {"replay": ReplayPolicy, "expert": ExpertPolicy, "noop": NoopPolicy}
_SPEC = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")


@runtime_checkable
class Policy(Protocol):
    """The policy interface (see the module docstring)."""

    def reset(self, instruction: str) -> None: ...

    def act(self, obs: dict[str, Any]) -> Any: ...


class PolicyLoadError(ValueError):
    """A policy spec that cannot be imported or does not give a policy."""


def spec_options(spec: str, query: str, known: dict[str, Callable[[str], Any]]) -> dict[str, Any]:
    """The ``k=v&...`` options after a policy spec's ``?``, each converted by ``known[k]``;
    PolicyLoadError naming an unknown option (and the known ones) or a value that does not
    convert."""
    options: dict[str, Any] = {}
    for key, value in parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)):
        if key not in known:
            raise PolicyLoadError(
                f"policy {spec!r}: unknown option {key!r} (options: {', '.join(known)})"
            )
        try:
            options[key] = known[key](value)
        except ValueError:
            kind = getattr(known[key], "__name__", "value")
            raise PolicyLoadError(
                f"policy {spec!r}: option {key}={value!r} is not a valid {kind}"
            ) from None
    return options


class FunctionPolicy:
    """A plain callable used as ``act(obs)``; ``reset`` does nothing."""

    def __init__(self, fn: Callable[[dict[str, Any]], Any]) -> None:
        self.fn = fn

    def reset(self, instruction: str) -> None:
        pass

    def act(self, obs: dict[str, Any]) -> Any:
        return self.fn(obs)

    def __repr__(self) -> str:
        return f"FunctionPolicy({getattr(self.fn, '__qualname__', self.fn)!r})"


def load_policy(spec: str, **kwargs: Any) -> Any:
    """A policy from a built-in name, ``package.module:name``, ``lerobot:PATH``,
    ``openpi:HOST:PORT`` or ``lerobot-dataset:DIR`` (see the module docstring).

    Raises :class:`PolicyLoadError` naming the problem (bad spec, module not importable, missing
    attribute, not a policy, constructor failure).
    """
    spec = str(spec).strip()
    if spec.startswith("lerobot-dataset:"):
        from bicoord_drake.policies.dataset_policy import load_dataset_policy

        return load_dataset_policy(spec, **kwargs)
    if spec.startswith("lerobot:"):
        from bicoord_drake.policies.lerobot_policy import load_lerobot_policy

        return load_lerobot_policy(spec, **kwargs)
    if spec.startswith("openpi:"):
        from bicoord_drake.policies.openpi_policy import load_openpi_policy

        return load_openpi_policy(spec, **kwargs)
    if spec in BUILTINS:
        return BUILTINS[spec](**kwargs)
    if not _SPEC.match(spec):
        raise PolicyLoadError(
            f"policy spec {spec!r} must be a built-in ({', '.join(BUILTINS)}), "
            "'package.module:name', 'lerobot:PATH', 'openpi:HOST:PORT' or 'lerobot-dataset:DIR'"
        )
    module_name, attr = spec.split(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # any import-time failure of user code is a load error
        raise PolicyLoadError(
            f"policy {spec!r}: cannot import module {module_name!r} ({type(exc).__name__}: {exc})"
        ) from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise PolicyLoadError(
                f"policy {spec!r}: {getattr(obj, '__name__', obj)!r} has no attribute {part!r}"
            )
        obj = getattr(obj, part)
    return _as_policy(obj, spec, kwargs)


def _as_policy(obj: Any, spec: str, kwargs: dict[str, Any]) -> Any:
    if inspect.isclass(obj) or (callable(obj) and not hasattr(obj, "act") and _no_args(obj)):
        try:
            obj = obj(**kwargs)
        except Exception as exc:
            raise PolicyLoadError(
                f"policy {spec!r}: constructing it failed ({type(exc).__name__}: {exc})"
            ) from None
    elif kwargs:
        raise PolicyLoadError(f"policy {spec!r} takes no arguments (it is not a class)")
    if hasattr(obj, "act"):
        if not callable(obj.act):
            raise PolicyLoadError(f"policy {spec!r}: its 'act' is not callable")
        return obj
    if callable(obj):
        return FunctionPolicy(obj)
    raise PolicyLoadError(
        f"policy {spec!r} is a {type(obj).__name__}, not a class, a callable or an object "
        "with act(obs)"
    )


def _no_args(fn: Callable) -> bool:
    """Whether `fn` can be called without arguments (a factory rather than act)."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return False
    return all(
        p.default is not p.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params
    )


def reset_policy(policy: Any, instruction: str) -> None:
    """Call the policy's ``reset(instruction)`` if it has one."""
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset(instruction)


def bind_policy(policy: Any, env: Any) -> None:
    """Call the policy's privileged ``bind(env)`` hook if it has one."""
    bind = getattr(policy, "bind", None)
    if callable(bind):
        bind(env)


def close_policy(policy: Any) -> None:
    """Call the policy's ``close()`` (release its model or connection) if it has one."""
    close = getattr(policy, "close", None)
    if callable(close):
        close()


#: The spec prefixes whose policies take ``action_size=`` and refuse another size at load.
SIZED_PREFIXES = ("lerobot:", "openpi:", "lerobot-dataset:")


def action_size_of(embodiment: str, action_mode: str = "qpos") -> int:
    """The numbers of one action of an environment of `embodiment` in `action_mode`: the
    robot's joint targets and openings (``qpos``) or both end poses with openings
    (``endpose``, 16)."""
    if action_mode == "endpose":
        from bicoord_drake.data.environment_state import POSE_SIZE
        from bicoord_drake.models.embodiment import SIDES

        return len(SIDES) * (POSE_SIZE + 1)
    if action_mode != "qpos":
        raise ValueError(f"action_mode must be 'qpos' or 'endpose', got {action_mode!r}")
    from bicoord_drake.models.layout import layout_of

    return layout_of(embodiment).action_size


def env_action_size(env: Any) -> int | None:
    """The action size of a :class:`bicoord_drake.env.Env` or a Gymnasium environment (None
    when it cannot be told)."""
    size = getattr(env, "action_size", None)
    if isinstance(size, int | np.integer):
        return int(size)
    unwrapped = getattr(env, "unwrapped", env)
    inner = getattr(unwrapped, "bicoord_env", None)
    if isinstance(getattr(inner, "action_size", None), int | np.integer):
        return int(inner.action_size)
    shape = getattr(getattr(unwrapped, "action_space", None), "shape", None)
    return int(np.prod(shape)) if shape else None


def load_policy_for(spec: str, *, action_size: int, **kwargs: Any) -> Any:
    """:func:`load_policy` for an environment whose actions have `action_size` numbers
    (:func:`action_size_of`): a ``lerobot:`` checkpoint or a ``lerobot-dataset:`` dataset whose
    actions have another size is refused here, naming both sizes, and an ``openpi:`` server's
    chunks are checked against it from the first one; other policies load as
    :func:`load_policy` loads them."""
    spec = str(spec).strip()
    if spec.startswith(SIZED_PREFIXES):
        kwargs = {"action_size": int(action_size), **kwargs}
    return load_policy(spec, **kwargs)


__all__ = [
    "BUILTINS",
    "ExpertPolicy",
    "FunctionPolicy",
    "NoopPolicy",
    "Policy",
    "PolicyLoadError",
    "ReplayPolicy",
    "SIZED_PREFIXES",
    "action_size_of",
    "bind_policy",
    "close_policy",
    "env_action_size",
    "load_policy",
    "load_policy_for",
    "reset_policy",
]

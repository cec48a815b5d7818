"""Built-in policies: ``replay``, ``expert`` and ``noop``.

They are privileged: :meth:`bind` reads the environment (its demonstration, its simulator)
after each ``env.reset()``. All three command joint targets (``action_mode="qpos"``).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.tasks.base import expert_actions

if TYPE_CHECKING:
    from bicoord_drake.env import Env


def _require_qpos(env: Env, name: str) -> None:
    if env.action_mode != "qpos":
        raise ValueError(f"the {name} policy commands joint targets: use action_mode='qpos'")


class ReplayPolicy:
    """The recorded actions of the demonstration the environment was reset from: those the
    station executed (``joint_action/executed`` of an episode generated with action noise,
    else ``joint_action``: :attr:`~bicoord_drake.data.episode.Episode.replay_action`), so the
    replay reproduces it.

    From the start frame of the reset's stage; in a stage rollout only that stage's frames. When
    the recording runs out it holds the last action.
    """

    def __init__(self) -> None:
        self._actions = np.zeros((0, 0))  # the demonstration's, from bind()
        self._t = 0

    def bind(self, env: Env) -> None:
        _require_qpos(env, "replay")
        if env.episode is None:
            raise ValueError(
                "the replay policy needs a demonstration: reset the environment with "
                "episode=... (scripts/evaluate.py: --data DIR)"
            )
        ep = env.episode
        start, end = env.start_frame, ep.length
        if env.stage is not None:
            end = int(ep.stages[env.stage][1])
        self._actions = np.asarray(ep.replay_action[start:end], dtype=float)
        self._hold = np.asarray(env.action, dtype=float)
        self._t = 0

    def reset(self, instruction: str) -> None:
        self._t = 0

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        if self._t < len(self._actions):
            self._hold = self._actions[self._t]
            self._t += 1
        return self._hold.copy()


class ExpertPolicy:
    """The task's planning expert, run in closed loop on the environment's simulator.

    It plans from the true world state (privileged) and is only defined from the start of a task
    (not from a stage reset); it acts as the generator runs it
    (:func:`~bicoord_drake.tasks.base.expert_actions`: below 15 Hz every k-th planned sample).
    When its plan ends it holds the last action.
    """

    def bind(self, env: Env) -> None:
        _require_qpos(env, "expert")
        if env.start_stage:
            raise ValueError("the expert policy plans from the start of the task, not a stage")
        self._plan: Iterator[np.ndarray] = expert_actions(env.task, env.scene, env.world_view())
        self._hold = np.asarray(env.action, dtype=float)
        self._bound = True

    def reset(self, instruction: str) -> None:
        if not getattr(self, "_bound", False):
            raise RuntimeError("the expert policy must be bound to an environment (bind(env))")

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        try:
            self._hold = np.asarray(next(self._plan), dtype=float)
        except StopIteration:
            pass
        return self._hold.copy()


class NoopPolicy:
    """Holds the action in effect at the reset, so the arms stay where they are.

    Unbound (no ``bind``), it holds the first observation's joint state (``qpos``).
    """

    def __init__(self) -> None:
        self._bound: np.ndarray | None = None
        self._hold: np.ndarray | None = None

    def bind(self, env: Env) -> None:
        if env.action_mode == "qpos":
            self._bound = np.asarray(env.action, dtype=float)
        else:  # endpose: the current TCP poses with the commanded openings
            a, layout = env.action, env.layout
            self._bound = np.concatenate(
                [np.r_[env.sim.tcp_pose(side), a[layout.gripper(side)]] for side in SIDES]
            )

    def reset(self, instruction: str) -> None:
        self._hold, self._bound = self._bound, None

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        if self._hold is None:
            self._hold = np.asarray(obs["joint_state"], dtype=float)
        return self._hold.copy()

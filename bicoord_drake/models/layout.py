"""Where each arm's joints and gripper opening sit in an action or joint-state vector.

Every vector the station takes or gives (``action``, ``joint_state``), the episode files'
``joint_action/vector`` / ``joint_state/vector`` and the LeRobot ``action`` /
``observation.state`` features share one layout, derived from the embodiment: per side, in
``SIDES`` order, the arm's ``n`` joint values then the gripper opening (1 = open)::

    [left q (n), left opening, right q (n), right opening]      2 (n + 1) numbers

The ViperX pair (n = 6) gives the 14-vector ``[left 6, left opening, right 6, right opening]``.
Code that reads or writes these vectors asks an :class:`ActionLayout` for sizes, slices and
indices instead of writing them down, so a robot with another joint count needs no change.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import AfterValidator

from bicoord_drake.config import StationConfig
from bicoord_drake.models.embodiment import SIDES, Embodiment, Side
from bicoord_drake.models.robots import EMBODIMENTS, get_embodiment

#: Size of one TCP pose vector: xyz + quaternion wxyz.
POSE_SIZE = 7


@dataclass(frozen=True)
class ActionLayout:
    """The vector layout of a two-arm robot whose arms have `arm_joints` joints each.

    `joint_names` (one arm's, optional) name the features of exported datasets."""

    arm_joints: int
    joint_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.arm_joints < 1:
            raise ValueError(f"an arm needs at least one joint, got {self.arm_joints}")
        names = tuple(self.joint_names)
        if names and len(names) != self.arm_joints:
            raise ValueError(f"{len(names)} joint names for {self.arm_joints} joints")
        object.__setattr__(self, "joint_names", names)

    # ---------------------------------------------------------------- sizes
    @property
    def arm_width(self) -> int:
        """Numbers per side: the arm's joints and the gripper opening."""
        return self.arm_joints + 1

    @property
    def action_size(self) -> int:
        """Length of an action (the commanded targets and openings)."""
        return len(SIDES) * self.arm_width

    @property
    def state_size(self) -> int:
        """Length of a measured joint state (the same layout as an action)."""
        return self.action_size

    # ---------------------------------------------------------------- indices
    def _side(self, side: str) -> int:
        try:
            return SIDES.index(side)  # type: ignore[arg-type]
        except ValueError:
            raise ValueError(f"side must be one of {SIDES}, got {side!r}") from None

    def arm(self, side: str) -> slice:
        """The entries of `side`'s arm joints."""
        start = self._side(side) * self.arm_width
        return slice(start, start + self.arm_joints)

    def gripper(self, side: str) -> int:
        """The index of `side`'s gripper opening."""
        return self._side(side) * self.arm_width + self.arm_joints

    @property
    def gripper_indices(self) -> list[int]:
        """Each side's gripper index, in ``SIDES`` order."""
        return [self.gripper(side) for side in SIDES]

    # ---------------------------------------------------------------- vectors
    def compose(
        self, arms: Mapping[str, np.ndarray | Sequence[float]], openings: Mapping[str, object]
    ) -> np.ndarray:
        """Arm joints and openings per side -> vectors of this layout. Works on one vector
        (arms (n,), scalar openings) and on a batch (arms (N, n), openings (N,))."""
        q = {side: np.asarray(arms[side], dtype=float) for side in SIDES}
        batch = q[SIDES[0]].shape[:-1]
        out = np.empty((*batch, self.action_size))
        for side in SIDES:
            out[..., self.arm(side)] = q[side]
            out[..., self.gripper(side)] = openings[side]
        return out

    def arm_positions(self, vector: np.ndarray) -> np.ndarray:
        """Both arms' joints, left then right (the planners' joint vector), of one vector or a
        batch."""
        v = np.asarray(vector)
        return np.concatenate([v[..., self.arm(side)] for side in SIDES], axis=-1)

    def openings(self, vector: np.ndarray) -> dict[Side, float]:
        """Each side's gripper opening in one vector."""
        v = np.asarray(vector)
        return {side: float(v[self.gripper(side)]) for side in SIDES}

    def split(self, vector: np.ndarray) -> dict[Side, tuple[np.ndarray, float]]:
        """One vector -> ``{side: (arm joints, opening)}``."""
        v = self.check(vector)
        return {side: (v[self.arm(side)], float(v[self.gripper(side)])) for side in SIDES}

    def check(self, vector: object, what: str = "action") -> np.ndarray:
        """`vector` as a float array of shape ``(action_size,)``; a ValueError naming `what`
        and this layout otherwise."""
        v = np.asarray(vector, dtype=float)
        if v.shape != (self.action_size,):
            raise ValueError(
                f"{what} must have shape ({self.action_size},) {self.describe()}, got {v.shape}"
            )
        return v

    # ---------------------------------------------------------------- names
    def feature_names(self) -> list[str]:
        """A name per entry: ``<side>_<joint>`` and ``<side>_gripper`` (LeRobot features)."""
        joints = self.joint_names or tuple(f"joint{i}" for i in range(self.arm_joints))
        return [f"{side}_{name}" for side in SIDES for name in (*joints, "gripper")]

    def describe(self) -> str:
        """The layout in words, e.g. ``[left 6 joints, left opening, right 6 joints, right
        opening]``."""
        n = self.arm_joints
        return "[" + ", ".join(f"{s} {n} joints, {s} opening" for s in SIDES) + "]"


def action_layout(embodiment: Embodiment) -> ActionLayout:
    """The vector layout of `embodiment`'s arms."""
    return ActionLayout(embodiment.num_arm_joints, tuple(embodiment.arm.joint_names))


def layout_of(name: str) -> ActionLayout:
    """The layout of the registered embodiment `name` (an unknown name is a ValueError that
    lists the valid ones)."""
    return action_layout(get_embodiment(name))


def default_embodiment() -> str:
    """The embodiment every setting defaults to (:class:`~bicoord_drake.config.StationConfig`'s)."""
    return StationConfig.model_fields["embodiment"].default


def check_embodiment(name: str) -> str:
    """`name` if an embodiment of that name is registered; a ValueError listing the valid names
    otherwise."""
    if name not in EMBODIMENTS:
        get_embodiment(name)  # raises, naming the valid embodiments
    return name


#: A settings field naming a registered embodiment (checked by :func:`check_embodiment`).
EmbodimentName = Annotated[str, AfterValidator(check_embodiment)]

"""Joint-space path length of one bimanual trajectory.

``PL = sum over both arms' arm joints j and frames t >= 2 of |q_{t,j} - q_{t-1,j}|`` in radians
(an L1 path length: every joint's travel, summed). Gripper joints are not arm joints and do not
count. For our episode files the joint positions are the *measured* ones, ``joint_state/vector``
(``[left q (n), left opening, right q (n), right opening]``); RoboTwin 2.0 files record the
robot's joint positions per frame in ``joint_action/{left,right}_arm``; BiCoord's release has no
joint positions, so its path length is unknown (``None``), never 0.

Numpy only; no Drake.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _as_joints(name: str, value: ArrayLike) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] < 1:
        raise ValueError(f"{name} must have shape (L, n) with n >= 1, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or inf")
    return arr


def joint_path_length(left_q: ArrayLike, right_q: ArrayLike) -> float:
    """Total joint-space path length (rad) of both arms: ``sum_t sum_j |q_t - q_{t-1}|``.

    Args:
        left_q, right_q: (L, n) arm joint positions per frame (no gripper), same L.

    Raises:
        ValueError: wrong shapes, mismatched lengths, empty input, NaN/inf.
    """
    left, right = _as_joints("left_q", left_q), _as_joints("right_q", right_q)
    if len(left) != len(right):
        raise ValueError(f"mismatched trajectory lengths: left_q={len(left)}, right_q={len(right)}")
    if len(left) == 0:
        raise ValueError("empty trajectory (length 0)")
    return float(np.abs(np.diff(left, axis=0)).sum() + np.abs(np.diff(right, axis=0)).sum())

"""The per-episode signals the coordination metrics use, independent of the file layout.

:mod:`bicoord_drake.data.readers` builds a :class:`Trajectory` from episode files; the metrics
consume it. Numpy only, so the metrics can import it without pulling in file readers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_INITIAL_DISTANCE = 1e-9
"""Initial inter-arm distances at or below this (metres) are rejected as zero: the relative
distance of the coordination metrics is undefined for them."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """The per-episode signals the metrics use, independent of the file layout."""

    source: str
    task: str
    layout: str
    left_xyz: np.ndarray
    right_xyz: np.ndarray
    left_gripper: np.ndarray
    right_gripper: np.ndarray
    n_stages: int | None = None
    n_objects: int | None = None
    success: bool | None = None
    left_q: np.ndarray | None = None
    """(L, n) arm joint positions per frame (no gripper), ``None`` when the file has none."""
    right_q: np.ndarray | None = None

    @property
    def length(self) -> int:
        return len(self.left_xyz)

"""Shape measures the skills share."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bicoord_drake.models.objects import BowlShape, BoxShape, CylinderShape, SphereShape
from bicoord_drake.planning.errors import PlanningError


def half_extent(shape, R: np.ndarray, u: Sequence[float]) -> float:
    """Half the extent of `shape` (orientation R in the frame of u) along the unit vector u."""
    u = np.asarray(u, dtype=float)
    R = np.asarray(R.matrix() if hasattr(R, "matrix") else R, dtype=float)
    if isinstance(shape, BoxShape):
        return float(np.abs(R.T @ u) @ (np.asarray(shape.size) / 2))
    if isinstance(shape, CylinderShape):
        c = abs(float(R[:, 2] @ u))
        return c * shape.length / 2 + shape.radius * float(np.sqrt(max(0.0, 1 - c * c)))
    if isinstance(shape, SphereShape):
        return shape.radius
    if isinstance(shape, BowlShape):
        c = abs(float(R[:, 2] @ u))
        return c * shape.height / 2 + shape.radius * float(np.sqrt(max(0.0, 1 - c * c)))
    raise PlanningError("unsupported_shape", f"no extent for {type(shape).__name__}")

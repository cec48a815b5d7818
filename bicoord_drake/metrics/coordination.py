"""Spatial-temporal coordination metrics of one bimanual trajectory (BiCoord, Sec. 3.2).

For a trajectory of length L with TCP positions ``p^l_t, p^r_t`` and commanded gripper openings
``G^l_t, G^r_t`` (1 = open):

- ``r_t = |p^l_t - p^r_t| / |p^l_1 - p^r_1|``; MRD = min r, ARD = mean r.
- an arm acts at t (``m_t = 1``) if it moved, ``|p_t - p_{t-1}| > move_tol`` (no movement test at
  the first frame), or its gripper is closed, ``G_t < closed_below``.
- SMT = sum_t m^l_t m^r_t; SMP = SMT / L.
- ``SMP_<d = (1/L) sum_t m^l_t m^r_t [r_t < d]``; STI = int_0^1 SMP_<(1-d) dd, computed exactly as
  ``(1/L) sum_t m^l_t m^r_t max(0, 1 - r_t)``.

Everything is vectorized numpy; no Drake.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bicoord_drake.data.trajectory import MIN_INITIAL_DISTANCE

MOVE_TOL = 1e-4
"""Default movement threshold in metres per frame."""
CLOSED_BELOW = 0.5
"""Default gripper opening below which the gripper counts as closed."""


@dataclass(frozen=True)
class CoordinationMetrics:
    """Coordination metrics of one trajectory; fractions, not percent."""

    smt: int
    smp: float
    mrd: float
    ard: float
    sti: float
    length: int


def _as_positions(name: str, value: ArrayLike) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (L, 3), got {arr.shape}")
    return arr


def _as_gripper(name: str, value: ArrayLike) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{name} must have shape (L,), got {arr.shape}")
    return arr


def _validated(
    left_xyz: ArrayLike,
    right_xyz: ArrayLike,
    left_gripper: ArrayLike,
    right_gripper: ArrayLike,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    arrays = (
        _as_positions("left_xyz", left_xyz),
        _as_positions("right_xyz", right_xyz),
        _as_gripper("left_gripper", left_gripper),
        _as_gripper("right_gripper", right_gripper),
    )
    names = ("left_xyz", "right_xyz", "left_gripper", "right_gripper")
    lengths = [len(a) for a in arrays]
    if len(set(lengths)) != 1:
        shown = ", ".join(f"{n}={n_}" for n, n_ in zip(names, lengths, strict=True))
        raise ValueError(f"mismatched trajectory lengths: {shown}")
    if lengths[0] == 0:
        raise ValueError("empty trajectory (length 0)")
    for name, arr in zip(names, arrays, strict=True):
        if not np.isfinite(arr).all():
            raise ValueError(f"{name} contains NaN or inf")
    return arrays


def _acting(
    xyz: np.ndarray, gripper: np.ndarray, move_tol: float, closed_below: float
) -> np.ndarray:
    """m_t: moved since the previous frame (not tested at t = 1) or gripper closed."""
    acting = gripper < closed_below
    step = xyz[1:] - xyz[:-1]
    acting[1:] |= np.einsum("ij,ij->i", step, step) > move_tol * move_tol
    return acting


def _relative_distance_and_both(
    left_xyz: ArrayLike,
    right_xyz: ArrayLike,
    left_gripper: ArrayLike,
    right_gripper: ArrayLike,
    move_tol: float,
    closed_below: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Validate inputs; return r_t and m^l_t m^r_t (bool)."""
    if not move_tol >= 0:
        raise ValueError(f"move_tol must be >= 0, got {move_tol}")
    pl, pr, gl, gr = _validated(left_xyz, right_xyz, left_gripper, right_gripper)
    delta = pl - pr
    dist = np.sqrt(np.einsum("ij,ij->i", delta, delta))
    if dist[0] <= MIN_INITIAL_DISTANCE:
        raise ValueError(
            f"zero initial distance between the arms ({dist[0]:.3g} m at the first frame); "
            "relative distance is undefined"
        )
    both = _acting(pl, gl, move_tol, closed_below) & _acting(pr, gr, move_tol, closed_below)
    return dist / dist[0], both


def coordination_metrics(
    left_xyz: ArrayLike,
    right_xyz: ArrayLike,
    left_gripper: ArrayLike,
    right_gripper: ArrayLike,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> CoordinationMetrics:
    """SMT, SMP, MRD, ARD, STI of one trajectory.

    Args:
        left_xyz, right_xyz: (L, 3) TCP positions in metres.
        left_gripper, right_gripper: (L,) commanded openings, 1 = open.
        move_tol: an arm moved if its TCP travelled more than this since the previous frame.
        closed_below: a gripper is closed when its opening is below this.

    Raises:
        ValueError: wrong shapes, mismatched lengths, empty input, NaN/inf, or zero initial
            distance between the arms.
    """
    r, both = _relative_distance_and_both(
        left_xyz, right_xyz, left_gripper, right_gripper, move_tol, closed_below
    )
    length = len(r)
    smt = int(np.count_nonzero(both))
    sti = float(np.maximum(1.0 - r[both], 0.0).sum()) / length
    return CoordinationMetrics(
        smt=smt,
        smp=smt / length,
        mrd=float(r.min()),
        ard=float(r.mean()),
        sti=sti,
        length=length,
    )


def smp_curve(
    left_xyz: ArrayLike,
    right_xyz: ArrayLike,
    left_gripper: ArrayLike,
    right_gripper: ArrayLike,
    thresholds: ArrayLike,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> np.ndarray:
    """``SMP_<d`` for each threshold d (strict ``r_t < d``); same shape as ``thresholds``.

    The paper's STI curve is ``smp_curve(..., 1 - d)`` against d; its integral over [0, 1] is STI.
    """
    d = np.asarray(thresholds, dtype=np.float64)
    if np.isnan(d).any():
        raise ValueError("thresholds contain NaN")
    r, both = _relative_distance_and_both(
        left_xyz, right_xyz, left_gripper, right_gripper, move_tol, closed_below
    )
    active = np.sort(r[both])
    return np.searchsorted(active, d, side="left") / len(r)


def arm_acting(
    xyz: ArrayLike,
    gripper: ArrayLike,
    *,
    move_tol: float = MOVE_TOL,
    closed_below: float = CLOSED_BELOW,
) -> np.ndarray:
    """``m_t`` of one arm: (L,) bool, it moved since the previous frame or its gripper is closed."""
    p, g = _as_positions("xyz", xyz), _as_gripper("gripper", gripper)
    if len(p) != len(g):
        raise ValueError(f"mismatched trajectory lengths: xyz={len(p)}, gripper={len(g)}")
    return _acting(p, g, move_tol, closed_below)

"""Evaluation metrics of policy rollouts: SR, SSR (BiCoord, Sec. 4.2) and TL."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _as_bool_array(name: str, value: ArrayLike, ndim: int) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    if arr.dtype != np.bool_:
        if not np.isin(arr, (0, 1)).all():
            raise ValueError(f"{name} must hold booleans (or 0/1)")
        arr = arr.astype(bool)
    return arr


def success_rate(successes: ArrayLike) -> float:
    """SR = successes / N for N rollouts; ``successes`` is (N,) booleans."""
    ok = _as_bool_array("successes", successes, 1)
    if ok.size == 0:
        raise ValueError("success_rate needs at least one rollout")
    return float(np.count_nonzero(ok)) / ok.size


def stage_success_rate(scores: ArrayLike, completed: ArrayLike) -> float:
    """SSR = (1/N) sum_i sum_j s_ij c_ij.

    Args:
        scores: stage scores, (M,) shared by all rollouts or (N, M) per rollout.
        completed: (N, M) booleans, whether rollout i completed stage j.
    """
    c = _as_bool_array("completed", completed, 2)
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim not in (1, 2) or s.shape[-1] != c.shape[1] or (s.ndim == 2 and s.shape != c.shape):
        raise ValueError(
            f"scores must have shape (M,) or (N, M) matching completed {c.shape}, got {s.shape}"
        )
    if c.shape[0] == 0:
        raise ValueError("stage_success_rate needs at least one rollout")
    if not np.isfinite(s).all() or (s < 0).any():
        raise ValueError("scores must be finite and non-negative")
    return float((s * c).sum()) / c.shape[0]


def trajectory_length(lengths: ArrayLike, successes: ArrayLike | None = None) -> float | None:
    """TL: mean length (control steps) of the successful rollouts.

    With ``successes`` omitted every trajectory counts (a dataset of demonstrations). Returns
    ``None`` when no rollout succeeded (TL undefined, shown as "-").
    """
    n = np.asarray(lengths, dtype=np.float64)
    if n.ndim != 1:
        raise ValueError(f"lengths must be 1-D, got shape {n.shape}")
    if not np.isfinite(n).all() or (n < 0).any():
        raise ValueError("lengths must be finite and non-negative")
    if successes is not None:
        ok = _as_bool_array("successes", successes, 1)
        if ok.shape != n.shape:
            raise ValueError(f"successes {ok.shape} and lengths {n.shape} differ in shape")
        n = n[ok]
    return float(n.mean()) if n.size else None

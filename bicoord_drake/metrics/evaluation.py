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


def stage_score(scores: ArrayLike, credit: ArrayLike, first: int = 0) -> float:
    """The stage-weighted score of ONE rollout, ``sum_j s_j * c_j`` over stages `first` and
    later (a rollout reset at stage `first` is not paid for the given stages before it).

    `credit` holds each stage's credit in [0, 1]: 1 when it counts, a fraction for partial
    credit (cook: 0.5 with one roll of two), booleans as 0/1. The stage monitor's ``score()``
    (env's ``info["score"]``) and SSR both come from here.
    """
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    c = np.asarray(credit, dtype=np.float64).reshape(-1)
    if s.shape != c.shape:
        raise ValueError(f"{s.size} stage scores but {c.size} credits")
    if not np.isfinite(c).all() or (c < 0).any() or (c > 1).any():
        raise ValueError(f"credits must be in [0, 1], got {c.tolist()}")
    return float((s[first:] * c[first:]).sum())


def stage_success_rate(scores: ArrayLike, completed: ArrayLike, first: int = 0) -> float:
    """SSR = (1/N) sum_i sum_j s_ij c_ij: the mean of :func:`stage_score` over rollouts.

    Args:
        scores: stage scores, (M,) shared by all rollouts or (N, M) per rollout.
        completed: (N, M) credits in [0, 1] of rollout i's stage j (partial credit), or
            booleans (completed or not).
        first: the first stage scored (a stage evaluation from stage `first`).
    """
    c = np.asarray(completed)
    if c.ndim != 2:
        raise ValueError(f"completed must be 2-D, got shape {c.shape}")
    c = c.astype(np.float64)
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim not in (1, 2) or s.shape[-1] != c.shape[1] or (s.ndim == 2 and s.shape != c.shape):
        raise ValueError(
            f"scores must have shape (M,) or (N, M) matching completed {c.shape}, got {s.shape}"
        )
    if c.shape[0] == 0:
        raise ValueError("stage_success_rate needs at least one rollout")
    if not np.isfinite(s).all() or (s < 0).any():
        raise ValueError("scores must be finite and non-negative")
    s = np.broadcast_to(s, c.shape)
    return float(np.mean([stage_score(si, ci, first) for si, ci in zip(s, c, strict=True)]))


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

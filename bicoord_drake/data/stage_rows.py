"""Stage rows, the annotation format of episode files and ``stages/episode{i}.json`` sidecars.

A row is ``[start, end, subgoal, left, right, score]``: frames ``[start, end)`` of one stage, its
sub-goal and per-arm descriptions and its score weight. An episode's rows are contiguous,
half-open and non-empty, covering ``[0, T)``. The stage monitor produces them; the episode writer
and readers check and store them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

ROW_FIELDS = ("start", "end", "subgoal", "left", "right", "score")
"""The fields of one stage row, in order."""


def check_rows(rows: Sequence[Sequence], T: int | None = None) -> None:
    """Raise ValueError unless rows are ``[start, end, subgoal, left, right, score]``,
    contiguous, non-empty, covering ``[0, T)``."""
    expected = 0
    for j, row in enumerate(rows):
        if len(row) != len(ROW_FIELDS):
            raise ValueError(f"stage row {j} must be [start, end, subgoal, left, right, score]")
        start, end = int(row[0]), int(row[1])
        if start != expected or end <= start:
            raise ValueError(
                f"stage row {j} spans [{start}, {end}); rows must be contiguous and non-empty "
                f"starting at {expected}"
            )
        expected = end
    if T is not None and expected != T:
        raise ValueError(f"stage rows cover [0, {expected}), expected [0, {T})")


def stage_index_from_rows(rows: Sequence[Sequence]) -> np.ndarray:
    """(T,) stage index per frame from contiguous half-open rows covering ``[0, T)``."""
    check_rows(rows)
    T = int(rows[-1][1]) if rows else 0
    index = np.empty(T, dtype=np.int64)
    for j, row in enumerate(rows):
        index[int(row[0]) : int(row[1])] = j
    return index

"""Run a task's stage predicates every control step: rollout scores (SSR) and demo annotations.

Frame convention: call :meth:`StageMonitor.update` once per recorded frame, with the state reached
*after* that frame's action (``sim.step(action)`` then ``WorldState.capture(sim, action)``). So
update ``t`` tells whether frame ``t``'s action achieved a sub-goal, and a stage completed at
update ``t`` ends after frame ``t`` (its annotation row ends at ``t + 1``).

Rollouts (PRODUCT.md, Evaluation): a transient stage's own credit is latched (the best value seen
at any update); a persistent stage's is its value at the end (:meth:`finish`, or the latest update
while the rollout runs). A stage counts when its credit is 1 and every stage it depends on counts;
a stage whose dependencies do not count gets no credit. ``score() = sum_j s_j * credit_j``.

Demonstrations: stage ``j`` spans from the end of stage ``j - 1`` to the first update, strictly
after stage ``j - 1`` completed, at which stage ``j`` holds in full; the last stage runs to ``T``.
Rows are ``[start, end, subgoal, left, right, score]``, contiguous, half-open, covering ``[0, T)``,
and each has at least one frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bicoord_drake.stages.stage import Stage, WorldState, resolve_dependencies

_FULL = 1.0 - 1e-9


class StageMonitor:
    """Stage predicates over a rollout or a demonstration (see the module docstring)."""

    def __init__(self, stages: Sequence[Stage], *, given: int = 0) -> None:
        """`given`: the first `given` stages count as done without being evaluated (a rollout
        reset to the start of stage `given`, after them)."""
        self.stages: tuple[Stage, ...] = tuple(stages)
        if not 0 <= given <= len(self.stages):
            raise ValueError(f"given must be in [0, {len(self.stages)}], got {given}")
        self.given = int(given)
        self.dependencies = resolve_dependencies(self.stages)
        self.reset()

    def reset(self) -> None:
        """Forget every update (start a new rollout)."""
        self._history: list[np.ndarray] = []
        self._final: np.ndarray | None = None

    # ---------------------------------------------------------------- stepping
    def update(self, state: WorldState) -> None:
        """Evaluate every stage predicate on the state reached after the current frame."""
        self._history.append(self.evaluate(state))

    def evaluate(self, state: WorldState) -> np.ndarray:
        """Each stage predicate's value on `state`, clipped to [0, 1] (no bookkeeping); given
        stages are 1 and their predicates are not called."""
        return np.array(
            [
                1.0 if j < self.given else min(max(float(s.predicate(state)), 0.0), 1.0)
                for j, s in enumerate(self.stages)
            ]
        )

    def finish(self, state: WorldState | None = None) -> None:
        """End the rollout: persistent stages are judged on `state` (default: the last update)."""
        if state is not None:
            self._final = self.evaluate(state)
        elif self._history:
            self._final = self._history[-1]

    @property
    def frames(self) -> int:
        """Number of updates so far."""
        return len(self._history)

    @property
    def history(self) -> np.ndarray:
        """(frames, S) predicate values per update."""
        return np.array(self._history).reshape(-1, len(self.stages))

    # ---------------------------------------------------------------- rollout scoring
    def credit(self) -> list[float]:
        """Per stage credit in [0, 1] after latching and dependencies."""
        if not self._history:
            return [0.0] * len(self.stages)
        history = self.history
        end = self._final if self._final is not None else history[-1]
        own = [
            history[:, j].max() if s.kind == "transient" else end[j]
            for j, s in enumerate(self.stages)
        ]
        counted: list[bool] = []
        credit: list[float] = []
        for j, deps in enumerate(self.dependencies):
            ok = all(counted[d] for d in deps)
            credit.append(float(own[j]) if ok else 0.0)
            counted.append(ok and own[j] >= _FULL)
        return credit

    def completed(self) -> list[bool]:
        """Per stage: does it count (PRODUCT.md, Evaluation)?"""
        return [c >= _FULL for c in self.credit()]

    def score(self) -> float:
        """Stage-weighted score of the rollout, sum_j s_j * credit_j."""
        return float(sum(s.score * c for s, c in zip(self.stages, self.credit(), strict=True)))

    @property
    def success(self) -> bool:
        """Every stage counts (with persistent stages judged now, or at `finish`)."""
        return all(self.completed())

    # ---------------------------------------------------------------- annotations
    def completion_frames(self) -> list[int | None]:
        """Per stage, the update at which it first held in full strictly after the previous
        stage did (None if it never did)."""
        history = self.history
        frames: list[int | None] = []
        after = -1
        for j in range(len(self.stages)):
            if after is None:
                frames.append(None)
                continue
            hits = np.flatnonzero(history[after + 1 :, j] >= _FULL)
            after = int(after + 1 + hits[0]) if len(hits) else None
            frames.append(after)
        return frames

    def annotations(self, T: int | None = None) -> list[list]:
        """Rows ``[start, end, subgoal, left, right, score]`` covering ``[0, T)``.

        `T` defaults to the number of updates. Raises ValueError when a stage before the last
        never completed or a stage would get no frames.
        """
        T = self.frames if T is None else int(T)
        rows: list[list] = []
        start = 0
        done = self.completion_frames()
        last = len(self.stages) - 1
        for j, stage in enumerate(self.stages):
            if j < last:
                if done[j] is None:
                    raise ValueError(
                        f"stage {j} ({stage.subgoal!r}) never completed; cannot annotate "
                        "a demonstration that did not reach every sub-goal"
                    )
                end = done[j] + 1
            else:
                end = T
            if end <= start or end > T:
                raise ValueError(
                    f"stage {j} ({stage.subgoal!r}) would span frames [{start}, {end}) of T = {T}"
                )
            rows.append([start, end, stage.subgoal, stage.left, stage.right, stage.score])
            start = end
        return rows

    def stage_index(self, T: int | None = None) -> np.ndarray:
        """(T,) index of the stage active at each frame."""
        return stage_index_from_rows(self.annotations(T))


def stage_index_from_rows(rows: Sequence[Sequence]) -> np.ndarray:
    """(T,) stage index per frame from contiguous half-open rows covering ``[0, T)``."""
    check_rows(rows)
    T = int(rows[-1][1]) if rows else 0
    index = np.empty(T, dtype=np.int64)
    for j, row in enumerate(rows):
        index[int(row[0]) : int(row[1])] = j
    return index


def check_rows(rows: Sequence[Sequence], T: int | None = None) -> None:
    """Raise ValueError unless rows are ``[start, end, subgoal, left, right, score]``,
    contiguous, non-empty, covering ``[0, T)``."""
    expected = 0
    for j, row in enumerate(rows):
        if len(row) != 6:
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

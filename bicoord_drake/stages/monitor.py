"""Run a task's stage predicates every control step: rollout scores (SSR) and demo annotations.

Frame convention: call :meth:`StageMonitor.update` once per recorded frame, with the state reached
*after* that frame's action (``sim.step(action)`` then ``WorldState.capture(sim, action)``). So
update ``t`` tells whether frame ``t``'s action achieved a sub-goal, and a stage completed at
update ``t`` ends after frame ``t`` (its annotation row ends at ``t + 1``).

Counting (PRODUCT.md, Evaluation), the same rule for rollouts and demonstrations: a stage's
credit comes only from updates *strictly after* the update at which every stage it depends on
counted (given stages count before the first update). A transient stage's credit is the best
value at such an update (latched); a persistent stage's is its value at the end (:meth:`finish`,
or the latest update), and it needs at least one such update. A stage counts when its credit
is 1; it *completed* at the first such update at which it held in full. So the same events in
the wrong order give the dependent stage 0. ``score() = stage_score(scores, credit, given)``.

Demonstrations: stage ``j``'s row ends after the update at which it completed (the last stage
runs to ``T``). Rows are ``[start, end, subgoal, left, right, score]``, contiguous, half-open,
covering ``[0, T)``, and each has at least one frame. :attr:`StageMonitor.success` holds only
when every stage counts *and* these rows exist, so success and :meth:`annotations` agree.

Stateful predicates (e.g. :func:`~bicoord_drake.stages.predicates.held_for`) are reset by
:meth:`StageMonitor.reset`, which the constructor calls: one monitor per episode, or a reset
before each.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bicoord_drake.data.stage_rows import stage_index_from_rows
from bicoord_drake.metrics.evaluation import stage_score
from bicoord_drake.stages.predicates import reset_predicate
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
        """Start a new episode: forget every update and reset every stateful predicate."""
        self._history: list[np.ndarray] = []
        self._final: np.ndarray | None = None
        for stage in self.stages:
            reset_predicate(stage.predicate)

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
    def _walk(self) -> tuple[list[float], list[bool], list[int | None]]:
        """(credit, counted, completed-at update) per stage (see the module docstring)."""
        S = len(self.stages)
        if not self._history:
            given = [j < self.given for j in range(S)]
            return [float(g) for g in given], given, [-1 if g else None for g in given]
        H = self.history.copy()
        end = self._final if self._final is not None else H[-1]
        persistent = np.array([s.kind == "persistent" for s in self.stages])
        H[-1, persistent] = end[persistent]
        credit: list[float] = [1.0] * self.given
        counted: list[bool] = [True] * self.given
        at: list[int | None] = [-1] * self.given
        for j in range(self.given, len(self.stages)):
            deps = self.dependencies[j]
            own, done, first = 0.0, False, None
            if all(counted[d] for d in deps):
                after = max([at[d] for d in deps], default=-1) + 1
                window = H[after:, j]
                if len(window):
                    own = float(window.max() if self.stages[j].kind == "transient" else window[-1])
                hits = np.flatnonzero(window >= _FULL)
                done = own >= _FULL and len(hits) > 0
                first = int(after + hits[0]) if done else None
            credit.append(own)
            counted.append(done)
            at.append(first)
        return credit, counted, at

    def credit(self) -> list[float]:
        """Per stage credit in [0, 1] after latching and dependencies."""
        return self._walk()[0]

    def completed(self) -> list[bool]:
        """Per stage: does it count (PRODUCT.md, Evaluation)?"""
        return self._walk()[1]

    def score(self) -> float:
        """Stage-weighted score of the rollout: :func:`stage_score` of the credits of the
        stages it was not given (a rollout reset at stage k is scored on stages k and later)."""
        return stage_score([s.score for s in self.stages], self.credit(), self.given)

    @property
    def success(self) -> bool:
        """Every stage counts (persistent stages judged now, or at `finish`) and the
        demonstration's stage rows exist (:meth:`annotations` would succeed)."""
        return self._row_ends(self.frames)[0] is not None

    # ---------------------------------------------------------------- annotations
    def completion_frames(self) -> list[int | None]:
        """Per stage, the update at which it completed (None if it does not count)."""
        return self._walk()[2]

    def _row_ends(self, T: int) -> tuple[list[int] | None, str]:
        """End frame of every stage row, or (None, why not)."""
        _, counted, at = self._walk()
        ends: list[int] = []
        start = 0
        last = len(self.stages) - 1
        for j, stage in enumerate(self.stages):
            if not counted[j]:
                return None, f"stage {j} ({stage.subgoal!r}) did not count"
            if j < self.given:  # given before the first update: no frames of its own
                ends.append(0)
                continue
            end = T if j == last else int(at[j]) + 1
            if end <= start or end > T:
                return None, (
                    f"stage {j} ({stage.subgoal!r}) would span frames [{start}, {end}) of T = {T}"
                )
            ends.append(end)
            start = end
        return ends, ""

    def annotations(self, T: int | None = None) -> list[list]:
        """Rows ``[start, end, subgoal, left, right, score]`` covering ``[0, T)``.

        `T` defaults to the number of updates. Raises ValueError when a stage does not count or
        a stage would get no frames (never when :attr:`success` holds and `T` is the number of
        updates).
        """
        if self.given:
            raise ValueError("a rollout that starts at a later stage is not a demonstration")
        T = self.frames if T is None else int(T)
        ends, why = self._row_ends(T)
        if ends is None:
            raise ValueError(f"cannot annotate the demonstration: {why}")
        starts = [0, *ends[:-1]]
        return [
            [a, b, s.subgoal, s.left, s.right, s.score]
            for a, b, s in zip(starts, ends, self.stages, strict=True)
        ]

    def stage_index(self, T: int | None = None) -> np.ndarray:
        """(T,) index of the stage active at each frame."""
        return stage_index_from_rows(self.annotations(T))

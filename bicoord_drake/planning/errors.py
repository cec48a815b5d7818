"""Typed planning failures: every solver result is checked and a failure says why."""

from __future__ import annotations


class PlanningError(RuntimeError):
    """A plan could not be found. `reason` is a short machine-friendly tag (e.g. 'ik_infeasible',
    'path_in_collision', 'timing_limits'); the message says which constraint failed."""

    def __init__(self, reason: str, message: str = "") -> None:
        self.reason = reason
        super().__init__(f"{reason}: {message}" if message else reason)

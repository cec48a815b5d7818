"""Wall seconds per phase of a piece of work (build, planning, physics, rendering, ...)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager


class Stopwatch:
    """Accumulates wall time under named phases.

    >>> clock = Stopwatch()
    >>> with clock("physics"):
    ...     pass
    >>> sorted(clock.seconds())
    ['physics']
    """

    def __init__(self) -> None:
        self._seconds: dict[str, float] = {}

    @contextmanager
    def __call__(self, phase: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.add(phase, time.perf_counter() - t0)

    def add(self, phase: str, seconds: float) -> None:
        self._seconds[phase] = self._seconds.get(phase, 0.0) + seconds

    def seconds(self, digits: int = 3) -> dict[str, float]:
        """Seconds per phase, rounded, in the order the phases were first timed."""
        return {phase: round(s, digits) for phase, s in self._seconds.items()}

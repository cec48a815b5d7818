"""Fixtures shared by the whole suite."""

from __future__ import annotations

import pytest


@pytest.fixture
def temporary_tasks(monkeypatch):
    """``register(*classes)``: task classes registered for this test only. The Gymnasium ids
    made for them meanwhile (``make_env`` registers every task it finds) leave with them, so
    the registry holds only the built-in tasks' ids afterwards (test_gym_env checks it)."""
    import gymnasium

    from bicoord_drake.gym_env import env_id
    from bicoord_drake.tasks import registry

    names: list[str] = []

    def register(*classes) -> None:
        for cls in classes:
            monkeypatch.setitem(registry._TASKS, cls.name, cls)
            names.append(cls.name)

    yield register
    for name in names:
        gymnasium.registry.pop(env_id(name), None)

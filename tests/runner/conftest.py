"""Shared fixtures of the runner tests: a local Ray instance of two CPUs, and a stand-in for the
``ray`` module whose nodes can die on demand (no Ray process involved)."""

from __future__ import annotations

import sys
import types
from dataclasses import dataclass
from typing import Any

import pytest


@pytest.fixture(scope="session")
def ray_cluster():
    """``ray.init(num_cpus=2)``; yields its GCS address (for drivers in other processes)."""
    ray = pytest.importorskip("ray", reason="the Ray tests need pip install -e '.[ray]'")
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()


class RayError(Exception):
    pass


class WorkerCrashedError(RayError):
    pass


class NodeDiedError(RayError):
    pass


class ObjectLostError(RayError):
    pass


class LocalRayletDiedError(RayError):
    pass


class RayTaskError(RayError):
    def __init__(self, cause: BaseException) -> None:
        super().__init__(str(cause))
        self.cause = cause


@dataclass(eq=False)  # hashable by identity, as ObjectRefs are
class Handle:
    value: Any = None
    error: BaseException | None = None


class FakeRay(types.ModuleType):
    """Enough of ``ray`` for :class:`~bicoord_drake.runner.backends.RayBackend`: already
    initialized, with `cpus` CPUs; a job runs when it is submitted. The next jobs fail with the
    errors in `failures` (a worker lost; the nodes live on). After `die_after` jobs the cluster
    dies: every later job fails with `death` and :meth:`nodes` reports no live node
    (``gcs_down``: the GCS cannot even be asked)."""

    def __init__(self, cpus: int = 4) -> None:
        super().__init__("ray")
        self.cpus = cpus
        self.die_after: int | None = None
        self.death: type[RayError] = NodeDiedError
        self.alive = True
        self.gcs_down = False
        self.failures: list[type[RayError]] = []
        self.submitted: list[tuple] = []
        self.exceptions = types.SimpleNamespace(
            WorkerCrashedError=WorkerCrashedError,
            NodeDiedError=NodeDiedError,
            ObjectLostError=ObjectLostError,
            LocalRayletDiedError=LocalRayletDiedError,
            RayTaskError=RayTaskError,
        )

    def is_initialized(self) -> bool:
        return True

    def cluster_resources(self) -> dict[str, float]:
        return {"CPU": float(self.cpus), "memory": 1e9}

    def remote(self, **options: Any):
        def wrap(fn):
            return types.SimpleNamespace(remote=lambda *args: self._run(fn, args))

        return wrap

    def _run(self, fn, args: tuple) -> Handle:
        self.submitted.append(args)
        if self.die_after is not None and len(self.submitted) > self.die_after:
            self.alive = False
            return Handle(error=self.death("the node died (stand-in)"))
        if self.failures:
            return Handle(error=self.failures.pop(0)("the worker died (stand-in)"))
        try:
            return Handle(value=fn(*args))
        except Exception as exc:  # noqa: BLE001 - delivered by get(), as Ray does
            return Handle(error=RayTaskError(exc))

    def wait(self, handles: list[Handle], num_returns: int = 1):
        return handles[:num_returns], handles[num_returns:]

    def get(self, handle: Handle) -> Any:
        if handle.error is not None:
            raise handle.error
        return handle.value

    def nodes(self) -> list[dict[str, Any]]:
        if self.gcs_down:
            raise ConnectionError("GCS unreachable (stand-in)")
        return [{"NodeID": "head", "Alive": self.alive}]

    def shutdown(self) -> None:
        pass


@pytest.fixture
def fake_ray(monkeypatch) -> FakeRay:
    """A :class:`FakeRay` in place of the ``ray`` module for this test."""
    fake = FakeRay()
    monkeypatch.setitem(sys.modules, "ray", fake)
    return fake

"""Shared fixtures of the runner tests: a local Ray instance of two CPUs, and a stand-in for the
``ray`` module whose nodes can die on demand (no Ray process involved)."""

from __future__ import annotations

import sys
import time
import types
from dataclasses import dataclass
from typing import Any

import pytest


@pytest.fixture
def isolated_cache(tmp_path, monkeypatch):
    """Keep the expert-check cache out of the home directory (``$BICOORD_CACHE``)."""
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))


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
    lost: bool = False  # never finishes: ray.wait never returns it


class FakeRay(types.ModuleType):
    """Enough of ``ray`` for :class:`~bicoord_drake.runner.backends.RayBackend`: already
    initialized, with `cpus` CPUs on the head node and `worker_nodes` (name -> CPUs) besides; a
    job runs when it is submitted. The next jobs fail with the errors in `failures` (a worker
    lost; the nodes live on). After `die_after` jobs the cluster dies: every later job fails
    with `death` and :meth:`nodes` reports no live node (``gcs_down``: the GCS cannot even be
    asked). :meth:`kill_node` ends a worker node without a word to the jobs: a job submitted
    while `hang` is set, or while no live node has a CPU, never finishes (Ray queues it for a
    node that never comes); :meth:`wait` on such jobs fails the test when it has no timeout or
    has waited `patience` seconds in all (instead of hanging it)."""

    def __init__(self, cpus: int = 4) -> None:
        super().__init__("ray")
        self.cpus = cpus
        self.worker_nodes: dict[str, int] = {}
        self.dead: set[str] = set()
        self.hang = False
        self.cancelled: list[Handle] = []
        self.patience = 10.0
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
        cpus = sum(node["Resources"].get("CPU", 0) for node in self.nodes() if node["Alive"])
        return {"CPU": float(cpus), "memory": 1e9}

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
        if self.hang or not self.cluster_resources()["CPU"]:
            return Handle(lost=True)
        try:
            return Handle(value=fn(*args))
        except Exception as exc:  # noqa: BLE001 - delivered by get(), as Ray does
            return Handle(error=RayTaskError(exc))

    def wait(self, handles: list[Handle], num_returns: int = 1, timeout: float | None = None):
        done = [h for h in handles if not h.lost][:num_returns]
        if not done:
            assert timeout is not None, "ray.wait without a timeout on a lost job: blocks forever"
            assert self.patience > 0, "ray.wait on lost jobs: nothing stopped the wait"
            time.sleep(min(timeout, self.patience))
            self.patience -= timeout
        return done, [h for h in handles if h not in done]

    def cancel(self, handle: Handle, force: bool = False) -> None:
        self.cancelled.append(handle)

    def get(self, handle: Handle) -> Any:
        assert not handle.lost, "ray.get on a lost job: blocks forever"
        if handle.error is not None:
            raise handle.error
        return handle.value

    def nodes(self) -> list[dict[str, Any]]:
        if self.gcs_down:
            raise ConnectionError("GCS unreachable (stand-in)")
        cpus = {"head": self.cpus, **self.worker_nodes}
        return [
            self._node(name, n, self.alive and name not in self.dead) for name, n in cpus.items()
        ]

    @staticmethod
    def _node(name: str, cpus: int, alive: bool) -> dict[str, Any]:
        """An entry of ``ray.nodes()``: a dead node, or a head started with --num-cpus 0, lists
        no CPU."""
        resources = {"CPU": float(cpus)} if cpus else {}
        return {
            "NodeID": name,
            "Alive": alive,
            "Resources": {**resources, "memory": 1e9} if alive else {},
        }

    def kill_node(self, *names: str) -> None:
        self.dead.update(names)

    def shutdown(self) -> None:
        pass


@pytest.fixture
def fake_ray(monkeypatch) -> FakeRay:
    """A :class:`FakeRay` in place of the ``ray`` module for this test."""
    fake = FakeRay()
    monkeypatch.setitem(sys.modules, "ray", fake)
    return fake

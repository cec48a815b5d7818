"""Where independent jobs (one seed, one rollout) run: here, in local processes, or on Ray.

A :class:`Backend` runs module-level functions and hands their results back as they finish::

    with make_backend("ray", workers=0, address="auto") as backend:
        jobs = [backend.submit(fn, seed) for seed in range(backend.slots)]
        while jobs:
            job = backend.wait(jobs)         # the first to finish (ray.wait / futures.wait)
            jobs.remove(job)
            value = backend.result(job)      # its return value; re-raises its exception

- ``local`` with one worker runs each job in this process when its result is asked for;
- ``local`` with N > 1 workers runs jobs in N spawned processes (``workers=0``: one per core of
  this machine, :func:`local_workers`);
- ``ray`` runs each job as a Ray task (1 CPU) on a local Ray instance started here, or on the
  cluster at ``address`` (``auto``: the one ``ray start`` made on this node); ``workers=0`` keeps
  one job in flight per CPU of the cluster. A worker process that dies during a job (killed, out
  of memory, node lost) makes Ray retry the job on another worker, up to ``RAY_RETRIES`` times;
  after that :meth:`Backend.result` raises :class:`WorkerLost`, or :class:`ClusterLost` when no
  node is left to run anything (this machine's raylet died, or no node of the cluster is alive):
  then every further job would be lost too. Exceptions raised by the job itself are not retried.

Workers are quiet: Drake's log and, on Ray, the workers' stdout/stderr stay off the driver's
terminal unless ``verbose`` (jobs call :func:`quiet_worker` first).
"""

from __future__ import annotations

import logging
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from multiprocessing import get_context
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    import argparse

BackendName = Literal["local", "ray"]
BACKENDS: tuple[str, ...] = ("local", "ray")
RAY_RETRIES = 3
"""Times Ray re-runs a job whose worker process died (its default for tasks, made explicit)."""


class WorkerLost(RuntimeError):
    """The process running a job died (and, on Ray, so did every retry)."""


class ClusterLost(RuntimeError):
    """No node is left to run jobs (the Ray cluster has no live node, or this machine's raylet
    died): the run must stop, and can resume once the cluster is back."""


def local_workers(workers: int) -> int:
    """Processes a local run uses: `workers`, or for 0 one per core this process may use."""
    if workers > 0:
        return workers
    try:
        cores = len(os.sched_getaffinity(0))  # honours taskset / cgroup CPU sets
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, cores)


def quiet_worker(verbose: bool = False) -> None:
    """Silence Drake's INFO/WARNING log in a worker (call after pydrake is imported: importing
    it sets the level)."""
    logging.getLogger("drake").setLevel(logging.DEBUG if verbose else logging.ERROR)


class Backend(ABC):
    """Runs jobs; :attr:`slots` is how many to keep in flight to use every worker."""

    slots: int = 1

    @abstractmethod
    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        """Start ``fn(*args)``; returns a handle for :meth:`wait` and :meth:`result`."""

    @abstractmethod
    def wait(self, handles: Sequence[Any]) -> Any:
        """Block until one of `handles` has finished; return it."""

    @abstractmethod
    def result(self, handle: Any) -> Any:
        """The finished job's value; re-raises its exception (:class:`WorkerLost` if its process
        died)."""

    def close(self) -> None:  # noqa: B027 - nothing to release by default
        """Stop unfinished jobs and release the workers."""

    def describe(self) -> str:
        return f"{type(self).__name__}({self.slots} workers)"

    def __enter__(self) -> Backend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class InlineBackend(Backend):
    """One worker: this process, running each job when its result is asked for (so a job
    submitted is in flight until then, as on the other backends)."""

    slots = 1

    def __init__(self) -> None:
        self._jobs: dict[Future, tuple[Callable[..., Any], tuple]] = {}

    def submit(self, fn: Callable[..., Any], *args: Any) -> Future:
        future: Future = Future()
        self._jobs[future] = (fn, args)
        return future

    def wait(self, handles: Sequence[Future]) -> Future:
        return handles[0]

    def result(self, handle: Future) -> Any:
        if handle in self._jobs:
            fn, args = self._jobs.pop(handle)
            try:
                handle.set_result(fn(*args))
            except Exception as exc:  # noqa: BLE001 - re-raised below, as other backends do
                handle.set_exception(exc)
        return handle.result()

    def describe(self) -> str:
        return "local (this process)"


class ProcessBackend(Backend):
    """A pool of `workers` spawned processes on this machine."""

    def __init__(self, workers: int, verbose: bool = False) -> None:
        self.slots = workers
        self._verbose = verbose
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        threads = rasterizer_threads(os.cpu_count() or 1, self.slots)
        return ProcessPoolExecutor(
            max_workers=self.slots,
            mp_context=get_context("spawn"),
            initializer=_init_process,
            initargs=(threads, self._verbose),
        )

    def submit(self, fn: Callable[..., Any], *args: Any) -> Future:
        from concurrent.futures.process import BrokenProcessPool

        try:
            return self._pool.submit(fn, *args)
        except BrokenProcessPool:  # a worker died: its jobs failed with WorkerLost; go on
            self._pool.shutdown(wait=False)
            self._pool = self._new_pool()
            return self._pool.submit(fn, *args)

    def wait(self, handles: Sequence[Future]) -> Future:
        done, _ = wait_futures(handles, return_when=FIRST_COMPLETED)
        return next(h for h in handles if h in done)

    def result(self, handle: Future) -> Any:
        from concurrent.futures.process import BrokenProcessPool

        try:
            return handle.result()
        except BrokenProcessPool as exc:
            raise WorkerLost(f"a worker process died: {exc}") from exc

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def describe(self) -> str:
        return f"local ({self.slots} processes)"


def rasterizer_threads(cores: int, workers: int) -> str:
    """Mesa llvmpipe's LP_NUM_THREADS for each of `workers` processes on `cores` cores.

    Left alone, llvmpipe starts one rasterizer thread per core in every worker. A worker with a
    core of its own rasterizes in its own thread ("0"): 12-16 % less time per frame than one
    separate rasterizer thread (benchmarks/bench_render_threads.md)."""
    share = cores // max(1, workers)
    return "0" if share <= 1 else str(share)


def _init_process(threads: str, verbose: bool) -> None:
    os.environ["LP_NUM_THREADS"] = threads
    if not verbose:
        # Spawned workers share the terminal: keep warnings of imports and solvers off it.
        import warnings

        warnings.simplefilter("ignore")
    quiet_worker(verbose)


class RayBackend(Backend):
    """Ray tasks of one CPU each, on a local instance or the cluster at `address`.

    `workers` is how many jobs are in flight (0: every CPU of the cluster, at least 1). The Ray
    instance is started here when none is running in this process and `address` is None, and
    shut down by :meth:`close`; a Ray already initialized by the caller (e.g.
    ``ray.init(num_cpus=2)``) is used as it is and left running.
    """

    def __init__(self, workers: int = 0, address: str | None = None, verbose: bool = False):
        try:
            import ray
        except ImportError:
            raise ImportError(
                "the Ray backend needs Ray: pip install -e '.[ray]' (or pip install 'ray>=2.40')"
            ) from None
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            options: dict[str, Any] = {"include_dashboard": False} if address is None else {}
            ray.init(
                address=address or "local",  # None could join a cluster found on this node
                log_to_driver=verbose,
                logging_level=logging.INFO if verbose else logging.ERROR,
                runtime_env={"env_vars": {"LP_NUM_THREADS": rasterizer_threads(1, 1)}},
                **options,
            )
            self._started = True
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.slots = workers if workers > 0 else max(1, cpus)
        self.cpus = cpus
        self._remote: dict[Callable, Any] = {}

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        if fn not in self._remote:
            self._remote[fn] = self._ray.remote(
                num_cpus=1, max_retries=RAY_RETRIES, retry_exceptions=False
            )(fn)
        return self._remote[fn].remote(*args)

    def wait(self, handles: Sequence[Any]) -> Any:
        done, _ = self._ray.wait(list(handles), num_returns=1)
        return done[0]

    def result(self, handle: Any) -> Any:
        exceptions = self._ray.exceptions
        try:
            return self._ray.get(handle)
        except (
            exceptions.WorkerCrashedError,
            exceptions.NodeDiedError,
            exceptions.ObjectLostError,
            exceptions.LocalRayletDiedError,
        ) as exc:
            # This machine's raylet gone: no job of this driver can be scheduled any more,
            # whatever the other nodes' state (the GCS may not have noticed yet).
            if isinstance(exc, exceptions.LocalRayletDiedError) or not self.alive():
                raise ClusterLost(
                    f"the Ray cluster has no live node ({type(exc).__name__})"
                ) from exc
            raise WorkerLost(
                f"its Ray worker died {RAY_RETRIES + 1} times ({type(exc).__name__})"
            ) from exc
        except exceptions.RayTaskError as exc:
            cause = getattr(exc, "cause", None)
            if isinstance(cause, BaseException):
                raise cause from exc
            raise

    def alive(self) -> bool:
        """Whether any node of the cluster is alive (False when the GCS cannot be reached)."""
        try:
            nodes = self._ray.nodes()
        except Exception:  # noqa: BLE001 - no answer from the GCS: no cluster to run on
            return False
        return any(node.get("Alive") for node in nodes)

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()

    def describe(self) -> str:
        return f"ray ({self.slots} in flight, {self.cpus} CPUs in the cluster)"


def make_backend(
    name: str, workers: int = 0, address: str | None = None, verbose: bool = False
) -> Backend:
    """The backend called `name` (``local`` or ``ray``) with `workers` jobs in flight; 0 means
    one per core of this machine (:func:`local_workers`), or on Ray one per CPU of the cluster.
    One local worker runs the jobs in this process."""
    if name == "local":
        if address:
            raise ValueError("ray_address is for the ray backend: add --backend ray")
        count = local_workers(workers)
        return ProcessBackend(count, verbose) if count > 1 else InlineBackend()
    if name == "ray":
        return RayBackend(workers, address, verbose)
    raise ValueError(f"unknown backend {name!r}; backends: {', '.join(BACKENDS)}")


def add_backend_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """The command-line options that choose a backend: ``--workers`` (`what` runs in parallel:
    "seeds", "rollouts"), ``--backend`` and ``--ray-address`` (shared by scripts/generate.py and
    scripts/evaluate.py)."""
    parser.add_argument(
        "--workers",
        type=int,
        default=0,
        metavar="N",
        help=f"{what} in flight (default: one per core of this machine, {local_workers(0)} here; "
        "with --backend ray one per CPU of the cluster); 1 runs them in this process",
    )
    parser.add_argument(
        "--backend",
        default="local",
        choices=("local", "ray"),
        help="local processes (default) or Ray (pip install -e '.[ray]')",
    )
    parser.add_argument(
        "--ray-address",
        help="join this Ray cluster (auto | HOST:PORT); default: start a local Ray instance",
    )

"""Backends: jobs come back with their values or their exceptions; Ray retries a killed worker."""

import os
import signal
import time

import pytest

from bicoord_drake.runner.backends import (
    InlineBackend,
    ProcessBackend,
    RayBackend,
    WorkerLost,
    make_backend,
    rasterizer_threads,
)


def square(x: int) -> int:
    return x * x


def fail(x: int) -> int:
    raise KeyError(f"no value for {x}")


def slow_pid(marker: str, seconds: float) -> int:
    """Append this process's pid to `marker`, sleep, return the pid."""
    with open(marker, "a") as fh:
        fh.write(f"{os.getpid()}\n")
    time.sleep(seconds)
    return os.getpid()


def drain(backend, fn, items) -> list:
    jobs = [backend.submit(fn, x) for x in items]
    out = []
    while jobs:
        job = backend.wait(jobs)
        jobs.remove(job)
        out.append(backend.result(job))
    return out


@pytest.fixture(scope="module")
def ray_backend(ray_cluster):
    with RayBackend(workers=2) as backend:
        yield backend


def test_unknown_backend_lists_the_valid_ones():
    with pytest.raises(ValueError, match="local, ray"):
        make_backend("slurm")


def test_a_ray_address_needs_the_ray_backend():
    with pytest.raises(ValueError, match="ray"):
        make_backend("local", address="auto")


def test_inline_and_process_pool_return_every_value():
    assert make_backend("local", workers=1).slots == 1
    assert drain(InlineBackend(), square, range(4)) == [0, 1, 4, 9]
    with ProcessBackend(2) as backend:
        assert sorted(drain(backend, square, range(6))) == [0, 1, 4, 9, 16, 25]


def test_a_killed_local_process_is_a_lost_job_and_the_pool_goes_on(tmp_path):
    marker = tmp_path / "pids"
    with ProcessBackend(2) as backend:
        job = backend.submit(slow_pid, str(marker), 30.0)
        deadline = time.time() + 120
        while not marker.exists() and time.time() < deadline:
            time.sleep(0.1)
        os.kill(int(marker.read_text().split()[0]), signal.SIGKILL)
        with pytest.raises(WorkerLost):
            backend.result(backend.wait([job]))
        assert sorted(drain(backend, square, range(3))) == [0, 1, 4]


def test_a_job_exception_reaches_the_driver_with_its_type(ray_backend):
    for backend in (InlineBackend(), ray_backend):
        job = backend.submit(fail, 3)
        with pytest.raises(KeyError, match="no value for 3"):
            backend.result(backend.wait([job]))


def test_ray_backend_uses_the_callers_instance(ray_backend):
    assert ray_backend.slots == 2 and ray_backend.cpus == 2
    assert sorted(drain(ray_backend, square, range(5))) == [0, 1, 4, 9, 16]


def test_ray_retries_a_job_whose_worker_is_killed(ray_backend, tmp_path):
    marker = tmp_path / "pids"
    job = ray_backend.submit(slow_pid, str(marker), 4.0)
    deadline = time.time() + 60
    while not marker.exists() and time.time() < deadline:
        time.sleep(0.1)
    first = int(marker.read_text().split()[0])
    os.kill(first, signal.SIGKILL)
    pid = ray_backend.result(ray_backend.wait([job]))
    assert pid != first
    assert [int(p) for p in marker.read_text().split()] == [first, pid]


def test_a_worker_with_one_core_rasterizes_in_its_own_thread():
    assert rasterizer_threads(cores=2, workers=2) == "0"
    assert rasterizer_threads(cores=2, workers=4) == "0"
    assert rasterizer_threads(cores=8, workers=2) == "4"

"""A local Ray instance of two CPUs, shared by the runner tests that need one."""

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

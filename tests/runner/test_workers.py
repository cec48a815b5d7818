"""--workers defaults to every core (every CPU of a Ray cluster); an explicit count is kept."""

import importlib.util
from pathlib import Path

import pytest

import bicoord_drake.runner.backends as backends
import bicoord_drake.runner.evaluate as evaluate_module
import bicoord_drake.runner.generate as gen
from bicoord_drake.runner.backends import (
    InlineBackend,
    ProcessBackend,
    RayBackend,
    local_workers,
    make_backend,
)
from bicoord_drake.runner.evaluate import EvaluateConfig
from bicoord_drake.runner.generate import GenerateConfig

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def cores(monkeypatch):
    """This machine has `cores.n` cores (set it before use)."""

    class Cores:
        n = 6

    monkeypatch.setattr(backends.os, "sched_getaffinity", lambda pid: set(range(Cores.n)))
    return Cores


def test_zero_workers_means_every_core(cores):
    assert local_workers(0) == 6 and local_workers(3) == 3 and local_workers(1) == 1
    cores.n = 1
    assert local_workers(0) == 1


def test_without_affinity_the_core_count_is_used(monkeypatch):
    monkeypatch.delattr(backends.os, "sched_getaffinity", raising=False)
    monkeypatch.setattr(backends.os, "cpu_count", lambda: 5)
    assert local_workers(0) == 5
    monkeypatch.setattr(backends.os, "cpu_count", lambda: None)
    assert local_workers(0) == 1


def test_the_default_local_backend_has_a_process_per_core(cores):
    with make_backend("local") as backend:  # no process starts before a job is submitted
        assert isinstance(backend, ProcessBackend) and backend.slots == 6
    with make_backend("local", workers=2) as backend:
        assert backend.slots == 2
    assert isinstance(make_backend("local", workers=1), InlineBackend)
    cores.n = 1
    assert isinstance(make_backend("local"), InlineBackend)


def test_the_default_ray_backend_keeps_every_cluster_cpu_busy(fake_ray):
    fake_ray.cpus = 12
    assert RayBackend().slots == 12 and RayBackend(workers=3).slots == 3
    assert make_backend("ray").slots == 12


def test_evaluation_is_parallel_by_default_on_a_multicore_machine(cores):
    config = EvaluateConfig(task="jigsaw", policy="noop")
    assert config.workers == 0 and config.parallel
    assert not config.model_copy(update={"workers": 1}).parallel
    cores.n = 1
    assert not config.parallel
    assert config.model_copy(update={"backend": "ray"}).parallel


@pytest.mark.parametrize("name", ["generate", "evaluate"])
def test_cli_default_and_explicit_workers(name, monkeypatch, capsys, tmp_path):
    """The scripts pass --workers to the run unchanged: 0 (every core) unless given."""
    seen = []

    def run(config, progress=None):
        seen.append(config.workers)
        raise ValueError("stopped before any seed (stand-in)")

    target = gen if name == "generate" else evaluate_module
    monkeypatch.setattr(target, "generate_dataset" if name == "generate" else "evaluate", run)
    spec = importlib.util.spec_from_file_location(f"{name}_cli", ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    argv = ["--task", "jigsaw", "--out", str(tmp_path)]
    argv += ["--policy", "noop"] if name == "evaluate" else []
    assert module.main(argv) == 1 and module.main([*argv, "--workers", "3"]) == 1
    assert seen == [0, 3] and "stand-in" in capsys.readouterr().err


def test_help_names_the_default(capsys):
    spec = importlib.util.spec_from_file_location("generate_cli", ROOT / "scripts" / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with pytest.raises(SystemExit):
        module.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"one per core of this machine, {local_workers(0)} here" in text
    assert GenerateConfig(task="jigsaw").workers == 0

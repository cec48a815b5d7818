"""A Ray cluster whose last node died: the run stops at the first lost job, records nothing for
the seeds in flight, says to run the same command again, and that run resumes. Simulated with a
stand-in ``ray`` module (conftest.FakeRay): no Ray process is started or killed."""

import importlib.util
import json
from pathlib import Path

import pytest

import bicoord_drake.runner.generate as gen
from bicoord_drake.runner.backends import ClusterLost, RayBackend, WorkerLost
from bicoord_drake.runner.generate import GenerateConfig, SeedOutcome, generate
from tests.runner.conftest import LocalRayletDiedError, NodeDiedError, WorkerCrashedError

ROOT = Path(__file__).resolve().parents[2]


def script(name: str):
    spec = importlib.util.spec_from_file_location(f"{name}_cli", ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def square(x: int) -> int:
    return x * x


def test_a_lost_worker_on_a_live_cluster_is_one_lost_job(fake_ray):
    backend = RayBackend(workers=2)
    fake_ray.failures = [WorkerCrashedError]
    with pytest.raises(WorkerLost, match="WorkerCrashedError"):
        backend.result(backend.wait([backend.submit(square, 3)]))
    assert backend.result(backend.submit(square, 5)) == 25  # the run goes on


@pytest.mark.parametrize(
    "error,alive,gcs_down",
    [
        (NodeDiedError, False, False),  # the GCS reports no live node
        (WorkerCrashedError, False, False),
        (NodeDiedError, True, True),  # the GCS cannot be reached at all
        (LocalRayletDiedError, True, False),  # this machine's raylet: whatever the GCS says yet
    ],
)
def test_no_live_node_is_a_lost_cluster(fake_ray, error, alive, gcs_down):
    backend = RayBackend(workers=2)
    fake_ray.failures = [error]
    job = backend.submit(square, 3)
    fake_ray.alive, fake_ray.gcs_down = alive, gcs_down
    with pytest.raises(ClusterLost, match="no live node") as info:
        backend.result(backend.wait([job]))
    assert error.__name__ in str(info.value) and not isinstance(info.value, WorkerLost)


def fake_episode(config, seed, staging):
    """Even seeds keep an episode (bytes), odd seeds fail: no physics."""
    if seed % 2:
        return SeedOutcome(config.task, seed, False, "planning: no grasp (stand-in)")
    files = {k: f"seed {seed} {k}".encode() for k in ("instructions", "stages", "video", "episode")}
    return SeedOutcome(config.task, seed, True, frames=10, worker="here:1", files=files)


@pytest.fixture
def episodes(monkeypatch):
    monkeypatch.setattr(gen, "produce_episode", fake_episode)
    monkeypatch.setattr(gen, "_summary", summary)


def summary(layout, manifest):
    kept = manifest.successes
    return gen.GenerateSummary(
        layout.root, len(kept), len(manifest.episodes), manifest.failures, None, None, None
    )


def manifest_seeds(out: Path) -> list[tuple[int, bool, str | None]]:
    data = json.loads((out / "jigsaw" / "default" / "manifest.json").read_text())
    return [(e["seed"], e["success"], e["reason"]) for e in data["episodes"]]


def test_generation_stops_at_once_records_nothing_lost_and_resumes(fake_ray, episodes, tmp_path):
    config = GenerateConfig(
        task="jigsaw", episodes=5, out=str(tmp_path), backend="ray", workers=2, render=False
    )
    fake_ray.die_after = 3  # seeds 0, 1, 2 run; the node dies under seed 3
    with pytest.raises(ClusterLost, match="no live node"):
        generate(config)
    # one lost job stops the run: nothing more than the slots in flight was submitted
    assert len(fake_ray.submitted) <= 3 + 2
    assert [(s, ok) for s, ok, _ in manifest_seeds(tmp_path)] == [(0, True), (1, False), (2, True)]
    dataset = json.loads((tmp_path / "dataset_default.json").read_text())
    assert dataset["tasks"]["jigsaw"]["tried"] == 3
    # the cluster is back: the same command resumes with the seeds that were in flight
    fake_ray.die_after, fake_ray.alive = None, True
    summary = generate(config)
    assert summary.kept == 5
    seeds = manifest_seeds(tmp_path)
    assert [s for s, _, _ in seeds] == list(range(9))
    assert not any("worker_lost" in (reason or "") for _, _, reason in seeds)


def test_generate_cli_says_to_run_again_in_one_line(fake_ray, episodes, tmp_path, capsys):
    fake_ray.die_after = 1
    argv = ["--task", "jigsaw", "--episodes", "3", "--out", str(tmp_path), "--no-render"]
    code = script("generate").main([*argv, "--backend", "ray", "--workers", "2"])
    err = capsys.readouterr().err
    assert code == 75
    lines = [line for line in err.replace("\r", "\n").splitlines() if "no live node" in line]
    assert len(lines) == 1 and "Traceback" not in err
    assert "run the same command again" in lines[0] and "NodeDiedError" in lines[0]
    assert [s for s, _, _ in manifest_seeds(tmp_path)] == [0]


def test_evaluate_cli_stops_with_the_same_status(fake_ray, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))
    fake_ray.die_after = 0  # dead before the first rollout
    argv = ["--task", "jigsaw", "--policy", "noop", "--episodes", "2", "--no-render"]
    argv += ["--no-expert-check", "--out", str(tmp_path), "--backend", "ray"]
    assert script("evaluate").main(argv) == 75
    err = capsys.readouterr().err
    assert "no live node" in err and "run the same command again" in err
    assert "Traceback" not in err and not (tmp_path / "jigsaw").exists()

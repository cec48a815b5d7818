"""Parallel evaluation (Ray, local processes): the same report as a sequential run, videos
written by the driver, the expert-check cache consulted before any job."""

import importlib.util
from pathlib import Path

import pytest

from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner.evaluate import EvaluateConfig, ExpertCheck, evaluate
from bicoord_drake.tasks import get_task

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "evaluate.py"


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))


def settings(tmp_path, name, **kw):
    base = dict(
        task="jigsaw",
        policy="noop",
        episodes=3,
        render=False,
        step_limit=4,
        expert_check=False,
        workers=1,
        out=str(tmp_path / name),
    )
    return EvaluateConfig(**{**base, **kw})


def summary(report):
    return [(r.seed, r.success, r.score, r.steps, r.completed) for r in report.rollouts]


def test_ray_report_equals_the_sequential_one_and_videos_reach_the_driver(ray_cluster, tmp_path):
    kw = dict(render=True, resolution="64x48")
    alone = evaluate(settings(tmp_path, "alone", **kw))
    video = tmp_path / "videos"
    on_ray = evaluate(settings(tmp_path, "ray", backend="ray", workers=0, video=str(video), **kw))
    assert summary(on_ray) == summary(alone)
    assert [r.seed for r in on_ray.rollouts] == [100000, 100001, 100002]
    assert (on_ray.sr, on_ray.ssr, on_ray.tl) == (alone.sr, alone.ssr, alone.tl)
    assert on_ray.stage_completion == alone.stage_completion
    for r in on_ray.rollouts:
        assert Path(r.video).parent == video and Path(r.video).stat().st_size > 0
        assert r.left_xyz.shape == (4, 3)


def test_ray_skips_seeds_the_cache_says_the_expert_fails(ray_cluster, tmp_path):
    # the plain scene at 15 Hz, as the evaluation below
    check = ExpertCheck(EpisodeSetup(task=get_task("jigsaw"), seed=0))
    for seed in (100000, 100002, 100003):
        check.store(seed, {"ok": True, "reason": None})
    check.store(100001, {"ok": False, "reason": "planning: no grasp"})
    report = evaluate(settings(tmp_path, "eval", backend="ray", workers=0, expert_check=True))
    assert [r.seed for r in report.rollouts] == [100000, 100002, 100003]
    assert report.skipped == [{"seed": 100001, "reason": "expert failed: planning: no grasp"}]


def test_cli_backend_flags(ray_cluster, tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("evaluate_cli", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    argv = [
        "--task",
        "jigsaw",
        "--policy",
        "noop",
        "--episodes",
        "2",
        "--no-render",
        "--step-limit",
        "3",
        "--no-expert-check",
        "--out",
        str(tmp_path),
        "--backend",
        "ray",
        "--workers",
        "2",
        "--json",
    ]
    assert module.main(argv) == 0
    assert '"n": 2' in capsys.readouterr().out
    assert module.main(["--task", "jigsaw", "--policy", "noop", "--ray-address", "auto"]) == 2
    assert "backend" in capsys.readouterr().err


def test_local_processes_give_the_sequential_report(tmp_path):
    alone = evaluate(settings(tmp_path, "alone"))
    pooled = evaluate(settings(tmp_path, "pool", workers=2))
    assert summary(pooled) == summary(alone) and pooled.report_path.exists()

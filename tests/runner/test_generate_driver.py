"""The generation driver without physics: several tasks in one run, the dataset manifest, files
placed from bytes or from a staging directory, lost workers retried by the next run.

`produce_episode` (the worker side, tested with real episodes in test_generate_ray.py) is
replaced by a stand-in whose verdicts are known: even seeds keep an episode, odd seeds fail."""

import json

import pytest

import bicoord_drake.runner.generate as gen
from bicoord_drake.runner.backends import InlineBackend, WorkerLost
from bicoord_drake.runner.generate import (
    GenerateConfig,
    SeedOutcome,
    generate,
    generate_dataset,
    resolve_tasks,
)
from bicoord_drake.tasks import list_tasks


def fake_episode(config, seed, staging):
    """Even seeds: an episode (its files as bytes, or written under `staging`); odd: a failure."""
    if seed % 2:
        return SeedOutcome(config.task, seed, False, "planning: no grasp (stand-in)")
    files = {
        kind: f"{config.task} seed {seed} {kind}".encode()
        for kind in ("instructions", "stages", "video", "episode")
    }
    outcome = SeedOutcome(config.task, seed, True, frames=10, worker="here:1")
    if staging is None:
        outcome.files = files
    else:
        outcome.staged = {}
        for kind, data in files.items():
            path = gen.Path(staging) / f"seed{seed}" / kind / "episode0"
            path.parent.mkdir(parents=True)
            path.write_bytes(data)
            outcome.staged[kind] = str(path)
    return outcome


@pytest.fixture
def fake(monkeypatch):
    monkeypatch.setattr(gen, "produce_episode", fake_episode)
    monkeypatch.setattr(gen, "_summary", lambda layout, manifest: summary(layout, manifest))


def summary(layout, manifest):
    kept = manifest.successes
    return gen.GenerateSummary(
        layout.root, len(kept), len(manifest.episodes), manifest.failures, None, None, None
    )


def test_task_lists():
    assert resolve_tasks("all") == list_tasks()
    assert resolve_tasks("jigsaw, cook,jigsaw") == ["jigsaw", "cook"]
    with pytest.raises(ValueError, match="unknown task 'origami'; tasks: .*jigsaw"):
        resolve_tasks("jigsaw,origami")


def test_ray_settings_need_the_ray_backend():
    with pytest.raises(ValueError, match="ray_address"):
        GenerateConfig(task="jigsaw", ray_address="auto")


def test_several_tasks_one_run_one_dataset_manifest(fake, tmp_path):
    seen = []
    config = GenerateConfig(task="jigsaw,cook", episodes=2, out=str(tmp_path), workers=1)
    result = generate_dataset(config, seen.append)
    assert set(result.tasks) == {"jigsaw", "cook"} and result.complete
    for task in ("jigsaw", "cook"):
        root = tmp_path / task / "default"
        manifest = json.loads((root / "manifest.json").read_text())
        assert [(e["seed"], e["success"], e["index"]) for e in manifest["episodes"]] == [
            (0, True, 0),
            (1, False, None),
            (2, True, 1),
        ]
        assert (root / "data" / "episode1.hdf5").read_bytes() == f"{task} seed 2 episode".encode()
        assert (root / "video" / "episode1.mp4").read_bytes() == f"{task} seed 2 video".encode()
    dataset = json.loads((tmp_path / "dataset_default.json").read_text())
    assert dataset["kept"] == 4 and dataset["settings"]["resolution"] == "320x240"
    assert dataset["tasks"]["cook"] == {
        "directory": "cook/default",
        "target": 2,
        "kept": 2,
        "tried": 3,
        "failed": 1,
    }
    # progress: once at the start, then after every seed, with per-task counts
    assert seen[0].counts == {"jigsaw": (0, 0, 2), "cook": (0, 0, 2)}
    assert len(seen) == 1 + 6 and seen[-1].kept == seen[-1].target == 4
    # the tasks advance together (one seed each in turn), not one after the other
    assert [s.message.split()[0] for s in seen[1:3]] == ["jigsaw", "cook"]


def test_local_workers_stage_files_and_the_driver_moves_them(fake, tmp_path):
    config = GenerateConfig(task="jigsaw", episodes=1, out=str(tmp_path), workers=1)
    summary = generate(config)
    root = tmp_path / "jigsaw" / "default"
    assert summary.kept == 1
    assert (root / "data" / "episode0.hdf5").read_bytes() == b"jigsaw seed 0 episode"
    assert not any((root / ".staging").iterdir())


def test_other_settings_in_the_same_out_are_refused(fake, tmp_path):
    generate(GenerateConfig(task="jigsaw", episodes=1, out=str(tmp_path), workers=1))
    with pytest.raises(ValueError, match="different settings"):
        generate(GenerateConfig(task="cook", episodes=1, out=str(tmp_path), fps=10, workers=1))


class LosingBackend(InlineBackend):
    """This process, except that the worker of seed 0 'dies' on every try."""

    def result(self, handle):
        value = super().result(handle)
        if value.seed == 0:
            raise WorkerLost("its Ray worker died 4 times (stand-in)")
        return value


def test_a_lost_seed_is_recorded_and_tried_again_by_the_next_run(fake, monkeypatch, tmp_path):
    config = GenerateConfig(task="jigsaw", episodes=1, out=str(tmp_path), workers=1)
    monkeypatch.setattr(gen, "make_backend", lambda *a, **k: LosingBackend())
    first = generate(config)
    assert [f.reason.split(":")[0] for f in first.failures] == ["worker_lost", "planning"]
    assert first.kept == 1  # seed 2
    monkeypatch.setattr(gen, "make_backend", lambda *a, **k: InlineBackend())
    again = generate(GenerateConfig(task="jigsaw", episodes=2, out=str(tmp_path), workers=1))
    manifest = json.loads((tmp_path / "jigsaw" / "default" / "manifest.json").read_text())
    assert [(e["seed"], e["success"]) for e in manifest["episodes"]] == [
        (1, False),
        (2, True),
        (0, True),
    ]
    assert again.kept == 2

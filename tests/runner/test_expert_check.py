"""The expert check of an evaluation runs on the rollouts' scene: with randomize, the seed's
randomized scene of the evaluation's split (its table height and clutter change the expert's
job), and its cached verdicts are kept apart from the plain scene's."""

import json
import os
from pathlib import Path

import pytest

import bicoord_drake.runner.evaluate_parallel as parallel
from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.runner import generate as gen
from bicoord_drake.runner.backends import InlineBackend
from bicoord_drake.runner.evaluate import EvaluateConfig, ExpertCheck, evaluate
from bicoord_drake.runner.rollouts import expert_verdict
from bicoord_drake.stages import Stage
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Task


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "cache"))


class ClutterOnly(Task):
    """A one-cube task that holds still; its stage holds only on a cluttered (randomized) scene
    whose textures come from the unseen split."""

    name = "clutter_only"
    step_limit = 10
    instructions_seen = ("Hold.",) * 5
    instructions_unseen = ("Stay.",) * 5

    def sample_scene(self, seed):
        return Scene(name=self.name, seed=seed, objects=(cube("c", 0.0, 0.0),))

    def stages(self, scene):
        unseen = scene.appearance is not None and scene.appearance.split == "unseen"
        return [Stage("hold", "hold", "hold", 1.0, lambda s: unseen, "persistent")]

    def expert(self, scene, view):
        home = view.embodiment.home_action()
        for _ in range(2):
            yield home


def test_the_verdict_is_the_one_of_the_randomized_scene_of_the_split():
    def verdict(**scene):
        return expert_verdict(EpisodeSetup(task=ClutterOnly(), seed=3, **scene))

    plain = verdict()
    assert not plain["ok"] and plain["reason"].startswith("stage_not_verified")
    assert not verdict(randomize=True, split="seen")["ok"]
    assert verdict(randomize=True, split="unseen") == {"ok": True, "reason": None}


def check(path, **settings) -> ExpertCheck:
    """The jigsaw expert check with these episode settings (fps: the station's rate)."""
    fps = settings.pop("fps", 15.0)
    station = StationConfig(control_rate=fps, **settings.pop("station", {}))
    setup = EpisodeSetup(task=get_task("jigsaw"), seed=0, station=station, **settings)
    return ExpertCheck(setup, path)


def test_the_cache_keeps_plain_and_randomized_verdicts_apart(tmp_path):
    path = tmp_path / "check.json"
    plain = check(path)
    plain.store(7, {"ok": False, "reason": "planning: no grasp"})
    unseen = check(path, randomize=True, split="unseen")
    assert unseen.lookup(7) is None  # the plain scene's verdict says nothing of this one
    unseen.store(7, {"ok": True, "reason": None})
    assert check(path, randomize=True, split="seen").lookup(7) is None
    # each verdict survives in the file under its own key
    assert check(path).lookup(7) == (False, "planning: no grasp")
    assert check(path, randomize=True, split="unseen").lookup(7) == (True, None)
    assert len(json.loads(path.read_text())) == 2


def test_the_cache_keeps_control_rates_and_physics_settings_apart(tmp_path):
    path = tmp_path / "check.json"
    check(path).store(7, {"ok": True, "reason": None})
    assert check(path, fps=10.0).lookup(7) is None
    assert check(path, station={"time_step": 1 / 150}).lookup(7) is None
    # cameras and resolution do not change what the expert does
    assert check(path, station={"render": False}).lookup(7) == (True, None)
    plain_key = check(path)._key(7)
    assert plain_key.startswith("7@15Hz@") and "station" not in plain_key


def test_for_config_takes_the_evaluation_scene_settings():
    task = get_task("jigsaw")
    config = EvaluateConfig(task="jigsaw", policy="noop", randomize=True, split="seen", fps=10)
    expert_check = ExpertCheck.for_config(task, config)
    assert (expert_check.fps, expert_check.randomize, expert_check.split) == (10.0, True, "seen")
    setup = expert_check.setup
    assert setup.embodiment == config.embodiment and not setup.station.render


@pytest.fixture
def expert_calls(monkeypatch):
    """run_expert replaced by a stand-in that fails every seed and records its scene settings."""
    calls = []

    def fake_run_expert(setup, depth=False):
        calls.append((setup.seed, setup.randomize, setup.split))
        return gen.EpisodeResult(setup.seed, False, "planning: stand-in")

    monkeypatch.setattr(gen, "run_expert", fake_run_expert)
    return calls


def settings(tmp_path, **kw):
    base = dict(task="jigsaw", policy="noop", episodes=1, max_tries=2, render=False)
    return EvaluateConfig(**{**base, "out": str(tmp_path / "eval"), **kw})


@pytest.mark.parametrize("split", ["seen", "unseen"])
def test_a_randomized_evaluation_checks_the_expert_on_its_scenes(tmp_path, expert_calls, split):
    report = evaluate(settings(tmp_path, randomize=True, split=split, workers=1))
    assert expert_calls == [(100000, True, split), (100001, True, split)]
    assert [s["seed"] for s in report.skipped] == [100000, 100001] and report.n == 0
    cached = Path(os.environ["BICOORD_CACHE"]) / "expert_check" / "jigsaw.json"
    assert all(f"@randomized-{split}@" in key for key in json.loads(cached.read_text()))
    # a plain evaluation of the same seeds does not take those verdicts: it checks again
    evaluate(settings(tmp_path, workers=1))
    assert expert_calls[2:] == [(100000, False, "unseen"), (100001, False, "unseen")]


def test_parallel_evaluation_checks_the_expert_on_its_scenes(tmp_path, expert_calls, monkeypatch):
    monkeypatch.setattr(parallel, "make_backend", lambda *a, **k: InlineBackend())
    report = evaluate(settings(tmp_path, randomize=True, workers=2))
    assert expert_calls == [(100000, True, "unseen"), (100001, True, "unseen")]
    assert len(report.skipped) == 2
    # the driver cached the workers' verdicts under the randomized scene's key
    again = evaluate(settings(tmp_path, randomize=True, workers=2))
    assert len(expert_calls) == 2 and len(again.skipped) == 2

"""generate: a seed that fails in any way is a failed seed with a reason, never a crashed run;
seeds outside [0, 2**32) are refused before anything runs."""

import json

import pytest
from pydantic import ValidationError

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.scene import Scene, cube
from bicoord_drake.runner import generate as gen
from bicoord_drake.stages import Stage, StageMonitor
from bicoord_drake.tasks.base import Task


class StandStill(Task):
    """A one-cube task whose expert holds still for three steps; its one stage always holds."""

    name = "stand_still"
    step_limit = 10
    instructions_seen = ("Hold still.",) * 5
    instructions_unseen = ("Do nothing.",) * 5

    def sample_scene(self, seed):
        return Scene(name=self.name, seed=seed, objects=(cube("c", 0.0, 0.0),))

    def stages(self, scene):
        return [Stage("be", "hold", "hold", 1.0, lambda s: True, "persistent")]

    def expert(self, scene, view):
        home = view.embodiment.home_action()
        for _ in range(3):
            yield home


def test_an_annotation_failure_is_a_failed_seed_with_its_reason(monkeypatch):
    setup = EpisodeSetup(task=StandStill(), seed=3, station=StationConfig(render=False))
    ok = gen.run_expert(setup)
    assert ok.success and ok.rows[-1][1] == 3

    def refuse(self, T=None):
        raise ValueError("stage 0 ('be') would span frames [0, 0) of T = 0")

    monkeypatch.setattr(StageMonitor, "annotations", refuse)
    result = gen.run_expert(setup)
    assert not result.success and result.reason.startswith("annotation: ")
    assert "would span" in result.reason


def test_a_seed_that_crashes_is_recorded_and_the_run_goes_on(tmp_path, monkeypatch):
    def flaky(setup, depth=False, action_noise=0.0):
        if setup.seed == 5:
            raise RuntimeError("simulator fault on purpose")
        return gen.EpisodeResult(setup.seed, False, "planning: ik_infeasible")

    monkeypatch.setattr(gen, "run_expert", flaky)
    config = gen.GenerateConfig(
        task="jigsaw", episodes=1, seed=4, max_tries=3, out=str(tmp_path), render=False, workers=1
    )
    summary = gen.generate(config)
    assert (summary.kept, summary.tried) == (0, 3)
    manifest = json.loads((summary.root / "manifest.json").read_text())
    reasons = {e["seed"]: e["reason"] for e in manifest["episodes"]}
    assert reasons[5].startswith("crashed: RuntimeError: simulator fault on purpose")
    assert reasons[4] == reasons[6] == "planning: ik_infeasible"


@pytest.mark.parametrize(
    "settings,words",
    [
        ({"seed": 2**70}, ["seed", "2**32"]),
        ({"seed": -1}, ["seed", "2**32"]),
        ({"seed": 2**32 - 2, "episodes": 2}, ["seed", "4294967295"]),
    ],
)
def test_seeds_outside_32_bits_are_refused_in_the_config(settings, words):
    with pytest.raises(ValidationError) as info:
        gen.GenerateConfig(task="jigsaw", **settings)
    assert all(w in str(info.value) for w in words)
    gen.GenerateConfig(task="jigsaw", seed=2**32 - 10, episodes=2)  # the top of the range


def test_an_episode_setup_refuses_a_seed_outside_32_bits():
    with pytest.raises(ValueError, match=r"\[0, 2\*\*32\)"):
        EpisodeSetup(task=StandStill(), seed=2**70)

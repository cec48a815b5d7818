"""Actions outside the robot's limits are counted per rollout and reported in the evaluation
summary and report.json (issue #53, item 6), not passed on silently."""

import json

import numpy as np
import pytest

from bicoord_drake.env import make_env
from bicoord_drake.runner.evaluate import EvaluateConfig, evaluate
from bicoord_drake.runner.rollouts import LimitCount

pytestmark = pytest.mark.usefixtures("isolated_cache")


def config(tmp_path, **kw) -> EvaluateConfig:
    settings = dict(
        task="jigsaw",
        policy="tests.policies.dummy:OutOfLimits",
        episodes=2,
        render=False,
        step_limit=4,
        expert_check=False,
        workers=1,
        out=str(tmp_path / "eval"),
    )
    settings.update(kw)
    return EvaluateConfig(**settings)


def test_the_count_of_one_action():
    env = make_env("jigsaw", 100000, render=False)
    env.reset()
    count = LimitCount(env)
    home = env.action.copy()
    count.update(home)
    assert count.actions == 0 and count.entries == {} and count.max_excess == 0.0
    upper = env.sim.station.embodiment.arm.upper
    at_limits = home.copy()
    at_limits[1], at_limits[6], at_limits[13] = upper[1], 0.0, 1.0 + 1e-9  # on them: inside
    count.update(at_limits)
    assert count.actions == 0
    beyond = home.copy()
    beyond[1], beyond[6] = upper[1] + 0.5, -0.25
    count.update(beyond)
    count.update(beyond)
    assert count.actions == 2
    assert count.entries == {"left_shoulder": 2, "left_gripper": 2}
    assert count.max_excess == pytest.approx(0.5)
    env.close()


def test_actions_outside_the_limits_are_counted_and_reported(tmp_path):
    report = evaluate(config(tmp_path))
    assert report.n == 2
    for r in report.rollouts:
        assert r.steps == 4 and r.error is None  # executed, not refused
        assert r.out_of_limits == 2
        assert r.out_of_limits_entries == {"left_waist": 2, "right_gripper": 1}
        assert r.out_of_limits_max == pytest.approx(10.0 - np.pi, abs=0.05)
    limits = report.out_of_limits
    assert limits["rollouts"] == 2 and limits["actions"] == 4 and limits["per_rollout"] == [2, 2]
    assert limits["entries"] == {"left_waist": 4, "right_gripper": 2}
    data = json.loads(report.report_path.read_text())
    assert data["out_of_limits"] == json.loads(json.dumps(limits))
    assert data["rollouts"][0]["out_of_limits"] == 2
    assert data["rollouts"][0]["out_of_limits_entries"] == {"left_waist": 2, "right_gripper": 1}
    text = report.format_text()
    assert "actions outside the joint limits: 4 in 2 of 2 rollouts" in text
    assert "per rollout: seed 100000 2, seed 100001 2" in text
    assert "per entry: left_waist 4, right_gripper 2" in text


def test_a_policy_within_the_limits_counts_none(tmp_path):
    report = evaluate(config(tmp_path, policy="noop", episodes=1))
    (r,) = report.rollouts
    assert r.out_of_limits == 0 and r.out_of_limits_entries == {}
    assert report.out_of_limits["actions"] == 0
    assert "outside the joint limits" not in report.format_text()

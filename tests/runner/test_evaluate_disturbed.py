"""Robustness evaluation (issue #54, item 3): ``disturb`` rolls every seed out clean and
disturbed, with the disturbances the expert's demonstration of that seed gets, and the report
gives both side by side.

The summary and report tests build reports from made-up rollouts; the flow tests replace the
traced expert run by a stand-in (a few short noop rollouts, no expert); one physics test runs
balance_roller's expert policy on one seed, pushed, against what generation draws for it. The
slow test replays generated demonstrations with a push."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydantic import ValidationError

from bicoord_drake.runner import evaluate_parallel
from bicoord_drake.runner import generate as gen
from bicoord_drake.runner.evaluate import (
    EvaluateConfig,
    RolloutResult,
    _report,
    evaluate,
    side_by_side,
)
from bicoord_drake.runner.rollouts import ExpertCheck
from bicoord_drake.sim.disturbances import Disturbance, disturbance_records
from bicoord_drake.tasks import get_task

PUSH = Disturbance(
    kind="push", step=1, duration=2, body="spare_left_0", force=(0.0, 0.6, 0.0), point=(0, 0, -0.01)
)
NO_WINDOW = "push: the expert's first plan leaves no time for a push"


pytestmark = pytest.mark.usefixtures("isolated_cache")


def config(tmp_path, **kw) -> EvaluateConfig:
    settings = dict(
        task="jigsaw",
        policy="noop",
        episodes=3,
        render=False,
        step_limit=4,
        expert_check=True,
        workers=1,
        disturb="push",
        out=str(tmp_path / "eval"),
    )
    settings.update(kw)
    return EvaluateConfig(**settings)


# --------------------------------------------------------------------------- the summary
def made_up(seed: int, success: bool, credit: list[float], pushed: bool) -> RolloutResult:
    records = disturbance_records([PUSH.model_copy(update={"step": 14})]) if pushed else []
    return RolloutResult(
        seed, success, 0.5 * sum(credit), 90 if success else 200, [c >= 1 for c in credit],
        credit, failure=None if success else "step_limit", disturbances=records,
    )  # fmt: skip


@pytest.fixture
def reports(tmp_path):
    """balance_roller (two stages of 0.5): four clean rollouts, three disturbed (seed 100002
    has no window for a push)."""
    task = get_task("balance_roller")
    cfg = EvaluateConfig(task="balance_roller", policy="p", render=False, disturb="push")
    clean = [
        made_up(100000, True, [1.0, 1.0], False),
        made_up(100001, True, [1.0, 1.0], False),
        made_up(100002, False, [1.0, 0.0], False),
        made_up(100003, True, [1.0, 1.0], False),
    ]
    disturbed = [
        made_up(100000, True, [1.0, 1.0], True),
        made_up(100001, False, [1.0, 0.0], True),
        made_up(100003, False, [0.0, 0.0], True),
    ]
    skipped = [{"seed": 100002, "reason": f"no_disturbance_window: {NO_WINDOW}"}]
    report = _report(task, cfg, clean, [], None)
    report.disturb = ("push",)
    report.disturbed = _report(task, cfg, disturbed, skipped, None)
    return report


def test_the_scores_stand_side_by_side(reports):
    both = side_by_side(reports, reports.disturbed)
    assert both["kinds"] == ["push"]
    assert both["n"] == {"clean": 4, "disturbed": 3}
    assert both["SR"] == {"clean": 0.75, "disturbed": pytest.approx(1 / 3)}
    assert both["SSR"] == {"clean": pytest.approx(0.875), "disturbed": pytest.approx(0.5)}
    assert both["TL"] == {"clean": 90.0, "disturbed": 90.0}
    assert both["skipped"] == {"clean": 0, "disturbed": 1}
    assert both["stages"] == [
        {"subgoal": "lift the roller together", "clean": 1.0, "disturbed": pytest.approx(2 / 3)},
        {"subgoal": "balance it on the block", "clean": 0.75, "disturbed": pytest.approx(1 / 3)},
    ]
    # on the three seeds with both rollouts the clean SR is 1.0, not 0.75
    assert both["paired"] == {
        "n": 3,
        "SR": {"clean": 1.0, "disturbed": pytest.approx(1 / 3)},
        "SSR": {"clean": 1.0, "disturbed": pytest.approx(0.5)},
    }


def test_the_summary_shows_both_columns(reports):
    text = reports.format_text()
    lines = text.splitlines()
    assert lines[0] == (
        "balance_roller | policy p | 4 rollouts clean, 3 disturbed (push), two per seed "
        "| 1 seeds without a disturbed rollout"
    )
    assert lines[1:7] == [
        "| | clean | disturbed (push) |",
        "|---|---:|---:|",
        "| rollouts | 4 | 3 |",
        "| SR | 75.0 % | 33.3 % |",
        "| SSR | 87.5 % | 50.0 % |",
        "| TL | 90.0 | 90.0 |",
    ]
    assert "on the 3 seeds with both: SR 100.0 % clean, 33.3 % disturbed; SSR 100.0 % " in text
    assert "| k | stage | score | clean | disturbed |" in lines
    assert "| 1 | balance it on the block | 0.50 | 75.0 % | 33.3 % |" in lines
    assert f"no disturbed rollout of seed 100002: no_disturbance_window: {NO_WINDOW}" in lines
    assert "failures: step_limit 1" in lines
    assert "failures of the disturbed rollouts: step_limit 2" in lines
    assert (
        "disturbances: seed 100000 push on 'spare_left_0' (0.6 N) at step 14; "
        "seed 100001 push on 'spare_left_0' (0.6 N) at step 14; seed 100003 push on "
        "'spare_left_0' (0.6 N) at step 14" in lines
    )


def test_without_disturbances_the_summary_is_the_one_column_one(reports):
    reports.disturbed, reports.disturb = None, ()
    lines = reports.format_text().splitlines()
    assert lines[:2] == [
        "balance_roller | policy p | 4 rollouts",
        "SR 75.0 %   SSR 87.5 %   TL 90.0",
    ]
    assert "| k | stage | score | completed |" in lines
    data = reports.to_json()
    assert not {"disturb", "side_by_side", "disturbed"} & set(data)
    assert all("disturbances" not in r for r in data["rollouts"])


def test_the_report_json_has_both_and_each_rollouts_disturbance(reports):
    data = json.loads(json.dumps(reports.to_json()))
    assert list(data)[:9] == [
        "task", "policy", "stage", "n", "SR", "SSR", "TL", "disturb", "side_by_side",
    ]  # fmt: skip
    assert data["SR"] == 0.75 and data["disturb"] == ["push"]
    assert data["side_by_side"]["SR"]["disturbed"] == pytest.approx(1 / 3)
    assert all("disturbances" not in r for r in data["rollouts"])  # the clean ones
    part = data["disturbed"]
    assert part["n"] == 3 and part["SR"] == pytest.approx(1 / 3)
    assert part["skipped"] == [{"seed": 100002, "reason": f"no_disturbance_window: {NO_WINDOW}"}]
    (d,) = part["rollouts"][0]["disturbances"]
    assert (d["kind"], d["body"], d["step"]) == ("push", "spare_left_0", 14)
    assert "config" not in part


def test_a_stage_evaluation_cannot_be_disturbed(tmp_path):
    with pytest.raises(ValidationError, match="drop the stage"):
        config(tmp_path, policy="replay", data=str(tmp_path), stage=1)


# --------------------------------------------------------------------------- the flow
@pytest.fixture
def traced(monkeypatch):
    """The traced expert run replaced: seed 100001 has no window, the others a push at step 1;
    the expert fails seed 100002. Returns the seeds it ran for."""
    calls = []

    def trace_expert(setup, disturb, action_noise=0.0):
        calls.append(setup.seed)
        drawn = {"push": NO_WINDOW if setup.seed == 100001 else PUSH}
        ok = setup.seed != 100002
        return gen.CleanRun(setup.seed, ok, None if ok else "planning: stand-in", drawn)

    def run_expert(*args, **kwargs):
        raise AssertionError("a disturbed evaluation's expert check is the traced run")

    monkeypatch.setattr(gen, "trace_expert", trace_expert)
    monkeypatch.setattr(gen, "run_expert", run_expert)
    return calls


def test_each_seed_is_rolled_out_clean_and_disturbed(tmp_path, traced):
    report = evaluate(config(tmp_path))
    assert traced == [100000, 100001, 100002, 100003]  # one traced run per seed
    assert [r.seed for r in report.rollouts] == [100000, 100001, 100003]
    assert report.skipped == [{"seed": 100002, "reason": "expert failed: planning: stand-in"}]
    assert all(r.disturbances == [] for r in report.rollouts)
    part = report.disturbed
    assert [r.seed for r in part.rollouts] == [100000, 100003]
    assert all(r.disturbances == disturbance_records([PUSH]) for r in part.rollouts)
    assert part.skipped == [{"seed": 100001, "reason": f"no_disturbance_window: {NO_WINDOW}"}]
    assert part.rollouts[0].steps == 4 and not part.rollouts[0].success
    data = json.loads(report.report_path.read_text())
    assert data["side_by_side"]["n"] == {"clean": 3, "disturbed": 2}
    assert report.disturbed.plot_path.name == "stage_success_disturbed.png"
    # the next evaluation takes the verdicts and the disturbances from the cache
    again = evaluate(config(tmp_path))
    assert len(traced) == 4
    assert [r.disturbances for r in again.disturbed.rollouts] == [
        r["disturbances"] for r in data["disturbed"]["rollouts"]
    ]


def test_without_disturb_each_seed_is_rolled_out_once(tmp_path, monkeypatch):
    """No traced run, no second rollout: the expert check and the rollouts as before."""
    from tests.policies.dummy import Spy

    def run_expert(setup, depth=False):
        return gen.EpisodeResult(setup.seed, True)

    def trace_expert(*args, **kwargs):
        raise AssertionError("no disturbances asked for: nothing to trace")

    monkeypatch.setattr(gen, "run_expert", run_expert)
    monkeypatch.setattr(gen, "trace_expert", trace_expert)
    Spy.bound.clear()
    report = evaluate(config(tmp_path, disturb="none", policy="tests.policies.dummy:Spy"))
    assert report.n == 3 and len(Spy.bound) == 3 and report.disturbed is None
    Spy.bound.clear()


def test_a_plain_verdict_in_the_cache_is_traced_again_once(tmp_path, traced):
    cfg = config(tmp_path)
    check = ExpertCheck.for_config(get_task("jigsaw"), cfg)
    check.store(100000, {"ok": True, "reason": None})  # what an undisturbed evaluation cached
    assert check.lookup(100000) == (True, None) and check.lookup_disturbances(100000) is None
    assert check.disturbances(100000) == {"push": PUSH} and traced == [100000]
    assert check.disturbances(100000) == {"push": PUSH} and traced == [100000]
    plain = ExpertCheck.for_config(get_task("jigsaw"), cfg.model_copy(update={"disturb": "none"}))
    assert plain(100000) == (True, None) and plain.lookup_disturbances(100000) == {}
    plain.store(100000, {"ok": True, "reason": None})  # keeps the drawn disturbances
    assert ExpertCheck.for_config(get_task("jigsaw"), cfg).lookup_disturbances(100000) == {
        "push": PUSH
    }


def test_the_expert_policy_and_no_check_still_get_the_disturbances(tmp_path, traced):
    report = evaluate(config(tmp_path, policy="expert", episodes=2, step_limit=2))
    assert [r.seed for r in report.rollouts] == [100000, 100001] and report.skipped == []
    assert [r.seed for r in report.disturbed.rollouts] == [100000]
    assert report.disturbed.expert_failures[0]["seed"] == 100000
    unchecked = evaluate(config(tmp_path, expert_check=False, episodes=3, out=str(tmp_path / "u")))
    assert [r.seed for r in unchecked.rollouts] == [100000, 100001, 100002]
    assert [r.seed for r in unchecked.disturbed.rollouts] == [100000, 100002]


def test_the_parallel_path_gives_the_sequential_report(tmp_path, traced, monkeypatch):
    from bicoord_drake.runner.backends import InlineBackend

    sequential = evaluate(config(tmp_path, out=str(tmp_path / "s")))
    traced.clear()
    monkeypatch.setenv("BICOORD_CACHE", str(tmp_path / "other_cache"))
    monkeypatch.setattr(evaluate_parallel, "make_backend", lambda *a, **k: InlineBackend())
    try:
        parallel = evaluate(config(tmp_path, workers=2, out=str(tmp_path / "p")))
    finally:
        if evaluate_parallel._WORKER.get("env") is not None:
            evaluate_parallel._WORKER["env"].close()
        evaluate_parallel._WORKER.clear()
    assert traced == [100000, 100001, 100002, 100003]  # drawn in the workers
    for a, b in ((sequential, parallel), (sequential.disturbed, parallel.disturbed)):
        assert [r.to_json() | {"seconds": 0} for r in a.rollouts] == [
            r.to_json() | {"seconds": 0} for r in b.rollouts
        ]
        assert a.skipped == b.skipped
    # the driver cached what the workers drew
    check = ExpertCheck.for_config(get_task("jigsaw"), config(tmp_path))
    assert check.lookup_disturbances(100003) == {"push": PUSH}


def test_a_worker_draws_or_takes_the_disturbances(traced):
    cfg = EvaluateConfig(
        task="jigsaw", policy="noop", render=False, step_limit=3, disturb="push", episodes=1
    )
    try:
        out = evaluate_parallel.rollout_job(cfg, 100000, None, check=True, video=False)
        assert out.verdict["disturbances"] == {
            "push": {"disturbance": PUSH.model_dump(mode="json")}
        }
        assert out.result.disturbances == [] and out.disturbed.disturbances == (
            disturbance_records([PUSH])
        )
        out = evaluate_parallel.rollout_job(cfg, 100001, None, False, False, {"push": NO_WINDOW})
        assert out.verdict is None and out.disturbed is None and traced == [100000]
        assert out.not_disturbed == f"no_disturbance_window: {NO_WINDOW}"
    finally:
        evaluate_parallel._WORKER["env"].close()
        evaluate_parallel._WORKER.clear()


# --------------------------------------------------------------------------- physics
def test_a_pushed_rollout_gets_the_push_generation_draws_for_its_seed(tmp_path):
    """balance_roller, evaluation seed 100000, the expert policy with ``disturb=push``: the
    disturbed rollout is pushed as generation pushes the expert's demonstration of that seed
    and scene (``run_expert(..., disturb=("push",))``), and ends as that demonstration does;
    the clean rollout is not pushed (about 30 s: five expert runs)."""
    cfg = config(tmp_path, task="balance_roller", policy="expert", episodes=1, step_limit=None)
    report = evaluate(cfg)
    (clean,), (pushed,) = report.rollouts, report.disturbed.rollouts
    assert clean.seed == pushed.seed == 100000
    assert clean.disturbances == [] and clean.success
    generated = gen.run_expert(cfg.episode_setup("balance_roller", 100000), disturb=("push",))
    (push,) = generated.disturbances
    assert push.kind == "push" and push.body == "block"
    assert pushed.disturbances == disturbance_records([push])
    assert pushed.success == generated.success
    assert "disturbances: seed 100000 push on 'block'" in report.format_text()


@pytest.mark.slow
def test_replayed_demonstrations_are_pushed_as_generated(tmp_path):
    """A clean demonstration (balance_roller seed 0) replayed with ``disturb=push``: the push
    is the one generation draws for it (the disturbed demonstration of seed 0 records it); a
    disturbed demonstration replayed gives its recorded push to the disturbed rollout, which
    then reproduces it (a success), and none to the clean one."""
    from bicoord_drake.data.episode import read_episode

    roots = {}
    for disturb in (None, "push"):
        summary = gen.generate(
            gen.GenerateConfig(
                task="balance_roller",
                seed=0,
                episodes=1,
                max_tries=1,
                render=False,
                disturb=disturb,
                out=str(tmp_path / "gen"),
                workers=1,
            )  # fmt: skip
        )
        assert summary.kept == 1
        roots[disturb] = summary.root / "data"
    recorded = read_episode(roots["push"] / "episode0.hdf5", images=False).disturbances
    clean = evaluate(config(tmp_path, task="balance_roller", policy="replay", step_limit=None,
                            data=str(roots[None]), out=str(tmp_path / "a")))  # fmt: skip
    assert clean.rollouts[0].success and clean.rollouts[0].disturbances == []
    assert clean.disturbed.rollouts[0].disturbances == disturbance_records(
        Disturbance.model_validate(r) for r in recorded
    )
    pushed = evaluate(config(tmp_path, task="balance_roller", policy="replay", step_limit=None,
                             data=str(roots["push"]), out=str(tmp_path / "b")))  # fmt: skip
    assert pushed.rollouts[0].disturbances == []
    assert pushed.disturbed.rollouts[0].success
    assert pushed.disturbed.rollouts[0].disturbances == clean.disturbed.rollouts[0].disturbances
    np.testing.assert_equal(pushed.to_json()["side_by_side"]["n"], {"clean": 1, "disturbed": 1})

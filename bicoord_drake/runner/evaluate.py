"""Policy rollouts -> SR / SSR / TL with stage-level detail (PRODUCT.md, Evaluation).

``evaluate(EvaluateConfig(task="jigsaw", policy="my_pkg.policy:Policy"))`` runs the policy on
evaluation seeds ``100000 * (1 + seed)`` upward. A seed whose expert fails (checked by running
the expert in physics on the rollout's scene, randomized with ``randomize``; verdict cached per
task, seed and settings in ``$BICOORD_CACHE/expert_check/<task>.json``, default
``~/.cache/bicoord_drake``) is skipped and reported, and the next seed is tried, until
``episodes`` rollouts ran. The ``expert`` policy is the exception: its rollouts are the
check, so a seed its expert fails is a failed rollout, counted in SR and SSR and listed in the
report (``expert_failures``), never skipped. With ``data`` the rollouts are the
demonstrations' own seeds and scenes (no expert check: they succeeded); ``stage = k`` resets
each rollout at the start of stage k of its demonstration (see :mod:`bicoord_drake.env`).

A rollout ends at success (in a stage rollout: when stage k counts) or at the step limit. A
policy that raises, or returns an invalid action (not executed), ends its rollout as a failure;
the error and traceback go to the report and evaluation continues with the next seed. A rollout
also ends early, as a failure, when nothing can be saved: a task object has left the table (on
the floor or outside the workspace, :mod:`bicoord_drake.env`; ``early_stop``, on by default) or
the physics diverged; the stages it completed before count as usual (persistent ones as they
stand when it ends). Nothing else ends a rollout early: a slow policy keeps its step limit.
Every failed rollout has its reason (``failure``: ``step_limit``, ``object_left_table``,
``physics_diverged``, ``invalid_action``, ``policy_raised``, ``simulation_raised``) and the
report counts them (``failures``).

Actions outside the robot's limits (an arm joint target outside the joint's range, a gripper
opening outside [0, 1]) are executed as the station can (openings clipped, joints stopped at
their limits) and counted: per rollout (``out_of_limits``, with the entries and the largest
excess) and for the evaluation (``out_of_limits`` of the report, a line of the summary).

Scores: SR = successes / N; SSR = (1/N) sum_i sum_j s_j c_ij with c_ij the stage's credit
(partial credit included: cook 0.25 per roll, exchange_mics 0.5 per mic), the mean of the
rollouts' ``info["score"]`` - both from :func:`bicoord_drake.metrics.stage_score`; TL = mean
steps of the successful rollouts (None when none succeeded). In a stage evaluation a rollout
succeeds when stage k counts and scores sum only stages k and later (the earlier ones were
given).

Robustness (``disturb``: the scenario's disturbance kinds, :mod:`bicoord_drake.sim.
disturbances`): every seed is rolled out twice, clean and disturbed, and the report gives both
side by side (:attr:`EvaluationReport.disturbed`, :func:`side_by_side`; ``--disturb`` costs two
rollouts per seed). A seed's disturbances are those the expert's demonstration of that seed
gets: drawn from the seed in the windows of a traced clean run of the expert on the rollout's
episode (:func:`~bicoord_drake.runner.generate.trace_expert`, as generation draws them). That
run is the expert check (cached with its verdict; with the expert policy or without the check
it runs for the disturbances alone). With ``data``, a demonstration generated with the kinds
gives its recorded disturbances, and its clean rollout is clean. A seed without a window for a
kind has no disturbed rollout: it is listed with the reason (the disturbed report's
``skipped``), not counted as a failure. Every disturbed rollout records its disturbances (kind,
body, step, ...).

Rollouts run in this process with one worker, otherwise as backend jobs
(:mod:`bicoord_drake.runner.evaluate_parallel`); the settings, the rollout and the expert check
both paths use are in :mod:`bicoord_drake.runner.rollouts` (their names are re-exported here).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bicoord_drake.data.episode import Episode, package_version, read_episode, write_json
from bicoord_drake.env import Env
from bicoord_drake.metrics import (
    coordination_by_test,
    stage_success_rate,
    success_rate,
    trajectory_length,
)
from bicoord_drake.metrics.report import EpisodeMetrics, summarize
from bicoord_drake.models.scene import Scene
from bicoord_drake.policies import action_size_of, close_policy, load_policy_for
from bicoord_drake.runner.evaluate_parallel import run_parallel
from bicoord_drake.runner.rollouts import (
    DIVERGED,
    OBJECT_LEFT_TABLE,
    EvaluateConfig,
    ExpertCheck,
    RolloutResult,
    demonstration_disturbances,
    evaluation_seed,
    find_episodes,
    make_evaluation_env,
    rollout,
    rollout_station,
)
from bicoord_drake.sim.disturbances import from_records, schedule_of
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Task

__all__ = [
    "EvaluateConfig",
    "EvaluationReport",
    "ExpertCheck",
    "RolloutResult",
    "evaluate",
    "evaluation_seed",
    "find_episodes",
    "plot_stage_success",
    "rollout",
    "side_by_side",
    "unmet_stages",
]


@dataclass
class EvaluationReport:
    """Scores, the per-stage table, every rollout, the skipped seeds and where files went."""

    task: str
    policy: str
    stage: int | None
    stages: list[dict[str, Any]]
    rollouts: list[RolloutResult]
    skipped: list[dict[str, Any]]
    sr: float | None
    ssr: float | None
    tl: float | None
    stage_completion: list[float]
    coordination: dict[str, float | None] | None
    config: dict[str, Any]
    expert_failures: list[dict[str, Any]] | None = None
    report_path: Path | None = None
    plot_path: Path | None = None
    seconds: float = 0.0
    #: With disturbances: their kinds, and the report of the disturbed rollouts (on the seeds
    #: of these, the clean ones; `skipped` there: the seeds without a disturbed rollout, and
    #: why). Its scores stand beside these (:func:`side_by_side`).
    disturb: tuple[str, ...] = ()
    disturbed: EvaluationReport | None = None

    @property
    def n(self) -> int:
        return len(self.rollouts)

    @property
    def failures(self) -> dict[str, int]:
        """How many rollouts failed for each reason (:data:`~bicoord_drake.runner.rollouts.
        FAILURES`), most common first."""
        counts: dict[str, int] = {}
        for r in self.rollouts:
            if not r.success:
                reason = r.failure or "unknown"
                counts[reason] = counts.get(reason, 0) + 1
        return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))

    @property
    def out_of_limits(self) -> dict[str, Any]:
        """Actions outside the robot's limits (:class:`~bicoord_drake.runner.rollouts.
        LimitCount`): ``rollouts`` that had any, ``actions`` in all, ``per_rollout`` (the count
        of each rollout, in order), ``entries`` (entry -> actions it was outside in, most
        first) and ``max_excess`` (the largest excess: rad, or opening units)."""
        entries: dict[str, int] = {}
        for r in self.rollouts:
            for name, n in r.out_of_limits_entries.items():
                entries[name] = entries.get(name, 0) + n
        return {
            "rollouts": sum(1 for r in self.rollouts if r.out_of_limits),
            "actions": sum(r.out_of_limits for r in self.rollouts),
            "per_rollout": [r.out_of_limits for r in self.rollouts],
            "entries": dict(sorted(entries.items(), key=lambda kv: (-kv[1], kv[0]))),
            "max_excess": max((r.out_of_limits_max for r in self.rollouts), default=0.0),
        }

    def _scores_json(self) -> dict[str, Any]:
        """What the clean and the disturbed rollouts' reports both have."""
        return {
            "n": self.n,
            "SR": self.sr,
            "SSR": self.ssr,
            "TL": self.tl,
            "stages": [
                {**s, "completed": c}
                for s, c in zip(self.stages, self.stage_completion, strict=True)
            ],
            "coordination": self.coordination,
            "failures": self.failures,
            "out_of_limits": self.out_of_limits,
            "skipped": self.skipped,
            "expert_failures": self.expert_failures,
            "rollouts": [r.to_json() for r in self.rollouts],
        }

    def to_json(self) -> dict[str, Any]:
        """report.json. With disturbances, also ``disturb`` (the kinds) and ``side_by_side``
        (:func:`side_by_side`) after the clean scores, and ``disturbed`` (the disturbed
        rollouts' scores, stages, failures, skipped seeds and rollouts, each with its
        ``disturbances``) after the clean rollouts."""
        scores = self._scores_json()
        if self.disturbed is not None:
            head = {k: scores.pop(k) for k in ("n", "SR", "SSR", "TL")}
            scores = {
                **head,
                "disturb": list(self.disturb),
                "side_by_side": side_by_side(self, self.disturbed),
                **scores,
                "disturbed": {
                    **self.disturbed._scores_json(),
                    "plot": str(self.disturbed.plot_path) if self.disturbed.plot_path else None,
                },
            }
        return {
            "task": self.task,
            "policy": self.policy,
            "stage": self.stage,
            **scores,
            "report": str(self.report_path) if self.report_path else None,
            "plot": str(self.plot_path) if self.plot_path else None,
            "seconds": round(self.seconds, 3),
            "config": self.config,
            "package_version": package_version(),
        }

    def format_text(self) -> str:
        """The human summary: scores, the per-stage completion table, failures, files; with
        disturbances, the clean and the disturbed rollouts' side by side."""
        where = f" from stage {self.stage}" if self.stage is not None else ""
        d = self.disturbed
        if d is None:
            lines = [
                f"{self.task} | policy {self.policy}{where} | {self.n} rollouts"
                + (f" | {len(self.skipped)} seeds skipped" if self.skipped else ""),
                f"SR {_pct(self.sr)}   SSR {_pct(self.ssr)}   TL {_steps(self.tl)}",
                "",
                "| k | stage | score | completed |",
                "|---:|---|---:|---:|",
            ]
        else:
            lines = self._side_by_side_lines(d, where)
        first = self.stage or 0
        for k, (s, c) in enumerate(zip(self.stages, self.stage_completion, strict=True)):
            shown = "given" if k < first else _pct(c)
            if d is not None:
                shown += f" | {_pct(d.stage_completion[k]) if d.rollouts else '-'}"
            lines.append(f"| {k} | {s['subgoal']} | {s['score']:.2f} | {shown} |")
        lines += self._notes()
        if d is not None:
            lines += d._notes(disturbed=True)
            described = [
                f"seed {r.seed} " + ", ".join(_describe(x) for x in r.disturbances)
                for r in d.rollouts
            ]
            if described:
                lines.append(
                    "disturbances: "
                    + "; ".join(described[:10])
                    + (f" and {len(described) - 10} more" if len(described) > 10 else "")
                )
        files = [str(p) for p in (self.report_path, self.plot_path) if p]
        if d is not None and d.plot_path:
            files.append(str(d.plot_path))
        if files:
            lines.append("written: " + ", ".join(files))
        return "\n".join(lines)

    def _side_by_side_lines(self, d: EvaluationReport, where: str) -> list[str]:
        """The head of a summary with disturbances: the scores of the clean and the disturbed
        rollouts in two columns, the same on the seeds that have both, the stages' header."""
        both = side_by_side(self, d)
        kinds = ",".join(self.disturb)
        lines = [
            f"{self.task} | policy {self.policy}{where} | {self.n} rollouts clean, {d.n} "
            f"disturbed ({kinds}), two per seed"
            + (f" | {len(self.skipped)} seeds skipped" if self.skipped else "")
            + (f" | {len(d.skipped)} seeds without a disturbed rollout" if d.skipped else ""),
            f"| | clean | disturbed ({kinds}) |",
            "|---|---:|---:|",
            f"| rollouts | {self.n} | {d.n} |",
            f"| SR | {_pct(self.sr)} | {_pct(d.sr)} |",
            f"| SSR | {_pct(self.ssr)} | {_pct(d.ssr)} |",
            f"| TL | {_steps(self.tl)} | {_steps(d.tl)} |",
        ]
        paired = both["paired"]
        if paired["n"] and paired["n"] != self.n:
            lines.append(
                f"on the {paired['n']} seeds with both: SR {_pct(paired['SR']['clean'])} clean, "
                f"{_pct(paired['SR']['disturbed'])} disturbed; SSR "
                f"{_pct(paired['SSR']['clean'])} clean, {_pct(paired['SSR']['disturbed'])} "
                "disturbed"
            )
        lines += ["", "| k | stage | score | clean | disturbed |", "|---:|---|---:|---:|---:|"]
        return lines

    def _notes(self, disturbed: bool = False) -> list[str]:
        """The lines under the stage table: coordination, skipped seeds, the expert's failures,
        failures by reason, early ends, out-of-limit actions and each rollout's error (of the
        disturbed rollouts, said so)."""
        what = "disturbed rollouts" if disturbed else "rollouts"
        lines = []
        if self.coordination:
            c = self.coordination
            lines.append(
                f"\ncoordination of the {what}: "
                + ", ".join(
                    f"{k} {v:.2f}"
                    for k, v in c.items()
                    if v is not None and k not in ("TL", "SN", "ON")
                )
            )
        for s in self.skipped:
            if disturbed:
                lines.append(f"no disturbed rollout of seed {s['seed']}: {s['reason']}")
            else:
                lines.append(f"skipped seed {s['seed']}: {s['reason']}")
        if self.expert_failures is not None:
            if disturbed:
                lines.append(
                    f"expert policy: {len(self.expert_failures)} of {self.n} disturbed "
                    "rollouts failed (the expert did not recover)"
                )
            else:
                lines.append(
                    f"expert policy: no seed is skipped; {len(self.expert_failures)} of "
                    f"{self.n} seeds the expert failed count as failures in SR and SSR"
                )
            for f in self.expert_failures:
                lines.append(
                    f"  expert failed {'disturbed ' if disturbed else ''}seed {f['seed']}: "
                    f"{f['reason']}"
                )
        if self.failures:
            lines.append(
                ("failures of the disturbed rollouts: " if disturbed else "failures: ")
                + ", ".join(f"{why} {n}" for why, n in self.failures.items())
            )
        diverged = sum(1 for r in self.rollouts if (r.error or "").startswith(DIVERGED))
        if diverged:
            lines.append(
                f"{diverged} of {len(self.rollouts)} {what} ended when the physics diverged "
                "(counted as failures, with the stages done before)"
            )
        lost = self.failures.get(OBJECT_LEFT_TABLE, 0)
        if lost:
            lines.append(
                f"{lost} of {len(self.rollouts)} {what} ended early when a task object left "
                "the table (counted as failures, with the stages done before; --no-early-stop "
                "runs them to the step limit)"
            )
        limits = self.out_of_limits
        if limits["actions"]:
            counted = [(r.seed, r.out_of_limits) for r in self.rollouts if r.out_of_limits]
            lines.append(
                f"actions outside the joint limits: {limits['actions']} in "
                f"{limits['rollouts']} of {self.n} {what} "
                "(openings are clipped to [0, 1], joints stop at their limits; at most "
                f"{limits['max_excess']:.3g} beyond)"
            )
            lines.append(
                "  per rollout: "
                + ", ".join(f"seed {seed} {n}" for seed, n in counted[:10])
                + (f" and {len(counted) - 10} more" if len(counted) > 10 else "")
            )
            entries = list(limits["entries"].items())
            lines.append(
                "  per entry: "
                + ", ".join(f"{name} {n}" for name, n in entries[:8])
                + (f" and {len(entries) - 8} more" if len(entries) > 8 else "")
            )
        for r in self.rollouts:
            if r.error:
                lines.append(f"{'disturbed ' if disturbed else ''}seed {r.seed} failed: {r.error}")
        return lines


def _pct(v: float | None) -> str:
    return "-" if v is None else f"{100 * v:.1f} %"


def _steps(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def _describe(record: dict[str, Any]) -> str:
    """``push on 'block' (1.2 N) at step 14`` of a rollout's disturbance record."""
    (d,) = from_records([record])
    return f"{d.describe()} at step {d.step}"


def side_by_side(clean: EvaluationReport, disturbed: EvaluationReport) -> dict[str, Any]:
    """The clean and the disturbed rollouts' scores side by side: ``n``, ``SR``, ``SSR``,
    ``TL`` and each stage's completion as ``{"clean": ..., "disturbed": ...}``, the seeds each
    skipped, and ``paired``: SR and SSR of both on the seeds that have both rollouts (the
    disturbed rollouts' seeds, unless a clean rollout is missing), with their number ``n``."""

    def pair(a: Any, b: Any) -> dict[str, Any]:
        return {"clean": a, "disturbed": b}

    def key(r: RolloutResult) -> tuple[int, str | None]:  # demonstrations may share a seed
        return (r.seed, r.episode)

    first = clean.stage or 0
    scores = [s["score"] for s in clean.stages]

    def rates(rollouts: list[RolloutResult]) -> tuple[float | None, float | None]:
        if not rollouts:
            return None, None
        credit = np.array([r.credit for r in rollouts], dtype=float)
        return (
            success_rate([r.success for r in rollouts]),
            stage_success_rate(scores, credit, first),
        )

    disturbed_keys = {key(r) for r in disturbed.rollouts}
    paired_clean = [r for r in clean.rollouts if key(r) in disturbed_keys]
    clean_keys = {key(r) for r in paired_clean}
    paired_disturbed = [r for r in disturbed.rollouts if key(r) in clean_keys]
    (sr_c, ssr_c), (sr_d, ssr_d) = rates(paired_clean), rates(paired_disturbed)
    stages = []
    for k, s in enumerate(clean.stages):
        d = disturbed.stage_completion[k] if disturbed.rollouts else None
        stages.append({"subgoal": s["subgoal"], **pair(clean.stage_completion[k], d)})
    return {
        "kinds": list(clean.disturb),
        "n": pair(clean.n, disturbed.n),
        "SR": pair(clean.sr, disturbed.sr),
        "SSR": pair(clean.ssr, disturbed.ssr),
        "TL": pair(clean.tl, disturbed.tl),
        "skipped": pair(len(clean.skipped), len(disturbed.skipped)),
        "stages": stages,
        "paired": {
            "n": len(paired_clean),
            "SR": pair(sr_c, sr_d),
            "SSR": pair(ssr_c, ssr_d),
        },
    }


# --------------------------------------------------------------------------- evaluation
def evaluate(
    config: EvaluateConfig,
    progress: Callable[[RolloutResult | None, str], None] | None = None,
) -> EvaluationReport:
    """Run the evaluation (see the module docstring). `progress(result, message)` is called after
    each rollout (result) and each skipped seed (None).

    Raises ValueError for bad input found before any rollout (unknown task, unloadable policy,
    no demonstrations, a stage the task does not have).
    """
    t_start = time.perf_counter()
    task = get_task(config.task)
    policy = load_policy_for(
        config.policy, action_size=action_size_of(config.embodiment, config.action_mode)
    )
    try:
        return _evaluate_with(task, policy, config, progress, t_start)
    finally:
        close_policy(policy)


def _evaluate_with(
    task: Task,
    policy: Any,
    config: EvaluateConfig,
    progress: Callable[[RolloutResult | None, str], None] | None,
    t_start: float,
) -> EvaluationReport:
    """:func:`evaluate` with the policy loaded (the caller closes it)."""
    if config.policy in ("replay", "expert") and config.action_mode != "qpos":
        raise ValueError(f"the {config.policy} policy commands joint targets: use qpos")
    if config.policy == "expert" and config.stage is not None:
        raise ValueError("the expert policy plans from the start of the task, not from a stage")
    video_dir = Path(config.video) if config.video else None
    rollouts: list[RolloutResult] = []
    skipped: list[dict[str, Any]] = []

    def note(result: RolloutResult | None, message: str) -> None:
        if progress:
            progress(result, message)

    kinds = config.disturb
    # with disturbances: each seed's disturbed rollout, or why it has none
    disturbed: list[RolloutResult] = []
    not_disturbed: list[dict[str, Any]] = []

    def disturbed_rollout(env: Env, seed: int, drawn: dict, episode: Episode | None) -> None:
        schedule, missing = schedule_of(drawn, kinds)
        if missing is not None:
            not_disturbed.append({"seed": seed, "reason": missing})
            note(None, f"seed {seed}: no disturbed rollout")
            return
        result = rollout(
            env,
            policy,
            seed=None if episode is not None else seed,
            episode=episode,
            video=video_path(seed, disturbed=True),
            disturbances=schedule,
        )
        disturbed.append(result)
        note(result, f"seed {seed} disturbed: {'success' if result.success else 'failure'}")

    def video_path(seed: int, disturbed: bool = False) -> Path | None:
        if video_dir is None:
            return None
        suffix = f"_stage{config.stage}" if config.stage is not None else ""
        suffix += "_disturbed" if disturbed else ""
        return video_dir / f"{task.name}_seed{seed}{suffix}.mp4"

    if config.parallel:
        (rollouts, skipped, env), (disturbed, not_disturbed) = run_parallel(
            task, config, note, video_path
        )
    elif config.data:
        paths = find_episodes(config.data, task.name)[: config.episodes]
        env = None
        for path in paths:
            episode = read_episode(path, images=False)
            if not episode.success:
                skipped.append({"seed": episode.seed, "reason": f"{path}: not a success"})
                note(None, f"skipped {path.name}")
                continue
            if config.stage is not None and config.stage >= len(episode.stages):
                raise ValueError(f"--stage {config.stage}: {path} has {len(episode.stages)} stages")
            station = rollout_station(config, episode)
            if env is None or env.config != station:
                env = make_evaluation_env(task, config, episode.seed, station=station)
            result = rollout(
                env,
                policy,
                episode=episode,
                stage=config.stage,
                video=video_path(episode.seed),
                disturbances=() if kinds else None,  # clean, even on a disturbed demonstration
            )
            rollouts.append(result)
            note(result, f"{path.name}: {'success' if result.success else 'failure'}")
            if kinds:
                note(None, f"{path.name}: disturbances")
                drawn = demonstration_disturbances(task, config, episode)
                disturbed_rollout(env, episode.seed, drawn, episode)
    else:
        # The expert evaluated against itself: a seed its expert fails is one of its failures,
        # never skipped (the rollout is the expert check).
        checked = config.expert_check and config.policy != "expert"
        check = ExpertCheck.for_config(task, config) if checked else None
        # the disturbances come with the expert check (one traced run per seed, cached)
        draws = None
        if kinds:
            draws = check if check is not None else ExpertCheck.for_config(task, config)
        max_tries = config.max_tries or 3 * config.episodes
        seed = evaluation_seed(config.seed)
        env = None
        tried = 0
        while len(rollouts) < config.episodes and tried < max_tries:
            tried += 1
            if check is not None:
                note(None, f"expert check, seed {seed}")
                ok, reason = check(seed)
                if not ok:
                    skipped.append({"seed": seed, "reason": f"expert failed: {reason}"})
                    note(None, f"seed {seed} skipped")
                    seed += 1
                    continue
            if env is None:
                env = make_evaluation_env(task, config, seed, config.fps)
            result = rollout(env, policy, seed=seed, video=video_path(seed))
            rollouts.append(result)
            note(result, f"seed {seed}: {'success' if result.success else 'failure'}")
            if draws is not None:
                note(None, f"disturbances, seed {seed}")
                disturbed_rollout(env, seed, draws.disturbances(seed), None)
            seed += 1
    report = _report(task, config, rollouts, skipped, env)
    if kinds:
        report.disturb = kinds
        report.disturbed = _report(task, config, disturbed, not_disturbed, env)
    if env is not None and hasattr(env, "close"):
        env.close()
    if config.policy == "expert":
        for part in (report, report.disturbed):
            if part is not None:
                part.expert_failures = [
                    {"seed": r.seed, "reason": r.error or unmet_stages(part.stages, r)}
                    for r in part.rollouts
                    if not r.success
                ]
    report.seconds = time.perf_counter() - t_start
    _write_outputs(report, config)
    return report


def unmet_stages(stages: list[dict[str, Any]], r: RolloutResult) -> str:
    """Why a rollout that did not raise failed: the stages that did not count."""
    missing = [s["subgoal"] for s, ok in zip(stages, r.completed, strict=True) if not ok]
    return f"stage_not_verified after {r.steps} steps: {', '.join(missing)}"


def _report(
    task: Task,
    config: EvaluateConfig,
    rollouts: list[RolloutResult],
    skipped: list[dict[str, Any]],
    env: Env | None,
) -> EvaluationReport:
    stages = env.stages if env is not None else task.stages(evaluated_scene(task, config))
    info = [
        {"subgoal": s.subgoal, "left": s.left, "right": s.right, "score": s.score} for s in stages
    ]
    first = config.stage or 0
    if not rollouts:
        return EvaluationReport(
            task=task.name,
            policy=config.policy,
            stage=config.stage,
            stages=info,
            rollouts=[],
            skipped=skipped,
            sr=None,
            ssr=None,
            tl=None,
            stage_completion=[0.0] * len(stages),
            coordination=None,
            config=config.model_dump(),
        )
    completed = np.array([r.completed for r in rollouts], dtype=bool)
    credit = np.array([r.credit for r in rollouts], dtype=float)
    successes = [r.success for r in rollouts]
    return EvaluationReport(
        task=task.name,
        policy=config.policy,
        stage=config.stage,
        stages=info,
        rollouts=rollouts,
        skipped=skipped,
        sr=success_rate(successes),
        ssr=stage_success_rate([s.score for s in stages], credit, first),
        tl=trajectory_length([r.steps for r in rollouts], successes),
        stage_completion=[float(c) for c in completed.mean(axis=0)],
        coordination=_coordination(task, rollouts, env),
        config=config.model_dump(),
    )


def evaluated_scene(task: Task, config: EvaluateConfig) -> Scene:
    """The scene of the evaluation's first seed, as its rollout gets it: the first
    demonstration's recorded scene with `data`, else the scene of the first evaluation seed in
    the evaluation's setup (its randomization and split)."""
    if config.data:
        for path in find_episodes(config.data, task.name)[:1]:
            scene = read_episode(path, images=False).scene
            if scene is not None:
                return scene
    return config.episode_setup(task, evaluation_seed(config.seed)).make_scene()


def _coordination(
    task: Task, rollouts: list[RolloutResult], env: Env | None
) -> dict[str, float | None] | None:
    """Dataset-level coordination metrics of the rollouts, under both movement tests (the
    paper's and the jitter-free one), with d0 and MRD/ARD in metres (``docs/metrics.md``)."""
    episodes = []
    n_objects = task.object_count(env.scene) if env is not None else None
    for r in rollouts:
        if r.left_xyz is None or len(r.left_xyz) == 0:
            continue
        try:
            by_test = coordination_by_test(
                r.left_xyz, r.right_xyz, r.grippers[:, 0], r.grippers[:, 1]
            )
        except ValueError:
            continue
        stages = len(r.completed)
        episodes.append(
            EpisodeMetrics(
                f"seed{r.seed}",
                task.name,
                by_test["jitter-free"],
                stages,
                n_objects,
                by_test=by_test,
            )
        )
    return summarize(episodes).overall.columns() if episodes else None


def _write_outputs(report: EvaluationReport, config: EvaluateConfig) -> None:
    root = Path(config.out) / report.task / config.label
    root.mkdir(parents=True, exist_ok=True)
    report.report_path = root / "report.json"
    if report.rollouts:
        report.plot_path = plot_stage_success(report, root / "stage_success.png")
    disturbed = report.disturbed
    if disturbed is not None and disturbed.rollouts:
        path = root / "stage_success_disturbed.png"
        disturbed.plot_path = plot_stage_success(
            disturbed, path, f"disturbed: {','.join(report.disturb)}"
        )
    write_json(report.report_path, report.to_json())


def plot_stage_success(report: EvaluationReport, path: str | Path, note: str = "") -> Path:
    """Bar chart of the share of rollouts that completed each stage (the paper's Figure 5);
    `note` is added to the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bicoord_drake.data.episode import atomic_path

    names = [f"{k}. {s['subgoal']}" for k, s in enumerate(report.stages)]
    values = [100 * c for c in report.stage_completion]
    given = [k < (report.stage or 0) for k in range(len(names))]
    fig, ax = plt.subplots(figsize=(max(4.0, 1.3 * len(names)), 3.6), layout="constrained")
    colors = ["#b0b0b0" if g else "#3a78b5" for g in given]
    bars = ax.bar(range(len(names)), values, color=colors)
    labels = ["given" if g else f"{v:.0f}%" for v, g in zip(values, given, strict=True)]
    ax.bar_label(bars, labels=labels, padding=2, fontsize=8)
    ax.set_xticks(range(len(names)), names, rotation=25, ha="right", fontsize=8)
    ax.set_ylim(0, 110)
    ax.set_ylabel("rollouts that completed the stage (%)")
    where = f", from stage {report.stage}" if report.stage is not None else ""
    where += f", {note}" if note else ""
    ax.set_title(f"{report.task} - {report.policy}{where} (N = {report.n})", fontsize=10)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
    return path

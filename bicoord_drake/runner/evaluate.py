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

from bicoord_drake.data.episode import package_version, read_episode, write_json
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
    evaluation_seed,
    find_episodes,
    make_evaluation_env,
    rollout,
    rollout_station,
)
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

    def to_json(self) -> dict[str, Any]:
        return {
            "task": self.task,
            "policy": self.policy,
            "stage": self.stage,
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
            "report": str(self.report_path) if self.report_path else None,
            "plot": str(self.plot_path) if self.plot_path else None,
            "seconds": round(self.seconds, 3),
            "config": self.config,
            "package_version": package_version(),
        }

    def format_text(self) -> str:
        """The human summary: scores, the per-stage completion table, failures, files."""

        def pct(v: float | None) -> str:
            return "-" if v is None else f"{100 * v:.1f} %"

        where = f" from stage {self.stage}" if self.stage is not None else ""
        lines = [
            f"{self.task} | policy {self.policy}{where} | {self.n} rollouts"
            + (f" | {len(self.skipped)} seeds skipped" if self.skipped else ""),
            f"SR {pct(self.sr)}   SSR {pct(self.ssr)}   "
            f"TL {'-' if self.tl is None else f'{self.tl:.1f}'}",
            "",
            "| k | stage | score | completed |",
            "|---:|---|---:|---:|",
        ]
        first = self.stage or 0
        for k, (s, c) in enumerate(zip(self.stages, self.stage_completion, strict=True)):
            shown = "given" if k < first else pct(c)
            lines.append(f"| {k} | {s['subgoal']} | {s['score']:.2f} | {shown} |")
        if self.coordination:
            c = self.coordination
            lines.append(
                "\ncoordination of the rollouts: "
                + ", ".join(
                    f"{k} {v:.2f}"
                    for k, v in c.items()
                    if v is not None and k not in ("TL", "SN", "ON")
                )
            )
        for s in self.skipped:
            lines.append(f"skipped seed {s['seed']}: {s['reason']}")
        if self.expert_failures is not None:
            lines.append(
                f"expert policy: no seed is skipped; {len(self.expert_failures)} of {self.n} "
                "seeds the expert failed count as failures in SR and SSR"
            )
            for f in self.expert_failures:
                lines.append(f"  expert failed seed {f['seed']}: {f['reason']}")
        if self.failures:
            lines.append("failures: " + ", ".join(f"{why} {n}" for why, n in self.failures.items()))
        diverged = sum(1 for r in self.rollouts if (r.error or "").startswith(DIVERGED))
        if diverged:
            lines.append(
                f"{diverged} of {len(self.rollouts)} rollouts ended when the physics diverged "
                "(counted as failures, with the stages done before)"
            )
        lost = self.failures.get(OBJECT_LEFT_TABLE, 0)
        if lost:
            lines.append(
                f"{lost} of {len(self.rollouts)} rollouts ended early when a task object left "
                "the table (counted as failures, with the stages done before; --no-early-stop "
                "runs them to the step limit)"
            )
        limits = self.out_of_limits
        if limits["actions"]:
            counted = [(r.seed, r.out_of_limits) for r in self.rollouts if r.out_of_limits]
            lines.append(
                f"actions outside the joint limits: {limits['actions']} in "
                f"{limits['rollouts']} of {self.n} rollouts (openings are clipped to [0, 1], "
                f"joints stop at their limits; at most {limits['max_excess']:.3g} beyond)"
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
                lines.append(f"seed {r.seed} failed: {r.error}")
        files = [str(p) for p in (self.report_path, self.plot_path) if p]
        if files:
            lines.append("written: " + ", ".join(files))
        return "\n".join(lines)


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

    def video_path(seed: int) -> Path | None:
        if video_dir is None:
            return None
        suffix = f"_stage{config.stage}" if config.stage is not None else ""
        return video_dir / f"{task.name}_seed{seed}{suffix}.mp4"

    if config.parallel:
        rollouts, skipped, env = run_parallel(task, config, note, video_path)
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
            )
            rollouts.append(result)
            note(result, f"{path.name}: {'success' if result.success else 'failure'}")
    else:
        # The expert evaluated against itself: a seed its expert fails is one of its failures,
        # never skipped (the rollout is the expert check).
        checked = config.expert_check and config.policy != "expert"
        check = ExpertCheck.for_config(task, config) if checked else None
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
            seed += 1
    report = _report(task, config, rollouts, skipped, env)
    if env is not None and hasattr(env, "close"):
        env.close()
    if config.policy == "expert":
        report.expert_failures = [
            {"seed": r.seed, "reason": r.error or unmet_stages(report.stages, r)}
            for r in rollouts
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
    write_json(report.report_path, report.to_json())


def plot_stage_success(report: EvaluationReport, path: str | Path) -> Path:
    """Bar chart of the share of rollouts that completed each stage (the paper's Figure 5)."""
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
    ax.set_title(f"{report.task} - {report.policy}{where} (N = {report.n})", fontsize=10)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
    return path

"""Policy rollouts -> SR / SSR / TL with stage-level detail (PRODUCT.md, Evaluation).

``evaluate(EvaluateConfig(task="jigsaw", policy="my_pkg.policy:Policy"))`` runs the policy on
evaluation seeds ``100000 * (1 + seed)`` upward. A seed whose expert fails (checked by running
the expert in physics, verdict cached per task, seed and settings in
``$BICOORD_CACHE/expert_check/<task>.json``, default ``~/.cache/bicoord_drake``) is skipped and
reported, and the next seed is tried, until ``episodes`` rollouts ran. The ``expert`` policy is
the exception: its rollouts are the check, so a seed its expert fails is a failed rollout,
counted in SR and SSR and listed in the report (``expert_failures``), never skipped. With
``data`` the rollouts are the demonstrations' own seeds and scenes (no expert check: they
succeeded); ``stage = k`` resets each rollout at the start of stage k of its demonstration (see
:mod:`bicoord_drake.env`).

A rollout ends at success (in a stage rollout: when stage k counts) or at the step limit. A
policy that raises, or returns an invalid action (not executed), ends its rollout as a failure;
the error and traceback go to the report and evaluation continues with the next seed.

Scores: SR = successes / N; SSR = (1/N) sum_i sum_j s_j c_ij with c_ij the stage's credit
(partial credit included: cook 0.25 per roll, exchange_mics 0.5 per mic), the mean of the
rollouts' ``info["score"]`` - both from :func:`bicoord_drake.metrics.stage_score`; TL = mean
steps of the successful rollouts (None when none succeeded). In a stage evaluation a rollout
succeeds when stage k counts and scores sum only stages k and later (the earlier ones were
given).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import re
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from bicoord_drake.config import SEED_LIMIT, check_seed_range, parse_resolution
from bicoord_drake.data.episode import (
    Episode,
    decode_rgb,
    encode_jpeg,
    package_version,
    read_episode,
    write_json,
    write_video,
)
from bicoord_drake.env import EVAL_SEED_START, Env, InvalidActionError, make_env
from bicoord_drake.metrics import (
    coordination_metrics,
    stage_success_rate,
    success_rate,
    trajectory_length,
)
from bicoord_drake.metrics.report import EpisodeMetrics, summarize
from bicoord_drake.policies import bind_policy, load_policy, reset_policy
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Task


def evaluation_seed(seed: int) -> int:
    """The first evaluation seed for CLI ``--seed``: ``100000 * (1 + seed)``."""
    return EVAL_SEED_START * (1 + int(seed))


class EvaluateConfig(BaseModel):
    """Settings of one evaluation (every field is a flag of scripts/evaluate.py)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    task: str
    policy: str = Field(description="built-in name or package.module:name")
    episodes: int = Field(100, ge=1, description="rollouts to run")
    seed: int = Field(
        0, ge=0, description="evaluation seeds start at 100000 * (1 + seed), below 2**32"
    )
    data: str | None = Field(None, description="demonstrations: their seeds and scenes")
    stage: int | None = Field(None, ge=0, description="reset at the start of this stage")
    video: str | None = Field(None, description="directory for head-camera rollout videos")
    out: str = Field("eval", description="report directory root")
    resolution: str = "320x240"
    render: bool = True
    depth: bool = False
    randomize: bool = Field(
        False, description="randomized textures, lights, table height, camera jitter, clutter"
    )
    split: Literal["seen", "unseen"] = Field(
        "unseen", description="instructions and (with randomize) textures of this split"
    )
    action_mode: Literal["qpos", "endpose"] = "qpos"
    fps: float = Field(15.0, gt=0, le=100, description="control rate (data: from the files)")
    step_limit: int | None = Field(None, ge=1, description="override the task's step limit")
    expert_check: bool = True
    max_tries: int = Field(0, ge=0, description="seeds to try at most (0: 3 x episodes)")
    workers: int = Field(
        0, ge=0, le=100_000, description="rollouts in flight (0: 1 locally, every CPU on Ray)"
    )
    backend: Literal["local", "ray"] = "local"
    ray_address: str | None = Field(None, description="join this Ray cluster (auto, HOST:PORT)")
    verbose: bool = Field(False, description="workers' Drake and Ray logs on the terminal")

    @field_validator("resolution")
    @classmethod
    def _resolution(cls, value: str) -> str:
        parse_resolution(value)
        return value

    @model_validator(mode="after")
    def _consistent(self) -> EvaluateConfig:
        if self.policy == "replay" and not self.data:
            raise ValueError("the replay policy needs demonstrations: give data (--data DIR)")
        if self.stage is not None and not self.data:
            raise ValueError("a stage evaluation needs demonstrations: give data (--data DIR)")
        if self.video and not self.render:
            raise ValueError("video needs rendering: drop --no-render")
        if not self.data:
            first = evaluation_seed(self.seed)
            largest = SEED_LIMIT // EVAL_SEED_START - 1
            if first >= SEED_LIMIT:
                raise ValueError(
                    f"seed {self.seed}: evaluation seeds would start at 100000 * (1 + seed) = "
                    f"{first}, past the largest seed 2**32 - 1; use a seed <= {largest}"
                )
            check_seed_range(first, self.max_tries or 3 * self.episodes, "evaluation seed")
        if self.ray_address and self.backend != "ray":
            raise ValueError("ray_address is a setting of the ray backend: add backend='ray'")
        return self

    @property
    def parallel(self) -> bool:
        """Rollouts run as backend jobs (Ray, or several local processes)."""
        return self.backend != "local" or self.workers > 1

    @property
    def label(self) -> str:
        """A file-name-safe name of the policy (and stage)."""
        name = re.sub(r"[^A-Za-z0-9_.-]+", "-", self.policy).strip("-")
        return name + (f"_stage{self.stage}" if self.stage is not None else "")


@dataclass
class RolloutResult:
    """One rollout: outcome, per-stage completion, and the error if it failed by raising."""

    seed: int
    success: bool
    score: float
    steps: int
    completed: list[bool]
    credit: list[float]
    start_stage: int = 0
    episode: str | None = None
    error: str | None = None
    traceback: str | None = None
    video: str | None = None
    seconds: float = 0.0
    left_xyz: np.ndarray | None = field(default=None, repr=False)
    right_xyz: np.ndarray | None = field(default=None, repr=False)
    grippers: np.ndarray | None = field(default=None, repr=False)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("left_xyz", "right_xyz", "grippers"):
            out.pop(key)
        return out


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
        for r in self.rollouts:
            if r.error:
                lines.append(f"seed {r.seed} failed: {r.error}")
        files = [str(p) for p in (self.report_path, self.plot_path) if p]
        if files:
            lines.append("written: " + ", ".join(files))
        return "\n".join(lines)


# --------------------------------------------------------------------------- rollouts
def rollout(
    env: Env,
    policy: Any,
    *,
    seed: int | None = None,
    episode: Episode | None = None,
    stage: int | None = None,
    video: str | Path | None = None,
) -> RolloutResult:
    """Run one rollout of `policy` in `env` until done; never raises for policy faults."""
    t0 = time.perf_counter()
    obs = env.reset(seed, stage=stage, episode=episode)
    frames: list[bytes] = []
    left, right, grippers = [], [], []
    error = tb = None

    def record(o: dict[str, Any]) -> None:
        if video is not None and "head_camera" in o:
            frames.append(encode_jpeg(o["head_camera"]))

    record(obs)
    who = "policy"
    try:
        bind_policy(policy, env)
        reset_policy(policy, env.instruction)
        while not env.done:
            tcp = (obs["left_endpose"][:3], obs["right_endpose"][:3])
            who = "policy"
            action = policy.act(obs)
            who = "simulation"
            obs, _ = env.step(action)
            left.append(tcp[0])
            right.append(tcp[1])
            grippers.append(env.action[[6, 13]])
            record(obs)
    except InvalidActionError as exc:
        error, tb = f"invalid action at step {env.steps}: {exc}", traceback.format_exc()
    except Exception as exc:  # a fault ends this rollout only
        error = f"{who} raised at step {env.steps}: {type(exc).__name__}: {exc}"
        tb = traceback.format_exc()
    info = env.info()
    target = env.stage
    done = info["completed"][target] if target is not None else info["success"]
    success = bool(done) and error is None
    result = RolloutResult(
        seed=int(env.seed),
        success=success,
        score=float(info["score"]),
        steps=env.steps,
        completed=[bool(c) for c in info["completed"]],
        credit=[float(c) for c in info["credit"]],
        start_stage=env.start_stage,
        episode=str(episode.path) if episode is not None else None,
        error=error,
        traceback=tb,
        left_xyz=np.array(left).reshape(-1, 3),
        right_xyz=np.array(right).reshape(-1, 3),
        grippers=np.array(grippers).reshape(-1, 2),
    )
    if video is not None and frames:
        path = write_video(video, (decode_rgb(f) for f in frames), env.config.control_rate)
        result.video = str(path)
    result.seconds = round(time.perf_counter() - t0, 3)
    return result


# --------------------------------------------------------------------------- expert check
def cache_dir() -> Path:
    """$BICOORD_CACHE or ~/.cache/bicoord_drake."""
    root = os.environ.get("BICOORD_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "bicoord_drake"
    )
    return Path(root)


@functools.cache
def code_fingerprint() -> str:
    """A short hash of the package's Python sources: changes whenever any expert, planner or
    simulation code changes, released or not."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


class ExpertCheck:
    """Whether the expert solves (task, seed) in physics, cached in a small JSON file.

    The key holds the control rate, the package version and :func:`code_fingerprint`, so an
    expert changed in any way (an edited checkout included) is checked again.
    """

    def __init__(self, task: Task, fps: float, path: Path | None = None) -> None:
        self.task, self.fps = task, float(fps)
        self.path = path or cache_dir() / "expert_check" / f"{task.name}.json"
        try:
            self._cache = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            self._cache = {}

    def _key(self, seed: int) -> str:
        return f"{seed}@{self.fps:g}Hz@{package_version()}+{code_fingerprint()}"

    def __call__(self, seed: int) -> tuple[bool, str | None]:
        """(ok, reason) for `seed`, from the cache or by running the expert."""
        if self.lookup(seed) is None:
            self.store(seed, expert_verdict(self.task, seed, self.fps))
        return self.lookup(seed)

    def lookup(self, seed: int) -> tuple[bool, str | None] | None:
        """The cached (ok, reason) of `seed`, None if not checked yet."""
        v = self._cache.get(self._key(seed))
        return None if v is None else (bool(v["ok"]), v.get("reason"))

    def store(self, seed: int, verdict: dict[str, Any]) -> None:
        """Cache a verdict of :func:`expert_verdict` (e.g. one a worker computed)."""
        self._cache[self._key(seed)] = verdict
        try:
            write_json(self.path, self._cache)
        except OSError:
            pass  # the cache is an optimisation


def expert_verdict(task: Task, seed: int, fps: float) -> dict[str, Any]:
    """``{"ok": ..., "reason": ...}``: whether the expert solves `seed` in physics (no cameras)."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.runner.generate import format_failure, run_expert

    try:
        result = run_expert(task, seed, StationConfig(control_rate=fps, render=False))
        return {"ok": result.success, "reason": result.reason}
    except Exception as exc:  # an expert crash is a failed seed, not a failed run
        return {"ok": False, "reason": f"expert crashed: {format_failure(exc)}"}


# --------------------------------------------------------------------------- evaluation
def find_episodes(data: str | Path, task: str) -> list[Path]:
    """Episode files of `task` under `data` (a file or a directory, searched recursively)."""
    import h5py

    root = Path(data)
    if root.is_file():
        paths = [root]
    elif root.is_dir():
        paths = sorted(root.rglob("*.hdf5"), key=_natural_key)
    else:
        raise ValueError(f"--data {root}: no such file or directory")
    out = []
    for p in paths:
        try:
            with h5py.File(p, "r") as f:
                name = f.attrs.get("task")
        except OSError:
            continue
        name = name.decode() if isinstance(name, bytes) else name
        if name == task:
            out.append(p)
    if not out:
        raise ValueError(f"--data {root}: no episode files of task {task!r}")
    return out


def _natural_key(path: Path) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", str(path))]


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
    policy = load_policy(config.policy)
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
        from bicoord_drake.runner.evaluate_parallel import run_parallel

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
            if env is None or env.config.control_rate != episode.fps:
                env = _make_env(task, config, episode.seed, episode.fps)
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
        check = ExpertCheck(task, config.fps) if checked else None
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
                env = _make_env(task, config, seed, config.fps)
            result = rollout(env, policy, seed=seed, video=video_path(seed))
            rollouts.append(result)
            note(result, f"seed {seed}: {'success' if result.success else 'failure'}")
            seed += 1
    report = _report(task, config, rollouts, skipped, env)
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


def _make_env(task: Task, config: EvaluateConfig, seed: int, fps: float) -> Env:
    return make_env(
        task,
        seed,
        action_mode=config.action_mode,
        resolution=config.resolution,
        depth=config.depth,
        render=config.render,
        fps=fps,
        split=config.split,
        randomize=config.randomize,
        step_limit=config.step_limit,
    )


def _report(
    task: Task,
    config: EvaluateConfig,
    rollouts: list[RolloutResult],
    skipped: list[dict[str, Any]],
    env: Env | None,
) -> EvaluationReport:
    stages = env.stages if env is not None else task.stages(task.sample_scene(0))
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


def _coordination(
    task: Task, rollouts: list[RolloutResult], env: Env | None
) -> dict[str, float | None] | None:
    """Dataset-level coordination metrics of the rollouts (SMP, MRD, ARD, STI in percent)."""
    episodes = []
    n_objects = task.object_count(env.scene) if env is not None else None
    for r in rollouts:
        if r.left_xyz is None or len(r.left_xyz) == 0:
            continue
        try:
            c = coordination_metrics(r.left_xyz, r.right_xyz, r.grippers[:, 0], r.grippers[:, 1])
        except ValueError:
            continue
        stages = len(r.completed)
        episodes.append(EpisodeMetrics(f"seed{r.seed}", task.name, c, stages, n_objects))
    return summarize(episodes).overall.as_dict() if episodes else None


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

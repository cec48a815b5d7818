"""Evaluation rollouts as backend jobs (Ray, or local processes): ``evaluate`` with
``backend="ray"`` or ``workers > 1`` comes here.

Each job is one seed (or one demonstration): the expert check when its verdict is not cached,
then the rollout, in a worker that keeps one environment and one policy instance for the jobs it
runs. The driver keeps the expert-check cache, writes the videos (workers return their bytes:
no shared file system needed) and gathers the results in seed order, so the report is the one a
sequential evaluation gives: the first ``episodes`` seeds whose expert succeeds.

With disturbances (``EvaluateConfig.disturb``) a job also runs the seed's disturbed rollout,
after the clean one, in the same worker; the disturbances drawn for the seed come from the
driver's cache when it has them, else the worker's expert check draws them (a traced run, one
per seed) and the driver caches them with the verdict.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bicoord_drake.config import StationConfig
from bicoord_drake.data.episode import Episode, atomic_path, read_episode
from bicoord_drake.env import Env
from bicoord_drake.models.scene import Scene
from bicoord_drake.runner.backends import make_backend, quiet_worker
from bicoord_drake.runner.rollouts import (
    EvaluateConfig,
    ExpertCheck,
    RolloutResult,
    demonstration_disturbances,
    drawn_from_json,
    evaluation_seed,
    expert_verdict,
    find_episodes,
    make_evaluation_env,
    recorded_disturbances,
    rollout,
    rollout_station,
)
from bicoord_drake.sim.disturbances import Disturbance, schedule_of
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Task


@dataclass
class SceneStages:
    """The scene and stages of the last rollout (what the report reads from an env)."""

    scene: Scene
    stages: tuple


@dataclass
class RolloutOutcome:
    """A job's answer: the expert verdict if it was checked, the rollout if it ran; with
    disturbances, the disturbed rollout, or why the seed has none (`not_disturbed`)."""

    seed: int
    verdict: dict[str, Any] | None = None
    result: RolloutResult | None = None
    video: bytes | None = None
    disturbed: RolloutResult | None = None
    disturbed_video: bytes | None = None
    not_disturbed: str | None = None


_WORKER: dict[str, Any] = {}
_ENV_FIELDS = {"policy", "action_mode", "step_limit", "early_stop"}
"""With the scenario but its seed range and the rollout's station, the settings a worker's
environment and policy are built with: another value builds anew."""


def rollout_job(
    config: EvaluateConfig,
    seed: int,
    episode: Episode | None,
    check: bool,
    video: bool,
    drawn: dict[str, Disturbance | str] | None = None,
) -> RolloutOutcome:
    """In a worker: the expert check of `seed` (if asked), then one rollout of the policy;
    with the config's disturbances, then the disturbed rollout, with the disturbances `drawn`
    for the seed (None: drawn here, by the expert check's traced run, or for a demonstration
    by :func:`~bicoord_drake.runner.rollouts.demonstration_disturbances`)."""
    quiet_worker(config.verbose)
    task = get_task(config.task)
    outcome = RolloutOutcome(seed)
    kinds = config.disturb
    draw = bool(kinds) and drawn is None and episode is None
    if check or draw:
        outcome.verdict = expert_verdict(config.episode_setup(task, seed), kinds if draw else ())
        if draw:
            drawn = drawn_from_json(outcome.verdict["disturbances"])
        if check and not outcome.verdict["ok"]:
            return outcome
    station = rollout_station(config, episode) if episode is not None else config.station
    env, policy = _worker_env(task, config, seed, station)

    def run(disturbances: Any) -> tuple[RolloutResult, bytes | None]:
        with tempfile.TemporaryDirectory(prefix="bicoord-rollout-") as tmp:
            path = Path(tmp) / "rollout.mp4" if video else None
            result = rollout(
                env,
                policy,
                seed=None if episode is not None else seed,
                episode=episode,
                stage=config.stage,
                video=path,
                disturbances=disturbances,
            )
            data = path.read_bytes() if path is not None and path.exists() else None
        result.video = None
        return result, data

    outcome.result, outcome.video = run(() if kinds else None)
    if kinds:
        if drawn is None:  # a demonstration's: recorded, or traced here
            drawn = demonstration_disturbances(task, config, episode)
        schedule, outcome.not_disturbed = schedule_of(drawn, kinds)
        if outcome.not_disturbed is None:
            outcome.disturbed, outcome.disturbed_video = run(schedule)
    return outcome


def _worker_env(
    task: Task, config: EvaluateConfig, seed: int, station: StationConfig
) -> tuple[Env, Any]:
    """This worker's environment and policy for `config` on `station` (made once, reused
    across jobs)."""
    from bicoord_drake.policies import action_size_of, close_policy, load_policy_for

    scenario = config.scenario.model_dump(exclude={"seed", "episodes", "station"})
    key = repr((config.model_dump(include=_ENV_FIELDS), scenario, station.model_dump()))
    if _WORKER.get("key") != key:
        close_policy(_WORKER.get("policy"))
        if _WORKER.get("env") is not None:
            _WORKER["env"].close()
        _WORKER.clear()
        _WORKER.update(
            key=key,
            env=make_evaluation_env(task, config, seed, station=station),
            policy=load_policy_for(
                config.policy, action_size=action_size_of(config.embodiment, config.action_mode)
            ),
        )
    return _WORKER["env"], _WORKER["policy"]


def run_parallel(
    task: Task,
    config: EvaluateConfig,
    note: Callable[[RolloutResult | None, str], None],
    video_path: Callable[..., Path | None],
) -> tuple[
    tuple[list[RolloutResult], list[dict[str, Any]], SceneStages | None],
    tuple[list[RolloutResult], list[dict[str, Any]]],
]:
    """Rollouts and skipped seeds (both in seed order) and the last rollout's scene; and
    the disturbed rollouts and the seeds without one (empty without disturbances).
    `video_path(seed, disturbed=False)`: where a rollout's video goes (None: nowhere)."""
    episodes = _demonstrations(task, config) if config.data else None
    # as in a sequential run: the expert policy's rollouts are its check (a failed seed counts)
    checked = config.expert_check and not config.data and config.policy != "expert"
    check = ExpertCheck.for_config(task, config) if checked else None
    kinds = config.disturb
    draws = None  # where the disturbances drawn for the seeds are cached (not for --data)
    if kinds and not config.data:
        draws = check if check is not None else ExpertCheck.for_config(task, config)
    max_tries = len(episodes) if episodes is not None else config.max_tries or 3 * config.episodes
    # keyed by submission order (= seed order; demonstrations may share a seed)
    done: dict[int, RolloutResult] = {}
    skipped: dict[int, dict[str, Any]] = {}
    disturbed: dict[int, RolloutResult] = {}
    not_disturbed: dict[int, dict[str, Any]] = {}
    scenes: dict[int, Scene | None] = {}
    pending: dict[Any, tuple[int, int]] = {}
    tried, seed = 0, evaluation_seed(config.seed)

    def skip(order: int, seed: int, reason: str) -> None:
        skipped[order] = {"seed": seed, "reason": reason}
        note(None, f"seed {seed} skipped")

    def keep_video(result: RolloutResult, data: bytes | None, target: Path | None) -> None:
        if target is not None and data is not None:
            with atomic_path(target) as tmp:
                tmp.write_bytes(data)
            result.video = str(target)

    with make_backend(config.backend, config.workers, config.ray_address, config.verbose) as pool:
        while True:
            while (
                len(pending) < pool.slots
                and len(done) + len(pending) < config.episodes
                and tried < max_tries
            ):
                order, episode = tried, episodes[tried] if episodes is not None else None
                tried += 1
                if episode is not None:
                    seed = episode.seed
                    if not episode.success:
                        skip(order, seed, f"{episode.path}: not a success")
                        continue
                cached = check.lookup(seed) if check is not None else None
                if cached is not None and not cached[0]:
                    skip(order, seed, f"expert failed: {cached[1]}")
                else:
                    want_check = check is not None and cached is None
                    video = video_path(seed) is not None
                    drawn = draws.lookup_disturbances(seed) if draws is not None else None
                    if episode is not None and kinds:
                        drawn = recorded_disturbances(config, episode)
                    job = pool.submit(rollout_job, config, seed, episode, want_check, video, drawn)
                    pending[job] = (order, seed)
                    scenes[order] = episode.scene if episode is not None else None
                seed += 1
            if not pending:
                break
            job = pool.wait(list(pending))
            order, job_seed = pending.pop(job)
            outcome: RolloutOutcome = pool.result(job)
            if outcome.verdict is not None:
                (check if check is not None else draws).store(job_seed, outcome.verdict)
                if check is not None and not outcome.verdict["ok"]:
                    skip(order, job_seed, f"expert failed: {outcome.verdict.get('reason')}")
                    continue
            result = outcome.result
            keep_video(result, outcome.video, video_path(job_seed))
            done[order] = result
            note(result, f"seed {job_seed}: {'success' if result.success else 'failure'}")
            if outcome.disturbed is not None:
                keep_video(
                    outcome.disturbed,
                    outcome.disturbed_video,
                    video_path(job_seed, disturbed=True),
                )
                disturbed[order] = outcome.disturbed
                ok = "success" if outcome.disturbed.success else "failure"
                note(outcome.disturbed, f"seed {job_seed} disturbed: {ok}")
            elif outcome.not_disturbed is not None:
                not_disturbed[order] = {"seed": job_seed, "reason": outcome.not_disturbed}
                note(None, f"seed {job_seed}: no disturbed rollout")
    rollouts = [done[k] for k in sorted(done)]
    info = None
    if done:
        last = max(done)
        scene = scenes.get(last) or config.episode_setup(task, done[last].seed).make_scene()
        info = SceneStages(scene, tuple(task.stages(scene)))
    return (rollouts, [skipped[k] for k in sorted(skipped)], info), (
        [disturbed[k] for k in sorted(disturbed)],
        [not_disturbed[k] for k in sorted(not_disturbed)],
    )


def _demonstrations(task: Task, config: EvaluateConfig) -> list[Episode]:
    """The demonstrations to roll out (read here: workers need no access to the files)."""
    out = []
    for path in find_episodes(config.data, task.name)[: config.episodes]:
        episode = read_episode(path, images=False)
        if config.stage is not None and config.stage >= len(episode.stages):
            raise ValueError(f"--stage {config.stage}: {path} has {len(episode.stages)} stages")
        out.append(episode)
    return out

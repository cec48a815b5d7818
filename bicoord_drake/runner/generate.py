"""Seeds -> verified expert demonstrations on disk.

``generate(GenerateConfig(task="jigsaw", episodes=3))`` tries seeds from ``seed`` upward until
``episodes`` demonstrations succeed. For each seed it samples the task's scene, builds the
station, runs the expert *in physics* through the station's action path with the stage monitor
watching every control step, and keeps the episode only if every stage verified. Failures (a
planning error, a stage that did not verify, the step limit) are recorded with their reason in
``manifest.json``, which is rewritten after every seed: an interrupted run resumes where it
stopped, and no partial episode file ever appears (files are written to a temporary name and
renamed).
"""

from __future__ import annotations

import os
import re
import time
import traceback
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from bicoord_drake.config import (
    SEED_LIMIT,
    CameraConfig,
    StationConfig,
    check_seed,
    check_seed_range,
    parse_resolution,
)
from bicoord_drake.data.episode import (
    EpisodeEntry,
    EpisodeLayout,
    EpisodeMeta,
    EpisodeRecorder,
    Manifest,
    read_manifest,
    save_episode,
    write_manifest,
)
from bicoord_drake.models.scene import Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station
from bicoord_drake.stages import StageMonitor, WorldState
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Task, WorldView


class GenerateConfig(BaseModel):
    """Settings of one generation run (every field is a CLI flag of scripts/generate.py)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    task: str
    episodes: int = Field(10, ge=1, description="successful episodes to produce")
    seed: int = Field(0, description="first seed to try, in [0, 2**32)")
    out: str = "data"
    resolution: str = "320x240"
    fps: float = Field(15.0, gt=0, le=100, description="control and recording rate, Hz")
    depth: bool = False
    render: bool = True
    config_name: str = Field("default", pattern=r"^[A-Za-z0-9_.-]+$")
    max_tries: int = Field(0, ge=0, description="give up after this many seeds (0: 5x episodes)")
    video: bool = True
    workers: int = Field(1, ge=1, le=64, description="seeds run in parallel processes")

    @field_validator("resolution")
    @classmethod
    def _resolution(cls, value: str) -> str:
        parse_resolution(value)
        return value

    @field_validator("seed")
    @classmethod
    def _seed(cls, value: int) -> int:
        return check_seed(value)

    @model_validator(mode="after")
    def _seeds_in_range(self) -> GenerateConfig:
        check_seed_range(self.seed, self.max_tries or 5 * self.episodes)
        return self

    def station_config(self) -> StationConfig:
        width, height = parse_resolution(self.resolution)
        cameras = CameraConfig(width=width, height=height, depth=self.depth)
        return StationConfig(control_rate=self.fps, render=self.render, cameras=cameras)

    def data_settings(self) -> dict:
        """The settings that shape the data: a resumed run must match them."""
        return self.model_dump(include={"task", "resolution", "fps", "depth", "render"})


@dataclass
class EpisodeResult:
    """What one seed produced: a recorder and annotations on success, a reason otherwise."""

    seed: int
    success: bool
    reason: str | None = None
    recorder: EpisodeRecorder | None = None
    rows: list = field(default_factory=list)
    instruction: str = ""
    scene: Scene | None = None
    timings: dict[str, float] = field(default_factory=dict)


def run_expert(
    task: Task, seed: int, station_config: StationConfig, depth: bool = False
) -> EpisodeResult:
    """Run `task`'s expert for `seed` in physics and verify every stage.

    Any failure of the seed (planning, a stage not verified, an annotation that cannot be made)
    is returned with its reason; a ValueError only for a seed outside [0, 2**32)."""
    seed = check_seed(seed)
    t0 = time.perf_counter()
    scene = task.sample_scene(seed)
    sim = Simulation(build_station(scene, station_config))
    monitor = StageMonitor(task.stages(scene))
    recorder = EpisodeRecorder(
        fps=station_config.control_rate, initial_action=sim.station.embodiment.home_action()
    )
    instruction = task.instruction(np.random.default_rng(seed), "seen")
    t_build = time.perf_counter()
    action = sim.station.embodiment.home_action()
    try:
        for action in task.expert(scene, WorldView(sim)):
            if len(recorder) >= task.step_limit:
                return EpisodeResult(
                    seed,
                    False,
                    f"step_limit: expert exceeded {task.step_limit} steps",
                    timings=_since(t0, t_build),
                )
            recorder.capture(sim, action, depth=depth)
            sim.step(action)
            monitor.update(WorldState.capture(sim, action, scene))
    except PlanningError as err:
        return EpisodeResult(seed, False, f"planning: {err}", timings=_since(t0, t_build))
    monitor.finish(WorldState.capture(sim, action, scene))
    timings = _since(t0, t_build)
    if not monitor.success:
        failed = [
            s.subgoal for s, ok in zip(monitor.stages, monitor.completed(), strict=True) if not ok
        ]
        return EpisodeResult(
            seed, False, f"stage_not_verified: {', '.join(failed)}", timings=timings
        )
    try:
        rows = monitor.annotations(len(recorder))
    except ValueError as err:  # cannot happen when success holds; never a crash of the run
        return EpisodeResult(seed, False, f"annotation: {err}", timings=timings)
    return EpisodeResult(
        seed,
        True,
        recorder=recorder,
        rows=rows,
        instruction=instruction,
        scene=scene,
        timings=timings,
    )


def _since(t0: float, t_build: float) -> dict[str, float]:
    now = time.perf_counter()
    return {"build": round(t_build - t0, 3), "expert": round(now - t_build, 3)}


@dataclass
class GenerateSummary:
    """The outcome of a run (also what the CLI prints)."""

    root: Path
    kept: int
    tried: int
    failures: list[EpisodeEntry]
    mean_length: float | None
    seconds_per_episode: float | None
    metrics_table: str | None


def generate(
    config: GenerateConfig, progress: Callable[[int, int, int, str], None] | None = None
) -> GenerateSummary:
    """Produce `config.episodes` verified episodes (resuming a previous run in the same
    directory). `progress(kept, tried, target, message)` is called after every seed.

    With ``config.workers > 1`` seeds run in a pool of processes; this process alone assigns
    episode indices (in the order episodes finish), writes files and the manifest."""
    task = get_task(config.task)
    layout = EpisodeLayout(Path(config.out), task.name, config.config_name)
    layout.make_dirs()
    manifest = _open_manifest(layout, config)
    station_config = config.station_config()
    max_tries = config.max_tries or 5 * config.episodes
    tried_seeds = {e.seed for e in manifest.episodes}
    next_seed = max(tried_seeds) + 1 if tried_seeds else config.seed
    started = time.perf_counter()
    pool = _pool(config.workers)
    pending: dict[Future, int] = {}
    try:
        while True:
            kept, tried = _kept(manifest, layout), len(manifest.episodes)
            while (
                len(pending) < config.workers
                and kept + len(pending) < config.episodes
                and tried + len(pending) < max_tries
                and next_seed < SEED_LIMIT
            ):
                pending[
                    pool.submit(_run_seed, task.name, next_seed, station_config, config.depth)
                ] = next_seed
                next_seed += 1
            if not pending:
                break
            done = next(as_completed(pending))
            seed = pending.pop(done)
            _record(done.result(), seed, task, layout, manifest, config, station_config)
            if progress:
                last = manifest.episodes[-1]
                message = f"seed {seed}: " + ("kept" if last.success else last.reason or "")
                progress(_kept(manifest, layout), len(manifest.episodes), config.episodes, message)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return _summary(layout, manifest, time.perf_counter() - started)


def _run_seed(
    task_name: str, seed: int, station_config: StationConfig, depth: bool
) -> EpisodeResult:
    """One seed, in a worker process (or inline): an unexpected error of the seed (a bug in an
    expert, a simulator fault) is that seed's failure with its reason, not the run's end."""
    try:
        return run_expert(get_task(task_name), seed, station_config, depth=depth)
    except Exception as exc:  # noqa: BLE001 - recorded in the manifest with the traceback's tail
        return EpisodeResult(seed, False, f"crashed: {format_failure(exc)}")


def _record(
    result: EpisodeResult,
    seed: int,
    task: Task,
    layout: EpisodeLayout,
    manifest: Manifest,
    config: GenerateConfig,
    station_config: StationConfig,
) -> None:
    """Write a kept episode's files, then the manifest entry of this seed."""
    entry = EpisodeEntry(
        seed=seed, success=result.success, reason=result.reason, timings=result.timings
    )
    if result.success:
        index = _kept(manifest, layout)
        t_write = time.perf_counter()
        meta = EpisodeMeta(
            task=task.name,
            seed=seed,
            instruction=result.instruction,
            embodiment=station_config.embodiment,
            success=True,
            object_count=task.object_count(result.scene),
            config=config.model_dump(),
            scene=result.scene,
        )
        save_episode(
            layout,
            index,
            result.recorder,
            result.rows,
            meta,
            instructions_seen=task.instructions("seen"),
            instructions_unseen=task.instructions("unseen"),
            video=config.video and config.render,
        )
        entry.index, entry.frames = index, len(result.recorder)
        entry.timings["write"] = round(time.perf_counter() - t_write, 3)
    manifest.episodes.append(entry)
    manifest.timings["total"] = round(
        manifest.timings.get("total", 0.0) + sum(entry.timings.values()), 3
    )
    write_manifest(layout.root, manifest)


class _InlinePool:
    """The one-worker 'pool': runs each seed in this process when it is submitted."""

    def submit(self, fn, *args) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - re-raised by future.result()
            future.set_exception(exc)
        return future

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        pass


def _pool(workers: int):
    if workers <= 1:
        return _InlinePool()
    threads = str(max(1, (os.cpu_count() or 1) // workers))
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=get_context("spawn"),
        initializer=_limit_threads,
        initargs=(threads,),
    )


def _limit_threads(threads: str) -> None:
    # Mesa's software renderer otherwise starts one thread per core in every worker.
    os.environ["LP_NUM_THREADS"] = threads


def _open_manifest(layout: EpisodeLayout, config: GenerateConfig) -> Manifest:
    if not layout.manifest.exists():
        return Manifest(
            task=config.task, config_name=config.config_name, config=config.data_settings()
        )
    manifest = read_manifest(layout.root)
    if manifest.config != config.data_settings():
        raise ValueError(
            f"{layout.root} holds data generated with different settings {manifest.config}; "
            "use another --out or --config-name to generate with these settings"
        )
    # An episode whose file is missing (e.g. deleted) is forgotten so its seed can be redone.
    manifest.episodes = [
        e for e in manifest.episodes if not e.success or layout.episode(e.index).exists()
    ]
    return manifest


def _kept(manifest: Manifest, layout: EpisodeLayout) -> int:
    return sum(1 for e in manifest.episodes if e.success)


def _summary(layout: EpisodeLayout, manifest: Manifest, elapsed: float) -> GenerateSummary:
    kept = [e for e in manifest.episodes if e.success]
    table = None
    if kept:
        from bicoord_drake.metrics.report import format_table, measure_paths

        metrics, _, _ = measure_paths([layout.root / "data"], "bicoord_drake")
        table = format_table(metrics) if metrics else None
    seconds = manifest.timings.get("total")
    return GenerateSummary(
        root=layout.root,
        kept=len(kept),
        tried=len(manifest.episodes),
        failures=[e for e in manifest.episodes if not e.success],
        mean_length=float(np.mean([e.frames for e in kept])) if kept else None,
        seconds_per_episode=seconds / len(kept) if kept and seconds else None,
        metrics_table=table,
    )


def format_failure(exc: BaseException) -> str:
    """One line for an unexpected error (the CLI shows it; the traceback goes to the log)."""
    text = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    return re.sub(r"\s+", " ", text)

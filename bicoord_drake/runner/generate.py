"""Seeds -> verified expert demonstrations on disk.

``generate(GenerateConfig(task="jigsaw", episodes=3))`` tries seeds from ``seed`` upward until
``episodes`` demonstrations succeed. For each seed it assembles the episode from the run's
scenario (:meth:`GenerateConfig.episode_setup`, :func:`bicoord_drake.episode_setup.assemble`:
scene, station, monitor), runs the expert *in physics* through the station's action path with
the stage monitor watching every control step, and keeps the episode only if every stage
verified. Failures (a
planning error, a stage that did not verify, the step limit) are recorded with their reason in
``manifest.json``, which is rewritten after every seed: an interrupted run resumes where it
stopped, and no partial episode file ever appears (files are written to a temporary name and
renamed). Every episode file records the scenario that made it (its ``scenario`` attribute:
the run's scenario at that task and seed), every manifest the run's scenario, so
``load_scenario(EPISODE)`` gives back the settings that make the episode again.

``generate_dataset`` does the same for several tasks in one run (``task="all"``: every task
that supports the run's robot, ``Task.supported_robots``; or a comma list) and writes
``<out>/dataset_<config_name>.json``. Seeds run as jobs of a backend
(:mod:`bicoord_drake.runner.backends`: this process, local processes, or Ray). Workers encode
a kept episode's files; by default they return them as bytes and this process writes them
(no shared file system needed); local workers, and Ray workers with ``shared_fs``, write them
under ``<task dir>/.staging/`` and this process renames them into place. Only this process
assigns episode indices and writes manifests, so a retried seed cannot make a duplicate.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator

from bicoord_drake.config import SEED_LIMIT, StationConfig, check_seed_range
from bicoord_drake.data.episode import (
    SCHEMA_VERSION,
    EpisodeEntry,
    EpisodeLayout,
    EpisodeMeta,
    EpisodeRecorder,
    Manifest,
    atomic_path,
    package_version,
    read_episode,
    read_manifest,
    save_episode,
    write_json,
    write_manifest,
)
from bicoord_drake.episode_setup import EpisodeSetup, assemble
from bicoord_drake.models.embodiment import SIDES
from bicoord_drake.models.layout import ActionLayout, default_embodiment
from bicoord_drake.models.scene import Scene
from bicoord_drake.planning.errors import PlanningError
from bicoord_drake.runner.backends import WorkerLost, make_backend, quiet_worker
from bicoord_drake.runner.stopwatch import Stopwatch
from bicoord_drake.scenario import (
    GENERATION_DEFAULTS,
    ActionNoise,
    RunConfig,
    action_noise_draw,
    parse_action_noise,
)
from bicoord_drake.sim.disturbances import (
    Disturbance,
    DisturbanceDriver,
    ExpertTrace,
    NoDisturbanceWindow,
    disturbance_records,
    parse_disturb,
    plan_disturbances,
    recovery_row,
    schedule_of,
)
from bicoord_drake.sim.frame_renderer import FrameRenderer
from bicoord_drake.stages import WorldState
from bicoord_drake.tasks import get_task
from bicoord_drake.tasks.base import Task, WorldView, expert_actions, step_limit_at


def default_config_name(
    randomize: bool = False,
    embodiment: str | None = None,
    noisy: bool = False,
    disturbed: bool = False,
) -> str:
    """The settings directory under ``<out>/<task>/``: ``default`` or ``randomized`` for the
    default robot, ``<embodiment>`` or ``<embodiment>_randomized`` for another one; with
    action noise (`noisy`) ``_noisy`` after it, with disturbances (`disturbed`) then
    ``_disturbed``."""
    name = embodiment or default_embodiment()
    if name == default_embodiment():
        base = "randomized" if randomize else "default"
    else:
        base = f"{name}_randomized" if randomize else name
    base = f"{base}_noisy" if noisy else base
    return f"{base}_disturbed" if disturbed else base


class GenerateConfig(RunConfig):
    """Settings of one generation run: its :class:`~bicoord_drake.scenario.Scenario` (what
    the data is: task, seeds, robot, station) and how the run executes (where to, how many
    workers). The scenario's fields are also taken and read by name (``task``, ``episodes``,
    ``seed``, ``fps``, ``resolution``, ...: :class:`~bicoord_drake.scenario.RunConfig`)."""

    DEFAULTS: ClassVar[dict[str, Any]] = GENERATION_DEFAULTS

    out: str = Field("data", description="output root")
    config_name: str = Field(
        None,  # type: ignore[assignment]  # filled in by _default_config_name
        pattern=r"^[A-Za-z0-9_.-]+$",
        description="settings directory (default: default, or the robot's name for another)",
    )
    max_tries: int = Field(0, ge=0, description="give up after this many seeds (0: 5x episodes)")
    video: bool = Field(True, description="a head-camera MP4 per episode (with cameras)")
    workers: int = Field(
        0,
        ge=0,
        le=100_000,
        description="seeds in flight (0: one per core here, one per CPU of the Ray cluster)",
    )
    backend: Literal["local", "ray"] = "local"
    ray_address: str | None = Field(None, description="join this Ray cluster (auto, HOST:PORT)")
    shared_fs: bool = Field(False, description="Ray workers write files to out themselves")
    verbose: bool = Field(False, description="workers' Drake and Ray logs on the terminal")

    @model_validator(mode="before")
    @classmethod
    def _default_config_name(cls, data: Any) -> Any:
        """No config name: ``default``, or the robot's name for another robot than the
        default, ``_noisy`` after it with action noise, ``_disturbed`` with disturbances
        (scripts/generate.py also names randomized runs apart)."""
        data = cls._fold(data)
        if isinstance(data, dict) and data.get("config_name") is None:
            scenario = data["scenario"]
            embodiment = scenario.get("embodiment")
            try:
                noisy = parse_action_noise(scenario.get("action_noise", 0.0)) != 0.0
            except ValueError:
                noisy = False  # the scenario's validation reports it
            try:
                disturbed = bool(parse_disturb(scenario.get("disturb")))
            except ValueError:
                disturbed = False  # the scenario's validation reports it
            name = default_config_name(False, embodiment, noisy, disturbed)
            return {**data, "config_name": name}
        return data

    @model_validator(mode="after")
    def _seeds_in_range(self) -> GenerateConfig:
        self._check_task()
        check_seed_range(self.seed, self.max_tries or 5 * self.episodes)
        return self

    @model_validator(mode="after")
    def _ray_only(self) -> GenerateConfig:
        if self.backend != "ray" and (self.ray_address or self.shared_fs):
            field = "ray_address" if self.ray_address else "shared_fs"
            raise ValueError(f"{field} is a setting of the ray backend: add backend='ray'")
        return self

    def station_config(self) -> StationConfig:
        """The station settings of every episode (the scenario's)."""
        return self.scenario.station

    def episode_setup(self, seed: int) -> EpisodeSetup:
        """The episode of `seed` of this run's (single) task: every setting of the data."""
        return self.scenario.episode_setup(seed)

    def for_task(self, name: str) -> GenerateConfig:
        """This run's settings for one of its tasks."""
        return self.replace(task=name)

    def data_settings(self) -> dict:
        """The settings that shape the data: a resumed run must match them
        (:func:`same_settings`). Settings at their defaults are left out but for the first
        six, so directories written before the others were recorded still resume."""
        settings: dict[str, Any] = {
            "task": self.task,
            "resolution": self.resolution,
            "fps": self.fps,
            "depth": self.depth,
            "render": self.render,
            "embodiment": self.embodiment,
        }
        if self.randomize:
            settings["randomize"] = True
        if self.split != "seen":
            settings["split"] = self.split
        if self.scenario.noisy:
            settings["action_noise"] = self.scenario.to_dict()["action_noise"]
        if self.scenario.disturbed:
            settings["disturb"] = list(self.scenario.disturb)
        station = _other_station_settings(self.station)
        if station != _other_station_settings(StationConfig()):
            settings["station"] = station
        return settings

    def record(self) -> dict[str, Any]:
        """The run's settings as the episode files' ``config`` attribute (flat; the full
        scenario is their ``scenario`` attribute)."""
        return {
            **self.data_settings(),
            "episodes": self.episodes,
            "seed": self.seed,
            "randomize": self.randomize,
            "split": self.split,
            **self.model_dump(include={"out", "config_name", "max_tries", "video"}),
        }


def _other_station_settings(station: StationConfig) -> dict[str, Any]:
    """The station's settings but those :meth:`GenerateConfig.data_settings` names apart."""
    settings = station.model_dump(mode="json", exclude={"embodiment", "control_rate", "render"})
    for key in ("width", "height", "depth"):
        settings["cameras"].pop(key)
    return settings


def same_settings(recorded: dict, settings: dict) -> bool:
    """Whether data recorded with `recorded` settings continues with `settings` (a directory
    written before the embodiment was recorded holds the default robot's data)."""
    return {"embodiment": default_embodiment(), **recorded} == settings


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
    #: The action-noise level (rad) the expert's actions were executed with (0: none).
    action_noise: float = 0.0
    #: The disturbances the episode ran with (none: a clean run), and the stage-annotation
    #: row of the recovery from each (:func:`~bicoord_drake.sim.disturbances.recovery_row`).
    disturbances: list[Disturbance] = field(default_factory=list)
    recovery: list[list] = field(default_factory=list)


@dataclass
class NoisyExecution:
    """DART's noisy execution (Laskey et al. 2017): each action the expert commands is
    executed with zero-mean Gaussian noise of standard deviation `level` (rad) on every arm
    joint target, clipped to the joint limits; the gripper openings are executed as commanded.
    The expert's action stays the label. `rng` is the episode's noise generator
    (:func:`~bicoord_drake.scenario.action_noise_draw`)."""

    level: float
    rng: np.random.Generator
    arm: np.ndarray  # the arm joints' indices in an action
    lower: np.ndarray  # their limits, in the same order
    upper: np.ndarray

    @classmethod
    def for_episode(
        cls, setting: ActionNoise, seed: int, layout: ActionLayout, lower: Any, upper: Any
    ) -> NoisyExecution:
        """The noise of episode `seed` of a run set to `setting` (a level, or a range to draw
        it from), for a robot of `layout` whose arms' joint limits are `lower`, `upper`
        (one arm's, (n,))."""
        level, rng = action_noise_draw(setting, seed)
        arm = np.concatenate([np.arange(layout.action_size)[layout.arm(s)] for s in SIDES])
        lower, upper = (np.tile(np.asarray(b, dtype=float), len(SIDES)) for b in (lower, upper))
        return cls(level, rng, arm, lower, upper)

    def apply(self, action: np.ndarray) -> np.ndarray:
        """The action to execute for the expert's `action` (a new array; one draw per arm
        joint, every call)."""
        executed = np.array(action, dtype=np.float64)
        q = executed[self.arm] + self.rng.normal(0.0, self.level, self.arm.size)
        executed[self.arm] = np.clip(q, self.lower, self.upper)
        return executed


def run_expert(
    setup: EpisodeSetup,
    depth: bool = False,
    action_noise: ActionNoise = 0.0,
    disturb: Sequence[str] = (),
) -> EpisodeResult:
    """Run the expert of `setup`'s episode in physics and verify every stage.

    The episode is assembled from `setup` (:func:`~bicoord_drake.episode_setup.assemble`:
    task, seed, randomized scene of its split, robot, station settings) on a station without
    cameras; only a verified episode is then rendered, from its recorded plant states
    (:class:`~bicoord_drake.sim.frame_renderer.FrameRenderer`), when ``setup.station`` asks for
    cameras (with `depth`, depth images too): a failed seed costs no rendering. The result's
    ``timings`` split the wall time into build, planning, physics, monitor, record, render and
    jpeg seconds. Generation uses its scenario's split (seen by default:
    :meth:`GenerateConfig.episode_setup`), the expert check of an evaluation the setup of its
    rollouts. The expert gets the task's step limit at the control rate
    (:func:`~bicoord_drake.tasks.base.step_limit_at`).

    With `action_noise` (a level in rad, or a range to draw the episode's level from; the
    scenario's ``action_noise``), the station executes each action with noise on the arm joint
    targets (:class:`NoisyExecution`, drawn from the seed): the recording keeps the expert's
    action as the label and the executed one beside it, the stage monitor watches what was
    executed, and the expert plans on from the measured world at its usual boundaries
    (:func:`~bicoord_drake.tasks.base.follow`). At 0 nothing changes: no noise generator, and
    the same actions bit for bit.

    With `disturb` (disturbance kinds, the scenario's ``disturb``:
    :mod:`bicoord_drake.sim.disturbances`), a clean run of the expert on the same seed (with
    the same action noise: :func:`trace_expert`) first shows where each kind may fire (its
    plan boundaries, what touches what: :class:`~bicoord_drake.sim.disturbances.ExpertTrace`;
    its seconds are the ``trace`` timing); one disturbance of each kind is drawn from the seed
    in its window (:func:`~bicoord_drake.sim.disturbances.plan_disturbances`) and the episode
    is run with them. The result carries them and a recovery row for each: from the
    disturbance's step to the next step at which the expert read the measured world to plan
    on. A seed without a window for a kind fails (``no_disturbance_window``). Without
    `disturb` nothing changes.

    Any failure of the seed (planning, a stage not verified, an annotation that cannot be made)
    is returned with its reason."""
    seed, station_config = setup.seed, setup.station
    clock = Stopwatch()
    kinds = parse_disturb(disturb) if disturb else ()
    schedule: list[Disturbance] | None = None
    if kinds:
        t0 = time.perf_counter()
        clean = trace_expert(setup, kinds, action_noise)  # its station is gone on return
        clock.add("trace", time.perf_counter() - t0)
        schedule, missing = clean.schedule(kinds)
        if missing is not None:
            return EpisodeResult(seed, False, missing, timings=clock.seconds())
    run = _simulate(setup, action_noise, clock, schedule=schedule)

    def failed(reason: str) -> EpisodeResult:
        return EpisodeResult(seed, False, reason, timings=clock.seconds())

    reason, rows = _verified(run)
    if reason is not None:
        return failed(reason)
    recorder = run.recorder
    recovery = []
    for d in schedule or ():
        end = recovery_end(d, run.reads, run.recovered, len(recorder))
        recovery.append(recovery_row(d, end))
    if schedule:
        recorder.disturbances = disturbance_records(schedule)
        recorder.recovery_rows = recovery
    if station_config.render and station_config.cameras.names:
        render_cameras(recorder, run.episode.scene, station_config, depth, clock)
    return EpisodeResult(
        seed,
        True,
        recorder=recorder,
        rows=rows,
        instruction=setup.instruction(),
        scene=run.episode.scene,
        timings=clock.seconds(),
        action_noise=0.0 if run.noise is None else run.noise.level,
        disturbances=list(schedule or ()),
        recovery=recovery,
    )


def recovery_end(d: Disturbance, reads: set[int], recovered: set[int], frames: int) -> int:
    """The frame a recovery from `d` ends at: for a drop or a knock, the first step after it
    at which the expert finished picking up (and re-placing) what fell or was knocked away, if
    it had to; otherwise, and for pushes, the first step after it at which the expert read the
    measured world to plan on (`frames`, the episode's length, at most)."""
    done = [b for b in recovered if b >= d.end] if d.kind in ("drop", "knock") else []
    end = min(done or [b for b in reads if b >= d.end], default=frames)
    return min(end, frames)


def _verified(run: _Simulated) -> tuple[str | None, list]:
    """Why the expert's physics run fails its seed (None: every stage verified) and, when it
    does not, the stage rows of its recording."""
    if run.failure is not None:
        return run.failure, []
    monitor = run.episode.monitor
    if not monitor.success:
        stages = zip(monitor.stages, monitor.completed(), strict=True)
        return f"stage_not_verified: {', '.join(s.subgoal for s, ok in stages if not ok)}", []
    try:
        return None, monitor.annotations(len(run.recorder))
    except ValueError as err:  # cannot happen when success holds; never a crash of the run
        return f"annotation: {err}", []


@dataclass
class CleanRun:
    """A clean (undisturbed) physics run of an expert, traced (:func:`trace_expert`): the
    verdict a plain run gives (`success`, and the `reason` of a failure, as
    :func:`run_expert`'s) and, per disturbance kind asked for, the disturbance drawn for the
    seed in its window, or the reason it has none (a ``NoDisturbanceWindow`` message)."""

    seed: int
    success: bool
    reason: str | None
    disturbances: dict[str, Disturbance | str] = field(default_factory=dict)

    def schedule(self, kinds: Sequence[str]) -> tuple[list[Disturbance], str | None]:
        """The disturbances of `kinds` and None, or ``([], "no_disturbance_window: ...")``
        for the first kind without a window (:func:`~bicoord_drake.sim.disturbances.
        schedule_of`)."""
        return schedule_of(self.disturbances, kinds)


def trace_expert(
    setup: EpisodeSetup, disturb: Sequence[str], action_noise: ActionNoise = 0.0
) -> CleanRun:
    """The clean run a disturbed episode of `setup` starts from: the expert in physics (no
    cameras, the same `action_noise`), every frame's contacts and the expert's plan boundaries
    traced (:class:`~bicoord_drake.sim.disturbances.ExpertTrace`), and one disturbance of each
    kind of `disturb` drawn for the seed in its window
    (:func:`~bicoord_drake.sim.disturbances.plan_disturbances`; each kind's draw does not
    depend on the others asked for). Generation (:func:`run_expert` with `disturb`) and a
    disturbed evaluation (its expert check) both take their disturbances from here, so the
    same seed and setup get the same disturbances."""
    kinds = parse_disturb(disturb)
    clean = _simulate(setup, action_noise, Stopwatch(), schedule=[], trace=True)
    reason, _ = _verified(clean)
    station = clean.episode.station
    plans: dict[str, Disturbance | str] = {}
    for kind in kinds:
        try:
            (plans[kind],) = plan_disturbances((kind,), setup.seed, clean.trace, station)
        except NoDisturbanceWindow as err:
            plans[kind] = str(err)
    return CleanRun(setup.seed, reason is None, reason, plans)


class _WatchedView(WorldView):
    """The expert's world view, noting each step at which the expert reads the measured world
    (its plan boundaries: :func:`~bicoord_drake.tasks.base.follow` syncs there)."""

    def __init__(self, sim: Any, reads: set[int], recovered: set[int] | None = None) -> None:
        super().__init__(sim)
        self._reads = reads
        self._recovered = recovered if recovered is not None else set()

    def note_recovered(self) -> None:
        self._recovered.add(self._sim.steps)

    def _read(self) -> None:
        self._reads.add(self._sim.steps)

    def object_poses(self) -> dict[str, np.ndarray]:
        self._read()
        return super().object_poses()

    def object_pose(self, name: str) -> np.ndarray:
        self._read()
        return super().object_pose(name)

    def object_transforms(self) -> dict:
        self._read()
        return super().object_transforms()

    def finger_contacts(self) -> dict[str, set[str]]:
        self._read()
        return super().finger_contacts()

    def state(self, action: np.ndarray) -> WorldState:
        self._read()
        return super().state(action)


@dataclass
class _Simulated:
    """One physics run of an expert (:func:`_simulate`)."""

    episode: Any  # the Assembly
    recorder: EpisodeRecorder
    noise: NoisyExecution | None
    failure: str | None = None
    #: The steps at which the expert read the world (only with a disturbance schedule).
    reads: set[int] = field(default_factory=set)
    #: The steps at which the expert finished a recovery (``WorldView.note_recovered``; only
    #: with a disturbance schedule).
    recovered: set[int] = field(default_factory=set)
    trace: ExpertTrace | None = None


def _simulate(
    setup: EpisodeSetup,
    action_noise: ActionNoise,
    clock: Stopwatch,
    schedule: list[Disturbance] | None = None,
    trace: bool = False,
) -> _Simulated:
    """Run `setup`'s expert in physics with the stage monitor watching (no cameras). With a
    `schedule` (a list, maybe empty), the expert's world reads are noted and the disturbances
    applied; with `trace`, every frame's facts are recorded too (:class:`ExpertTrace`)."""
    seed, station_config = setup.seed, setup.station
    with clock("build"):
        episode = assemble(setup.without_cameras())
        task, scene, sim, monitor = episode.task, episode.scene, episode.sim, episode.monitor
        recorder = EpisodeRecorder(
            fps=station_config.control_rate,
            initial_action=episode.embodiment.home_action(),
            layout=episode.layout,
        )
    action = executed = episode.embodiment.home_action()
    limit = step_limit_at(task, station_config.control_rate)
    noise = None
    if action_noise:
        arm = episode.embodiment.arm
        noise = NoisyExecution.for_episode(action_noise, seed, episode.layout, arm.lower, arm.upper)
    run = _Simulated(episode, recorder, noise)
    view, driver, tracer = episode.view, None, None
    if schedule is not None:
        view = _WatchedView(sim, run.reads, run.recovered)
        driver = DisturbanceDriver(sim, schedule) if schedule else None
        if trace:
            tracer = run.trace = ExpertTrace(sim)
            tracer.reads = run.reads
    record_executed = noise is not None or any(d.kind == "drop" for d in schedule or ())
    try:
        expert = expert_actions(task, scene, view)
        while True:
            with clock("planning"):
                next_action = next(expert, None)
            if next_action is None:
                break
            action = executed = next_action
            if len(recorder) >= limit:
                run.failure = f"step_limit: expert exceeded {limit} steps"
                return run
            if noise is not None:
                executed = noise.apply(action)
            if driver is not None:
                executed = driver.before_step(len(recorder), executed)
            if tracer is not None:
                tracer.capture()
            with clock("record"):
                recorder.capture(sim, action, executed=executed if record_executed else None)
            with clock("physics"):
                sim.step(executed)
            with clock("monitor"):
                monitor.update(WorldState.capture(sim, executed, scene))
    except PlanningError as err:
        run.failure = f"planning: {err}"
        return run
    with clock("monitor"):
        monitor.finish(WorldState.capture(sim, executed, scene))
    return run


def render_cameras(
    recorder: EpisodeRecorder,
    scene: Scene,
    station_config: StationConfig,
    depth: bool,
    clock: Stopwatch,
) -> None:
    """Render a recording's camera frames from its plant states; `clock` gets the seconds of
    rendering (``render``) and of JPEG encoding (``jpeg``)."""
    t0 = time.perf_counter()
    renderer = FrameRenderer(scene, station_config, depth=depth)
    recorder.attach_images(renderer.render_all(recorder.plant_states))
    clock.add("render", renderer.seconds)
    clock.add("jpeg", time.perf_counter() - t0 - renderer.seconds)


@dataclass
class GenerateSummary:
    """The outcome of one task's run (also what the CLI prints)."""

    root: Path
    kept: int
    tried: int
    failures: list[EpisodeEntry]
    mean_length: float | None
    seconds_per_episode: float | None
    metrics_table: str | None
    target: int = 0


@dataclass
class Throughput:
    """What one run produced per wall second: the kept demonstrations' simulated seconds, and
    the workers' seconds per phase over every seed it tried (kept or not)."""

    kept: int = 0
    simulated_seconds: float = 0.0
    phases: dict[str, float] = field(default_factory=dict)

    def add(self, outcome: SeedOutcome, fps: float) -> None:
        for phase, seconds in outcome.timings.items():
            self.phases[phase] = self.phases.get(phase, 0.0) + seconds
        if outcome.success and outcome.frames:
            self.kept += 1
            self.simulated_seconds += outcome.frames / fps

    def describe(self, wall_seconds: float) -> str:
        """Two lines: the rate, and where the workers' time went (percent per phase)."""
        rate = self.simulated_seconds / wall_seconds if wall_seconds > 0 else 0.0
        busy = sum(self.phases.values())
        split = ", ".join(
            f"{phase} {100 * s / busy:.0f} %"
            for phase, s in sorted(self.phases.items(), key=lambda kv: -kv[1])
            if busy > 0
        )
        return (
            f"this run: {self.kept} kept episodes, {self.simulated_seconds:.1f} simulated s in "
            f"{wall_seconds:.1f} wall s = {rate:.2f} simulated s per wall s\n"
            f"worker time ({busy:.0f} s): {split or 'none'}"
        )


@dataclass
class DatasetSummary:
    """The outcome of a run over one or more tasks."""

    tasks: dict[str, GenerateSummary]
    manifest: Path
    backend: str
    seconds: float
    throughput: Throughput = field(default_factory=Throughput)

    @property
    def complete(self) -> bool:
        return all(s.kept >= s.target for s in self.tasks.values())

    @property
    def counts(self) -> dict[str, tuple[int, int, int]]:
        """Task -> (kept, tried, target), as in :class:`RunProgress`."""
        return {name: (s.kept, s.tried, s.target) for name, s in self.tasks.items()}


POSTFIX_WIDTH = 60
"""Characters of :meth:`RunProgress.postfix` at most (the bar, counts and ETA need the rest of
a terminal line)."""


@dataclass
class RunProgress:
    """What the progress callback gets after every finished seed."""

    counts: dict[str, tuple[int, int, int]]  # task -> (kept, tried, target)
    message: str
    running: tuple[str, ...] = ()  # the task of every seed in flight, in submission order

    @property
    def kept(self) -> int:
        return sum(min(k, t) for k, _, t in self.counts.values())

    @property
    def target(self) -> int:
        return sum(t for _, _, t in self.counts.values())

    def postfix(self, width: int = POSTFIX_WIDTH) -> str:
        """One short line for a progress bar, whatever the number of tasks: tasks done, kept
        and tried seeds over every task, and the task in flight (the one with the most seeds
        running, ``+N`` for the others). The per-task counts are :func:`format_counts`'s."""
        done = sum(1 for k, _, t in self.counts.values() if k >= t)
        kept = sum(k for k, _, _ in self.counts.values())
        tried = sum(tr for _, tr, _ in self.counts.values())
        text = f"{done}/{len(self.counts)} tasks done, {kept}/{tried} kept/tried"
        if self.running:
            ranked = Counter(self.running).most_common()
            others = f" +{len(ranked) - 1}" if len(ranked) > 1 else ""
            room = max(width - len(text) - 2 - len(others), 4)
            name = ranked[0][0]
            if len(name) > room:
                name = name[: room - 1] + "…"
            text += f", {name}{others}"
        return text if len(text) <= width else text[: width - 1] + "…"


def format_counts(counts: dict[str, tuple[int, int, int]]) -> str:
    """The per-task table of a run: kept, target, tried and failed seeds, then the totals."""
    rows = [(t, k, n, tr, tr - k) for t, (k, tr, n) in counts.items()]
    if len(rows) > 1:
        rows.append(("all", *(sum(r[i] for r in rows) for i in range(1, 5))))
    name = max(len("task"), *(len(r[0]) for r in rows))
    header = ("task", "kept", "target", "tried", "failed")
    lines = [f"{header[0]:<{name}}  " + "  ".join(f"{h:>6}" for h in header[1:])]
    lines += [f"{r[0]:<{name}}  " + "  ".join(f"{v:>6}" for v in r[1:]) for r in rows]
    return "\n".join(lines)


def resolve_tasks(spec: str, embodiment: str | None = None) -> list[str]:
    """``all``, one task name or a comma-separated list -> task names (unknown names are a
    ValueError that lists the valid ones). With `embodiment`, ``all`` is every task that
    supports that robot (``Task.supported_robots``; :func:`skipped_tasks` names the others);
    a named task that does not support it was refused by the scenario already."""
    from bicoord_drake.tasks import list_tasks
    from bicoord_drake.tasks.registry import tasks_for_robot

    valid = list_tasks()
    if spec.strip() == "all":
        if embodiment is None:
            return list(valid)
        names = tasks_for_robot(embodiment)
        if not names:
            raise ValueError(f"no task supports the robot {embodiment!r} (Task.supported_robots)")
        return names
    names = [n.strip() for n in spec.split(",") if n.strip()]
    unknown = [n for n in names if n not in valid]
    if unknown or not names:
        raise ValueError(
            f"unknown task {', '.join(map(repr, unknown)) or repr(spec)}; "
            f"tasks: {', '.join(valid)} (or all)"
        )
    return list(dict.fromkeys(names))


def skipped_tasks(spec: str, embodiment: str) -> list[str]:
    """The tasks ``all`` leaves out for `embodiment` (they do not support it); none for a
    named task or list."""
    from bicoord_drake.tasks import list_tasks

    if spec.strip() != "all":
        return []
    kept = set(resolve_tasks(spec, embodiment))
    return [name for name in list_tasks() if name not in kept]


def generate(
    config: GenerateConfig, progress: Callable[[RunProgress], None] | None = None
) -> GenerateSummary:
    """Produce `config.episodes` verified episodes of the one task `config.task` (resuming a
    previous run in the same directory); see :func:`generate_dataset`."""
    names = resolve_tasks(config.task, config.embodiment)
    if len(names) != 1:
        raise ValueError(f"generate() makes one task, got {names}: use generate_dataset()")
    return generate_dataset(config, progress).tasks[names[0]]


def generate_dataset(
    config: GenerateConfig, progress: Callable[[RunProgress], None] | None = None
) -> DatasetSummary:
    """Produce `config.episodes` verified episodes of every task `config.task` names (``all``:
    every task that supports the robot; a name or a comma list), resuming previous runs in
    the same directories.

    Seeds run as jobs of the configured backend (:mod:`bicoord_drake.runner.backends`). This
    process alone assigns episode indices (in the order episodes finish), places the files and
    writes each task's ``manifest.json`` and the run's ``dataset_<config_name>.json``.
    `progress` is called once at the start and after every finished seed.

    Raises :class:`~bicoord_drake.runner.backends.ClusterLost` when the Ray cluster has no live
    node left: the seeds in flight are not recorded, so running again resumes with them."""
    names = resolve_tasks(config.task, config.embodiment)
    dataset = _DatasetManifest(config)  # checks the settings before any directory is made
    runs = [_TaskRun(config.for_task(name)) for name in names]
    started = time.perf_counter()
    throughput = Throughput()
    pending: dict[Any, tuple[_TaskRun, int]] = {}
    with make_backend(config.backend, config.workers, config.ray_address, config.verbose) as pool:
        dataset.backend = pool.describe()

        def report(message: str) -> None:
            if progress:
                counts = {r.name: (r.kept, len(r.manifest.episodes), r.target) for r in runs}
                running = tuple(r.name for r, _ in pending.values())
                progress(RunProgress(counts, message, running))

        message = f"started on {dataset.backend}"
        while True:
            while len(pending) < pool.slots and (run := _neediest(runs)) is not None:
                seed = run.take_seed()
                job = pool.submit(produce_episode, run.config, seed, run.staging)
                pending[job] = (run, seed)
            report(message)  # with the seeds now in flight
            if not pending:
                break
            job = pool.wait(list(pending))
            run, seed = pending.pop(job)
            try:
                outcome = pool.result(job)
            except WorkerLost as exc:
                outcome = SeedOutcome(run.name, seed, False, f"{WORKER_LOST}: {exc}")
            run.record(outcome)
            throughput.add(outcome, config.fps)
            dataset.write(runs)
            message = f"{run.name} seed {seed}: " + ("kept" if outcome.success else outcome.reason)
    dataset.write(runs)
    summaries = {r.name: r.summary() for r in runs}
    return DatasetSummary(
        summaries, dataset.path, dataset.backend, time.perf_counter() - started, throughput
    )


WORKER_LOST = "worker_lost"
"""Reason of a seed whose worker process died on every try; the next run tries it again."""

EPISODE_FILES = ("instructions", "stages", "video", "episode")
"""An episode's files in the order they are placed: the HDF5 file last, so its presence means
a complete episode."""


@dataclass
class SeedOutcome:
    """What a worker returns for one seed: the verdict and, for a kept episode, its files as
    bytes (`files`, the default) or as paths already written on a shared file system
    (`staged`)."""

    task: str
    seed: int
    success: bool
    reason: str | None = None
    timings: dict[str, float] = field(default_factory=dict)
    frames: int | None = None
    worker: str | None = None
    files: dict[str, bytes] | None = None
    staged: dict[str, str] | None = None

    @property
    def nbytes(self) -> int:
        """Bytes of episode files carried back to the driver."""
        return sum(len(b) for b in (self.files or {}).values())


def produce_episode(config: GenerateConfig, seed: int, staging: str | None) -> SeedOutcome:
    """One seed, in a worker: run the expert in physics; for a success, encode the episode's
    files (HDF5, MP4, sidecars) and return them as bytes, or write them under ``staging``
    (a directory on a shared file system) and return their paths."""
    quiet_worker(config.verbose)
    task = get_task(config.task)
    try:
        disturb = {"disturb": config.scenario.disturb} if config.scenario.disturbed else {}
        result = run_expert(
            config.episode_setup(seed),
            depth=config.depth,
            action_noise=config.action_noise,
            **disturb,
        )
    except Exception as exc:  # noqa: BLE001 - recorded in the manifest with the traceback's tail
        result = EpisodeResult(seed, False, f"crashed: {format_failure(exc)}")
    outcome = SeedOutcome(
        task.name,
        seed,
        result.success,
        result.reason,
        timings=dict(result.timings),
        worker=f"{socket.gethostname()}:{os.getpid()}",
    )
    if not result.success:
        return outcome
    t_encode = time.perf_counter()
    outcome.frames = len(result.recorder)
    if staging is not None:
        layout = EpisodeLayout(Path(staging), f"seed{seed}", ".")
        paths = _save(result, task, config, layout)
        outcome.staged = {kind: str(path) for kind, path in paths.items()}
    else:
        with tempfile.TemporaryDirectory(prefix="bicoord-episode-") as tmp:
            paths = _save(result, task, config, EpisodeLayout(Path(tmp), "e", "."))
            outcome.files = {kind: path.read_bytes() for kind, path in paths.items()}
    outcome.timings["encode"] = round(time.perf_counter() - t_encode, 3)
    return outcome


def _save(
    result: EpisodeResult, task: Task, config: GenerateConfig, layout: EpisodeLayout
) -> dict[str, Path]:
    meta = EpisodeMeta(
        task=task.name,
        seed=result.seed,
        instruction=result.instruction,
        embodiment=config.embodiment,
        success=True,
        object_count=task.object_count(result.scene),
        config=config.record(),
        scene=result.scene,
        scenario=config.scenario.for_episode(task.name, result.seed).to_yaml(),
        extra=_extra_attrs(result),
    )
    return save_episode(
        layout,
        0,
        result.recorder,
        result.rows,
        meta,
        instructions_seen=task.instructions("seen"),
        instructions_unseen=task.instructions("unseen"),
        video=config.video and config.render,
    )


def _extra_attrs(result: EpisodeResult) -> dict[str, Any]:
    """The episode file's attributes beyond the usual ones: the action-noise level and the
    disturbance kinds (comma list), each only when on."""
    extra: dict[str, Any] = {}
    if result.action_noise:
        extra["action_noise"] = result.action_noise
    if result.disturbances:
        extra["disturb"] = ",".join(dict.fromkeys(d.kind for d in result.disturbances))
    return extra


class _TaskRun:
    """One task's directory, manifest and seed bookkeeping during a run (driver side)."""

    def __init__(self, config: GenerateConfig) -> None:
        self.config = config
        self.name = config.task
        self.target = config.episodes
        self.layout = EpisodeLayout(Path(config.out), config.task, config.config_name)
        self.layout.make_dirs()
        self.manifest = _open_manifest(self.layout, config)
        stage_root = self.layout.root / ".staging"
        shutil.rmtree(stage_root, ignore_errors=True)  # left by an interrupted run
        self.staging = str(stage_root.resolve()) if _stages_files(config) else None
        self.max_tries = config.max_tries or 5 * config.episodes
        self.pending: set[int] = set()
        self._next = config.seed

    @property
    def kept(self) -> int:
        return _kept(self.manifest, self.layout)

    def needs(self) -> bool:
        tried = len(self.manifest.episodes)
        busy = len(self.pending)
        return (
            self.kept + busy < self.target
            and tried + busy < self.max_tries
            and self._next < SEED_LIMIT
        )

    def take_seed(self) -> int:
        """The lowest seed from ``config.seed`` up that was neither tried nor is running."""
        taken = {e.seed for e in self.manifest.episodes} | self.pending
        while self._next in taken:
            self._next += 1
        self.pending.add(self._next)
        return self._next

    def record(self, outcome: SeedOutcome) -> None:
        """Place a kept episode's files under the next index, then the seed's manifest entry."""
        self.pending.discard(outcome.seed)
        entry = EpisodeEntry(
            seed=outcome.seed,
            success=outcome.success,
            reason=outcome.reason,
            timings=outcome.timings,
            worker=outcome.worker,
        )
        if outcome.success:
            index = self.kept
            t_write = time.perf_counter()
            _place_files(outcome, self.layout, index)
            entry.index, entry.frames = index, outcome.frames
            entry.timings["write"] = round(time.perf_counter() - t_write, 3)
        self.manifest.episodes.append(entry)
        totals = self.manifest.timings
        for phase, seconds in [*entry.timings.items(), ("total", sum(entry.timings.values()))]:
            totals[phase] = round(totals.get(phase, 0.0) + seconds, 3)
        write_manifest(self.layout.root, self.manifest)

    def summary(self) -> GenerateSummary:
        summary = _summary(self.layout, self.manifest)
        summary.target = self.target
        return summary


def _stages_files(config: GenerateConfig) -> bool:
    """Whether workers write episode files themselves (local processes share this disk; Ray
    workers do only when told the output is on a shared file system)."""
    return config.backend == "local" or config.shared_fs


def _neediest(runs: list[_TaskRun]) -> _TaskRun | None:
    """The task furthest from its target that still needs seeds (tasks progress together)."""
    open_runs = [r for r in runs if r.needs()]
    if not open_runs:
        return None
    return min(open_runs, key=lambda r: (r.kept + len(r.pending)) / r.target)


def _place_files(outcome: SeedOutcome, layout: EpisodeLayout, index: int) -> None:
    """Write (bytes) or move (staged paths) a kept episode's files to their final names."""
    for kind in EPISODE_FILES:
        final = getattr(layout, kind)(index)
        if outcome.files is not None:
            if kind in outcome.files:
                with atomic_path(final) as tmp:
                    tmp.write_bytes(outcome.files[kind])
        elif outcome.staged is not None and kind in outcome.staged:
            os.replace(outcome.staged[kind], final)
    if outcome.staged:
        shutil.rmtree(Path(outcome.staged["episode"]).parents[1], ignore_errors=True)


class _DatasetManifest:
    """``<out>/dataset_<config_name>.json``: the run's tasks, settings and per-task counts."""

    def __init__(self, config: GenerateConfig) -> None:
        self.path = Path(config.out) / f"dataset_{config.config_name}.json"
        self.config_name = config.config_name
        self.settings = {k: v for k, v in config.data_settings().items() if k != "task"}
        self.scenario = config.scenario.to_dict()
        self.backend = ""
        self.tasks: dict[str, Any] = {}
        if self.path.exists():
            try:
                old = json.loads(self.path.read_text(encoding="utf-8"))
            except ValueError as exc:
                raise ValueError(f"{self.path}: invalid dataset manifest ({exc})") from None
            if not same_settings(old.get("settings") or {}, self.settings):
                raise ValueError(
                    f"{self.path} describes data generated with different settings "
                    f"{old.get('settings')}; use another --out or --config-name"
                )
            self.tasks = dict(old.get("tasks", {}))
        self.created = time.time()

    def write(self, runs: list[_TaskRun]) -> None:
        for r in runs:
            self.tasks[r.name] = {
                "directory": str(r.layout.root.relative_to(self.path.parent)),
                "target": r.target,
                "kept": r.kept,
                "tried": len(r.manifest.episodes),
                "failed": len(r.manifest.failures),
            }
        write_json(
            self.path,
            {
                "schema_version": SCHEMA_VERSION,
                "config_name": self.config_name,
                "settings": self.settings,
                "scenario": self.scenario,
                "tasks": self.tasks,
                "kept": sum(t["kept"] for t in self.tasks.values()),
                "backend": self.backend,
                "updated": time.time(),
                "package_version": package_version(),
            },
        )


def _open_manifest(layout: EpisodeLayout, config: GenerateConfig) -> Manifest:
    scenario = config.scenario.to_dict()
    if not layout.manifest.exists():
        return Manifest(
            task=config.task,
            config_name=config.config_name,
            config=config.data_settings(),
            scenario=scenario,
        )
    manifest = read_manifest(layout.root)
    if not same_settings(manifest.config, config.data_settings()):
        raise ValueError(
            f"{layout.root} holds data generated with different settings {manifest.config}; "
            "use another --out or --config-name to generate with these settings"
        )
    manifest.config = config.data_settings()  # an older manifest gets the robot's name
    manifest.scenario = scenario  # the latest run's (seeds and episodes may have grown)
    # An episode whose file is missing (e.g. deleted) is forgotten so its seed can be redone;
    # so is a seed whose worker died (not the expert's verdict).
    manifest.episodes = [
        e
        for e in manifest.episodes
        if (e.success and layout.episode(e.index).exists())
        or (not e.success and not (e.reason or "").startswith(WORKER_LOST))
    ]
    return manifest


def _kept(manifest: Manifest, layout: EpisodeLayout) -> int:
    return sum(1 for e in manifest.episodes if e.success)


def _summary(layout: EpisodeLayout, manifest: Manifest) -> GenerateSummary:
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


def compare_regenerated(episode: str | Path, root: str | Path, seed: int) -> str:
    """One line: whether the episode of `seed` generated under `root` has the actions of the
    `episode` file it was made from, bit for bit (the labels, and the executed actions of an
    episode with action noise)."""
    root = Path(root)
    kept = [e for e in read_manifest(root).episodes if e.seed == seed and e.success]
    if not kept:
        return f"seed {seed} was not kept: nothing to compare with {episode}"
    made = read_episode(root / "data" / f"episode{kept[0].index}.hdf5", images=False)
    recorded = read_episode(episode, images=False)
    same_executed = (made.executed_action is None) == (recorded.executed_action is None) and (
        made.executed_action is None
        or np.array_equal(made.executed_action, recorded.executed_action)
    )
    if np.array_equal(made.joint_action, recorded.joint_action) and same_executed:
        return f"{made.path}: the actions of {episode}, bit for bit ({made.length} steps)"
    return (
        f"{made.path}: the actions differ from {episode} ({made.length} steps, recorded "
        f"{recorded.length})"
    )


def format_failure(exc: BaseException) -> str:
    """One line for an unexpected error (the CLI shows it; the traceback goes to the log)."""
    text = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    return re.sub(r"\s+", " ", text)

"""What every evaluation path shares (sequential here, parallel in
:mod:`bicoord_drake.runner.evaluate_parallel`): the settings, the environment, one rollout, the
expert check and the demonstrations to replay.

:mod:`bicoord_drake.runner.evaluate` drives an evaluation and re-exports the public names, so
``from bicoord_drake.runner.evaluate import EvaluateConfig`` keeps working. Imports run one way:
``evaluate -> evaluate_parallel -> rollouts`` and ``evaluate -> rollouts``.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import re
import time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator

from bicoord_drake.config import SEED_LIMIT, StationConfig, check_seed_range
from bicoord_drake.data.episode import (
    Episode,
    decode_rgb,
    encode_jpeg,
    package_version,
    write_json,
    write_video,
)
from bicoord_drake.env import EVAL_SEED_START, OBJECT_LEFT_TABLE, Env, InvalidActionError
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.models.appearance import Split
from bicoord_drake.models.layout import default_embodiment
from bicoord_drake.policies import bind_policy, reset_policy
from bicoord_drake.runner import generate as generation
from bicoord_drake.runner.backends import local_workers
from bicoord_drake.scenario import (
    EVALUATION_DEFAULTS,
    RunConfig,
    evaluation_seed,
    recorded_scenario,
)
from bicoord_drake.sim.disturbances import (
    Disturbance,
    disturbance_records,
    from_records,
    parse_disturb,
)
from bicoord_drake.sim.simulation import PhysicsDivergedError
from bicoord_drake.tasks.base import Task

#: How a rollout whose physics diverged is reported (the start of its error).
DIVERGED = "physics diverged"
#: Why a rollout failed (:attr:`RolloutResult.failure`): it ran to its step limit, a task object
#: left the table (an early stop, ``EvaluateConfig.early_stop``), the physics diverged, the
#: policy returned an invalid action, or the policy or the simulation raised.
STEP_LIMIT = "step_limit"
PHYSICS_DIVERGED = "physics_diverged"
INVALID_ACTION = "invalid_action"
FAILURES = (
    STEP_LIMIT,
    OBJECT_LEFT_TABLE,
    PHYSICS_DIVERGED,
    INVALID_ACTION,
    "policy_raised",
    "simulation_raised",
)


class EvaluateConfig(RunConfig):
    """Settings of one evaluation: its :class:`~bicoord_drake.scenario.Scenario` (the
    rollouts' task, seeds, robot and station; split unseen and 100 episodes by default) and
    the policy, demonstrations and execution. The scenario's fields are also taken and read by
    name (``task``, ``episodes``, ``seed``, ``fps``, ...:
    :class:`~bicoord_drake.scenario.RunConfig`); evaluation seeds start at
    ``100000 * (1 + seed)``.

    With the scenario's ``disturb`` (disturbance kinds) every seed is rolled out twice, clean
    and disturbed (:attr:`disturb`)."""

    DEFAULTS: ClassVar[dict[str, Any]] = EVALUATION_DEFAULTS

    policy: str = Field(description="built-in name or package.module:name")
    data: str | None = Field(None, description="demonstrations: their seeds, scenes and rates")
    stage: int | None = Field(None, ge=0, description="reset at the start of this stage")
    video: str | None = Field(None, description="directory for head-camera rollout videos")
    out: str = Field("eval", description="report directory root")
    action_mode: Literal["qpos", "endpose"] = "qpos"
    step_limit: int | None = Field(
        None, ge=1, description="override the task's step limit (default: at the control rate)"
    )
    early_stop: bool = Field(
        True,
        description="end a rollout, as a failure, once a task object has left the table "
        "(bicoord_drake.env); off: every rollout that does not succeed runs its step limit",
    )
    expert_check: bool = True
    max_tries: int = Field(0, ge=0, description="seeds to try at most (0: 3 x episodes)")
    workers: int = Field(
        0,
        ge=0,
        le=100_000,
        description="rollouts in flight (0: one per core here, one per CPU of the Ray cluster)",
    )
    backend: Literal["local", "ray"] = "local"
    ray_address: str | None = Field(None, description="join this Ray cluster (auto, HOST:PORT)")
    verbose: bool = Field(False, description="workers' Drake and Ray logs on the terminal")

    @model_validator(mode="after")
    def _consistent(self) -> EvaluateConfig:
        self._check_task()
        if self.policy == "replay" and not self.data:
            raise ValueError("the replay policy needs demonstrations: give data (--data DIR)")
        if self.stage is not None and not self.data:
            raise ValueError("a stage evaluation needs demonstrations: give data (--data DIR)")
        if self.stage is not None and self.disturb:
            raise ValueError(
                "disturb evaluates rollouts from the start of the task (a disturbance's step "
                "counts from the episode's first frame): drop the stage (--stage) or disturb"
            )
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
    def disturb(self) -> tuple[str, ...]:
        """The disturbance kinds of the disturbed rollouts (the scenario's ``disturb``; empty:
        clean rollouts only). Each seed then gets a clean rollout and a disturbed one, with
        the disturbances the expert's demonstration of that seed gets
        (:func:`~bicoord_drake.runner.generate.trace_expert`)."""
        return tuple(self.scenario.disturb)

    @property
    def parallel(self) -> bool:
        """Rollouts run as backend jobs (Ray, or several local processes)."""
        return self.backend != "local" or local_workers(self.workers) > 1

    @property
    def label(self) -> str:
        """A file-name-safe name of the policy (and stage)."""
        name = re.sub(r"[^A-Za-z0-9_.-]+", "-", self.policy).strip("-")
        return name + (f"_stage{self.stage}" if self.stage is not None else "")

    def episode_setup(self, task: Task | str, seed: int, fps: float | None = None) -> EpisodeSetup:
        """The rollout episode of `seed` (at `fps`, default this config's control rate): the
        scene, robot and station every rollout and every expert check of this evaluation get."""
        scenario = self.scenario if fps is None else self.scenario.with_overrides({"fps": fps})
        return scenario.episode_setup(seed, task)


@dataclass
class RolloutResult:
    """One rollout: outcome, per-stage completion, and why it failed: `failure` (one of
    :data:`FAILURES`; None for a success) and `error` (what happened, for every failure but the
    step limit; its traceback when something raised).

    Actions outside the robot's limits (:class:`LimitCount`): `out_of_limits` is how many of
    the rollout's executed actions had an entry outside them, `out_of_limits_entries` how many
    of those each entry (``left_waist``, ``right_gripper``, ...) was outside in, and
    `out_of_limits_max` the largest excess (rad for a joint, opening units for a gripper).

    `disturbances`: those the rollout applied (mappings of the fields of
    :class:`~bicoord_drake.sim.disturbances.Disturbance`: kind, body, step, duration, side,
    force, torque, point); in the report only when there are some."""

    seed: int
    success: bool
    score: float
    steps: int
    completed: list[bool]
    credit: list[float]
    start_stage: int = 0
    episode: str | None = None
    error: str | None = None
    failure: str | None = None
    traceback: str | None = None
    video: str | None = None
    seconds: float = 0.0
    out_of_limits: int = 0
    out_of_limits_entries: dict[str, int] = field(default_factory=dict)
    out_of_limits_max: float = 0.0
    disturbances: list[dict[str, Any]] = field(default_factory=list)
    left_xyz: np.ndarray | None = field(default=None, repr=False)
    right_xyz: np.ndarray | None = field(default=None, repr=False)
    grippers: np.ndarray | None = field(default=None, repr=False)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("left_xyz", "right_xyz", "grippers"):
            out.pop(key)
        if not self.disturbances:
            out.pop("disturbances")  # the record of a clean rollout, as before disturbances
        return out


# --------------------------------------------------------------------------- rollouts
#: How far past a limit an action entry may be and still count as within it (round-off of an
#: action recorded at its limit), rad or opening units.
LIMIT_SLACK = 1e-6


class LimitCount:
    """Counts the actions of one rollout that are outside the robot's limits: an arm joint
    target outside the joint's range or a gripper opening outside [0, 1].

    Nothing is refused or changed here: the station clips an opening to [0, 1] and drives an
    arm joint toward its target until the plant's joint limit stops it, so a policy's target
    beyond a limit is not executed as given; the count says how often that happened. It reads
    the joint action in effect after each step (``env.action``: the policy's action in
    ``qpos`` mode, the inverse kinematics' joint targets with the policy's openings in
    ``endpose`` mode)."""

    def __init__(self, env: Env) -> None:
        from bicoord_drake.models.embodiment import SIDES

        arm, layout = env.sim.station.embodiment.arm, env.layout
        self.low = layout.compose(dict.fromkeys(SIDES, arm.lower), dict.fromkeys(SIDES, 0.0))
        self.high = layout.compose(dict.fromkeys(SIDES, arm.upper), dict.fromkeys(SIDES, 1.0))
        self.names = layout.feature_names()
        self.actions = 0
        self.entries: dict[str, int] = {}
        self.max_excess = 0.0

    def update(self, action: np.ndarray) -> None:
        """Count `action` (the joint action in effect) if an entry is outside its limits."""
        a = np.asarray(action, dtype=float)
        excess = np.maximum(self.low - a, a - self.high)
        outside = np.flatnonzero(excess > LIMIT_SLACK)
        if outside.size == 0:
            return
        self.actions += 1
        for k in outside:
            self.entries[self.names[k]] = self.entries.get(self.names[k], 0) + 1
        self.max_excess = max(self.max_excess, float(excess[outside].max()))


def rollout(
    env: Env,
    policy: Any,
    *,
    seed: int | None = None,
    episode: Episode | None = None,
    stage: int | None = None,
    video: str | Path | None = None,
    disturbances: Sequence[Disturbance] | None = None,
) -> RolloutResult:
    """Run one rollout of `policy` in `env` until done (success, the step limit, or an early
    stop of `env`: a task object lost, the physics diverged); never raises for policy
    faults. `disturbances` are applied in it (``Env.reset``; None: those `episode`
    recorded, if any)."""
    t0 = time.perf_counter()
    obs = env.reset(seed, stage=stage, episode=episode, disturbances=disturbances)
    frames: list[bytes] = []
    left, right, grippers = [], [], []
    error = tb = failure = None

    def record(o: dict[str, Any]) -> None:
        if video is not None and "head_camera" in o:
            frames.append(encode_jpeg(o["head_camera"]))

    record(obs)
    limits = LimitCount(env)
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
            limits.update(env.action)
            left.append(tcp[0])
            right.append(tcp[1])
            grippers.append(env.action[env.layout.gripper_indices])
            record(obs)
    except InvalidActionError as exc:
        error, tb = f"invalid action at step {env.steps}: {exc}", traceback.format_exc()
        failure = INVALID_ACTION
    except PhysicsDivergedError as exc:
        error, tb = f"{DIVERGED} at step {env.steps}: {exc}", traceback.format_exc()
        failure = PHYSICS_DIVERGED
    except Exception as exc:  # a fault ends this rollout only
        error = f"{who} raised at step {env.steps}: {type(exc).__name__}: {exc}"
        tb, failure = traceback.format_exc(), f"{who}_raised"
    if error is None and env.failure is not None:  # an early stop: a task object lost
        error, failure = env.failure, OBJECT_LEFT_TABLE
    info = env.info()
    target = env.stage
    done = info["completed"][target] if target is not None else info["success"]
    success = bool(done) and error is None
    if not success and failure is None:
        failure = STEP_LIMIT
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
        failure=failure,
        traceback=tb,
        out_of_limits=limits.actions,
        out_of_limits_entries=dict(sorted(limits.entries.items(), key=lambda kv: (-kv[1], kv[0]))),
        out_of_limits_max=round(limits.max_excess, 6),
        disturbances=disturbance_records(env.disturbances),
        left_xyz=np.array(left).reshape(-1, 3),
        right_xyz=np.array(right).reshape(-1, 3),
        grippers=np.array(grippers).reshape(-1, 2),
    )
    if video is not None and frames:
        path = write_video(video, (decode_rgb(f) for f in frames), env.config.control_rate)
        result.video = str(path)
    result.seconds = round(time.perf_counter() - t0, 3)
    return result


def make_evaluation_env(
    task: Task,
    config: EvaluateConfig,
    seed: int,
    fps: float | None = None,
    *,
    station: StationConfig | None = None,
) -> Env:
    """The environment of an evaluation with `config`'s settings, built for `seed` (at `fps`,
    or on `station`: a demonstration's, :func:`rollout_station`)."""
    setup = config.episode_setup(task, seed, fps)
    if station is not None:
        setup = setup.replace(station=station)
    return Env(
        setup,
        action_mode=config.action_mode,
        step_limit=config.step_limit,
        early_stop=config.early_stop,
    )


def rollout_station(config: EvaluateConfig, episode: Episode) -> StationConfig:
    """The station of a rollout on a demonstration: the rate and physics it was recorded with
    (its recorded scenario; for a file from before that, its rate and the evaluation's
    physics), with the evaluation's robot, cameras and rendering."""
    own = config.station
    recorded = recorded_scenario(episode)
    station = recorded.station if recorded is not None else own
    return StationConfig(
        **{
            **station.model_dump(),
            "control_rate": episode.fps,
            "embodiment": own.embodiment,
            "render": own.render,
            "cameras": own.cameras,
        }
    )


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
    """Whether the expert solves a seed's episode in physics, cached in a small JSON file.

    `setup` is the evaluation's episode settings (:meth:`EvaluateConfig.episode_setup`; any
    seed): the check of a seed runs on exactly the episode its rollout gets - with `randomize`,
    the seed's randomized scene of `split` (its table height and clutter change what the expert
    must do), on its robot and station. The key holds the seed, the control rate, that scene
    (``randomized-<split>``, nothing for the plain scene), the robot and the station's other
    settings (each only when not the default), the package version and
    :func:`code_fingerprint`, so an expert changed in any way (an edited checkout included) is
    checked again.

    With `disturb` (disturbance kinds: a disturbed evaluation) the check is the traced clean
    run a disturbed demonstration starts from (:func:`~bicoord_drake.runner.generate.
    trace_expert`): one expert run per seed gives both the verdict and the disturbance of
    each kind drawn for the seed (or why it has no window), cached with the verdict
    (:meth:`disturbances`).
    """

    def __init__(
        self, setup: EpisodeSetup, path: Path | None = None, disturb: Sequence[str] = ()
    ) -> None:
        self.setup = setup.without_cameras()
        self.task = setup.get_task()
        self.disturb = parse_disturb(disturb)
        self.path = path or cache_dir() / "expert_check" / f"{self.task.name}.json"
        try:
            self._cache = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            self._cache = {}

    @classmethod
    def for_config(cls, task: Task, config: EvaluateConfig) -> ExpertCheck:
        """The check of an evaluation with `config` (its scenes, robot and control rate, and
        its disturbance kinds)."""
        setup = config.episode_setup(task, evaluation_seed(config.seed))
        return cls(setup, disturb=config.disturb)

    @property
    def fps(self) -> float:
        return self.setup.station.control_rate

    @property
    def randomize(self) -> bool:
        return self.setup.randomize

    @property
    def split(self) -> Split:
        return self.setup.split

    def _key(self, seed: int) -> str:
        setup = self.setup
        scene = f"@randomized-{setup.split}" if setup.randomize else ""
        robot = "" if setup.embodiment == default_embodiment() else f"@{setup.embodiment}"
        return (
            f"{seed}@{self.fps:g}Hz{scene}{robot}{_station_key(setup.station)}"
            f"@{package_version()}+{code_fingerprint()}"
        )

    def __call__(self, seed: int) -> tuple[bool, str | None]:
        """(ok, reason) for `seed`, from the cache or by running the expert (with `disturb`,
        traced: its disturbances are then cached too)."""
        if self.lookup(seed) is None or self.lookup_disturbances(seed) is None:
            self.store(seed, expert_verdict(self.setup.for_seed(seed), self.disturb))
        return self.lookup(seed)

    def lookup(self, seed: int) -> tuple[bool, str | None] | None:
        """The cached (ok, reason) of `seed`, None if not checked yet."""
        v = self._cache.get(self._key(seed))
        return None if v is None else (bool(v["ok"]), v.get("reason"))

    def disturbances(self, seed: int) -> dict[str, Disturbance | str]:
        """Kind -> the disturbance drawn for `seed` (or why the kind has no window there), for
        each of this check's kinds; from the cache or by running the traced expert."""
        self(seed)
        return self.lookup_disturbances(seed) or {}

    def lookup_disturbances(self, seed: int) -> dict[str, Disturbance | str] | None:
        """The cached disturbances of `seed` (as :meth:`disturbances`; empty without kinds),
        None if a kind was not drawn yet."""
        drawn = (self._cache.get(self._key(seed)) or {}).get("disturbances", {})
        if any(kind not in drawn for kind in self.disturb):
            return None
        return drawn_from_json({k: drawn[k] for k in self.disturb})

    def store(self, seed: int, verdict: dict[str, Any]) -> None:
        """Cache a verdict of :func:`expert_verdict` (e.g. one a worker computed); the
        disturbances of kinds it did not draw stay cached."""
        key = self._key(seed)
        kept = (self._cache.get(key) or {}).get("disturbances", {})
        if kept or "disturbances" in verdict:
            verdict = {**verdict, "disturbances": {**kept, **verdict.get("disturbances", {})}}
        self._cache[key] = verdict
        try:
            write_json(self.path, self._cache)
        except OSError:
            pass  # the cache is an optimisation


#: Station settings that do not change what the expert does in physics.
_NOT_PHYSICS = {"embodiment", "control_rate", "render", "cameras"}


def _station_key(station: StationConfig) -> str:
    """``@station-<hash>`` of the station's physics settings, empty when they are the
    defaults (cache keys of default stations stay what they were)."""
    settings = station.model_dump(exclude=_NOT_PHYSICS)
    if settings == StationConfig().model_dump(exclude=_NOT_PHYSICS):
        return ""
    text = json.dumps(settings, sort_keys=True)
    return "@station-" + hashlib.sha256(text.encode()).hexdigest()[:8]


def expert_verdict(setup: EpisodeSetup, disturb: Sequence[str] = ()) -> dict[str, Any]:
    """``{"ok": ..., "reason": ...}``: whether the expert solves `setup`'s episode in physics
    (no cameras): its scene (plain, or with `randomize` the seed's randomized scene of its
    split), robot and station. With `disturb` (disturbance kinds) the run is traced
    (:func:`~bicoord_drake.runner.generate.trace_expert`) and ``"disturbances"`` holds, per
    kind, the disturbance drawn for the seed (:func:`drawn_to_json`)."""
    try:
        if disturb:
            clean = generation.trace_expert(setup.without_cameras(), disturb)
            drawn = drawn_to_json(clean.disturbances)
            return {"ok": clean.success, "reason": clean.reason, "disturbances": drawn}
        result = generation.run_expert(setup.without_cameras())
        return {"ok": result.success, "reason": result.reason}
    except Exception as exc:  # an expert crash is a failed seed, not a failed run
        reason = f"expert crashed: {generation.format_failure(exc)}"
        if not disturb:
            return {"ok": False, "reason": reason}
        # no trace, no window: the seed's disturbed rollout is skipped with this reason
        drawn = drawn_to_json(dict.fromkeys(parse_disturb(disturb), reason))
        return {"ok": False, "reason": reason, "disturbances": drawn}


def drawn_to_json(drawn: Mapping[str, Disturbance | str]) -> dict[str, dict[str, Any]]:
    """Kind -> ``{"disturbance": its fields}`` or ``{"no_window": reason}`` (JSON values)."""
    return {
        kind: {"disturbance": d.model_dump(mode="json")}
        if isinstance(d, Disturbance)
        else {"no_window": str(d)}
        for kind, d in drawn.items()
    }


def drawn_from_json(data: Mapping[str, Mapping[str, Any]]) -> dict[str, Disturbance | str]:
    """The inverse of :func:`drawn_to_json`."""
    return {
        kind: from_records([v["disturbance"]])[0] if "disturbance" in v else str(v["no_window"])
        for kind, v in data.items()
    }


def demonstration_disturbances(
    task: Task, config: EvaluateConfig, episode: Episode
) -> dict[str, Disturbance | str]:
    """Kind -> the disturbance of each of `config`'s kinds for a rollout on the demonstration
    `episode` (or why it has no window): the one the demonstration recorded, if it was
    generated with that kind; else the one generation draws for it, from a traced clean run
    of the expert on the rollout's episode (the demonstration's seed, scene, physics and
    action-noise level: :func:`~bicoord_drake.runner.generate.trace_expert`)."""
    kinds = config.disturb
    recorded = recorded_disturbances(config, episode)
    if recorded is not None:
        return recorded
    setup = config.episode_setup(task, episode.seed)
    setup = setup.replace(station=rollout_station(config, episode))
    setup = setup.with_scene(episode.seed, episode.scene) if episode.scene else setup
    try:
        traced = generation.trace_expert(setup, kinds, episode.action_noise)
    except Exception as exc:  # an expert crash: no window, the disturbed rollout is skipped
        return dict.fromkeys(kinds, f"expert crashed: {generation.format_failure(exc)}")
    return traced.disturbances


def recorded_disturbances(
    config: EvaluateConfig, episode: Episode
) -> dict[str, Disturbance | str] | None:
    """Kind -> the disturbance of each of `config`'s kinds that the demonstration `episode`
    was generated with; None unless it recorded every kind."""
    recorded = {d.kind: d for d in from_records(episode.disturbances)}
    if all(kind in recorded for kind in config.disturb):
        return {kind: recorded[kind] for kind in config.disturb}
    return None


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
